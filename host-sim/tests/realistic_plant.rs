//! The realistic plant end to end: the run options' `plant` reaches the whole-body rig's
//! simulator (`--plant realistic`), and the whole-body controller holds the soak's claims on it
//! for a few seconds of seeded goals and pushes.
#![allow(clippy::unwrap_used, reason = "tests")]

use host_sim::plant::PlantKind;
use host_sim::scenarios::{soak, RunOptions};

#[test]
fn the_soak_holds_its_claims_on_the_realistic_plant() {
    let realistic = RunOptions { plant: PlantKind::Realistic, ..RunOptions::default() };
    let (metrics, series) = soak::run(3.0, soak::SEED, None, &realistic).unwrap();
    let (ideal, _) = soak::run(3.0, soak::SEED, None, &RunOptions::default()).unwrap();
    // The same seeded goals and pushes acted on both plants; the robot moved differently.
    assert!(metrics.goals >= 1 && metrics.pushes >= 1, "{metrics:?}");
    assert_eq!((metrics.goals, metrics.pushes), (ideal.goals, ideal.pushes));
    assert!((metrics.max_energy_j - ideal.max_energy_j).abs() > 1e-6, "{metrics:?} vs {ideal:?}");
    assert_eq!(metrics.fault_count, 0, "{metrics:?}");
    let outcome = soak::evaluate(&metrics, series).unwrap();
    assert!(outcome.summary.failed_claims().is_empty(), "{:?} {metrics:?}", outcome.summary.failed_claims());
}

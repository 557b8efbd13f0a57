//! The kernel's algorithms never allocate: a counting global allocator sees zero allocations
//! while every dynamics algorithm runs on the Justin-like model (f64 and f32).
//!
//! A separate test binary, because the global allocator is process-wide.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "test code")]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use fixtures::justin;
use kernel::dynamics::{
    coriolis_matrix, crba, forward_dynamics, forward_kinematics, frame_drift, frame_jacobian, gravity,
    kinetic_energy, potential_energy, rnea,
};
use kernel::Data;
use nalgebra::{RealField, SMatrix, SVector};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged; only counts calls.
#[allow(unsafe_code, reason = "a GlobalAlloc impl is unsafe by definition")]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn run_all<T: RealField + Copy>() -> usize {
    let model = justin::model::<T>().unwrap();
    let mut data = Box::new(Data::new(&model));
    let q = justin::home_configuration::<T>();
    let v = SVector::<T, { justin::N }>::repeat(nalgebra::convert(0.3));
    let tau = SVector::<T, { justin::N }>::repeat(nalgebra::convert(1.0));
    let mut jacobian = SMatrix::<T, 6, { justin::N }>::zeros();

    let before = ALLOCATIONS.load(Ordering::SeqCst);
    forward_kinematics(&model, &mut data, &q, &v).unwrap();
    crba(&model, &mut data);
    coriolis_matrix(&model, &mut data);
    gravity(&model, &mut data);
    rnea(&model, &mut data, &tau).unwrap();
    frame_jacobian(&model, &data, justin::RIGHT_TCP, &mut jacobian).unwrap();
    frame_drift(&model, &data, justin::LEFT_TCP).unwrap();
    kinetic_energy(&model, &data);
    potential_energy(&model, &data);
    forward_dynamics(&model, &mut data, &tau).unwrap();
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

#[test]
fn dynamics_algorithms_do_not_allocate() {
    assert_eq!(run_all::<f64>(), 0, "f64 dynamics allocated");
    assert_eq!(run_all::<f32>(), 0, "f32 dynamics allocated");
}

//! What the controller reports: the full [`Telemetry`] of the last cycle (Sec. 7.2:
//! "information about task execution") and the [`TelemetryMessage`] summary it sends to the
//! planner each cycle.

use heapless::Vec;
use nalgebra::{RealField, SVector, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use super::capacity::WIRE_TCP_ERRORS;
use super::capacity::{MAX_ACTIVE, MAX_LEVELS};
use super::config::TaskKind;
use super::error::CommandError;
use super::faults::{Fault, SafeOutput};
use super::guard::Saturation;
use super::layout::PerArm;

/// What the controller found in its last cycle (Sec. 7.2: "information about task execution").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Telemetry<T: RealField, const N: usize, const A: usize> {
    /// Cycle counter of the frame.
    pub cycle: u64,
    /// Controller time since the first valid frame (s).
    pub time_s: T,
    /// The fault of this cycle, if any.
    pub fault: Option<Fault>,
    /// Consecutive faulty cycles.
    pub fault_cycles: u32,
    /// Changes of the output mode since the first cycle ([`super::recovery`]).
    pub mode_changes: u32,
    /// TCP error `(p − p_des, 2ε)` in the desired frame's axes (m, rad-like), per arm
    /// ([`ArmId`](super::layout::ArmId)); zero for a TCP without Cartesian task.
    pub tcp_error: PerArm<Vector6<T>, A>,
    /// Where the Cartesian force limits (Table 7.1) acted: the task clamped its spring force,
    /// or the command-side limit the commanded contact force ([`super::force_limit`]).
    pub tcp_force_limited: PerArm<[bool; 6], A>,
    /// Estimated wrench each TCP applies on its environment (N, Nm), desired-frame axes, per
    /// arm ([`ArmId`](super::layout::ArmId)): `−(J_u J_uᵀ + μ I)⁻¹ J_u τ̂_ext`
    /// ([`super::force_limit`]).
    pub contact_wrench: PerArm<Vector6<T>, A>,
    /// Contact-force governor correction per arm and axis (N, Nm): positive lowers the
    /// upper force bound, negative raises the lower one ([`super::force_limit`]).
    pub force_limit_correction: PerArm<Vector6<T>, A>,
    /// Number of levels in the last projection.
    pub level_count: usize,
    /// Potential energy of each level's springs (J): the level's storage function.
    pub level_storage: [T; MAX_LEVELS],
    /// Its rate, backward difference (W).
    pub level_storage_rate: [T; MAX_LEVELS],
    /// `‖N_i τ_i‖` per level (Nm).
    pub level_torque_norm: [T; MAX_LEVELS],
    /// Conflict of each level with the ones above, `1 − ‖N_i τ_i‖/‖τ_i‖`.
    pub level_conflict: [T; MAX_LEVELS],
    /// Hierarchy entries of the last cycle, in hierarchy order (the first `task_count`).
    pub tasks: [Option<TaskKind>; MAX_ACTIVE],
    /// Number of entries in `tasks`.
    pub task_count: usize,
    /// Largest row activation of each entry.
    pub task_activation: [T; MAX_ACTIVE],
    /// `‖τ_task‖` of each entry before projection (Nm), as in Fig. 6.5.
    pub task_torque_norm: [T; MAX_ACTIVE],
    /// Smallest distance over all collision pairs (m), `None` without a collision task; exact
    /// up to the broad-phase distance (the larger emit distance of the two fields), a lower
    /// bound beyond it.
    pub min_collision_distance: Option<T>,
    /// Collision rows on the stack.
    pub collision_rows: usize,
    /// Manipulability of each arm (when its task runs), per arm ([`ArmId`](super::layout::ArmId)).
    pub manipulability: PerArm<T, A>,
    /// Estimated external joint torque (momentum residual, Nm).
    pub external_torque: SVector<T, N>,
    /// `‖external_torque‖` above the threshold.
    pub contact: bool,
    /// `½ ẏᵀ M_cl ẏ` with the closed-loop inertia (J).
    pub kinetic_energy: T,
    /// Sum of the task potentials (J).
    pub potential_energy: T,
    /// Virtual force on the platform after the deadband (N, N, Nm).
    pub virtual_force: Vector3<T>,
    /// Commanded platform velocity (m/s, m/s, rad/s).
    pub base_velocity: Vector3<T>,
    /// Commanded platform acceleration used in the compensation (m/s², rad/s²).
    pub base_acceleration: Vector3<T>,
    /// `true` while the ICR repulsion acts.
    pub icr_repelling: bool,
    /// What the output guards changed.
    pub saturation: Saturation<T>,
}

impl<T: RealField + Copy, const N: usize, const A: usize> Telemetry<T, N, A> {
    /// The telemetry before the first cycle: every count and value zero, no fault.
    pub(super) fn empty() -> Self {
        Self {
            cycle: 0,
            time_s: T::zero(),
            fault: None,
            fault_cycles: 0,
            mode_changes: 0,
            tcp_error: [Vector6::zeros(); A],
            tcp_force_limited: [[false; 6]; A],
            contact_wrench: [Vector6::zeros(); A],
            force_limit_correction: [Vector6::zeros(); A],
            level_count: 0,
            level_storage: [T::zero(); MAX_LEVELS],
            level_storage_rate: [T::zero(); MAX_LEVELS],
            level_torque_norm: [T::zero(); MAX_LEVELS],
            level_conflict: [T::zero(); MAX_LEVELS],
            tasks: [None; MAX_ACTIVE],
            task_count: 0,
            task_activation: [T::zero(); MAX_ACTIVE],
            task_torque_norm: [T::zero(); MAX_ACTIVE],
            min_collision_distance: None,
            collision_rows: 0,
            manipulability: [T::zero(); A],
            external_torque: SVector::zeros(),
            contact: false,
            kinetic_energy: T::zero(),
            potential_energy: T::zero(),
            virtual_force: Vector3::zeros(),
            base_velocity: Vector3::zeros(),
            base_acceleration: Vector3::zeros(),
            icr_repelling: false,
            saturation: Saturation::none(),
        }
    }
}

/// The telemetry summary the controller sends to the planner each cycle (Sec. 7.2): TCP
/// errors, storage functions and their rates per level, task activations, contact, energy,
/// output mode and fault.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TelemetryMessage<T> {
    /// Cycle counter.
    pub cycle: u64,
    /// Output mode of the cycle.
    pub mode: SafeOutput,
    /// Fault code (0 = none), see [`fault_code`].
    pub fault: u8,
    /// TCP errors per arm ([`ArmId`](super::layout::ArmId)): `(x, y, z, rx, ry, rz)` (m, rad-like);
    /// the first [`WIRE_TCP_ERRORS`] arms on the wire, zero for an arm the robot does not have.
    pub tcp_error: [[T; 6]; WIRE_TCP_ERRORS],
    /// Storage function (potential) per level (J).
    pub level_storage: Vec<T, MAX_LEVELS>,
    /// Its rate per level (W).
    pub level_storage_rate: Vec<T, MAX_LEVELS>,
    /// `(task, largest activation)` per hierarchy entry.
    pub activations: Vec<(TaskKind, T), MAX_ACTIVE>,
    /// Smallest collision distance (m), negative if none is computed.
    pub min_collision_distance: T,
    /// Norm of the external-torque estimate (Nm).
    pub external_torque_norm: T,
    /// Contact detected.
    pub contact: bool,
    /// Kinetic plus task potential energy (J).
    pub energy: T,
    /// Any output guard acted.
    pub saturated: bool,
}

/// A stable small code per fault class for the wire (0 = none).
pub fn fault_code(fault: Option<Fault>) -> u8 {
    match fault {
        None => 0,
        Some(Fault::NonFiniteSensor { .. }) => 1,
        Some(Fault::PositionOutOfRange { .. }) => 2,
        Some(Fault::VelocityOutOfRange { .. }) => 3,
        Some(Fault::StaleFrame { .. }) => 4,
        Some(Fault::CycleGap { .. }) => 5,
        Some(Fault::InconsistentFrame) => 6,
        Some(Fault::Dynamics(_)) => 7,
        Some(Fault::Task(_)) => 8,
        Some(Fault::Hierarchy(_)) => 9,
        Some(Fault::Platform(_)) => 10,
        Some(Fault::NonFiniteOutput) => 11,
    }
}

impl<T: RealField + Copy> TelemetryMessage<T> {
    /// The summary of a cycle's telemetry.
    pub fn from_telemetry<const N: usize, const A: usize>(telemetry: &Telemetry<T, N, A>, mode: SafeOutput) -> Self {
        let t = telemetry;
        let levels = t.level_count.min(MAX_LEVELS);
        let collect = |values: &[T]| values.iter().take(levels).copied().collect::<Vec<T, MAX_LEVELS>>();
        let activations = t
            .tasks
            .iter()
            .zip(t.task_activation.iter())
            .take(t.task_count)
            .filter_map(|(kind, a)| kind.map(|k| (k, *a)))
            .collect();
        let external: SVector<T, N> = t.external_torque;
        Self {
            cycle: t.cycle,
            mode,
            fault: fault_code(t.fault),
            tcp_error: core::array::from_fn(|i| t.tcp_error.get(i).map_or([T::zero(); 6], |e| (*e).into())),
            level_storage: collect(&t.level_storage),
            level_storage_rate: collect(&t.level_storage_rate),
            activations,
            min_collision_distance: t.min_collision_distance.unwrap_or_else(|| -T::one()),
            external_torque_norm: external.norm(),
            contact: t.contact,
            energy: t.kinetic_energy + t.potential_energy,
            saturated: t.saturation.any(),
        }
    }

    /// Encodes into `buffer` (postcard); returns the used prefix.
    pub fn encode<'b>(&self, buffer: &'b mut [u8]) -> Result<&'b mut [u8], CommandError>
    where
        T: Serialize,
    {
        postcard::to_slice(self, buffer).map_err(|_| CommandError::Decode)
    }
}

//! The controller's capacities: the fixed sizes of its tables (tasks, levels, rows), chosen at
//! compile time so that every cycle runs without allocation in bounded time.

/// Most task specifications in a hierarchy.
pub const MAX_TASKS: usize = 16;
/// Most priority levels.
pub const MAX_LEVELS: usize = 8;
/// Most rows on the stack in one cycle (all tasks, all levels).
pub const MAX_ROWS: usize = 128;
/// Most rows one task emits in one cycle (a collision field's closest pairs, the end stops,
/// a joint impedance of every coordinate).
pub const MAX_TASK_ROWS: usize = 32;
/// Most hierarchy entries at once: the tasks of the current hierarchy plus those fading out.
pub const MAX_ACTIVE: usize = 2 * MAX_TASKS;
/// TCP errors in the telemetry message on the wire ([`super::telemetry::TelemetryMessage`]): the
/// first two arms' (zero for an arm the robot does not have). serde has no `Serialize` for an
/// array of a generic length `A`.
pub const WIRE_TCP_ERRORS: usize = 2;

//! The board runtime of the whole-body controller: the Justin controller (`f32`) stepped at
//! 1 kHz, its sensor and actuator frames on a serial link (`link` crate).
//!
//! - [`runtime`]: board-independent — the controller step on the robot's samples, link faults
//!   and safe output, statistics.
//! - [`serial_robot`]: the `hal` joint-torque and platform-velocity interfaces over the serial
//!   link, on any `embedded-io` port.
//! - [`uart`]: the CMSDK APB UART of the MPS2 boards behind `embedded-io`.
//! - [`board`]: the QEMU MPS2 boards: UART0 and the SysTick control tick.
//! - [`probe`]: region markers (the runtime's step is region 0) and stack painting of the
//!   measuring images (`wcet/README.md`).
//!
//! The images are thin binaries in `src/bin/` (`runtime.rs` is the control loop).
#![no_std]

pub mod board;
pub mod probe;
pub mod runtime;
pub mod serial_robot;
pub mod uart;

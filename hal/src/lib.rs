//! Hardware abstraction for a wheeled humanoid: the interfaces between the
//! control application and the robot.
//!
//! # Layers
//!
//! ```text
//!   application loop (firmware, host-sim)   reads, steps, writes; handles errors
//!        │ uses                 │ uses
//!        ▼                      ▼
//!   kernel (step)           hal (this crate)   ◄── implemented by host-sim and by board drivers
//! ```
//!
//! The kernel never calls these traits: its `step` maps one sensor frame to
//! one actuator frame and knows nothing about buses or clocks. The application
//! loop ties both together, once per control cycle:
//!
//! 1. read the sensors ([`JointTorqueInterface::read`],
//!    [`PlatformVelocityInterface::read`], [`CycleClock::now`]);
//! 2. call the kernel's step with the samples;
//! 3. write the actuators ([`JointTorqueInterface::write_torque`],
//!    [`PlatformVelocityInterface::write_velocity`]).
//!
//! This crate does not depend on the kernel (nor on any linear-algebra crate):
//! data cross the boundary as plain arrays, with the scalar type `T` and the
//! number of joints `N` chosen by the user.
//!
//! # Pattern
//!
//! One module per capability ([`joint_torque`], [`platform_velocity`],
//! [`clock`]), in the style of embedded-hal 1.0:
//!
//! - every method is fallible; each implementation names its error type
//!   through [`ErrorType`], and every error reports a portable [`ErrorKind`]
//!   through [`Error::kind`];
//! - an ideal implementation (a simulator, a test double) uses
//!   [`core::convert::Infallible`] as its error;
//! - `&mut D` implements every trait that `D` implements, so generic code can
//!   take an interface by value and callers can lend theirs;
//! - each trait's documentation says what implementors MUST do.
//!
//! The crate is `no_std`, never allocates, has no `unsafe` and no panicking
//! code path. The feature `defmt` derives `defmt::Format` for every public
//! type.
//!
//! # Example
//!
//! One control cycle with ideal in-memory devices and a stand-in for the
//! kernel's step (a joint damper):
//!
//! ```
//! use core::convert::Infallible;
//! use hal::{ErrorType, JointSample, JointTorqueInterface};
//!
//! /// An ideal one-joint body that measures the commanded torque.
//! struct Body {
//!     frame: JointSample<f32, 1>,
//! }
//!
//! impl ErrorType for Body {
//!     type Error = Infallible;
//! }
//!
//! impl JointTorqueInterface<f32, 1> for Body {
//!     fn read(&mut self) -> Result<JointSample<f32, 1>, Infallible> {
//!         self.frame.cycle += 1;
//!         Ok(self.frame)
//!     }
//!     fn write_torque(&mut self, torque: &[f32; 1]) -> Result<(), Infallible> {
//!         self.frame.torque = *torque;
//!         Ok(())
//!     }
//! }
//!
//! /// The application loop's cycle, generic over the interface.
//! fn cycle<J: JointTorqueInterface<f32, 1>>(mut joints: J) -> Result<u64, J::Error> {
//!     let sample = joints.read()?;
//!     let [velocity] = sample.velocity;
//!     let torque = [-2.0 * velocity]; // the kernel's step goes here
//!     joints.write_torque(&torque)?;
//!     Ok(sample.cycle)
//! }
//!
//! let mut body = Body {
//!     frame: JointSample { position: [0.0], velocity: [0.5], torque: [0.0], cycle: 0 },
//! };
//! assert_eq!(cycle(&mut body)?, 1);
//! assert_eq!(body.frame.torque, [-1.0]);
//! # Ok::<(), Infallible>(())
//! ```
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod clock;
pub mod error;
pub mod joint_torque;
pub mod platform_velocity;

pub use clock::CycleClock;
pub use error::{Error, ErrorKind, ErrorType};
pub use joint_torque::{JointSample, JointTorqueInterface};
pub use platform_velocity::{PlatformCommand, PlatformSample, PlatformVelocityInterface, LEGS};

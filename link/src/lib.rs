//! The serial link between a controller board and its host (the robot's I/O, or `host-sim`).
//!
//! `#![no_std]`, no allocation. Every message is a [`Frame`]: a sequence number and one
//! [`Payload`] (a sensor frame in, an actuator frame out, a planner command, telemetry or the
//! board's runtime statistics; before the lockstep, the chunks of the [`setup`] message that
//! configures the board's controller for the scenario, and the board's reply). On the wire a frame is its postcard encoding followed by the
//! CRC-32 (ISO-HDLC) of that encoding, little-endian, COBS-encoded and terminated by a zero byte
//! ([`codec`]). [`FrameReader`] reassembles frames from any [`embedded_io::Read`] byte stream
//! and checks their sequence numbers; [`write_frame`] writes one to any [`embedded_io::Write`],
//! so a board's UART driver and a host's TCP socket plug in alike.
//!
//! Every way a frame can go wrong is a [`LinkError`]: corrupted (bad CRC, or a payload that does
//! not decode), truncated (cut inside a COBS run or shorter than a CRC), oversized or replayed (a sequence
//! number already seen); frames missing before a valid one are counted in [`Received::lost`].
#![no_std]

pub mod codec;
pub mod frames;
pub mod reader;
pub mod setup;

pub use codec::{decode, encode, write_frame, LinkError, MAX_ENCODED, MAX_FRAME_BYTES};
pub use frames::{
    ActuatorMsg, Frame, Joints, LinkFault, OutputMode, Payload, RuntimeStats, SensorMsg, MAX_JOINTS, MAX_MESSAGE_BYTES,
};
pub use reader::{FrameReader, ReadResult, Received, SequenceCheck};
pub use setup::{RigSetup, SetupAssembler, SetupChunk, SetupFault, SetupReply, Volume, VolumeCore};

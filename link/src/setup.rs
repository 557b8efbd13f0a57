//! The SETUP message: the scenario's rig, sent to the board before the lockstep.
//!
//! The host encodes a [`RigSetup`] with postcard and sends it as a sequence of
//! [`SetupChunk`] frames (each a link frame with its own CRC, numbered `index` of `total`,
//! [`split`]). The board collects them in a fixed buffer ([`SetupAssembler`]), decodes the
//! whole ([`decode`]), builds its controller through the kernel's validating constructor and
//! answers with a [`SetupReply`]: accepted with the CRC-32 of the configuration's encoding
//! ([`checksum`]; the host compares it with its own), or refused with a typed [`SetupFault`].

use kernel::controller::config::{TaskSpec, MAX_TASKS};
use kernel::tasks::collision::{Core, SweptSphere};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::codec::CHECKSUM;
use crate::frames::LinkFault;

/// Most environment volumes a rig has (table, wall, …).
pub const MAX_ENVIRONMENT_VOLUMES: usize = 4;
/// Bytes of configuration one chunk carries.
pub const SETUP_CHUNK_BYTES: usize = 128;
/// Most bytes of an encoded [`RigSetup`] (the board's assembly buffer).
pub const MAX_SETUP_BYTES: usize = 1024;
/// Most chunks of one setup.
pub const MAX_SETUP_CHUNKS: usize = MAX_SETUP_BYTES.div_ceil(SETUP_CHUNK_BYTES);

/// What a scenario's rig changes in the whole-body controller of Ch. 6 (Justin's model, its
/// collision model, `whole_body::controller_config`): the environment volumes, the platform
/// axes the admittance moves and the task hierarchy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RigSetup {
    /// Environment volumes in the world frame.
    pub environment: heapless::Vec<Volume, MAX_ENVIRONMENT_VOLUMES>,
    /// Platform axes `(x, y, θ)` the admittance moves (`false` holds the base at rest).
    pub free_base_axes: [bool; 3],
    /// The task hierarchy.
    pub hierarchy: heapless::Vec<TaskSpec, MAX_TASKS>,
}

/// A swept-sphere volume in `f32` (the kernel's `SweptSphere` on the wire).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Volume {
    /// The 1 (sphere), 2 (capsule) or 3 (triangle) points the sphere is swept over (m).
    pub core: VolumeCore,
    /// Radius (m).
    pub radius: f32,
}

/// The core of a [`Volume`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum VolumeCore {
    /// A point.
    Point([f32; 3]),
    /// A segment.
    Segment([[f32; 3]; 2]),
    /// A triangle.
    Triangle([[f32; 3]; 3]),
}

impl Volume {
    /// The volume of the kernel's `volume`, rounded to `f32`.
    pub fn from_swept_sphere(volume: &SweptSphere<f64>) -> Self {
        let point = |p: &Vector3<f64>| [p.x as f32, p.y as f32, p.z as f32];
        let core = match &volume.core {
            Core::Point(p) => VolumeCore::Point(point(p)),
            Core::Segment(s) => VolumeCore::Segment(s.each_ref().map(point)),
            Core::Triangle(t) => VolumeCore::Triangle(t.each_ref().map(point)),
        };
        Self { core, radius: volume.radius as f32 }
    }

    /// The kernel's volume (the collision model checks it when it is built).
    pub fn swept_sphere(&self) -> SweptSphere<f32> {
        let point = |p: &[f32; 3]| Vector3::new(p[0], p[1], p[2]);
        let core = match &self.core {
            VolumeCore::Point(p) => Core::Point(point(p)),
            VolumeCore::Segment(s) => Core::Segment(s.each_ref().map(point)),
            VolumeCore::Triangle(t) => Core::Triangle(t.each_ref().map(point)),
        };
        SweptSphere { core, radius: self.radius }
    }
}

/// One piece of an encoded [`RigSetup`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SetupChunk {
    /// Position in the sequence, from 0.
    pub index: u16,
    /// Chunks in the sequence.
    pub total: u16,
    /// The bytes.
    pub bytes: heapless::Vec<u8, SETUP_CHUNK_BYTES>,
}

/// The board's answer to a complete (or broken) setup.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SetupReply {
    /// The controller is built; the CRC-32 of the configuration's encoding.
    Accepted {
        /// [`checksum`] of the assembled bytes.
        checksum: u32,
    },
    /// The setup was refused; the board has no controller until a valid setup.
    Refused(SetupFault),
}

/// Why a setup was refused.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SetupFault {
    /// A frame of the sequence failed on the link (bad CRC, cut, replayed, …).
    Link(LinkFault),
    /// A chunk's index is not the next one.
    OutOfOrder,
    /// A chunk's total differs from the first chunk's, or is more than [`MAX_SETUP_CHUNKS`].
    WrongTotal,
    /// Another frame came before the last chunk.
    Incomplete,
    /// The assembled bytes are not a [`RigSetup`].
    Undecodable,
    /// The environment volumes do not make a collision model.
    InvalidEnvironment,
    /// The kernel's constructor refused the configuration.
    InvalidConfiguration,
}

/// The CRC-32 of a setup's encoding, which the board acknowledges.
pub fn checksum(encoded: &[u8]) -> u32 {
    CHECKSUM.checksum(encoded)
}

/// Encodes `setup` into `out`; the chunks to send, or `None` if it does not fit.
pub fn split<'o>(
    setup: &RigSetup,
    out: &'o mut [u8; MAX_SETUP_BYTES],
) -> Option<impl Iterator<Item = SetupChunk> + 'o> {
    let encoded: &'o [u8] = postcard::to_slice(setup, out).ok()?;
    let total = u16::try_from(encoded.len().div_ceil(SETUP_CHUNK_BYTES)).ok()?;
    Some(encoded.chunks(SETUP_CHUNK_BYTES).zip(0..).filter_map(move |(bytes, index)| {
        Some(SetupChunk { index, total, bytes: heapless::Vec::from_slice(bytes).ok()? })
    }))
}

/// The setup in `encoded` (all of it, nothing after).
pub fn decode(encoded: &[u8]) -> Result<RigSetup, SetupFault> {
    match postcard::take_from_bytes(encoded) {
        Ok((setup, [])) => Ok(setup),
        _ => Err(SetupFault::Undecodable),
    }
}

/// Collects the chunks of one setup in a fixed buffer.
#[derive(Debug, Default)]
pub struct SetupAssembler {
    buffer: heapless::Vec<u8, MAX_SETUP_BYTES>,
    /// The sequence's total, while one is in progress.
    total: Option<u16>,
    next: u16,
}

impl SetupAssembler {
    /// An assembler with no setup in progress.
    pub const fn new() -> Self {
        Self { buffer: heapless::Vec::new(), total: None, next: 0 }
    }

    /// Whether a sequence has started and not ended.
    pub fn in_progress(&self) -> bool {
        self.total.is_some()
    }

    /// Takes one chunk: chunk 0 starts a new sequence (dropping one in progress). Returns the
    /// assembled bytes after the last chunk; a chunk that does not fit the sequence ends it.
    pub fn push(&mut self, chunk: &SetupChunk) -> Result<Option<&[u8]>, SetupFault> {
        if chunk.index == 0 {
            self.buffer.clear();
            self.total = Some(chunk.total);
            self.next = 0;
        }
        let result = self.accept(chunk);
        if !matches!(result, Ok(false)) {
            self.total = None;
        }
        match result {
            Ok(true) => Ok(Some(&self.buffer)),
            Ok(false) => Ok(None),
            Err(fault) => Err(fault),
        }
    }

    /// Appends `chunk`; `true` when it was the last.
    fn accept(&mut self, chunk: &SetupChunk) -> Result<bool, SetupFault> {
        let total = self.total.ok_or(SetupFault::OutOfOrder)?;
        if chunk.total != total || usize::from(total) > MAX_SETUP_CHUNKS {
            return Err(SetupFault::WrongTotal);
        }
        if chunk.index != self.next {
            return Err(SetupFault::OutOfOrder);
        }
        self.buffer.extend_from_slice(&chunk.bytes).map_err(|_| SetupFault::WrongTotal)?;
        self.next += 1;
        Ok(self.next == total)
    }

    /// Ends a sequence in progress because another frame came (`Incomplete`) or a frame failed
    /// on the link (`Link`); `None` if none was in progress.
    pub fn interrupt(&mut self, link_fault: Option<LinkFault>) -> Option<SetupFault> {
        self.total.take()?;
        Some(link_fault.map_or(SetupFault::Incomplete, SetupFault::Link))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, reason = "tests")]
    extern crate std;
    use std::vec::Vec;

    use kernel::controller::config::{ArmId, Field, TaskKind};

    use super::*;

    fn setup() -> RigSetup {
        let wall =
            Volume { core: VolumeCore::Triangle([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 1.0]]), radius: 0.01 };
        let mut hierarchy = heapless::Vec::new();
        for (level, kind) in [
            TaskKind::EndStops,
            TaskKind::CollisionAvoidance(Field::Strong),
            TaskKind::CartesianImpedance(ArmId::RIGHT),
        ]
        .into_iter()
        .enumerate()
        {
            hierarchy.push(TaskSpec { kind, level: level as u8 }).unwrap();
        }
        RigSetup {
            environment: heapless::Vec::from_slice(&[wall; 4]).unwrap(),
            free_base_axes: [true, false, true],
            hierarchy,
        }
    }

    fn chunks(setup: &RigSetup) -> (Vec<SetupChunk>, u32) {
        let mut out = [0; MAX_SETUP_BYTES];
        let chunks: Vec<SetupChunk> = split(setup, &mut out).unwrap().collect();
        let length: usize = chunks.iter().map(|c| c.bytes.len()).sum();
        (chunks, checksum(&out[..length]))
    }

    #[test]
    fn a_setup_survives_its_chunks_and_the_checksum_is_the_encodings() {
        let (chunks, sent) = chunks(&setup());
        assert!(chunks.len() >= 2, "{} chunks", chunks.len());
        let mut assembler = SetupAssembler::new();
        for chunk in &chunks[..chunks.len() - 1] {
            assert_eq!(assembler.push(chunk), Ok(None));
            assert!(assembler.in_progress());
        }
        let bytes = assembler.push(chunks.last().unwrap()).unwrap().unwrap().to_vec();
        assert!(!assembler.in_progress());
        assert_eq!(checksum(&bytes), sent);
        assert_eq!(decode(&bytes), Ok(setup()));
    }

    #[test]
    fn broken_sequences_are_typed_faults() {
        let (chunks, _) = chunks(&setup());
        let mut assembler = SetupAssembler::new();
        // A chunk skipped.
        assembler.push(&chunks[0]).unwrap();
        assert_eq!(assembler.push(&SetupChunk { index: 2, ..chunks[1].clone() }), Err(SetupFault::OutOfOrder));
        assert!(!assembler.in_progress());
        // A chunk without a start.
        assert_eq!(assembler.push(&chunks[1]), Err(SetupFault::OutOfOrder));
        // A total that changes, or more chunks than the buffer holds.
        assembler.push(&chunks[0]).unwrap();
        assert_eq!(assembler.push(&SetupChunk { total: 9, ..chunks[1].clone() }), Err(SetupFault::WrongTotal));
        let too_many = SetupChunk { total: MAX_SETUP_CHUNKS as u16 + 1, ..chunks[0].clone() };
        assert_eq!(assembler.push(&too_many), Err(SetupFault::WrongTotal));
        // Cut short by another frame, or by a frame the link refused.
        assert_eq!(assembler.interrupt(None), None);
        assembler.push(&chunks[0]).unwrap();
        assert_eq!(assembler.interrupt(None), Some(SetupFault::Incomplete));
        assembler.push(&chunks[0]).unwrap();
        assert_eq!(assembler.interrupt(Some(LinkFault::Corrupted)), Some(SetupFault::Link(LinkFault::Corrupted)));
        // A short total: the bytes end inside the encoding.
        let mut out = [0; MAX_SETUP_BYTES];
        let encoded = postcard::to_slice(&setup(), &mut out).unwrap();
        assert_eq!(decode(&encoded[..encoded.len() - 1]), Err(SetupFault::Undecodable));
        assert_eq!(decode(&[&*encoded, &[0]].concat()), Err(SetupFault::Undecodable));
    }

    #[test]
    fn volumes_keep_their_points_in_f32() {
        let triangle = SweptSphere {
            core: Core::Triangle([Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.2, 0.3), Vector3::zeros()]),
            radius: 0.05,
        };
        let volume = Volume::from_swept_sphere(&triangle);
        assert_eq!(volume.core, VolumeCore::Triangle([[1.0, 2.0, 3.0], [0.1, 0.2, 0.3], [0.0; 3]]));
        let back = volume.swept_sphere();
        assert_eq!(back.radius, 0.05_f32);
        assert_eq!(
            back.core,
            Core::Triangle([Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.2, 0.3), Vector3::zeros()])
        );
    }
}

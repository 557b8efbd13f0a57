//! Reassembling frames from a byte stream and checking their sequence numbers.

use crate::codec::{decode, LinkError, MAX_ENCODED};
use crate::frames::Frame;

/// A valid frame and how many frames the sender sent before it that never arrived.
#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    /// The frame.
    pub frame: Frame,
    /// Frames skipped since the last accepted one (0: none missing).
    pub lost: u32,
}

/// A frame, or why the bytes up to a frame's end were refused.
pub type ReadResult<E> = Result<Received, LinkError<E>>;

/// Collects bytes up to each terminating zero and decodes the frame before it.
///
/// After an oversized frame the bytes up to the next zero are dropped, so one bad frame costs
/// one frame. Sequence numbers are checked by [`SequenceCheck`].
pub struct FrameReader {
    buffer: [u8; MAX_ENCODED],
    len: usize,
    overflowed: bool,
    sequence: SequenceCheck,
}

impl Default for FrameReader {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameReader {
    /// An empty reader that accepts any first sequence number.
    pub const fn new() -> Self {
        Self { buffer: [0; MAX_ENCODED], len: 0, overflowed: false, sequence: SequenceCheck::new() }
    }

    /// Takes one byte; at a frame's end returns the frame or why it is refused.
    pub fn push<E>(&mut self, byte: u8) -> Option<ReadResult<E>> {
        if byte != 0 {
            match self.buffer.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            return Some(Err(LinkError::Oversized));
        }
        if len == 0 {
            return None; // an idle zero between frames
        }
        let frame = self.buffer.get_mut(..len).map_or(Err(LinkError::Oversized), decode);
        Some(frame.and_then(|frame| Ok(Received { lost: self.sequence.accept(frame.seq)?, frame })))
    }

    /// Reads from `port` until one frame ends (blocking as `port.read` does).
    pub fn read<R: embedded_io::Read>(&mut self, port: &mut R) -> ReadResult<R::Error> {
        let mut byte = [0u8; 1];
        loop {
            if port.read(&mut byte).map_err(LinkError::Io)? == 0 {
                return Err(LinkError::Closed);
            }
            if let Some(result) = self.push(byte[0]) {
                return result;
            }
        }
    }

    /// Takes every byte `port` has ready without blocking; returns the first frame that ends.
    pub fn poll<R: embedded_io::Read + embedded_io::ReadReady>(
        &mut self,
        port: &mut R,
    ) -> Option<ReadResult<R::Error>> {
        let mut byte = [0u8; 1];
        loop {
            match port.read_ready() {
                Ok(true) => {}
                Ok(false) => return None,
                Err(e) => return Some(Err(LinkError::Io(e))),
            }
            match port.read(&mut byte) {
                Ok(0) => return Some(Err(LinkError::Closed)),
                Ok(_) => {}
                Err(e) => return Some(Err(LinkError::Io(e))),
            }
            if let Some(result) = self.push(byte[0]) {
                return Some(result);
            }
        }
    }
}

/// The receiver's view of the sender's sequence numbers: each frame must carry a number above
/// the last accepted one; skipped numbers are reported as lost frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SequenceCheck {
    next: Option<u32>,
}

impl SequenceCheck {
    /// Accepts any first number.
    pub const fn new() -> Self {
        Self { next: None }
    }

    /// Accepts `seq` (returning how many frames were skipped before it) or refuses it as
    /// replayed; a refused number does not change what is expected.
    pub fn accept<E>(&mut self, seq: u32) -> Result<u32, LinkError<E>> {
        let lost = match self.next {
            Some(expected) if seq < expected => return Err(LinkError::Replayed { seq, expected }),
            Some(expected) => seq - expected,
            None => 0,
        };
        self.next = Some(seq.wrapping_add(1));
        Ok(lost)
    }
}

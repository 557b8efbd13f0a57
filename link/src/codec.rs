//! One frame on the wire: `COBS(postcard(frame) ‖ CRC-32(postcard(frame)) as 4 bytes LE) ‖ 0`.

use crc::{Crc, CRC_32_ISO_HDLC};

use crate::frames::Frame;

/// The frame checksum: CRC-32 (ISO-HDLC, as Ethernet and zlib).
pub(crate) const CHECKSUM: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);
/// Bytes of the checksum after the payload.
const CHECKSUM_BYTES: usize = 4;
/// Most bytes of a frame's postcard encoding plus its checksum.
pub const MAX_FRAME_BYTES: usize = 512;
/// Most bytes of an encoded frame on the wire, the terminating zero included.
pub const MAX_ENCODED: usize = cobs::max_encoding_length(MAX_FRAME_BYTES) + 1;

/// What can go wrong with a frame, or with the byte stream that carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkError<E> {
    /// The checksum does not match, or the payload does not decode.
    Corrupted,
    /// The frame ends inside a COBS run, or is shorter than its checksum.
    Truncated,
    /// The frame is longer than [`MAX_FRAME_BYTES`] (or does not fit the encoding buffer).
    Oversized,
    /// A sequence number at or below the last accepted one.
    Replayed {
        /// The frame's sequence number.
        seq: u32,
        /// The next sequence number expected.
        expected: u32,
    },
    /// The byte stream ended (end of file, connection closed).
    Closed,
    /// The byte stream failed.
    Io(E),
}

impl<E> core::fmt::Display for LinkError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Corrupted => f.write_str("corrupted frame"),
            Self::Truncated => f.write_str("truncated frame"),
            Self::Oversized => f.write_str("oversized frame"),
            Self::Replayed { seq, expected } => write!(f, "replayed frame {seq} (expected {expected})"),
            Self::Closed => f.write_str("link closed"),
            Self::Io(_) => f.write_str("link I/O error"),
        }
    }
}

/// Encodes `frame` into `out`, the terminating zero included; returns the bytes to send.
pub fn encode<'o>(frame: &Frame, out: &'o mut [u8; MAX_ENCODED]) -> Result<&'o [u8], LinkError<()>> {
    let mut raw = [0u8; MAX_FRAME_BYTES];
    let body_len = postcard::to_slice(frame, &mut raw[..MAX_FRAME_BYTES - CHECKSUM_BYTES])
        .map_err(|_| LinkError::Oversized)?
        .len();
    let (body, tail) = raw.split_at_mut(body_len);
    let crc = CHECKSUM.checksum(body).to_le_bytes();
    tail.get_mut(..CHECKSUM_BYTES).ok_or(LinkError::Oversized)?.copy_from_slice(&crc);
    let raw = raw.get(..body_len + CHECKSUM_BYTES).ok_or(LinkError::Oversized)?;
    let n = cobs::try_encode(raw, out).map_err(|_| LinkError::Oversized)?;
    *out.get_mut(n).ok_or(LinkError::Oversized)? = 0;
    out.get(..=n).ok_or(LinkError::Oversized)
}

/// Decodes one COBS-encoded frame (without its terminating zero) in place, checking the CRC.
pub fn decode<E>(encoded: &mut [u8]) -> Result<Frame, LinkError<E>> {
    // Without zero bytes the only invalid COBS is a run that goes past the end: a cut frame.
    let n = cobs::decode_in_place(encoded).map_err(|_| LinkError::Truncated)?;
    let raw = encoded.get(..n).ok_or(LinkError::Corrupted)?;
    if n < CHECKSUM_BYTES {
        return Err(LinkError::Truncated);
    }
    let (body, crc) = raw.split_at(n - CHECKSUM_BYTES);
    if CHECKSUM.checksum(body).to_le_bytes() != crc {
        return Err(LinkError::Corrupted);
    }
    postcard::from_bytes(body).map_err(|_| LinkError::Corrupted)
}

/// Encodes `frame` and writes it to `port`, then flushes.
pub fn write_frame<W: embedded_io::Write>(port: &mut W, frame: &Frame) -> Result<(), LinkError<W::Error>> {
    let mut out = [0u8; MAX_ENCODED];
    let bytes = encode(frame, &mut out).map_err(|_| LinkError::Oversized)?;
    port.write_all(bytes).map_err(LinkError::Io)?;
    port.flush().map_err(LinkError::Io)
}

//! Frames: `0x00, COBS(version ‖ postcard(message) ‖ CRC-32), 0x00`.
//!
//! The CRC is the blob's CRC-32 (ISO-HDLC) over the version byte and the
//! message, little-endian. A delimiter on both sides means garbage on the
//! line forms a frame of its own, which fails and is counted, and never
//! swallows the good frame after it. Empty frames (two delimiters in a row)
//! are the idle line, not counted.

use serde::de::DeserializeOwned;
use serde::Serialize;

use super::message::{RxCounts, PROTOCOL_VERSION};
use crate::map::crc32;

/// Why a message could not be framed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EncodeError {
    /// The encoded frame does not fit the buffer given.
    TooLarge,
}

/// Why a received frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Longer than the receive buffer: dropped up to the next delimiter.
    Overflow,
    /// Not valid COBS.
    Cobs,
    /// Too short to hold a version byte and a CRC.
    Short,
    /// The CRC does not match.
    Crc,
    /// Another protocol version.
    Version(u8),
    /// The payload is no message of this type, or has bytes left over.
    Decode,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Overflow => f.write_str("frame longer than the receive buffer"),
            Self::Cobs => f.write_str("not valid COBS"),
            Self::Short => f.write_str("frame too short"),
            Self::Crc => f.write_str("CRC mismatch"),
            Self::Version(v) => write!(f, "protocol version {v}, expected {PROTOCOL_VERSION}"),
            Self::Decode => f.write_str("payload is not a message"),
        }
    }
}

impl core::error::Error for FrameError {}

/// Bytes a frame of a payload of `n` bytes (message only) can take;
/// `usize::MAX` for a payload past half the address space (no memory holds
/// such a frame, and the exact count would not fit).
pub const fn max_frame_len(n: usize) -> usize {
    // Delimiters, version and CRC around the COBS of n + 5 bytes.
    let m = n.saturating_add(5);
    if m > usize::MAX / 2 {
        return usize::MAX;
    }
    2 + cobs::max_encoding_length(m)
}

/// Frames `msg` into `out`; returns the bytes written. `N` is the scratch
/// size for the unframed payload (version, message, CRC).
pub fn encode<T: Serialize, const N: usize>(msg: &T, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut raw = [0u8; N];
    // Every slice through `get`: no panic path. A scratch under 5 bytes, or
    // one the message fills, is TooLarge.
    let payload = raw.get_mut(1..N.saturating_sub(4)).ok_or(EncodeError::TooLarge)?;
    let n = postcard::to_slice(msg, payload).map_err(|_| EncodeError::TooLarge)?.len().saturating_add(1);
    *raw.first_mut().ok_or(EncodeError::TooLarge)? = PROTOCOL_VERSION;
    let crc = crc32(raw.get(..n).ok_or(EncodeError::TooLarge)?);
    // (`n ≤ N`: the sum cannot wrap; saturating says so to the compiler.)
    let end = n.saturating_add(4);
    raw.get_mut(n..end).ok_or(EncodeError::TooLarge)?.copy_from_slice(&crc.to_le_bytes());
    let body = raw.get(..end).ok_or(EncodeError::TooLarge)?;
    let Some((first, rest)) = out.split_first_mut() else { return Err(EncodeError::TooLarge) };
    *first = 0;
    let k = cobs::try_encode(body, rest).map_err(|_| EncodeError::TooLarge)?;
    let end = rest.get_mut(k).ok_or(EncodeError::TooLarge)?;
    *end = 0;
    Ok(k + 2)
}

/// A receiver: bytes in, messages out, every bad frame dropped and counted.
/// Holds one frame of up to `N` encoded bytes.
#[derive(Clone, Debug)]
pub struct Decoder<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
    counts: RxCounts,
}

impl<const N: usize> Default for Decoder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Decoder<N> {
    /// Empty, counts at zero.
    pub const fn new() -> Self {
        Self {
            buf: [0; N],
            len: 0,
            overflow: false,
            counts: RxCounts { ok: 0, overflow: 0, cobs: 0, short: 0, crc: 0, version: 0, decode: 0 },
        }
    }

    /// Frames received so far, by fate.
    pub fn counts(&self) -> RxCounts {
        self.counts
    }

    /// One byte from the line. At a delimiter that ends a non-empty frame:
    /// the message, or why the frame was dropped (already counted).
    pub fn push<T: DeserializeOwned>(&mut self, byte: u8) -> Option<Result<T, FrameError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len = self.len.saturating_add(1);
                }
                None => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            self.counts.overflow = self.counts.overflow.saturating_add(1);
            return Some(Err(FrameError::Overflow));
        }
        if len == 0 {
            return None;
        }
        let r = self.decode(len);
        match r {
            Ok(_) => self.counts.ok = self.counts.ok.saturating_add(1),
            Err(FrameError::Overflow) => self.counts.overflow = self.counts.overflow.saturating_add(1),
            Err(FrameError::Cobs) => self.counts.cobs = self.counts.cobs.saturating_add(1),
            Err(FrameError::Short) => self.counts.short = self.counts.short.saturating_add(1),
            Err(FrameError::Crc) => self.counts.crc = self.counts.crc.saturating_add(1),
            Err(FrameError::Version(_)) => self.counts.version = self.counts.version.saturating_add(1),
            Err(FrameError::Decode) => self.counts.decode = self.counts.decode.saturating_add(1),
        }
        Some(r)
    }

    fn decode<T: DeserializeOwned>(&mut self, len: usize) -> Result<T, FrameError> {
        let n = cobs_in_place(&mut self.buf, len)?;
        let raw = self.buf.get(..n).ok_or(FrameError::Cobs)?;
        if raw.len() < 5 {
            return Err(FrameError::Short);
        }
        let (body, crc) = raw.split_at(raw.len() - 4);
        if crc32(body).to_le_bytes() != crc {
            return Err(FrameError::Crc);
        }
        let Some((&version, message)) = body.split_first() else { return Err(FrameError::Short) };
        if version != PROTOCOL_VERSION {
            return Err(FrameError::Version(version));
        }
        match postcard::take_from_bytes(message) {
            Ok((msg, [])) => Ok(msg),
            _ => Err(FrameError::Decode),
        }
    }
}

/// COBS-decodes `buf[..len]` in place through `cobs`'s byte-wise state
/// machine (what `cobs::decode` runs), writing with `get_mut`:
/// `cobs::decode_in_place` indexes its buffer with checks the compiler
/// cannot remove, which would leave a panic path in the firmware. In
/// place is safe: every decoded byte costs at least one input byte, and
/// the first is the overhead byte, so the write index stays behind the
/// read index. The unit test `cobs_matches_the_crate` checks it against
/// `cobs::decode` on every kind of frame.
fn cobs_in_place(buf: &mut [u8], len: usize) -> Result<usize, FrameError> {
    use cobs::{DecodeResult, DecoderState};
    let mut state = DecoderState::Idle;
    let mut n = 0usize;
    for i in 0..=len {
        // The frame's bytes, then the delimiter the decoder expects.
        let byte = if i < len { *buf.get(i).ok_or(FrameError::Cobs)? } else { 0 };
        match state.feed(byte) {
            Err(_) => return Err(FrameError::Cobs),
            Ok(DecodeResult::NoData) => {}
            Ok(DecodeResult::DataStart) => n = 0,
            Ok(DecodeResult::DataContinue(b)) => {
                *buf.get_mut(n).ok_or(FrameError::Cobs)? = b;
                n += 1;
            }
            Ok(DecodeResult::DataComplete) => return Ok(n),
        }
    }
    Err(FrameError::Cobs)
}

#[cfg(test)]
mod tests {
    use super::cobs_in_place;

    /// Against `cobs::decode` (the crate's own streaming decoder into a
    /// separate buffer): every zero-free input of random length and bytes,
    /// and every well-formed frame the crate's encoder makes, decode to the
    /// same bytes or are refused by both.
    #[test]
    fn cobs_matches_the_crate() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for case in 0..20_000 {
            let mut len = (next() % 590) as usize;
            let mut src = [0u8; 600];
            let mut sent: Option<([u8; 590], usize)> = None;
            if case % 2 == 0 {
                for b in src[..len].iter_mut() {
                    // Small codes are the interesting ones.
                    *b = if next() % 3 == 0 { (next() % 8) as u8 + 1 } else { (next() % 255) as u8 + 1 };
                }
            } else {
                let mut raw = [0u8; 590];
                for b in raw[..len].iter_mut() {
                    *b = if next() % 4 == 0 { 0 } else { next() as u8 };
                }
                sent = Some((raw, len));
                len = cobs::encode(&raw[..len], &mut src);
            }
            let mut want = [0u8; 600];
            let expected = cobs::decode(&src[..len], &mut want).map(|r| r.frame_size()).ok();
            let mut buf = src;
            let got = cobs_in_place(&mut buf, len).ok();
            assert_eq!(got, expected, "case {case}: {:?}", &src[..len]);
            if let Some(n) = got {
                assert_eq!(&buf[..n], &want[..n], "case {case}");
            }
            if let Some((raw, m)) = sent {
                assert_eq!(got, Some(m), "case {case}: a well-formed frame refused");
                assert_eq!(&buf[..m], &raw[..m], "case {case}");
            }
        }
    }
}

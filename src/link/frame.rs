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

/// Bytes a frame of a payload of `n` bytes (message only) can take.
pub const fn max_frame_len(n: usize) -> usize {
    // Delimiters, version and CRC around the COBS of n + 5 bytes.
    2 + cobs::max_encoding_length(n + 5)
}

/// Frames `msg` into `out`; returns the bytes written. `N` is the scratch
/// size for the unframed payload (version, message, CRC).
pub fn encode<T: Serialize, const N: usize>(msg: &T, out: &mut [u8]) -> Result<usize, EncodeError> {
    let mut raw = [0u8; N];
    if N < 5 {
        return Err(EncodeError::TooLarge);
    }
    raw[0] = PROTOCOL_VERSION;
    let n = postcard::to_slice(msg, &mut raw[1..N - 4]).map_err(|_| EncodeError::TooLarge)?.len() + 1;
    let crc = crc32(&raw[..n]);
    raw[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    let body = &raw[..n + 4];
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
            if self.len < N {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.len = 0;
        self.overflow = false;
        if overflow {
            self.counts.overflow += 1;
            return Some(Err(FrameError::Overflow));
        }
        if len == 0 {
            return None;
        }
        let r = self.decode(len);
        match r {
            Ok(_) => self.counts.ok += 1,
            Err(FrameError::Overflow) => self.counts.overflow += 1,
            Err(FrameError::Cobs) => self.counts.cobs += 1,
            Err(FrameError::Short) => self.counts.short += 1,
            Err(FrameError::Crc) => self.counts.crc += 1,
            Err(FrameError::Version(_)) => self.counts.version += 1,
            Err(FrameError::Decode) => self.counts.decode += 1,
        }
        Some(r)
    }

    fn decode<T: DeserializeOwned>(&mut self, len: usize) -> Result<T, FrameError> {
        let n = cobs::decode_in_place(&mut self.buf[..len]).map_err(|_| FrameError::Cobs)?;
        let raw = &self.buf[..n];
        if raw.len() < 5 {
            return Err(FrameError::Short);
        }
        let (body, crc) = raw.split_at(raw.len() - 4);
        if crc32(body).to_le_bytes() != crc {
            return Err(FrameError::Crc);
        }
        if body[0] != PROTOCOL_VERSION {
            return Err(FrameError::Version(body[0]));
        }
        match postcard::take_from_bytes(&body[1..]) {
            Ok((msg, [])) => Ok(msg),
            _ => Err(FrameError::Decode),
        }
    }
}

//! Scenario files: a recorded or simulated run (ring geometry, odometry
//! increments, per-transducer echo times as the driver times them, ground
//! truth) in a compact, versioned, CRC-checked binary form that a board can
//! replay through the real driver. Read in place with no allocation; every
//! field is checked once, in [`Scenario::parse`], so iteration cannot fail.
//!
//! Layout (little-endian; `docs/scenario.md`):
//!
//! | offset | field | bytes |
//! |---|---|---|
//! | 0 | magic `ECSN` | 4 |
//! | 4 | version (1) | 2 |
//! | 6 | header length `64 + 12·n` | 2 |
//! | 8 | CRC-32 of the map blob it was made on | 4 |
//! | 12 | transducers `n` (1..=255) | 2 |
//! | 14 | record length (40) | 2 |
//! | 16 | records | 4 |
//! | 20 | speed of sound the echo times assume, µm/s | 4 |
//! | 24 | ring period, µs | 4 |
//! | 28 | slot length, µs | 4 |
//! | 32 | start pose x, y (m), φ (rad): `f32` ×3 | 12 |
//! | 44 | its standard deviations: `f32` ×3 | 12 |
//! | 56 | pass bounds: position RMSE (m), heading RMSE (°): `f32` ×2 | 8 |
//! | 64 | mounts: `i32` x mm, y mm, heading mdeg, ×n | 12·n |
//! | … | records, 40 bytes each (below) | 40·records |
//! | end | CRC-32 of everything before it | 4 |
//!
//! A record: `u32` firing time (µs from the start, wrapping), `u32` ring
//! cycle, `u8` transducer, `u8` slot, `u8` flags (bit 0: an echo), `u8` 0,
//! `u32` echo round-trip time (µs; 0 without an echo), odometry increment
//! since the previous record in the robot's frame (forward m, left m, turn
//! rad: `f32` ×3), and the true pose at the firing (x m, y m, φ rad: `f32` ×3).
//!
//! ```
//! use echoloc::scenario::{Header, Record, Scenario, write};
//! use echoloc::predict::Mount;
//! let header = Header {
//!     map_crc: 7, speed_um_per_s: 343_400_000, period_us: 600_000, slot_us: 35_000,
//!     start: [1.0, 2.0, 0.0], start_sigma: [0.05, 0.05, 0.02], bound_position_m: 0.1, bound_heading_deg: 2.0,
//! };
//! let mounts = [Mount { x_mm: 100, y_mm: 0, heading_mdeg: 0 }];
//! let rec = Record { time_us: 0, cycle: 0, transducer: 0, slot: 0, echo_us: Some(11_650),
//!                    odometry: [0.0; 3], truth: [1.0, 2.0, 0.0] };
//! let mut bytes = Vec::new();
//! write(&header, &mounts, &[rec], |b| bytes.extend_from_slice(b)).unwrap();
//! let s = Scenario::parse(&bytes).unwrap();
//! assert_eq!(s.records().next(), Some(rec));
//! assert!(s.check_map(7).is_ok());
//! ```

use crate::map::Crc32;
use crate::predict::Mount;

pub mod replay;

/// `ECSN`.
pub const MAGIC: [u8; 4] = *b"ECSN";
/// The format version this reader takes.
pub const VERSION: u16 = 1;
/// Bytes before the mounts.
pub const FIXED_HEADER_LEN: usize = 64;
/// Bytes per mount.
pub const MOUNT_LEN: usize = 12;
/// Bytes per record.
pub const RECORD_LEN: usize = 40;
/// Mount coordinates beyond this, mm, are refused (a ring is not 100 m wide).
pub const MAX_MOUNT_MM: i32 = 100_000;

/// The run as a whole.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// CRC-32 of the map blob the scenario was made on.
    pub map_crc: u32,
    /// Speed of sound the echo times assume, µm/s.
    pub speed_um_per_s: u32,
    /// Ring period, µs.
    pub period_us: u32,
    /// Slot length, µs.
    pub slot_us: u32,
    /// Where the filter starts: x, y (m), φ (rad).
    pub start: [f32; 3],
    /// The start's standard deviations.
    pub start_sigma: [f32; 3],
    /// The replay fails if the position RMSE exceeds this, m.
    pub bound_position_m: f32,
    /// ... or the heading RMSE this, degrees.
    pub bound_heading_deg: f32,
}

/// One firing.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Record {
    /// Firing time, µs from the start (wrapping).
    pub time_us: u32,
    /// Ring cycle.
    pub cycle: u32,
    /// Which transducer fired.
    pub transducer: u8,
    /// Its slot in the cycle.
    pub slot: u8,
    /// The echo's round-trip time, µs, if one came.
    pub echo_us: Option<u32>,
    /// Odometry since the previous record: forward m, left m, turn rad.
    pub odometry: [f32; 3],
    /// The true pose at the firing: x m, y m, φ rad.
    pub truth: [f32; 3],
}

/// Why a scenario was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScenarioError {
    /// Shorter than its header says, or not a whole number of records.
    Length,
    /// Not a scenario.
    Magic,
    /// A version this reader does not take.
    Version(u16),
    /// The header's own sizes disagree (transducer count, header or record length).
    Layout,
    /// The CRC does not match: the file is damaged.
    Crc {
        /// Stored.
        stored: u32,
        /// Computed.
        computed: u32,
    },
    /// A header field out of range (a non-finite pose, a zero speed of sound).
    Header,
    /// Mount `n` out of range.
    Mount(u8),
    /// Record `n` is malformed (transducer out of range, unknown flags, an
    /// echo time with no echo, a non-finite number).
    Record(u32),
    /// The scenario was made on another map.
    MapMismatch {
        /// The map it was made on.
        expected: u32,
        /// The map given.
        found: u32,
    },
    /// More records than the format counts (2³² − 1).
    Count,
    /// The ring driver replaying it runs on other timing than the scenario
    /// was made for (ring period, slot length or speed of sound).
    Driver {
        /// The scenario's ring period, slot length (µs) and speed of sound (µm/s).
        expected: [u32; 3],
        /// The driver's.
        found: [u32; 3],
    },
}

impl Header {
    /// `Ok` if a ring driver with this period and slot length (µs) and speed
    /// of sound (µm/s) fires and times as the scenario assumes, so that
    /// replaying it through that driver ([`replay`]) reproduces its records.
    pub fn check_driver(&self, period_us: u32, slot_us: u32, speed_um_per_s: u32) -> Result<(), ScenarioError> {
        let expected = [self.period_us, self.slot_us, self.speed_um_per_s];
        let found = [period_us, slot_us, speed_um_per_s];
        if expected == found {
            Ok(())
        } else {
            Err(ScenarioError::Driver { expected, found })
        }
    }

    /// Every float finite, deviations and bounds not negative, a speed of sound.
    fn is_valid(&self) -> bool {
        let bounds = [self.bound_position_m, self.bound_heading_deg];
        self.speed_um_per_s != 0
            && self.start.iter().chain(&self.start_sigma).chain(&bounds).all(|v| v.is_finite())
            && self.start_sigma.iter().chain(&bounds).all(|&v| v >= 0.0)
    }
}

fn mount_ok(m: &Mount) -> bool {
    m.x_mm.unsigned_abs() <= MAX_MOUNT_MM as u32
        && m.y_mm.unsigned_abs() <= MAX_MOUNT_MM as u32
        && m.heading_mdeg.unsigned_abs() <= 360_000
}

impl core::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Length => write!(f, "truncated, or not a whole number of records"),
            Self::Magic => write!(f, "not a scenario (no ECSN magic)"),
            Self::Version(v) => write!(f, "version {v}, this reader takes {VERSION}"),
            Self::Layout => write!(f, "header sizes disagree (transducers, header or record length)"),
            Self::Crc { stored, computed } => {
                write!(f, "damaged: CRC {computed:#010x} does not match the stored {stored:#010x}")
            }
            Self::Header => write!(f, "a header field out of range"),
            Self::Mount(i) => write!(f, "mount {i} out of range (beyond ±100 m or ±360°)"),
            Self::Record(i) => write!(f, "record {i} malformed"),
            Self::MapMismatch { expected, found } => {
                write!(f, "made on the map with CRC {expected:#010x}, not this one ({found:#010x})")
            }
            Self::Count => write!(f, "more records than a scenario holds"),
            Self::Driver { expected, found } => write!(
                f,
                "made for a ring of period {} µs, slot {} µs, sound {} µm/s; the driver runs {} µs, {} µs, {} µm/s",
                expected[0], expected[1], expected[2], found[0], found[1], found[2]
            ),
        }
    }
}

impl core::error::Error for ScenarioError {}

/// One checked record's fields.
fn record_of(r: &[u8]) -> Record {
    Record {
        time_us: u32_at(r, 0),
        cycle: u32_at(r, 4),
        transducer: u8_at(r, 8),
        slot: u8_at(r, 9),
        echo_us: (u8_at(r, 10) & 1 == 1).then(|| u32_at(r, 12)),
        odometry: f32x3(r, 16),
        truth: f32x3(r, 28),
    }
}

// Callers read only offsets their lengths were checked for; `get` keeps a
// read past the end a 0 rather than a panic path.
fn u8_at(b: &[u8], o: usize) -> u8 {
    b.get(o).copied().unwrap_or(0)
}
fn u16_at(b: &[u8], o: usize) -> u16 {
    match b.get(o..o.saturating_add(2)) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}
fn u32_at(b: &[u8], o: usize) -> u32 {
    match b.get(o..o.saturating_add(4)) {
        Some(&[x, y, z, w]) => u32::from_le_bytes([x, y, z, w]),
        _ => 0,
    }
}
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_bits(u32_at(b, o))
}
fn f32x3(b: &[u8], o: usize) -> [f32; 3] {
    [f32_at(b, o), f32_at(b, o + 4), f32_at(b, o + 8)]
}

/// A validated scenario, read in place.
#[derive(Clone, Copy, Debug)]
pub struct Scenario<'a> {
    header: Header,
    mounts: &'a [u8],
    records: &'a [u8],
}

impl<'a> Scenario<'a> {
    /// Checks everything once: sizes, CRC, every header field, mount and
    /// record. Nothing is trusted before this returns.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, ScenarioError> {
        let magic_ok = bytes.get(..4) == Some(&MAGIC[..]);
        if bytes.len() < FIXED_HEADER_LEN + 4 {
            return Err(if bytes.len() >= 4 && !magic_ok { ScenarioError::Magic } else { ScenarioError::Length });
        }
        if !magic_ok {
            return Err(ScenarioError::Magic);
        }
        let version = u16_at(bytes, 4);
        if version != VERSION {
            return Err(ScenarioError::Version(version));
        }
        let n = u16_at(bytes, 12) as usize;
        let header_len = u16_at(bytes, 6) as usize;
        if n == 0
            || n > 255
            || header_len != FIXED_HEADER_LEN + MOUNT_LEN * n
            || u16_at(bytes, 14) as usize != RECORD_LEN
        {
            return Err(ScenarioError::Layout);
        }
        let count = u32_at(bytes, 16) as usize;
        let want = count.checked_mul(RECORD_LEN).and_then(|r| r.checked_add(header_len + 4));
        if want != Some(bytes.len()) {
            return Err(ScenarioError::Length);
        }
        let body = bytes.len() - 4;
        let stored = u32_at(bytes, body);
        let computed = crate::map::crc32(bytes.get(..body).unwrap_or(&[]));
        if stored != computed {
            return Err(ScenarioError::Crc { stored, computed });
        }
        let header = Header {
            map_crc: u32_at(bytes, 8),
            speed_um_per_s: u32_at(bytes, 20),
            period_us: u32_at(bytes, 24),
            slot_us: u32_at(bytes, 28),
            start: f32x3(bytes, 32),
            start_sigma: f32x3(bytes, 44),
            bound_position_m: f32_at(bytes, 56),
            bound_heading_deg: f32_at(bytes, 60),
        };
        if !header.is_valid() {
            return Err(ScenarioError::Header);
        }
        let (Some(mounts), Some(records)) = (bytes.get(FIXED_HEADER_LEN..header_len), bytes.get(header_len..body))
        else {
            return Err(ScenarioError::Layout);
        };
        let s = Scenario { header, mounts, records };
        for i in 0..n {
            let m = s.mount_unchecked(i);
            if !mount_ok(&m) {
                return Err(ScenarioError::Mount(i as u8));
            }
        }
        for (i, r) in s.records.chunks_exact(RECORD_LEN).enumerate() {
            let bad = u8_at(r, 8) as usize >= n
                || u8_at(r, 10) & !1 != 0
                || u8_at(r, 11) != 0
                || (u8_at(r, 10) & 1 == 0) != (u32_at(r, 12) == 0)
                || !f32x3(r, 16).iter().chain(f32x3(r, 28).iter()).all(|v| v.is_finite());
            if bad {
                return Err(ScenarioError::Record(i as u32));
            }
        }
        Ok(s)
    }

    /// The run's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// How many transducers the ring has.
    pub fn transducers(&self) -> usize {
        self.mounts.len() / MOUNT_LEN
    }

    fn mount_unchecked(&self, i: usize) -> Mount {
        // i < 255 (the header's count): the offsets are in range; saturating
        // keeps an out-of-range i a read past the end (0), not a wrap.
        let o = i.saturating_mul(MOUNT_LEN);
        let at = |k| u32_at(self.mounts, o.saturating_add(k)) as i32;
        Mount { x_mm: at(0), y_mm: at(4), heading_mdeg: at(8) }
    }

    /// Mount `i`.
    pub fn mount(&self, i: usize) -> Option<Mount> {
        (i < self.transducers()).then(|| self.mount_unchecked(i))
    }

    /// How many records.
    pub fn len(&self) -> usize {
        self.records.len() / RECORD_LEN
    }

    /// No records.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The records in firing order.
    pub fn records(&self) -> impl Iterator<Item = Record> + 'a {
        self.records.chunks_exact(RECORD_LEN).map(record_of)
    }

    /// Record `i`, if there is one.
    pub fn record(&self, i: usize) -> Option<Record> {
        self.records.chunks_exact(RECORD_LEN).nth(i).map(record_of)
    }

    /// `Ok` if the scenario was made on the map whose blob has CRC `map_crc`.
    pub fn check_map(&self, map_crc: u32) -> Result<(), ScenarioError> {
        if map_crc == self.header.map_crc {
            Ok(())
        } else {
            Err(ScenarioError::MapMismatch { expected: self.header.map_crc, found: map_crc })
        }
    }
}

/// Writes a scenario to `sink` in pieces, checking what the reader checks,
/// so a file this writes always parses. Nothing is written when the input
/// is refused.
pub fn write(
    header: &Header,
    mounts: &[Mount],
    records: &[Record],
    mut sink: impl FnMut(&[u8]),
) -> Result<(), ScenarioError> {
    let n = mounts.len();
    if n == 0 || n > 255 {
        return Err(ScenarioError::Layout);
    }
    let count = u32::try_from(records.len()).map_err(|_| ScenarioError::Count)?;
    if !header.is_valid() {
        return Err(ScenarioError::Header);
    }
    for (i, m) in mounts.iter().enumerate() {
        if !mount_ok(m) {
            return Err(ScenarioError::Mount(i as u8));
        }
    }
    for (i, r) in records.iter().enumerate() {
        let finite = r.odometry.iter().chain(r.truth.iter()).all(|v| v.is_finite());
        if usize::from(r.transducer) >= n || r.echo_us == Some(0) || !finite {
            return Err(ScenarioError::Record(i as u32));
        }
    }
    let mut crc = Crc32::new();
    let mut put = |b: &[u8]| {
        crc.update(b);
        sink(b);
    };
    let header_len = (FIXED_HEADER_LEN + MOUNT_LEN * n) as u16;
    put(&MAGIC);
    put(&VERSION.to_le_bytes());
    put(&header_len.to_le_bytes());
    put(&header.map_crc.to_le_bytes());
    put(&(n as u16).to_le_bytes());
    put(&(RECORD_LEN as u16).to_le_bytes());
    put(&count.to_le_bytes());
    put(&header.speed_um_per_s.to_le_bytes());
    put(&header.period_us.to_le_bytes());
    put(&header.slot_us.to_le_bytes());
    for v in header.start.iter().chain(header.start_sigma.iter()) {
        put(&v.to_le_bytes());
    }
    put(&header.bound_position_m.to_le_bytes());
    put(&header.bound_heading_deg.to_le_bytes());
    for m in mounts {
        put(&m.x_mm.to_le_bytes());
        put(&m.y_mm.to_le_bytes());
        put(&m.heading_mdeg.to_le_bytes());
    }
    for r in records {
        let mut b = [0u8; RECORD_LEN];
        b[0..4].copy_from_slice(&r.time_us.to_le_bytes());
        b[4..8].copy_from_slice(&r.cycle.to_le_bytes());
        b[8] = r.transducer;
        b[9] = r.slot;
        b[10] = u8::from(r.echo_us.is_some());
        b[12..16].copy_from_slice(&r.echo_us.unwrap_or(0).to_le_bytes());
        for (k, v) in r.odometry.iter().chain(r.truth.iter()).enumerate() {
            #[allow(
                clippy::indexing_slicing,
                reason = "six f32 fields at 16..40 of a 40-byte record: in range by construction"
            )]
            b[16 + 4 * k..20 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        put(&b);
    }
    let c = crc.finish();
    sink(&c.to_le_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    extern crate std;
    use std::vec::Vec;

    fn sample() -> Vec<u8> {
        let header = Header {
            map_crc: 0xDEAD_BEEF,
            speed_um_per_s: 343_000_000,
            period_us: 600_000,
            slot_us: 35_000,
            start: [1.0, 2.0, 0.5],
            start_sigma: [0.05, 0.05, 0.02],
            bound_position_m: 0.1,
            bound_heading_deg: 2.0,
        };
        let mounts =
            [Mount { x_mm: 100, y_mm: 20, heading_mdeg: 10_000 }, Mount { x_mm: -100, y_mm: 0, heading_mdeg: 180_000 }];
        let recs: Vec<Record> = (0..5u32)
            .map(|i| Record {
                time_us: i * 35_000,
                cycle: i / 2,
                transducer: (i % 2) as u8,
                slot: (i % 2) as u8,
                echo_us: (i != 3).then_some(5_000 + i),
                odometry: [0.01 * i as f32, 0.0, 0.001],
                truth: [1.0 + 0.01 * i as f32, 2.0, 0.5],
            })
            .collect();
        let mut out = Vec::new();
        write(&header, &mounts, &recs, |b| out.extend_from_slice(b)).unwrap();
        out
    }

    #[test]
    fn round_trip() {
        let b = sample();
        assert_eq!(b.len(), 64 + 24 + 5 * 40 + 4);
        let s = Scenario::parse(&b).unwrap();
        assert_eq!(s.len(), 5);
        assert_eq!(s.transducers(), 2);
        assert_eq!(s.mount(1), Some(Mount { x_mm: -100, y_mm: 0, heading_mdeg: 180_000 }));
        assert_eq!(s.mount(2), None);
        let r: Vec<Record> = s.records().collect();
        assert_eq!(r[3].echo_us, None);
        assert_eq!(r[4].echo_us, Some(5_004));
        assert_eq!(r[4].truth, [1.04, 2.0, 0.5]);
        assert_eq!(s.check_map(1), Err(ScenarioError::MapMismatch { expected: 0xDEAD_BEEF, found: 1 }));
    }

    #[test]
    fn every_byte_flip_and_truncation_is_refused() {
        let b = sample();
        for i in 0..b.len() {
            for bit in [0x01u8, 0x80] {
                let mut c = b.clone();
                c[i] ^= bit;
                assert!(Scenario::parse(&c).is_err(), "flip at byte {i} accepted");
            }
        }
        for len in 0..b.len() {
            assert!(Scenario::parse(&b[..len]).is_err(), "truncation to {len} accepted");
        }
    }
}

//! The localization field: what Monte Carlo localization needs from the
//! map, compiled on the host into the blob (version 3) and read in place
//! from flash with the rest of it (DESIGN §4.8, `docs/map-blob.md`).
//!
//! It is a grid of *nodes* every `node_mm` millimetres over the part of the
//! map a transducer can be in. Each node holds, for `dirs` headings evenly
//! spread over the full turn, the exact prediction (the predictor's own,
//! window, signature tests, κ and all) of a transducer standing on the node
//! and facing that heading, one byte each ([`Expected`]). A node also says
//! whether the robot's centre may stand there (*free*): the space particles
//! are drawn from.
//!
//! ```text
//! field header (64 bytes, u32 unless said)
//!                 node_mm, origin x i32, origin y i32, cols, rows, dirs,
//!                 runs, nodes, free_nodes, reach_mm, clearance_mm,
//!                 r_min_mm, r_max_mm, half_angle_mdeg, delta_max_mdeg, fallback_mdeg
//! row starts      u32 × (rows + 1): the runs of row r are row_start[r]..row_start[r+1]
//! runs × 8        col u16, len u16, first u32: nodes col..col+len of the row,
//!                 numbered from `first` (each run's first is the last's end)
//! free bits       u32 × ⌈nodes / 32⌉: bit n % 32 of word n / 32 for node n
//! entries         u8 × nodes × dirs, node by node, zero-padded to 4 bytes
//! ```
//!
//! Only the nodes a transducer can reach are stored (free space grown by
//! `reach_mm`), in runs along each row, so the flash it takes grows with
//! the map's free area, not its bounding box: `dirs / node_mm²` bytes a
//! square metre (1 KiB at 64 headings every 250 mm).

use bytemuck::{Pod, Zeroable};

use super::BlobError;
use crate::geometry::COORD_MAX;

/// Length of the field's header, bytes.
pub const FIELD_HEADER_LEN: usize = 64;

/// Most headings a node may hold (an index is a `u8`).
pub const MAX_DIRS: u32 = 256;

/// The field's header.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct FieldHeader {
    /// Node spacing, mm (0 with no field).
    pub node_mm: u32,
    /// Node (0, 0), mm.
    pub origin_x: i32,
    /// Node (0, 0), mm.
    pub origin_y: i32,
    /// Columns of the node grid.
    pub cols: u32,
    /// Rows of the node grid.
    pub rows: u32,
    /// Headings per node, evenly spread from 0 (the map's +x) counter-clockwise.
    pub dirs: u32,
    /// Runs stored.
    pub runs: u32,
    /// Nodes stored.
    pub nodes: u32,
    /// Of them, free nodes (where the robot's centre may stand).
    pub free_nodes: u32,
    /// Stored nodes reach this far beyond the free ones, mm (a transducer
    /// on the ring stands within it of the robot's centre).
    pub reach_mm: u32,
    /// A free node is at least this far from every obstacle, mm.
    pub clearance_mm: u32,
    /// The window the predictions were made with: R_min, mm.
    pub r_min_mm: u32,
    /// R_max, mm.
    pub r_max_mm: u32,
    /// θ_o, millidegrees.
    pub half_angle_mdeg: u32,
    /// δ_max, millidegrees.
    pub delta_max_mdeg: u32,
    /// Where the prediction with δ_max credits no surface, the entry holds
    /// the first surface a lobe this wide finds, unsure, millidegrees (0:
    /// none; else above δ_max and below 90°). A sonar hears faces beyond the
    /// tracker's lobe at times (rough, near, or at an edge); the particles'
    /// model then scores such an echo as the unsure echo it may be rather
    /// than as one from nowhere.
    pub fallback_mdeg: u32,
}

/// A run of stored nodes along a row.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct FieldRun {
    /// First column.
    pub col: u16,
    /// Nodes in the run (at least 1).
    pub len: u16,
    /// Index of its first node.
    pub first: u32,
}

/// Ranges of the codes 1..=127: 400 mm × q^(code − 1), q = 14^(1/126), so
/// code 127 is 5 600 mm and one step is 2.1 % of the range (a code is
/// within 1.05 % of the range it stands for).
pub const RANGE_TABLE_MM: [f32; 128] = range_table();

const fn range_table() -> [f32; 128] {
    // 14^(1/126), to f32 precision (exp(ln 14 / 126)).
    const Q: f64 = 1.021_165_783_282_242_7;
    let mut t = [0.0f32; 128];
    let mut r = 400.0f64;
    let mut c = 1;
    while c < 128 {
        #[allow(clippy::indexing_slicing)] // const: checked at compile time
        {
            t[c] = r as f32;
        }
        r *= Q;
        c += 1;
    }
    t
}

/// What a transducer on a node, facing one of its headings, should hear:
/// one byte. `0` (and `0x80`): nothing predicted in the window; else bits
/// 0–6 a range code ([`RANGE_TABLE_MM`]) and bit 7 set when the prediction
/// is *sure* (κ ≥ 0.9 and no nearer mapped surface a sonar may hear first).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Expected {
    /// Nothing predicted: the transducer should hear no mapped surface.
    Nothing,
    /// An echo.
    Echo {
        /// Range, mm.
        range_mm: f32,
        /// κ ≥ 0.9 and unambiguous.
        sure: bool,
    },
}

impl Expected {
    /// Decodes a field byte.
    #[inline]
    pub fn decode(b: u8) -> Self {
        let code = usize::from(b & 0x7F);
        match RANGE_TABLE_MM.get(code) {
            Some(&range_mm) if code != 0 => Expected::Echo { range_mm, sure: b & 0x80 != 0 },
            _ => Expected::Nothing,
        }
    }

    /// The byte for a prediction of `range_mm` (clamped to the table's
    /// 400–5 600 mm), or for none.
    pub fn encode(range_mm: Option<u32>, sure: bool) -> u8 {
        let Some(r) = range_mm else { return 0 };
        let r = r as f32;
        // The code whose range is nearest in ratio: compare r² with the
        // product of two neighbours (their geometric mean, squared).
        let mut code = 1u8;
        for (c, w) in (2u8..).zip(RANGE_TABLE_MM.windows(2).skip(1)) {
            if let [lo, hi] = *w {
                if r * r < lo * hi {
                    break;
                }
                code = c;
            }
        }
        code | if sure { 0x80 } else { 0 }
    }
}

/// The field's parts, for writing it ([`Map::compile_with_field`](super::Map::compile_with_field)).
#[derive(Clone, Copy, Debug)]
pub struct FieldParts<'b> {
    /// The header; its counts must match the slices.
    pub header: FieldHeader,
    /// Row starts, `rows + 1`.
    pub row_start: &'b [u32],
    /// The runs.
    pub runs: &'b [FieldRun],
    /// Free bits, `⌈nodes / 32⌉` words.
    pub free: &'b [u32],
    /// `nodes × dirs` bytes.
    pub entries: &'b [u8],
}

impl FieldParts<'_> {
    /// No field: a map that cannot localize globally (its blob is smaller).
    pub const NONE: FieldParts<'static> =
        FieldParts { header: FIELD_HEADER_NONE, row_start: &[0], runs: &[], free: &[], entries: &[] };

    /// Bytes the field takes in the blob.
    pub fn len(&self) -> usize {
        FIELD_HEADER_LEN
            + 4 * self.row_start.len()
            + 8 * self.runs.len()
            + 4 * self.free.len()
            + self.entries.len().next_multiple_of(4)
    }

    /// Whether it is [`FieldParts::NONE`]-like: no nodes.
    pub fn is_empty(&self) -> bool {
        self.header.nodes == 0
    }

    /// Writes the field through `put`.
    pub(super) fn write(&self, put: &mut impl FnMut(&[u8])) {
        put(bytemuck::bytes_of(&self.header));
        put(bytemuck::cast_slice(self.row_start));
        put(bytemuck::cast_slice(self.runs));
        put(bytemuck::cast_slice(self.free));
        put(self.entries);
        let pad = self.entries.len().next_multiple_of(4) - self.entries.len();
        put([0u8; 3].get(..pad).unwrap_or(&[]));
    }
}

const FIELD_HEADER_NONE: FieldHeader = FieldHeader {
    node_mm: 0,
    origin_x: 0,
    origin_y: 0,
    cols: 0,
    rows: 0,
    dirs: 0,
    runs: 0,
    nodes: 0,
    free_nodes: 0,
    reach_mm: 0,
    clearance_mm: 0,
    r_min_mm: 0,
    r_max_mm: 0,
    half_angle_mdeg: 0,
    delta_max_mdeg: 0,
    fallback_mdeg: 0,
};

/// The field read in place. See the module docs.
#[derive(Clone, Copy, Debug)]
pub struct FieldView<'a> {
    header: FieldHeader,
    row_start: &'a [u32],
    runs: &'a [FieldRun],
    free: &'a [u32],
    entries: &'a [u8],
}

/// Why a field does not validate (inside [`BlobError::Field`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FieldError {
    /// Spacing, headings, grid size or coordinates out of range, or a
    /// fallback lobe not between δ_max and 90°.
    Header,
    /// Row starts not from 0 to `runs`, or decreasing.
    RowStart {
        /// The row.
        row: u32,
    },
    /// A run empty, past the row's end, overlapping the previous one, or
    /// not numbered where the previous ended.
    Run {
        /// The run's index.
        run: u32,
    },
    /// The runs' nodes do not add up to `nodes`.
    NodeCount,
    /// Free bits past the last node, or not `free_nodes` of them.
    FreeBits,
}

impl<'a> FieldView<'a> {
    /// An empty field.
    pub const EMPTY: FieldView<'static> =
        FieldView { header: FIELD_HEADER_NONE, row_start: &[0], runs: &[], free: &[], entries: &[] };

    /// Reads and checks a field that fills `bytes` exactly (4-aligned).
    pub(super) fn parse(bytes: &'a [u8]) -> Result<Self, BlobError> {
        let bad = BlobError::Field;
        let h: FieldHeader = *bytemuck::try_from_bytes(bytes.get(..FIELD_HEADER_LEN).ok_or(BlobError::Truncated)?)
            .map_err(|_| BlobError::Misaligned)?;
        let empty = h.nodes == 0;
        let header_ok = if empty {
            h == FieldHeader { reach_mm: h.reach_mm, clearance_mm: h.clearance_mm, ..FIELD_HEADER_NONE }
        } else {
            h.node_mm > 0
                && h.dirs > 0
                && h.dirs <= MAX_DIRS
                && h.cols > 0
                && h.rows > 0
                && h.cols <= u32::from(u16::MAX)
                && h.rows <= u32::from(u16::MAX)
                && (h.fallback_mdeg == 0 || (h.fallback_mdeg > h.delta_max_mdeg && h.fallback_mdeg < 90_000))
                && within(h.origin_x, h.cols, h.node_mm)
                && within(h.origin_y, h.rows, h.node_mm)
        };
        if !header_ok {
            return Err(bad(FieldError::Header));
        }
        let rows = h.rows as u64;
        let sizes = [
            4 * (rows + 1),
            8 * h.runs as u64,
            4 * (h.nodes as u64).div_ceil(32),
            // Below 2⁶⁴ − 2³³ (two u32s), so rounding up to 4 cannot wrap.
            (h.nodes as u64 * h.dirs as u64).wrapping_add(3) & !3,
        ];
        let need = sizes.iter().fold(FIELD_HEADER_LEN as u64, |a, &b| a.saturating_add(b));
        if (bytes.len() as u64) < need {
            return Err(BlobError::Truncated);
        }
        if bytes.len() as u64 > need {
            return Err(BlobError::TrailingBytes);
        }
        let mut at = FIELD_HEADER_LEN;
        let mut take = |n: u64| -> Result<&'a [u8], BlobError> {
            let end = at.checked_add(n as usize).ok_or(BlobError::Truncated)?;
            let s = bytes.get(at..end).ok_or(BlobError::Truncated)?;
            at = end;
            Ok(s)
        };
        let cast32 = |s: &'a [u8]| bytemuck::try_cast_slice::<u8, u32>(s).map_err(|_| BlobError::Misaligned);
        let row_start = cast32(take(sizes[0])?)?;
        let runs: &[FieldRun] = bytemuck::try_cast_slice(take(sizes[1])?).map_err(|_| BlobError::Misaligned)?;
        let free = cast32(take(sizes[2])?)?;
        let padded = take(sizes[3])?;
        let n_entries = (h.nodes as usize).saturating_mul(h.dirs as usize);
        let (entries, pad) = padded.split_at(n_entries.min(padded.len()));
        if let Some(i) = pad.iter().position(|&b| b != 0) {
            return Err(BlobError::ReservedByte { offset: i });
        }
        let v = Self { header: h, row_start, runs, free, entries };
        v.check()?;
        Ok(v)
    }

    /// Row starts, runs, the node count and the free bits.
    fn check(&self) -> Result<(), BlobError> {
        let h = &self.header;
        if self.row_start.first() != Some(&0) || self.row_start.last() != Some(&h.runs) {
            return Err(BlobError::Field(FieldError::RowStart { row: 0 }));
        }
        let mut next_node = 0u32;
        for (r, w) in self.row_start.windows(2).enumerate() {
            let (&[lo, hi], row) = (w, r as u32) else { continue };
            if lo > hi || hi > h.runs {
                return Err(BlobError::Field(FieldError::RowStart { row }));
            }
            let mut col_end = 0u32;
            for k in lo..hi {
                let bad = BlobError::Field(FieldError::Run { run: k });
                let run = self.runs.get(k as usize).ok_or(bad)?;
                let (col, len) = (u32::from(run.col), u32::from(run.len));
                if len == 0 || (k > lo && col <= col_end) || col + len > h.cols || run.first != next_node {
                    return Err(bad);
                }
                col_end = col + len;
                next_node = next_node.checked_add(len).ok_or(bad)?;
            }
        }
        if next_node != h.nodes {
            return Err(BlobError::Field(FieldError::NodeCount));
        }
        let tail = h.nodes % 32;
        let last_ok = tail == 0 || self.free.last().is_none_or(|&w| w >> tail == 0);
        // Wrapping is exact: `free` holds ⌈nodes / 32⌉ words (checked above)
        // and, with the tail clear, at most `nodes` ≤ u32::MAX bits are set.
        let count: u32 = self.free.iter().fold(0u32, |n, w| n.wrapping_add(w.count_ones()));
        if !last_ok || count != h.free_nodes {
            return Err(BlobError::Field(FieldError::FreeBits));
        }
        Ok(())
    }

    /// The header.
    pub fn header(&self) -> &FieldHeader {
        &self.header
    }

    /// Whether there is no field (a map compiled without one).
    pub fn is_empty(&self) -> bool {
        self.header.nodes == 0
    }

    /// The δ_max, degrees, the field's predictions were made with: how far
    /// off its normal a face of this map still echoes, the map's own lobe
    /// (`None`: no field, or none recorded). The tracker predicts with it
    /// too (`WindowParams::with_map_lobe`), so the particles and the EKF
    /// hear the map alike.
    pub fn delta_max_deg(&self) -> Option<f32> {
        let d = self.header.delta_max_mdeg;
        (!self.is_empty() && d > 0 && d < 90_000).then(|| d as f32 / 1000.0)
    }

    /// The fallback lobe, degrees ([`FieldHeader::fallback_mdeg`]; `None`:
    /// no field, or none).
    pub fn fallback_deg(&self) -> Option<f32> {
        let d = self.header.fallback_mdeg;
        (!self.is_empty() && d > 0).then(|| d as f32 / 1000.0)
    }

    /// Headings per node.
    pub fn dirs(&self) -> u32 {
        self.header.dirs
    }

    /// Nodes stored.
    pub fn nodes(&self) -> u32 {
        self.header.nodes
    }

    /// Free nodes.
    pub fn free_nodes(&self) -> u32 {
        self.header.free_nodes
    }

    /// The node at column `col`, row `row`, if stored.
    #[inline]
    pub fn node_at(&self, col: u32, row: u32) -> Option<u32> {
        let lo = *self.row_start.get(row as usize)?;
        let hi = *self.row_start.get((row as usize).saturating_add(1))?;
        let runs = self.runs.get(lo as usize..hi as usize)?;
        // Rows hold a few runs: a linear scan beats a search.
        for r in runs {
            let c0 = u32::from(r.col);
            if col < c0 {
                return None;
            }
            if col < c0 + u32::from(r.len) {
                // Validated: a run's nodes are numbered below `nodes` (u32).
                return Some(r.first.wrapping_add(col - c0));
            }
        }
        None
    }

    /// The nodes at columns `col` and `col + 1` of row `row`, if stored
    /// (one scan of the row's runs for both).
    #[inline]
    pub fn pair_at(&self, col: u32, row: u32) -> (Option<u32>, Option<u32>) {
        let (Some(&lo), Some(&hi)) =
            (self.row_start.get(row as usize), self.row_start.get((row as usize).saturating_add(1)))
        else {
            return (None, None);
        };
        let runs = self.runs.get(lo as usize..hi as usize).unwrap_or(&[]);
        let mut first = None;
        for r in runs {
            let c0 = u32::from(r.col);
            let end = c0 + u32::from(r.len);
            if first.is_none() {
                if col < c0 {
                    // col is not stored; col + 1 may start this run.
                    return (None, (col + 1 == c0).then_some(r.first));
                }
                if col < end {
                    // Validated: a run's nodes are numbered below `nodes` (u32).
                    let n = r.first.wrapping_add(col - c0);
                    // (`col + 1 < end`, as a difference: `col < end` here.)
                    if end - col > 1 {
                        return (Some(n), Some(n.wrapping_add(1)));
                    }
                    first = Some(n);
                    continue;
                }
            } else {
                return (first, (c0 == col + 1).then_some(r.first));
            }
        }
        (first, None)
    }

    /// Node `n`'s bytes, one a heading.
    #[inline]
    pub fn entries(&self, n: u32) -> Option<&'a [u8]> {
        let d = self.header.dirs as usize;
        let at = (n as usize).checked_mul(d)?;
        self.entries.get(at..at.checked_add(d)?)
    }

    /// Whether the robot's centre may stand on node `n`.
    #[inline]
    pub fn is_free(&self, n: u32) -> bool {
        self.free.get(n as usize / 32).is_some_and(|w| w >> (n % 32) & 1 == 1)
    }

    /// Node `n`'s column and row.
    pub fn cell_of(&self, n: u32) -> Option<(u32, u32)> {
        if n >= self.header.nodes {
            return None;
        }
        // The last run starting at or before n.
        let k = self.runs.partition_point(|r| r.first <= n).checked_sub(1)?;
        let run = self.runs.get(k)?;
        let row = self.row_start.partition_point(|&s| s as usize <= k).checked_sub(1)?;
        // `run.first ≤ n` (the search), and the run lies within the row.
        Some((u32::from(run.col).wrapping_add(n.wrapping_sub(run.first)), row as u32))
    }

    /// Node `n`'s position, mm.
    pub fn position_mm(&self, n: u32) -> Option<(i32, i32)> {
        let (c, r) = self.cell_of(n)?;
        let h = &self.header;
        // `parse` checked that every node's coordinates are within ±COORD_MAX.
        Some((
            h.origin_x.wrapping_add(c.wrapping_mul(h.node_mm) as i32),
            h.origin_y.wrapping_add(r.wrapping_mul(h.node_mm) as i32),
        ))
    }
}

/// `origin + (count − 1) · step` stays within ±COORD_MAX.
fn within(origin: i32, count: u32, step: u32) -> bool {
    let far = i64::from(origin) + i64::from(count.saturating_sub(1)) * i64::from(step);
    i64::from(origin).abs() <= i64::from(COORD_MAX) && far.abs() <= i64::from(COORD_MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_table_ends_and_ratio() {
        assert_eq!(RANGE_TABLE_MM[1], 400.0);
        assert!((RANGE_TABLE_MM[127] - 5600.0).abs() < 0.05, "{}", RANGE_TABLE_MM[127]);
        for c in 2..128 {
            let q = RANGE_TABLE_MM[c] / RANGE_TABLE_MM[c - 1];
            assert!((q - 1.021_165_8).abs() < 1e-5);
        }
    }

    #[test]
    fn encode_is_nearest_in_ratio() {
        for r in (300..6000).step_by(7) {
            let b = Expected::encode(Some(r), r % 2 == 0);
            let Expected::Echo { range_mm, sure } = Expected::decode(b) else { panic!("{r}") };
            assert_eq!(sure, r % 2 == 0);
            // Brute force over every code.
            let best = (1..128)
                .min_by(|&a, &b| {
                    let e = |c: usize| (libm::logf(RANGE_TABLE_MM[c] / r as f32)).abs();
                    e(a).partial_cmp(&e(b)).unwrap()
                })
                .unwrap();
            let want = RANGE_TABLE_MM[best];
            // Ties in ratio may round either way.
            assert!((libm::logf(range_mm / r as f32).abs() - libm::logf(want / r as f32).abs()).abs() < 1e-4, "{r}");
            if (400..=5600).contains(&r) {
                assert!((range_mm / r as f32 - 1.0).abs() <= 0.0106, "{r} -> {range_mm}");
            }
        }
        assert_eq!(Expected::decode(Expected::encode(None, true)), Expected::Nothing);
        assert_eq!(Expected::decode(0x80), Expected::Nothing);
    }
}

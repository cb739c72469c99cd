//! Uniform grid index: cell → ids of the pieces whose box overlaps the cell.
//!
//! Stored compactly (CSR): `start[c]` is where cell `c`'s ids begin in
//! `refs`; they end where cell `c + 1`'s begin (or at `refs.len()`). A box
//! query reports each piece exactly once, without a visited set: a piece is
//! reported only from the cell holding the lower-left corner of (its box ∩
//! the query box), which is always one of the visited cells.

use heapless::Vec;

use super::{Capacity, MapError, QueryStats};
use crate::geometry::{Point, Rect};

pub(super) struct Grid<const CELLS: usize, const REFS: usize> {
    origin: Point,
    cell_mm: u32,
    cols: u16,
    rows: u16,
    start: Vec<u32, CELLS>,
    refs: Vec<u16, REFS>,
}

impl<const CELLS: usize, const REFS: usize> Grid<CELLS, REFS> {
    pub(super) const fn new() -> Self {
        Self { origin: Point::new(0, 0), cell_mm: 0, cols: 0, rows: 0, start: Vec::new(), refs: Vec::new() }
    }

    pub(super) fn clear(&mut self) {
        self.origin = Point::new(0, 0);
        self.cell_mm = 0;
        self.cols = 0;
        self.rows = 0;
        self.start.clear();
        self.refs.clear();
    }

    pub(super) fn dims(&self) -> (u32, u16, u16) {
        (self.cell_mm, self.cols, self.rows)
    }

    pub(super) fn refs_len(&self) -> usize {
        self.refs.len()
    }

    /// The borrowed form every query runs on.
    pub(super) fn index(&self) -> GridRef<'_> {
        GridRef {
            origin: self.origin,
            cell_mm: self.cell_mm,
            cols: self.cols,
            rows: self.rows,
            start: &self.start,
            refs: &self.refs,
        }
    }

    // An all-zero empty grid keeps `Map::new()` in .bss rather than .data (no
    // flash image of an empty map); `cell_mm` is only read once `cols > 0`.

    /// Builds the index over `boxes` (piece id = position).
    pub(super) fn build(&mut self, boxes: impl Iterator<Item = Rect> + Clone, cell_mm: u32) -> Result<(), MapError> {
        self.clear();
        self.cell_mm = cell_mm;
        let Some(bounds) = boxes.clone().reduce(Rect::union) else {
            return Ok(());
        };
        let cell = cell_mm as i64;
        let cols = (bounds.max.x as i64 - bounds.min.x as i64) / cell + 1;
        let rows = (bounds.max.y as i64 - bounds.min.y as i64) / cell + 1;
        if cols * rows > CELLS as i64 || cols > u16::MAX as i64 || rows > u16::MAX as i64 {
            return Err(MapError::Full(Capacity::Cells));
        }
        self.origin = bounds.min;
        self.cell_mm = cell_mm;
        self.cols = cols as u16;
        self.rows = rows as u16;
        let ncells = (cols * rows) as usize;
        // Pass 1: count references per cell, then turn counts into end offsets.
        let _ = self.start.resize(ncells, 0);
        let mut total: u64 = 0;
        for b in boxes.clone() {
            let (x0, y0, x1, y1) = self.index().cell_range(b);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    self.start[y as usize * self.cols as usize + x as usize] += 1;
                }
            }
            total += (x1 - x0 + 1) as u64 * (y1 - y0 + 1) as u64;
        }
        if total > REFS as u64 {
            self.clear();
            return Err(MapError::Full(Capacity::CellRefs));
        }
        let mut acc = 0u32;
        for s in self.start.iter_mut() {
            acc += *s;
            *s = acc;
        }
        // Pass 2: fill backwards; each cell's end offset walks down to its start.
        let _ = self.refs.resize(total as usize, 0);
        for (id, b) in boxes.enumerate() {
            let (x0, y0, x1, y1) = self.index().cell_range(b);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = y as usize * self.cols as usize + x as usize;
                    self.start[c] -= 1;
                    self.refs[self.start[c] as usize] = id as u16;
                }
            }
        }
        Ok(())
    }
}

/// A grid index borrowed from wherever it lives: a [`Grid`] in RAM or a
/// compiled map's sections in flash. `start[c]` is where cell `c`'s ids
/// begin; they end at `start[c + 1]`, or at `refs.len()` for the last cell.
/// The compiled form keeps a sentinel entry, which the same rule ignores.
#[derive(Clone, Copy)]
pub(super) struct GridRef<'a> {
    pub(super) origin: Point,
    pub(super) cell_mm: u32,
    pub(super) cols: u16,
    pub(super) rows: u16,
    pub(super) start: &'a [u32],
    pub(super) refs: &'a [u16],
}

impl GridRef<'_> {
    /// Cell column (or row) of a coordinate, clamped into the grid.
    pub(super) fn cell_of(&self, v: i32, origin: i32, n: u16) -> u16 {
        // Below 2³² after the clamp: one hardware division on a Cortex-M4
        // (an i64 division is a library call).
        let off = (v as i64 - origin as i64).clamp(0, u32::MAX as i64) as u32;
        (off / self.cell_mm.max(1)).min((n as u32).saturating_sub(1)) as u16
    }

    /// The cells `(x0, y0, x1, y1)` a box covers, clamped into the grid.
    pub(super) fn cell_range(&self, r: Rect) -> (u16, u16, u16, u16) {
        (
            self.cell_of(r.min.x, self.origin.x, self.cols),
            self.cell_of(r.min.y, self.origin.y, self.rows),
            self.cell_of(r.max.x, self.origin.x, self.cols),
            self.cell_of(r.max.y, self.origin.y, self.rows),
        )
    }

    /// The ids indexed in cell `c` (empty when out of range).
    pub(super) fn cell(&self, c: usize) -> &[u16] {
        let lo = self.start.get(c).map_or(0, |&s| s as usize);
        let hi = match self.start.get(c + 1) {
            Some(&e) if c + 1 < self.cols as usize * self.rows as usize => e as usize,
            _ => self.refs.len(),
        };
        self.refs.get(lo..hi).unwrap_or(&[])
    }

    /// Calls `f(id)` once for every indexed piece whose box (as given by
    /// `bbox`) overlaps `area`.
    pub(super) fn query(&self, area: Rect, bbox: impl Fn(u16) -> Rect, mut f: impl FnMut(u16, Rect)) -> QueryStats {
        let mut stats = QueryStats::default();
        if self.cols == 0 || self.rows == 0 {
            return stats;
        }
        let (x0, y0, x1, y1) = self.cell_range(area);
        let cell = self.cell_mm as i64;
        for y in y0..=y1 {
            let y_start = self.origin.y as i64 + y as i64 * cell;
            for x in x0..=x1 {
                let x_start = self.origin.x as i64 + x as i64 * cell;
                stats.cells = stats.cells.wrapping_add(1);
                for &id in self.cell(y as usize * self.cols as usize + x as usize) {
                    let b = bbox(id);
                    if !b.overlaps(&area) {
                        continue;
                    }
                    // Reported from its home cell only: the cell of the lower-left
                    // corner of (its box ∩ the area). A piece listed in this cell has
                    // its box's lower-left cell at or before it, so this is the home
                    // column when it is the area's first or the box starts in it
                    // (comparisons, where the cell number would cost a division).
                    let home_x = x == x0 || b.min.x as i64 >= x_start;
                    let home_y = y == y0 || b.min.y as i64 >= y_start;
                    if home_x && home_y {
                        stats.candidates = stats.candidates.wrapping_add(1);
                        f(id, b);
                    }
                }
            }
        }
        stats
    }
}

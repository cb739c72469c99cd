//! Beacon collection: which pieces are in a placed window.

use heapless::Vec;

#[cfg(doc)]
use super::MAX_PSEUDO_PATHS;
use super::{PathLayout, Sector, WindowError, WindowParams};
use crate::geometry::Point;
use crate::map::{MapError, MapSource, Piece};

/// How to collect beacons.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Strategy {
    /// The paper's pseudo-paths against buffered outlines.
    PseudoPaths,
    /// Exact true-outline ∩ sector.
    Exact,
}

/// Why collection failed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CollectError {
    /// The map refused the query (not finished).
    Map(MapError),
    /// More beacons than the output set holds; nothing is returned.
    TooManyBeacons,
    /// The pseudo-path strategy on a window placed without a layout
    /// ([`Window::place`]; [`Window::place_for`] lays one out).
    NoPseudoPaths,
}

impl core::fmt::Display for CollectError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Map(e) => write!(f, "the map refused the query: {e:?}"),
            Self::TooManyBeacons => f.write_str("more beacons in the window than the search holds"),
            Self::NoPseudoPaths => f.write_str(
                "the pseudo-path strategy on a window placed without a layout (place it with Window::place_for)",
            ),
        }
    }
}

/// Counts of one collection's work, modulo 2³² (as [`crate::predict::PredictStats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CollectStats {
    /// Grid cells visited.
    pub cells: u32,
    /// Candidate pieces from the grid.
    pub candidates: u32,
    /// Pseudo-path × piece tests run (0 for the exact strategy).
    pub path_tests: u32,
    /// Exact piece × sector tests run (0 for pseudo-paths).
    pub sector_tests: u32,
}

impl core::ops::AddAssign for CollectStats {
    /// Sums the counts, modulo 2³².
    fn add_assign(&mut self, o: CollectStats) {
        self.cells = self.cells.wrapping_add(o.cells);
        self.candidates = self.candidates.wrapping_add(o.candidates);
        self.path_tests = self.path_tests.wrapping_add(o.path_tests);
        self.sector_tests = self.sector_tests.wrapping_add(o.sector_tests);
    }
}

/// A window placed in the map: the sector and, when the pseudo-path strategy
/// will search it, its pseudo-path layout.
///
/// The layout is made only where that strategy runs ([`Window::place_for`]
/// with [`Strategy::PseudoPaths`]): the exact strategy never reads the paths,
/// so it works for any `d_s_min`, however many paths eq. (2) would ask for
/// (the paper's generalisation to IR sensors needs small ones). The paths'
/// end points are computed when asked ([`Window::paths`]) rather than stored,
/// so a window is the same ~150 bytes on the stack either way; a search of
/// the window's candidates keeps them for its own length ([`PathEnds`]).
#[derive(Clone, Debug)]
pub struct Window {
    /// The annular sector.
    pub sector: Sector,
    /// The parameters it was placed with.
    pub params: WindowParams,
    /// The pseudo-path layout, when laid out.
    layout: Option<PathLayout>,
}

impl Window {
    /// Places the window of `params` at `apex`, looking along `heading_rad`,
    /// for the exact strategy: no pseudo-paths are laid out, so any
    /// `d_s_min` is accepted. Searching it with [`Strategy::PseudoPaths`]
    /// is refused ([`CollectError::NoPseudoPaths`]).
    pub fn place(params: &WindowParams, apex: Point, heading_rad: f32) -> Result<Self, WindowError> {
        Self::place_for(params, apex, heading_rad, Strategy::Exact)
    }

    /// Places the window for `strategy`: as [`Window::place`], and for
    /// [`Strategy::PseudoPaths`] with its layout, eq. (1)–(6), which may be
    /// refused ([`WindowError::TooManyPseudoPaths`], or
    /// [`WindowError::BadRange`] when an end point leaves the coordinates).
    pub fn place_for(
        params: &WindowParams,
        apex: Point,
        heading_rad: f32,
        strategy: Strategy,
    ) -> Result<Self, WindowError> {
        params.validate()?;
        let sector =
            Sector::new(apex, heading_rad, params.half_angle_deg.to_radians(), params.r_min_mm, params.r_max_mm)?;
        let layout = match strategy {
            Strategy::Exact => None,
            Strategy::PseudoPaths => {
                let layout = params.layout()?;
                // End points reach R_max / cos θ_o: refuse a window that would
                // leave the coordinate range. They lie on a line, so the two
                // outermost decide for all of them.
                for k in [0, layout.n_pp.saturating_sub(1)] {
                    sector.to_map(layout.endpoint_x(k), params.r_max_mm as f32).ok_or(WindowError::BadRange)?;
                }
                Some(layout)
            }
        };
        Ok(Self { sector, params: *params, layout })
    }

    /// The pseudo-path layout, if this window was placed for the pseudo-path strategy.
    pub fn layout(&self) -> Option<&PathLayout> {
        self.layout.as_ref()
    }

    /// The pseudo-paths' end points in the map frame, mm, in layout order
    /// (none when no layout was made).
    pub fn paths(&self) -> impl Iterator<Item = Point> + '_ {
        (0..self.path_count()).filter_map(move |k| self.path_end(k))
    }

    /// How many pseudo-paths the layout has (0 without one).
    fn path_count(&self) -> u32 {
        self.layout.map_or(0, |l| l.n_pp)
    }

    /// Path `k`'s end point in the map frame (`None` past the last path, or
    /// when it would leave the coordinates).
    #[inline]
    fn path_end(&self, k: u32) -> Option<Point> {
        let l = self.layout.filter(|l| k < l.n_pp)?;
        self.sector.to_map(l.endpoint_x(k), self.params.r_max_mm as f32)
    }

    /// Whether `strategy` can search this window.
    pub fn supports(&self, strategy: Strategy) -> bool {
        strategy == Strategy::Exact || self.layout.is_some()
    }
}

/// Most pseudo-path end points [`PathEnds`] keeps: 21 paths cover MARGE's
/// 30° window with `d_s_min` 300 mm.
pub const CACHED_PATHS: usize = 32;

/// A window's pseudo-path end points, each computed once for all the
/// window's candidate pieces rather than once per piece, when first asked
/// for: the first [`CACHED_PATHS`] of them, kept relative to the apex in
/// 16 bits (128 bytes in the frame of the search that holds them). Paths
/// past those, or with ends more than 32 m off, are computed each time, as
/// [`Window::paths`] does. Lazily: a window whose few candidates are each
/// met by one of the first paths computes only those.
///
/// ```
/// use echoloc::geometry::Point;
/// use echoloc::window::{PathEnds, Strategy, Window, WindowParams};
///
/// let w = Window::place_for(&WindowParams::MARGE, Point::new(0, 0), 0.0, Strategy::PseudoPaths).unwrap();
/// let mut ends = PathEnds::new(&w);
/// assert_eq!(ends.len() as usize, w.paths().count());
/// // The same points as the window's, whatever order they are asked in.
/// let last = ends.len() - 1;
/// assert_eq!(ends.get(last), w.paths().last());
/// assert_eq!(ends.get(0), w.paths().next());
/// assert_eq!(ends.get(last + 1), None);
/// ```
pub struct PathEnds<'w> {
    window: &'w Window,
    /// End points less the apex: the first `filled` are computed.
    rel: [(i16, i16); CACHED_PATHS],
    filled: usize,
}

impl<'w> PathEnds<'w> {
    /// None computed yet.
    pub fn new(window: &'w Window) -> Self {
        Self { window, rel: [(0, 0); CACHED_PATHS], filled: 0 }
    }

    /// How many paths the window has (0 when placed for the exact strategy).
    pub fn len(&self) -> u32 {
        self.window.path_count()
    }

    /// Whether the window has no paths.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Path `k`'s end point, as the `k`-th of [`Window::paths`] (`None`
    /// when it would leave the coordinates, or `k` is past the last path).
    pub fn get(&mut self, k: u32) -> Option<Point> {
        let w = self.window;
        let o = w.sector.apex;
        let i = k as usize;
        if i < self.filled {
            // `to_map`'s end point less the apex, added back: in range.
            let &(dx, dy) = self.rel.get(i)?;
            return Some(Point::new(o.x.wrapping_add(i32::from(dx)), o.y.wrapping_add(i32::from(dy))));
        }
        let g = w.path_end(k)?;
        if i == self.filled {
            let d = g.sub(o);
            if let (Some(slot), Ok(dx), Ok(dy)) = (self.rel.get_mut(i), i16::try_from(d.0), i16::try_from(d.1)) {
                *slot = (dx, dy);
                self.filled = i + 1;
            }
        }
        Some(g)
    }
}

/// Whether `p` is a beacon of `window` by `strategy`, counting the tests.
/// (The pseudo-paths' end points are computed for this piece alone: a
/// search of many pieces makes them once, [`PathEnds`], and asks
/// [`is_beacon_with`].)
pub fn is_beacon(window: &Window, strategy: Strategy, p: &Piece<'_>, stats: &mut CollectStats) -> bool {
    match strategy {
        Strategy::PseudoPaths => is_beacon_with(window, Some(&mut PathEnds::new(window)), p, stats),
        Strategy::Exact => is_beacon_with(window, None, p, stats),
    }
}

/// [`is_beacon`] with the window's pseudo-path end points made once:
/// `Some(ends)` for the pseudo-path strategy (`ends` of `window`), `None`
/// for the exact one.
pub fn is_beacon_with(
    window: &Window,
    ends: Option<&mut PathEnds<'_>>,
    p: &Piece<'_>,
    stats: &mut CollectStats,
) -> bool {
    let o = window.sector.apex;
    match ends {
        Some(ends) => {
            let shape = p.buffered;
            let to = shape.tvector(o);
            // Strictly outside the piece (nearly always), its cone from the
            // transducer passes over the paths beside it in two cross
            // products each; inside, every path is tested in full.
            let cone = shape.cone_from(o, to);
            for k in 0..ends.len() {
                let Some(g) = ends.get(k) else { continue };
                stats.path_tests = stats.path_tests.wrapping_add(1);
                let hit = match &cone {
                    Some(c) => shape.hits_from(to, c, o, g),
                    None => shape.hits_segment(o, g),
                };
                if hit {
                    return true;
                }
            }
            false
        }
        None => {
            stats.sector_tests = stats.sector_tests.wrapping_add(1);
            window.sector.meets(p.shape)
        }
    }
}

/// Collects into `out` (cleared first) the ids of the pieces in the window,
/// in grid order. On error `out` is left empty.
pub fn collect_beacons<M: MapSource + ?Sized, const B: usize>(
    map: &M,
    window: &Window,
    strategy: Strategy,
    out: &mut Vec<u16, B>,
) -> Result<CollectStats, CollectError> {
    out.clear();
    if !window.supports(strategy) {
        return Err(CollectError::NoPseudoPaths);
    }
    let mut stats = CollectStats::default();
    let mut full = false;
    let mut ends = (strategy == Strategy::PseudoPaths).then(|| PathEnds::new(window));
    let q = map
        .for_each_candidate(window.sector.bbox(), |p| {
            let hit = is_beacon_with(window, ends.as_mut(), &p, &mut stats);
            if hit && out.push(p.id).is_err() {
                full = true;
            }
        })
        .map_err(CollectError::Map)?;
    stats.cells = q.cells;
    stats.candidates = q.candidates;
    if full {
        out.clear();
        return Err(CollectError::TooManyBeacons);
    }
    Ok(stats)
}

#[cfg(test)]
mod tests {
    use super::{PathEnds, Strategy, Window, WindowParams, CACHED_PATHS};
    use crate::geometry::Point;

    /// Against `to_map` of each path's lateral coordinate, asked for in a
    /// scrambled order (the cache fills in order only), on windows with few
    /// and many paths (past the cache), near and far ends (past 16 bits),
    /// and apexes near the edge of the coordinates.
    #[test]
    fn path_ends_are_the_windows_paths() {
        let mut x = 0x6a09_e667_f3bc_c908u64;
        let mut next = |m: u64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x % m
        };
        let (mut cached, mut uncached, mut windows) = (0, 0, 0);
        for _ in 0..3_000 {
            let params = WindowParams {
                r_min_mm: 0,
                r_max_mm: [2_000, 5_500, 30_000, 60_000][next(4) as usize],
                half_angle_deg: 5.0 + next(50) as f32,
                delta_max_deg: next(30) as f32,
                ds_min_mm: [100, 300, 1_000, 3_000][next(4) as usize],
                tb_mm: [0, 300][next(2) as usize],
            };
            let edge = crate::geometry::COORD_MAX - 40_000;
            let c = |v: u64| v as i32 - 1_000_000;
            let apex =
                if next(4) == 0 { Point::new(edge, -edge) } else { Point::new(c(next(2_000_000)), c(next(2_000_000))) };
            let Ok(w) = Window::place_for(&params, apex, next(6283) as f32 / 1000.0, Strategy::PseudoPaths) else {
                continue;
            };
            windows += 1;
            let layout = *w.layout().unwrap();
            let want = |k: u32| w.sector.to_map(layout.endpoint_x(k), params.r_max_mm as f32);
            let mut ends = PathEnds::new(&w);
            assert_eq!(ends.len(), layout.n_pp);
            let n = layout.n_pp;
            for i in 0..2 * n + 2 {
                let k = if i % 3 == 0 { next(n as u64 + 2) as u32 } else { i / 2 };
                assert_eq!(ends.get(k), if k < n { want(k) } else { None }, "path {k} of {n}, {params:?} at {apex:?}");
            }
            if ends.filled == (n as usize).min(CACHED_PATHS) {
                cached += 1;
            } else {
                uncached += 1;
            }
        }
        assert!(
            windows > 1_000 && cached > 500 && uncached > 100,
            "{windows} windows, {cached} cached, {uncached} not"
        );
    }

    #[test]
    fn an_exact_window_has_no_path_ends() {
        let w = Window::place(&WindowParams::MARGE, Point::new(0, 0), 0.0).unwrap();
        let mut ends = PathEnds::new(&w);
        assert!(ends.is_empty());
        assert_eq!(ends.get(0), None);
    }
}

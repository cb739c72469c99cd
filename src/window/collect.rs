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
/// so a window is the same ~150 bytes on the stack either way.
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
        let r = self.params.r_max_mm as f32;
        let n = self.layout.map_or(0, |l| l.n_pp);
        (0..n).filter_map(move |k| self.layout.and_then(|l| self.sector.to_map(l.endpoint_x(k), r)))
    }

    /// Whether `strategy` can search this window.
    pub fn supports(&self, strategy: Strategy) -> bool {
        strategy == Strategy::Exact || self.layout.is_some()
    }
}

/// Whether `p` is a beacon of `window` by `strategy`, counting the tests.
pub fn is_beacon(window: &Window, strategy: Strategy, p: &Piece<'_>, stats: &mut CollectStats) -> bool {
    let o = window.sector.apex;
    match strategy {
        Strategy::PseudoPaths => {
            let shape = p.buffered;
            let to = shape.tvector(o);
            // Strictly outside the piece (nearly always), its cone from the
            // transducer passes over the paths beside it in two cross
            // products each; inside, every path is tested in full.
            let cone = shape.cone_from(o, to);
            for g in window.paths() {
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
        Strategy::Exact => {
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
    let q = map
        .for_each_candidate(window.sector.bbox(), |p| {
            let hit = is_beacon(window, strategy, &p, &mut stats);
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

//! Sensor windows (paper §3, DESIGN §4.1): the window's parameters and
//! pseudo-path layout, its placement in the map, and the search for the
//! beacons in it.
//!
//! Two strategies collect beacons into a fixed-capacity set:
//!
//! * [`Strategy::PseudoPaths`], the paper's: candidates from the grid, then
//!   each pseudo-path (transducer → end point) tested against the candidates'
//!   *buffered* outlines with t-vectors; the transducer's t-vector is computed
//!   once per piece. Complete when `t_b ≥ w` (see
//!   [`WindowParams::pseudo_paths_complete`]).
//! * [`Strategy::Exact`]: candidates from the grid, then an exact test of
//!   each *true* outline against the annular sector. Always complete and
//!   never collects a piece outside the window.
//!
//! ```
//! use echoloc::geometry::Point;
//! use echoloc::map::{Map, ObstacleKind};
//! use echoloc::window::{collect_beacons, Strategy, Window, WindowParams};
//!
//! let mut map: Map<16, 256, 64, 256> = Map::new();
//! let wall = [Point::new(2000, -1000), Point::new(2000, 1000)];
//! map.add_obstacle(ObstacleKind::Wall, &[&wall[..]]).unwrap();
//! map.finish(300, 1000).unwrap();
//!
//! let params = WindowParams { tb_mm: 300, ..WindowParams::MARGE };
//! let window = Window::place(&params, Point::new(0, 0), 0.0).unwrap(); // looking along +x
//! let mut beacons: heapless::Vec<u16, 8> = heapless::Vec::new();
//! collect_beacons(&map, &window, Strategy::Exact, &mut beacons).unwrap();
//! assert_eq!(&beacons[..], &[0]);
//! ```

mod collect;
mod params;
mod sector;

pub use collect::{
    collect_beacons, is_beacon, is_beacon_with, CollectError, CollectStats, PathEnds, Strategy, Window, CACHED_PATHS,
};
pub use params::{PathLayout, WindowError, WindowParams, MAX_PSEUDO_PATHS, MAX_RANGE_MM};
pub use sector::Sector;

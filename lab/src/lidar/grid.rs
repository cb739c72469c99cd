//! The occupancy grid a SLAM user would make from a lidar run
//! (`echoloc-lab map from-scans`): log-odds ray casting of every beam from
//! the laser's pose (cells the beam crossed are more likely free, the cell
//! of its return more likely occupied; *Probabilistic Robotics* §9.2),
//! written as ROS map_server's YAML and trinary PGM, as `map_saver` writes
//! them (occupied 0, free 254, unknown 205; thresholds 0.65 and 0.196).
//!
//! The shared logs' poses are SLAM-corrected, so this is the map a user's
//! SLAM would have made of the same pass, minus SLAM's own pose errors.

use std::path::Path;

use super::LidarRun;

/// How a grid is made.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridOptions {
    /// Cell size, m.
    pub resolution_m: f64,
    /// Beams are used up to this range, m; a return beyond it, or none,
    /// clears the cells up to it (gmapping's `maxUrange`).
    pub max_range_m: f64,
    /// Border of unknown cells around what the scans saw, m.
    pub margin_m: f64,
}

impl Default for GridOptions {
    fn default() -> Self {
        Self { resolution_m: 0.05, max_range_m: 20.0, margin_m: 1.0 }
    }
}

/// Log-odds of a return in its cell (p = 0.7).
const L_OCC: f32 = 0.847;
/// Log-odds of a beam crossing a cell (p = 0.4).
const L_FREE: f32 = -0.405;
/// Clamp of the log-odds (p within 0.7 %…99.3 %), so a cell can change its mind.
const L_MAX: f32 = 5.0;
/// map_saver's thresholds: occupied at p ≥ 0.65, free at p ≤ 0.196.
pub const OCCUPIED_THRESH: f64 = 0.65;
pub const FREE_THRESH: f64 = 0.196;
/// Most cells a grid may have (about 400 MB of log-odds would be a mistake).
const MAX_CELLS: usize = 100_000_000;

/// A grid of log-odds, row 0 at the bottom (the map's smallest y).
#[derive(Clone, Debug)]
pub struct OccupancyGrid {
    /// The corner of cell (0, 0), m.
    pub origin: (f64, f64),
    /// Cell size, m.
    pub resolution: f64,
    pub width: usize,
    pub height: usize,
    log_odds: Vec<f32>,
}

/// What a cell is, by map_saver's thresholds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Occ {
    Free,
    Occupied,
    Unknown,
}

impl OccupancyGrid {
    /// The cell (column, row) of map point `p`, if inside.
    pub fn cell_of(&self, p: (f64, f64)) -> Option<(usize, usize)> {
        let u = ((p.0 - self.origin.0) / self.resolution).floor();
        let v = ((p.1 - self.origin.1) / self.resolution).floor();
        (u >= 0.0 && v >= 0.0 && u < self.width as f64 && v < self.height as f64).then_some((u as usize, v as usize))
    }

    /// The probability that cell (`c`, `r`) is occupied.
    pub fn p(&self, c: usize, r: usize) -> f64 {
        let l = f64::from(self.log_odds[r * self.width + c]);
        1.0 - 1.0 / (1.0 + l.exp())
    }

    /// What cell (`c`, `r`) is.
    pub fn occ(&self, c: usize, r: usize) -> Occ {
        let p = self.p(c, r);
        if self.log_odds[r * self.width + c] == 0.0 {
            Occ::Unknown
        } else if p >= OCCUPIED_THRESH {
            Occ::Occupied
        } else if p <= FREE_THRESH {
            Occ::Free
        } else {
            Occ::Unknown
        }
    }

    /// What the cell of map point `p` is (unknown outside).
    pub fn occ_at(&self, p: (f64, f64)) -> Occ {
        self.cell_of(p).map_or(Occ::Unknown, |(c, r)| self.occ(c, r))
    }

    /// Counts of (free, occupied, unknown) cells.
    pub fn counts(&self) -> (usize, usize, usize) {
        let mut n = (0, 0, 0);
        for r in 0..self.height {
            for c in 0..self.width {
                match self.occ(c, r) {
                    Occ::Free => n.0 += 1,
                    Occ::Occupied => n.1 += 1,
                    Occ::Unknown => n.2 += 1,
                }
            }
        }
        n
    }

    /// The trinary PGM (P5) map_saver writes: row 0 of the image is the
    /// top (the largest y).
    pub fn pgm(&self) -> Vec<u8> {
        let mut out = format!("P5\n# echoloc-lab map from-scans\n{} {}\n255\n", self.width, self.height).into_bytes();
        for r in (0..self.height).rev() {
            out.extend((0..self.width).map(|c| match self.occ(c, r) {
                Occ::Occupied => 0u8,
                Occ::Free => 254,
                Occ::Unknown => 205,
            }));
        }
        out
    }

    /// The map_server YAML naming `image` (a file name beside it).
    pub fn yaml(&self, image: &str) -> String {
        format!(
            "image: {image}\nmode: trinary\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n",
            self.resolution, self.origin.0, self.origin.1
        )
    }

    /// Adds one beam from `o` towards `end` (a return there when `hit`).
    fn beam(&mut self, o: (f64, f64), end: (f64, f64), hit: bool) {
        let res = self.resolution;
        let to_cell = |p: (f64, f64)| ((p.0 - self.origin.0) / res, (p.1 - self.origin.1) / res);
        let (a, b) = (to_cell(o), to_cell(end));
        // Amanatides and Woo's walk over every cell the segment crosses.
        let (mut cx, mut cy) = (a.0.floor() as i64, a.1.floor() as i64);
        let (ex, ey) = (b.0.floor() as i64, b.1.floor() as i64);
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (sx, sy) = (dx.signum() as i64, dy.signum() as i64);
        let t_of = |p: f64, d: f64, c: i64, s: i64| {
            if d == 0.0 {
                f64::INFINITY
            } else {
                let edge = if s > 0 { (c + 1) as f64 } else { c as f64 };
                (edge - p) / d
            }
        };
        let (mut tx, mut ty) = (t_of(a.0, dx, cx, sx), t_of(a.1, dy, cy, sy));
        let (stx, sty) = (
            if dx == 0.0 { f64::INFINITY } else { 1.0 / dx.abs() },
            if dy == 0.0 { f64::INFINITY } else { 1.0 / dy.abs() },
        );
        let max_steps = (ex - cx).unsigned_abs() + (ey - cy).unsigned_abs() + 2;
        for _ in 0..max_steps {
            if (cx, cy) == (ex, ey) {
                break;
            }
            self.add(cx, cy, L_FREE);
            if tx < ty {
                cx += sx;
                tx += stx;
            } else {
                cy += sy;
                ty += sty;
            }
        }
        self.add(ex, ey, if hit { L_OCC } else { L_FREE });
    }

    fn add(&mut self, c: i64, r: i64, l: f32) {
        if c >= 0 && r >= 0 && (c as usize) < self.width && (r as usize) < self.height {
            let v = &mut self.log_odds[r as usize * self.width + c as usize];
            *v = (*v + l).clamp(-L_MAX, L_MAX);
        }
    }
}

/// The grid of every beam of `run`.
pub fn build(run: &LidarRun, o: &GridOptions) -> Result<OccupancyGrid, String> {
    let positive = |v: f64| v > 0.0 && v.is_finite();
    if !positive(o.resolution_m) || !positive(o.max_range_m) {
        return Err(format!(
            "resolution {} m, maximum range {} m: both must be positive",
            o.resolution_m, o.max_range_m
        ));
    }
    // The extent: every laser pose and every used return.
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    let mut grow = |p: (f64, f64)| {
        lo = (lo.0.min(p.0), lo.1.min(p.1));
        hi = (hi.0.max(p.0), hi.1.max(p.1));
    };
    for s in &run.scans {
        grow((s.laser[0], s.laser[1]));
        for i in 0..s.ranges.len() {
            if let Some(e) = beam_end(s, i, o.max_range_m) {
                grow(e.0);
            }
        }
    }
    let m = o.margin_m.max(0.0) + o.resolution_m;
    let origin = (
        ((lo.0 - m) / o.resolution_m).floor() * o.resolution_m,
        ((lo.1 - m) / o.resolution_m).floor() * o.resolution_m,
    );
    let width = ((hi.0 + m - origin.0) / o.resolution_m).ceil() as usize;
    let height = ((hi.1 + m - origin.1) / o.resolution_m).ceil() as usize;
    if width.saturating_mul(height) > MAX_CELLS {
        return Err(format!(
            "{width} × {height} cells of {} m: the run spans more than a grid should ({MAX_CELLS} cells); a coarser --resolution-m?",
            o.resolution_m
        ));
    }
    let mut g =
        OccupancyGrid { origin, resolution: o.resolution_m, width, height, log_odds: vec![0.0; width * height] };
    for s in &run.scans {
        let from = (s.laser[0], s.laser[1]);
        for i in 0..s.ranges.len() {
            if let Some((end, hit)) = beam_end(s, i, o.max_range_m) {
                g.beam(from, end, hit);
            }
        }
    }
    Ok(g)
}

/// Where beam `i` of `s` ends within `max_range` m, and whether it ends on
/// a return. A beam with no return clears up to `max_range`.
fn beam_end(s: &super::Scan, i: usize, max_range: f64) -> Option<((f64, f64), bool)> {
    let r = f64::from(*s.ranges.get(i)?);
    let (hit, r) = if r.is_finite() && r <= max_range { (true, r) } else { (false, max_range) };
    let a = s.laser[2] + s.bearing(i);
    Some(((s.laser[0] + r * a.cos(), s.laser[1] + r * a.sin()), hit))
}

/// Writes `g` as `yaml` and the PGM beside it (same stem), each whole or
/// not at all; returns the image's path.
pub fn write(g: &OccupancyGrid, yaml: &Path) -> Result<std::path::PathBuf, crate::error::LabError> {
    let stem = yaml.file_stem().and_then(|s| s.to_str()).filter(|s| !s.is_empty()).ok_or_else(|| {
        crate::error::LabError(format!("{}: give a file name for the map's YAML (MAP.yaml)", yaml.display()))
    })?;
    let image = yaml.with_file_name(format!("{stem}.pgm"));
    crate::files::write_all(&[
        (image.clone(), g.pgm()),
        (yaml.to_path_buf(), g.yaml(&format!("{stem}.pgm")).into_bytes()),
    ])?;
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar::Scan;

    /// A laser at the centre of a 4 m square room, turning: 4 scans of 361 beams.
    fn room() -> LidarRun {
        let scans = (0..4)
            .map(|k| {
                let th = f64::from(k) * std::f64::consts::FRAC_PI_2;
                let ranges = (0..361)
                    .map(|i| {
                        let b = th - std::f64::consts::FRAC_PI_2 + f64::from(i) * std::f64::consts::PI / 360.0;
                        // Distance to the square's side |x| = 2 or |y| = 2.
                        (2.0 / b.cos().abs().max(b.sin().abs())) as f32
                    })
                    .collect();
                Scan {
                    time_s: f64::from(k),
                    robot: [0.0, 0.0, th],
                    laser: [0.0, 0.0, th],
                    odometry: None,
                    angle_min: -std::f64::consts::FRAC_PI_2,
                    angle_step: std::f64::consts::PI / 360.0,
                    ranges,
                    line: 0,
                }
            })
            .collect();
        LidarRun { scans, format: "test".into(), skipped: vec![], first_index: 0 }
    }

    #[test]
    fn a_square_room_maps_as_its_walls() {
        let g = build(&room(), &GridOptions::default()).unwrap();
        // Inside free, the walls occupied, outside unknown.
        assert_eq!(g.occ_at((0.0, 0.0)), Occ::Free);
        assert_eq!(g.occ_at((1.5, -1.2)), Occ::Free);
        // The wall at 2 m lies on a cell boundary: the return's cell is on one side of it.
        for (p, d) in [
            ((2.0, 0.3), (0.01, 0.0)),
            ((-2.0, -1.0), (0.01, 0.0)),
            ((0.7, 2.0), (0.0, 0.01)),
            ((-1.3, -2.0), (0.0, 0.01)),
        ] {
            let (a, b) = (g.occ_at((p.0 - d.0, p.1 - d.1)), g.occ_at((p.0 + d.0, p.1 + d.1)));
            assert!(a == Occ::Occupied || b == Occ::Occupied, "{p:?}: {a:?} {b:?}");
        }
        assert_eq!(g.occ_at((2.6, 0.0)), Occ::Unknown);
        // The files map_saver would write, read back by hand: the YAML names
        // the PGM; the PGM is P5, 255, row 0 at the top; occupied 0, free 254.
        let dir = std::env::temp_dir().join(format!("echoloc-grid-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let yaml = dir.join("room.yaml");
        let image = write(&g, &yaml).unwrap();
        let text = std::fs::read_to_string(&yaml).unwrap();
        assert!(text.contains("image: room.pgm") && text.contains("resolution: 0.05"), "{text}");
        let pgm = std::fs::read(&image).unwrap();
        let header = format!("P5\n# echoloc-lab map from-scans\n{} {}\n255\n", g.width, g.height);
        assert!(pgm.starts_with(header.as_bytes()));
        let px = &pgm[header.len()..];
        assert_eq!(px.len(), g.width * g.height);
        let (free, occ, _) = g.counts();
        assert_eq!(px.iter().filter(|&&v| v == 254).count(), free);
        assert_eq!(px.iter().filter(|&&v| v == 0).count(), occ);
        // Image row 0 is the top: the cell at the map's (0, 1) m is free there.
        let (c, r) = g.cell_of((0.0, 1.0)).unwrap();
        assert_eq!(px[(g.height - 1 - r) * g.width + c], 254);
    }
}

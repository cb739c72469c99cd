//! A lidar robot's run in (issue #35, DESIGN §4.9): the laser's scans at
//! the robot's poses, read from CARMEN logs ([`carmen`]: `FLASER`,
//! `ROBOTLASER1`, `ODOM`) or ROS 2 bags ([`bag`]: `LaserScan`); the occupancy grid a SLAM user would make from
//! one pass of it ([`grid`], `echoloc-lab map from-scans`). The sonar ring's
//! readings derived from the scans live beside the simulator, in
//! [`crate::from_scans`].
//!
//! ```no_run
//! use echoloc_lab::lidar::{read, Pass};
//! let run = read("intel-corrected.log.gz".as_ref())?;
//! let first_half = run.pass(Pass::parse("0:455")?)?;
//! println!("{} scans over {:.0} m", first_half.scans.len(), first_half.path_length_m());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod bag;
pub mod carmen;
pub mod grid;

use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

/// One laser scan at the pose it was taken from.
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// When it was taken, s (as logged; not always increasing in real logs).
    pub time_s: f64,
    /// The robot's pose in the map (x m, y m, θ rad): the reference
    /// (SLAM-corrected in the shared logs).
    pub robot: [f64; 3],
    /// The laser's pose in the map (the robot's, with the laser's offset).
    pub laser: [f64; 3],
    /// The odometry the log carries with the scan, if any (its own frame).
    pub odometry: Option<[f64; 3]>,
    /// Bearing of the first beam from the laser's axis, rad.
    pub angle_min: f64,
    /// Angle between beams, rad (positive: counter-clockwise).
    pub angle_step: f64,
    /// Ranges, m; `f32::INFINITY` where the beam had no return.
    pub ranges: Vec<f32>,
    /// Where it is in the source: its line (CARMEN) or message index (bag).
    pub line: u64,
}

#[cfg(test)]
impl Scan {
    /// A scan taken at time 0 from `pose` (x, y, heading; the laser at the
    /// robot's centre), its first beam `angle_min` off the heading and the
    /// others `angle_step` apart (the tests' scans of hand-made walls).
    pub(crate) fn taken_at(pose: [f64; 3], angle_min: f64, angle_step: f64, ranges: Vec<f32>) -> Self {
        Scan { time_s: 0.0, robot: pose, laser: pose, odometry: None, angle_min, angle_step, ranges, line: 0 }
    }
}

impl Scan {
    /// Bearing of beam `i` from the laser's axis, rad.
    pub fn bearing(&self, i: usize) -> f64 {
        self.angle_min + i as f64 * self.angle_step
    }

    /// Beam `i`'s return in the map (m), if it had one.
    pub fn point(&self, i: usize) -> Option<(f64, f64)> {
        let r = f64::from(*self.ranges.get(i)?);
        if !r.is_finite() {
            return None;
        }
        let a = self.laser[2] + self.bearing(i);
        Some((self.laser[0] + r * a.cos(), self.laser[1] + r * a.sin()))
    }

    /// Every return in the map, m.
    pub fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        (0..self.ranges.len()).filter_map(|i| self.point(i))
    }
}

/// A lidar run: the scans in the order they were taken.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LidarRun {
    /// The scans.
    pub scans: Vec<Scan>,
    /// The format it was read from (`carmen FLASER`, `carmen ROBOTLASER1`, …).
    pub format: String,
    /// Lines or messages of kinds that carry no scan, left out, by kind.
    pub skipped: Vec<(String, usize)>,
    /// The index in the whole run of the first scan here (after [`LidarRun::pass`]).
    pub first_index: usize,
}

impl LidarRun {
    /// Distance the robot drove, m (straight between scans).
    pub fn path_length_m(&self) -> f64 {
        self.scans.windows(2).map(|w| (w[1].robot[0] - w[0].robot[0]).hypot(w[1].robot[1] - w[0].robot[1])).sum()
    }

    /// The scans of `pass` (indices into the whole run).
    pub fn pass(&self, pass: Pass) -> Result<LidarRun, LidarError> {
        let n = self.first_index + self.scans.len();
        let (from, to) = (pass.from.unwrap_or(self.first_index), pass.to.unwrap_or(n));
        if from < self.first_index || to > n || from + 2 > to {
            return Err(LidarError::Pass(format!(
                "{pass}: the run has scans {}..{n}; a pass needs at least two of them",
                self.first_index
            )));
        }
        Ok(LidarRun {
            scans: self.scans[from - self.first_index..to - self.first_index].to_vec(),
            format: self.format.clone(),
            skipped: self.skipped.clone(),
            first_index: from,
        })
    }
}

impl LidarRun {
    /// The scans of several passes, in the order given (a map made from
    /// every part of a run but the one driven: `0:200,320:`).
    pub fn passes(&self, passes: &[Pass]) -> Result<LidarRun, LidarError> {
        let mut out: Option<LidarRun> = None;
        for &p in passes {
            let part = self.pass(p)?;
            match &mut out {
                None => out = Some(part),
                Some(o) => o.scans.extend(part.scans),
            }
        }
        out.ok_or_else(|| LidarError::Pass("no pass given".into()))
    }
}

/// Parses `FROM:TO[,FROM:TO…]`.
pub fn parse_passes(s: &str) -> Result<Vec<Pass>, LidarError> {
    s.split(',').map(Pass::parse).collect()
}

/// Part of a run: scans `from..to` (indices into the whole run, either end
/// open), written `FROM:TO`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pass {
    /// First scan (none: the first).
    pub from: Option<usize>,
    /// One past the last (none: the end).
    pub to: Option<usize>,
}

impl Pass {
    /// `FROM:TO`, `FROM:`, `:TO` or `:`.
    pub fn parse(s: &str) -> Result<Pass, LidarError> {
        let bad = || LidarError::Pass(format!("{s:?}: expected FROM:TO, scan indices (either may be left out)"));
        let (a, b) = s.split_once(':').ok_or_else(bad)?;
        let num = |t: &str| -> Result<Option<usize>, LidarError> {
            let t = t.trim();
            if t.is_empty() {
                Ok(None)
            } else {
                t.parse().map(Some).map_err(|_| bad())
            }
        };
        Ok(Pass { from: num(a)?, to: num(b)? })
    }
}

impl fmt::Display for Pass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = |v: Option<usize>| v.map(|v| v.to_string()).unwrap_or_default();
        write!(f, "{}:{}", s(self.from), s(self.to))
    }
}

/// Why a lidar run could not be read.
#[derive(Debug)]
pub enum LidarError {
    /// The file could not be read.
    Io { path: PathBuf, source: std::io::Error },
    /// A CARMEN log line is wrong.
    Carmen { path: PathBuf, line: u64, problem: String },
    /// The file has no scan with a pose.
    NoScans { path: PathBuf, skipped: Vec<(String, usize)> },
    /// A pass that is not part of the run.
    Pass(String),
    /// The file is of no kind this reads.
    Format { path: PathBuf, problem: String },
    /// A ROS 2 bag that is not a lidar run ([`bag`]).
    Bag { path: PathBuf, source: Box<bag::Error> },
}

impl fmt::Display for LidarError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LidarError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            LidarError::Carmen { path, line, problem } => write!(f, "{}: line {line}: {problem}", path.display()),
            LidarError::NoScans { path, skipped } => {
                let kinds: Vec<String> = skipped.iter().map(|(k, n)| format!("{n} {k}")).collect();
                write!(
                    f,
                    "{}: no laser scan with a pose (FLASER, ROBOTLASER1) in it{}",
                    path.display(),
                    if kinds.is_empty() { String::new() } else { format!("; it has {}", kinds.join(", ")) }
                )
            }
            LidarError::Pass(p) => write!(f, "--pass {p}"),
            LidarError::Format { path, problem } => write!(f, "{}: {problem}", path.display()),
            // The bag's own file errors name the file (an MCAP inside the directory) already.
            LidarError::Bag { source, .. } if source.names_file() => write!(f, "{source}"),
            LidarError::Bag { path, source } => write!(f, "{}: {source}", path.display()),
        }
    }
}

impl std::error::Error for LidarError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LidarError::Io { source, .. } => Some(source),
            LidarError::Bag { source, .. } => Some(source.as_ref()),
            _ => None,
        }
    }
}

impl From<LidarError> for crate::error::LabError {
    fn from(e: LidarError) -> Self {
        crate::error::LabError(e.to_string())
    }
}

/// Reads a lidar run: a ROS 2 bag with a laser (a rosbag2 directory, or a
/// `.mcap` file; [`bag`], its topics found by type), else a CARMEN log
/// (plain, or gzip-compressed as Radish keeps them).
pub fn read(path: &Path) -> Result<LidarRun, LidarError> {
    read_with(path, &bag::Options::default())
}

/// Whether `path` is a ROS 2 bag: a directory with rosbag2's `metadata.yaml`,
/// or a file ending in `.mcap`.
pub fn is_bag(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file();
    }
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap"))
}

/// [`read`], a bag read with `options`.
pub fn read_with(path: &Path, options: &bag::Options) -> Result<LidarRun, LidarError> {
    if is_bag(path) {
        return bag::read(path, options)
            .map(|b| b.run)
            .map_err(|e| LidarError::Bag { path: path.to_path_buf(), source: Box::new(e) });
    }
    let raw = std::fs::read(path).map_err(|e| LidarError::Io { path: path.to_path_buf(), source: e })?;
    let text = if raw.starts_with(&[0x1f, 0x8b]) {
        let mut s = String::new();
        flate2::read::MultiGzDecoder::new(raw.as_slice()).read_to_string(&mut s).map_err(|e| LidarError::Format {
            path: path.to_path_buf(),
            problem: format!("not a readable gzip file: {e}"),
        })?;
        s
    } else {
        String::from_utf8(raw).map_err(|_| LidarError::Format {
            path: path.to_path_buf(),
            problem: "not text: expected a CARMEN log (FLASER, ROBOTLASER1, ODOM lines), plain or gzip".into(),
        })?
    };
    carmen::parse(&text).map_err(|e| e.at(path))
}

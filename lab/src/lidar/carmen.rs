//! CARMEN logs: one message per line, `NAME fields… ipc_timestamp
//! ipc_hostname logger_timestamp`.
//!
//! | message | fields read |
//! |---|---|
//! | `FLASER n r₁…rₙ x y θ odom_x odom_y odom_θ t host t_log` | a front laser over 180° from −90°: n = 181 or 361 spans −90° to +90° inclusive, any other n steps 180°/n from −90° (Radish's 180 beams: −90° to +89°); (x, y, θ) the laser's pose; returns at or beyond [`NO_RETURN_M`] are none |
//! | `ROBOTLASER1 type start fov res max_range accuracy remission_mode n r₁…rₙ m e₁…eₘ lx ly lθ rx ry rθ tv rv fwd side turn t host t_log` | any laser: its own angles and maximum range; the laser's and the robot's poses |
//! | `ODOM x y θ tv rv accel t host t_log` | the odometry, kept with the next scan |
//! | `PARAM robot_frontlaser_offset d` | the front laser `d` m ahead of the robot's centre (FLASER) |
//!
//! Other messages (`PARAM`s, `SYNC`, `NEFF`, `RAWLASER`, `TRUEPOS`, …) are
//! counted and left out. A line of a known message with a missing or bad
//! field refuses the whole log, naming the line.

use std::path::Path;

use super::{LidarError, LidarRun, Scan};

/// A FLASER return this long or longer is no return, m (the SICK LMS's
/// "nothing" in Radish's logs is 50 m or more; README of `shared/data`).
pub const NO_RETURN_M: f64 = 49.9;

/// A parse error before the file's path is known.
#[derive(Debug)]
pub enum ParseError {
    /// A line and what is wrong there.
    Line(u64, String),
    /// No scan at all (the kinds of line seen).
    NoScans(Vec<(String, usize)>),
}

impl ParseError {
    /// The error, naming `path`.
    pub fn at(self, path: &Path) -> LidarError {
        match self {
            ParseError::Line(line, problem) => LidarError::Carmen { path: path.to_path_buf(), line, problem },
            ParseError::NoScans(skipped) => LidarError::NoScans { path: path.to_path_buf(), skipped },
        }
    }
}

/// Parses a CARMEN log's text.
pub fn parse(text: &str) -> Result<LidarRun, ParseError> {
    let mut scans = Vec::new();
    let mut skipped: Vec<(String, usize)> = Vec::new();
    let mut formats: Vec<&'static str> = Vec::new();
    let mut front_offset_m = 0.0;
    let mut odometry: Option<[f64; 3]> = None;
    for (k, l) in text.lines().enumerate() {
        let line = k as u64 + 1;
        let t: Vec<&str> = l.split_whitespace().collect();
        let Some(&name) = t.first() else { continue };
        if name.starts_with('#') {
            continue;
        }
        let err = |p: String| ParseError::Line(line, format!("{name}: {p}"));
        let mut f = Fields { t: &t, at: 1 };
        match name {
            "PARAM" if t.get(1) == Some(&"robot_frontlaser_offset") => {
                front_offset_m = f.skip(1).and_then(|f| f.num("robot_frontlaser_offset")).map_err(err)?;
            }
            "ODOM" => {
                let p = f.pose("x y theta").map_err(err)?;
                odometry = Some(p);
            }
            "FLASER" => {
                let s = flaser(&mut f, front_offset_m, odometry.take(), line).map_err(err)?;
                scans.push(s);
                if !formats.contains(&"FLASER") {
                    formats.push("FLASER");
                }
            }
            "ROBOTLASER1" => {
                let s = robotlaser(&mut f, odometry.take(), line).map_err(err)?;
                scans.push(s);
                if !formats.contains(&"ROBOTLASER1") {
                    formats.push("ROBOTLASER1");
                }
            }
            other => match skipped.iter_mut().find(|(k, _)| k == other) {
                Some((_, n)) => *n += 1,
                None => skipped.push((other.to_string(), 1)),
            },
        }
    }
    if scans.is_empty() {
        return Err(ParseError::NoScans(skipped));
    }
    Ok(LidarRun { scans, format: format!("carmen {}", formats.join("+")), skipped, first_index: 0 })
}

/// The fields of one line, read left to right.
struct Fields<'a> {
    t: &'a [&'a str],
    at: usize,
}

impl Fields<'_> {
    fn skip(&mut self, n: usize) -> Result<&mut Self, String> {
        if self.at + n > self.t.len() {
            return Err(format!("the line ends after {} fields", self.t.len() - 1));
        }
        self.at += n;
        Ok(self)
    }

    fn num(&mut self, what: &str) -> Result<f64, String> {
        let s = self.t.get(self.at).ok_or_else(|| format!("the line ends before {what}"))?;
        let v: f64 = s.parse().map_err(|_| format!("{what} {s:?} is not a number"))?;
        if !v.is_finite() {
            return Err(format!("{what} {s:?} is not finite"));
        }
        self.at += 1;
        Ok(v)
    }

    fn count(&mut self, what: &str, most: usize) -> Result<usize, String> {
        let v = self.num(what)?;
        if v < 0.0 || v.fract() != 0.0 || v > most as f64 {
            return Err(format!("{what} {v} is not a count of at most {most}"));
        }
        Ok(v as usize)
    }

    fn pose(&mut self, what: &str) -> Result<[f64; 3], String> {
        let p = [self.num(what)?, self.num(what)?, self.num(what)?];
        if p[0].abs() > 1e6 || p[1].abs() > 1e6 {
            return Err(format!("{what} ({}, {}) is beyond 1 000 km", p[0], p[1]));
        }
        Ok(p)
    }

    /// `n` ranges; at or beyond `no_return` (or negative: some loggers'
    /// "none") is no return.
    fn ranges(&mut self, n: usize, no_return: f64) -> Result<Vec<f32>, String> {
        (0..n)
            .map(|i| {
                let r = self.num(&format!("range {i}"))?;
                Ok(if r >= no_return || r <= 0.0 { f32::INFINITY } else { r as f32 })
            })
            .collect()
    }
}

/// Most beams in one scan (a 0.25° laser over 360° has 1 440).
const MAX_BEAMS: usize = 8192;

fn flaser(f: &mut Fields<'_>, front_offset_m: f64, odometry: Option<[f64; 3]>, line: u64) -> Result<Scan, String> {
    let n = f.count("num_readings", MAX_BEAMS)?;
    if n < 2 {
        return Err(format!("{n} readings: a scan needs at least two"));
    }
    let ranges = f.ranges(n, NO_RETURN_M)?;
    let laser = f.pose("x y theta")?;
    let odom = f.pose("odom_x odom_y odom_theta")?;
    let time_s = f.num("ipc_timestamp")?;
    let (fov, inclusive) = (std::f64::consts::PI, n == 181 || n == 361);
    let step = if inclusive { fov / (n - 1) as f64 } else { fov / n as f64 };
    let (s, c) = laser[2].sin_cos();
    let robot = [laser[0] - c * front_offset_m, laser[1] - s * front_offset_m, laser[2]];
    Ok(Scan {
        time_s,
        robot,
        laser,
        odometry: odometry.or(Some(odom)),
        angle_min: -fov / 2.0,
        angle_step: step,
        ranges,
        line,
    })
}

fn robotlaser(f: &mut Fields<'_>, odometry: Option<[f64; 3]>, line: u64) -> Result<Scan, String> {
    f.skip(1)?; // laser_type
    let start = f.num("start_angle")?;
    let fov = f.num("field_of_view")?;
    let res = f.num("angular_resolution")?;
    let max_range = f.num("maximum_range")?;
    f.skip(2)?; // accuracy, remission_mode
    let n = f.count("num_readings", MAX_BEAMS)?;
    if n < 2 {
        return Err(format!("{n} readings: a scan needs at least two"));
    }
    if !(res > 0.0 && res <= fov.abs().max(res)) || start.abs() > 2.0 * std::f64::consts::PI {
        return Err(format!("start_angle {start}, angular_resolution {res}: not a laser's angles (radians)"));
    }
    if max_range <= 0.0 {
        return Err(format!("maximum_range {max_range}: must be positive"));
    }
    let ranges = f.ranges(n, max_range)?;
    let m = f.count("num_remissions", MAX_BEAMS)?;
    f.skip(m)?;
    let laser = f.pose("laser_pose")?;
    let robot = f.pose("robot_pose")?;
    f.skip(5)?; // tv rv forward_safety_dist side_safety_dist turn_axis
    let time_s = f.num("timestamp")?;
    Ok(Scan { time_s, robot, laser, odometry, angle_min: start, angle_step: res, ranges, line })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flaser_line(n: usize, r: f64, pose: (f64, f64, f64), t: f64) -> String {
        let rs: Vec<String> = (0..n).map(|_| format!("{r}")).collect();
        format!("FLASER {n} {} {} {} {} 0 0 0 {t} host {t}", rs.join(" "), pose.0, pose.1, pose.2)
    }

    #[test]
    fn flaser_beams_span_the_front_half() {
        let run = parse(&flaser_line(180, 2.0, (1.0, 2.0, 0.0), 5.0)).unwrap();
        let s = &run.scans[0];
        assert_eq!(s.ranges.len(), 180);
        // −90° to +89°: the first beam points to the right (−y), the last nearly left.
        let p0 = s.point(0).unwrap();
        assert!((p0.0 - 1.0).abs() < 1e-9 && (p0.1 - 0.0).abs() < 1e-9, "{p0:?}");
        assert!((s.bearing(179).to_degrees() - 89.0).abs() < 1e-9);
        let run = parse(&flaser_line(181, 2.0, (0.0, 0.0, 0.0), 5.0)).unwrap();
        assert!((run.scans[0].bearing(180).to_degrees() - 90.0).abs() < 1e-9);
        assert_eq!(run.scans[0].time_s, 5.0);
    }

    #[test]
    fn no_returns_and_the_laser_offset() {
        let text =
            format!("PARAM robot_frontlaser_offset 0.2 nohost 0\n{}", flaser_line(180, 50.0, (1.0, 1.0, 1.0), 0.0));
        let s = &parse(&text).unwrap().scans[0];
        assert!(s.ranges.iter().all(|r| r.is_infinite()));
        assert_eq!(s.points().count(), 0);
        // The robot is 0.2 m behind the laser along θ = 1 rad.
        assert!((s.robot[0] - (1.0 - 0.2 * 1f64.cos())).abs() < 1e-12);
        assert!((s.robot[1] - (1.0 - 0.2 * 1f64.sin())).abs() < 1e-12);
    }

    #[test]
    fn robotlaser1_reads_its_own_angles_and_poses() {
        let l = "ROBOTLASER1 0 -1.5 3.0 0.5 20 0.01 0 7 1 2 3 4 30 6 7 0 1 2 3 4 5 6 0.1 0.2 0 0 0 12.5 host 12.5";
        let run = parse(l).unwrap();
        let s = &run.scans[0];
        assert_eq!((s.angle_min, s.angle_step), (-1.5, 0.5));
        assert_eq!(s.laser, [1.0, 2.0, 3.0]);
        assert_eq!(s.robot, [4.0, 5.0, 6.0]);
        assert!(s.ranges[4].is_infinite(), "30 m is beyond the 20 m maximum");
        assert_eq!(s.time_s, 12.5);
        assert_eq!(run.format, "carmen ROBOTLASER1");
    }

    #[test]
    fn bad_lines_name_their_line_and_field() {
        let text = format!("ODOM 0 0 0 0 0 0 0 h 0\n{}", "FLASER 180 1 2 3");
        match parse(&text).unwrap_err() {
            ParseError::Line(2, p) => assert!(p.contains("FLASER") && p.contains("range 3"), "{p}"),
            e => panic!("{e:?}"),
        }
        match parse("FLASER 3 1 x 1 0 0 0 0 0 0 0 h 0").unwrap_err() {
            ParseError::Line(1, p) => assert!(p.contains("range 1 \"x\" is not a number"), "{p}"),
            e => panic!("{e:?}"),
        }
        match parse("PARAM a b\nSYNC x\nNEFF 3\n").unwrap_err() {
            ParseError::NoScans(k) => assert_eq!(k, vec![("PARAM".into(), 1), ("SYNC".into(), 1), ("NEFF".into(), 1)]),
            e => panic!("{e:?}"),
        }
    }

    #[test]
    fn odometry_goes_with_the_next_scan() {
        let text = format!(
            "ODOM 5 6 0.5 0 0 0 1 h 1\n{}\n{}",
            flaser_line(180, 1.0, (0.0, 0.0, 0.0), 1.0),
            flaser_line(180, 1.0, (0.0, 0.0, 0.0), 2.0)
        );
        let run = parse(&text).unwrap();
        assert_eq!(run.scans[0].odometry, Some([5.0, 6.0, 0.5]));
        // Without an ODOM line before it, the scan's own odometry fields.
        assert_eq!(run.scans[1].odometry, Some([0.0, 0.0, 0.0]));
    }
}

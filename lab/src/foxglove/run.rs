//! A run of the filters (`simulate`, `replay`) as Foxglove messages: the
//! map, each reading's poses, covariance, sensor window and verdict, each
//! ring cycle's particles and hypotheses while searching, and the
//! localizer's mode with the reason it changed.

use echoloc::map::MapSource;
use echoloc::predict::Mount;
use echoloc::referencing::Reading;
use foxglove::messages::{FrameTransforms, Log, PackedElementField, PointCloud, SceneUpdate};

use super::scene::{self, arc, entity, line, stamp, LINE_LIST, LINE_LOOP, LINE_STRIP};
use super::{Recording, RecordingError};
use crate::simulate::filters::{predict_params, CycleRow, Methods, PlaceRow, Step, Trace};

/// Clouds are recorded at most this often (run time, s): a ring cycle's
/// end while searching or lost, unless the last was nearer than this.
pub const CLOUD_INTERVAL_S: f64 = 0.25;

/// The run's time, ns.
pub fn t_ns(s: f64) -> u64 {
    (s.max(0.0) * 1e9).round() as u64
}

/// Records a run into a new recording. `steps` and `trace` are the filters'
/// input and output; `unmapped` the simulator's clutter outlines (m).
pub fn record<M: MapSource>(
    map: &M,
    mounts: &[Mount],
    steps: &[Step],
    trace: &Trace,
    unmapped: &[Vec<(f64, f64)>],
) -> Result<Recording, RecordingError> {
    let mut rec = Recording::new()?;
    record_into(&mut rec, map, mounts, steps, trace, unmapped);
    Ok(rec)
}

/// The map as a scene: the obstacles' outlines (shared edges inside an
/// obstacle left out), the pieces' C-space buffers, the unmapped objects.
pub fn map_scene<M: MapSource>(map: &M, t0: u64, unmapped: &[Vec<(f64, f64)>]) -> SceneUpdate {
    let mm = |p: &echoloc::geometry::Point| (f64::from(p.x) / 1000.0, f64::from(p.y) / 1000.0);
    let mut outline = Vec::new();
    for o in map.obstacles_iter() {
        let pieces: Vec<Vec<(i32, i32)>> = (o.first_piece..o.first_piece + o.piece_count)
            .filter_map(|id| map.piece(id))
            .map(|p| p.shape.vertices().iter().map(|q| (q.x, q.y)).collect())
            .collect();
        let edges: std::collections::HashSet<_> =
            pieces.iter().flat_map(|v| (0..v.len()).map(move |i| (v[i], v[(i + 1) % v.len()]))).collect();
        for v in &pieces {
            for i in 0..v.len() {
                let (a, b) = (v[i], v[(i + 1) % v.len()]);
                if !(v.len() > 2 && edges.contains(&(b, a))) {
                    outline.push((f64::from(a.0) / 1000.0, f64::from(a.1) / 1000.0));
                    outline.push((f64::from(b.0) / 1000.0, f64::from(b.1) / 1000.0));
                }
            }
        }
    }
    let buffers = map
        .pieces_iter()
        .map(|p| {
            let v: Vec<(f64, f64)> = p.buffered.vertices().iter().map(mm).collect();
            line(LINE_LOOP, &v, 1.0, [0.0, 0.67, 0.31, 0.8])
        })
        .collect();
    let mut ents = vec![
        entity(t0, "map/outlines", vec![line(LINE_LIST, &outline, 2.0, [0.0, 0.35, 0.86, 1.0])], vec![]),
        entity(t0, "map/buffers", buffers, vec![]),
    ];
    if !unmapped.is_empty() {
        let l = unmapped.iter().map(|o| line(LINE_LOOP, o, 2.0, [0.9, 0.0, 0.63, 1.0])).collect();
        ents.push(entity(t0, "map/unmapped", l, vec![]));
    }
    scene::scene(ents)
}

/// Advertises a run's channels to a live view before the first message.
pub fn advertise(rec: &mut Recording) {
    rec.advertise::<SceneUpdate>("/map");
    rec.advertise::<FrameTransforms>("/tf");
    for name in ["ekf", "dead_reckoning", "threshold", "truth"] {
        rec.advertise::<foxglove::messages::PoseInFrame>(&format!("/pose/{name}"));
    }
    for topic in ["/ekf/covariance", "/sonar", "/hypotheses"] {
        rec.advertise::<SceneUpdate>(topic);
    }
    rec.advertise::<Log>("/localization/mode");
    rec.advertise::<PointCloud>("/particles");
}

/// Records a run into `rec` (live or not).
pub fn record_into<M: MapSource>(
    rec: &mut Recording,
    map: &M,
    mounts: &[Mount],
    steps: &[Step],
    trace: &Trace,
    unmapped: &[Vec<(f64, f64)>],
) {
    let t0 = steps.first().map_or(0, |s| t_ns(s.time_s));
    rec.write_map(t0, &map_scene(map, t0, unmapped));
    let window = window_of(map.buffer_mm());
    let methods = [
        ("ekf", Some(Methods::Ekf)),
        ("dead_reckoning", Some(Methods::DeadReckoning)),
        ("threshold", Some(Methods::Threshold)),
        ("truth", None),
    ];
    let mut mode = ModeLog::default();
    let mut cycle = Cycles::default();
    let mut clouds = trace.cycle_clouds.iter().peekable();
    let mut places = trace.cycle_places.iter().peekable();
    // The cloud as drawn at the start, before any reading (no weights yet: uniform).
    if !trace.cycle_clouds.is_empty() {
        if let Some(c) = trace.clouds.first().filter(|c| c.why == "start" && !c.particles.is_empty()) {
            let w = vec![1.0 / c.particles.len() as f32; c.particles.len()];
            rec.write("/particles", t0, &particle_cloud(t0, &c.particles, &w));
            cycle.last_cloud_s = Some(c.time_s);
        }
    }
    for (i, s) in steps.iter().enumerate() {
        let t = t_ns(s.time_s);
        let mut transforms = Vec::new();
        for (name, m) in methods {
            let p = match m {
                Some(m) => trace.poses(m).get(i).copied(),
                None => trace.truth.get(i).copied().flatten(),
            };
            let Some(p) = p else { continue };
            transforms.push(scene::transform(t, name, p));
            rec.write(&format!("/pose/{name}"), t, &scene::pose_in_map(t, p));
        }
        rec.write("/tf", t, &FrameTransforms { transforms });
        if let Some(&x) = trace.ekf.get(i) {
            let j = trace.judged.get(i);
            let observed = match s.reading {
                Reading::Echo { range_mm } => Some(range_mm),
                _ => None,
            };
            let at = At { t, pose: x, covariance: trace.covariance_after.get(i).map(|c| [c[0], c[1], c[3]]) };
            let sonar = Sonar {
                mount: mounts.get(usize::from(s.transducer)),
                transducer: s.transducer,
                verdict: j.and_then(|j| j.verdict).map(|v| format!("{v:?}")),
                predicted_mm: j.and_then(|j| j.predicted_mm),
                observed_mm: observed,
            };
            reading_messages(rec, "ekf", &at, &sonar, window);
        }
        // The mode after this reading, with why it changed: the cycle that
        // closed before it says.
        if let Some(&m) = trace.modes.get(i) {
            let before = cycle.row.checked_sub(1).and_then(|k| trace.cycles.get(k));
            mode.log(rec, t, m.name(), before);
        }
        // The cycle's end: its cloud and hypotheses.
        let last_of_cycle = steps.get(i + 1).is_none_or(|n| n.cycle != s.cycle);
        if last_of_cycle {
            if let Some(row) = trace.cycles.get(cycle.row) {
                let t = t_ns(row.time_s);
                while let Some(c) = clouds.next_if(|c| c.cycle <= cycle.row) {
                    if c.cycle == cycle.row && cycle.cloud_due(row.time_s) {
                        rec.write("/particles", t, &particle_cloud(t, &c.poses, &c.weights));
                    }
                }
                let mut living: &[PlaceRow] = &[];
                while let Some((k, p)) = places.next_if(|(k, _)| *k <= cycle.row) {
                    if *k == cycle.row {
                        living = p;
                    }
                }
                cycle.hypotheses(rec, t, row, living);
            }
            cycle.row += 1;
        }
    }
}

/// Where the recording is in the trace's cycles.
#[derive(Default)]
struct Cycles {
    /// The row of the cycle under way.
    row: usize,
    /// When the last cloud was recorded, s.
    last_cloud_s: Option<f64>,
    /// Hypotheses are on screen.
    shown: bool,
}

impl Cycles {
    fn cloud_due(&mut self, time_s: f64) -> bool {
        if self.last_cloud_s.is_some_and(|l| time_s - l < CLOUD_INTERVAL_S) {
            return false;
        }
        self.last_cloud_s = Some(time_s);
        true
    }

    /// The cycle's hypotheses (the place test's living places, each with
    /// its standing; the particles' heaviest cluster; the old bank's best
    /// rival), or their removal when the search is over.
    fn hypotheses(&mut self, rec: &mut Recording, t: u64, row: &CycleRow, places: &[PlaceRow]) {
        let mut ents = Vec::new();
        // The best first, in the cluster's green; the others amber.
        let best = places.iter().map(|p| p.margin).filter(|m| !m.is_nan()).fold(f32::NEG_INFINITY, f32::max);
        for (k, p) in places.iter().enumerate() {
            let colour = if p.margin == best { [0.0, 0.59, 0.24, 1.0] } else { [0.95, 0.6, 0.0, 1.0] };
            let m = p.pose.map(f64::from);
            let (pts, _) = scene::ellipse(m[0], m[1], p.covariance.map(f64::from), 2.0);
            let mut e = entity(
                t,
                &format!("hypothesis/place/{k}"),
                vec![line(LINE_LOOP, &pts, 1.5, colour)],
                vec![
                    ("evidence_over_null_nats", format!("{:.1}", p.evidence)),
                    ("smallest_lead_nats", format!("{:.1}", p.margin)),
                    ("cycles_lived", p.cycles.to_string()),
                ],
            );
            e.arrows.push(scene::arrow(m, 0.4, colour));
            ents.push(e);
        }
        if let Some((mean, cov, weight)) = row.cluster {
            let m = mean.map(f64::from);
            let (pts, sd) = scene::ellipse(m[0], m[1], cov.map(f64::from), 2.0);
            let mut e = entity(
                t,
                "hypothesis/cluster",
                vec![line(LINE_LOOP, &pts, 2.0, [0.0, 0.59, 0.24, 1.0])],
                vec![
                    ("weight", format!("{weight:.3}")),
                    ("sigma_x_m", format!("{:.3}", sd[0])),
                    ("sigma_y_m", format!("{:.3}", sd[1])),
                    ("lead_nats", format!("{:.1}", row.lead)),
                    ("hypotheses_alive", row.hypotheses.to_string()),
                ],
            );
            e.arrows.push(scene::arrow(m, 0.5, [0.0, 0.59, 0.24, 1.0]));
            ents.push(e);
        }
        if let Some((p, lead)) = row.rival {
            let mut e = entity(t, "hypothesis/rival", vec![], vec![("lead_nats", format!("{lead:.1}"))]);
            e.arrows.push(scene::arrow(p.map(f64::from), 0.5, [0.85, 0.1, 0.1, 1.0]));
            ents.push(e);
        }
        if ents.is_empty() && !self.shown {
            return;
        }
        self.shown = !ents.is_empty();
        rec.write("/hypotheses", t, &scene::scene_replacing_all(t, ents));
    }
}

/// The particles as a point cloud in `map`: x, y, z (0), heading (rad),
/// weight, each a little-endian `f32`.
pub fn particle_cloud(t: u64, poses: &[[f32; 3]], weights: &[f32]) -> PointCloud {
    const FLOAT32: i32 = 7;
    let fields = ["x", "y", "z", "heading", "weight"]
        .iter()
        .enumerate()
        .map(|(k, n)| PackedElementField { name: (*n).into(), offset: 4 * k as u32, r#type: FLOAT32 })
        .collect();
    let mut data = Vec::with_capacity(poses.len() * 20);
    for (k, p) in poses.iter().enumerate() {
        for v in [p[0], p[1], 0.0, p[2], weights.get(k).copied().unwrap_or(0.0)] {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    PointCloud {
        timestamp: Some(stamp(t)),
        frame_id: "map".into(),
        pose: Some(scene::pose([0.0; 3])),
        point_stride: 20,
        fields,
        data: data.into(),
    }
}

/// The localizer's mode, logged at the start and at each change.
#[derive(Default)]
pub struct ModeLog {
    last: Option<&'static str>,
}

impl ModeLog {
    /// Logs `now` at `t` if it is new, with the reason the closed cycle
    /// `before` gives.
    pub fn log(&mut self, rec: &mut Recording, t: u64, now: &'static str, before: Option<&CycleRow>) {
        if self.last == Some(now) {
            return;
        }
        let reason = match (self.last, before) {
            (None, _) => "at the start".to_string(),
            (_, Some(r)) if r.handoff => {
                format!(
                    "the particles handed off to the EKF (cluster weight {:.2}, lead {:.1} nats)",
                    r.cluster_weight, r.lead
                )
            }
            // With the place test, how far the tracked pose trailed the null.
            (_, Some(r)) if r.woke && r.behind > 0.0 => {
                format!("the EKF was lost (its pose trails the null by {:.1} nats): the particles woke", r.behind)
            }
            (_, Some(r)) if r.woke => "the EKF was lost: the particles woke".to_string(),
            (_, Some(r)) if r.calmed => "the EKF beside the search was no longer lost".to_string(),
            _ => "the EKF's lost flag changed".to_string(),
        };
        self.last = Some(now);
        rec.write("/localization/mode", t, &mode_message(t, now, &reason));
    }
}

/// `now` (searching, tracking, lost) as a log line: INFO while tracking,
/// WARNING while searching, ERROR when lost.
pub fn mode_message(t: u64, now: &str, reason: &str) -> Log {
    let level = match now {
        "tracking" => 2,
        "lost" => 4,
        _ => 3,
    };
    Log {
        timestamp: Some(stamp(t)),
        level,
        message: format!("{now}: {reason}"),
        name: "localizer".into(),
        file: String::new(),
        line: 0,
    }
}

/// The sensor window: R_min, R_max (m), half-angle (rad).
pub type Window = (f64, f64, f64);

/// The window of a map with C-space buffer `buffer_mm`.
pub fn window_of(buffer_mm: u32) -> Window {
    // R_min, R_max and θ_o do not depend on the map's lobe.
    let w = predict_params(buffer_mm, &echoloc::map::FieldView::EMPTY).window;
    (f64::from(w.r_min_mm) / 1000.0, f64::from(w.r_max_mm) / 1000.0, f64::from(w.half_angle_deg).to_radians())
}

/// When and where a reading left the filter.
pub struct At {
    pub t: u64,
    pub pose: [f64; 3],
    /// σ²x, σxy, σ²y.
    pub covariance: Option<[f32; 3]>,
}

/// One transducer's reading.
pub struct Sonar<'a> {
    pub mount: Option<&'a Mount>,
    pub transducer: u8,
    /// The verdict's name (`Confirmed`, …).
    pub verdict: Option<String>,
    pub predicted_mm: Option<u32>,
    pub observed_mm: Option<u32>,
}

/// The colour of a verdict by name (RGBA, 0–1).
pub fn verdict_color_named(v: Option<&str>) -> [f64; 4] {
    match v {
        Some("Confirmed") => [0.0, 0.7, 0.2, 1.0],
        Some("UnknownObstacle") => [1.0, 0.55, 0.0, 1.0],
        Some("RemovedOrMissed") => [0.9, 0.1, 0.1, 1.0],
        Some("NothingAsPredicted") => [0.3, 0.6, 1.0, 1.0],
        Some("Unpredicted") => [0.55, 0.55, 0.55, 1.0],
        _ => [0.6, 0.3, 0.8, 1.0],
    }
}

/// The covariance ellipse and the sensor window of one reading. The window
/// is drawn in the frame of the estimate it was judged from (`frame`, which
/// `/tf` places), at the transducer's mount: the same bytes every time for a
/// transducer, which the chunks' compression takes almost for nothing; the
/// predicted and observed ranges are chords across it.
pub fn reading_messages(rec: &mut Recording, frame: &str, at: &At, s: &Sonar<'_>, (r_min, r_max, half): Window) {
    let (t, x) = (at.t, at.pose);
    if let Some(c) = at.covariance {
        let (disc, sd) = scene::ellipse_disc(x[0], x[1], c.map(f64::from), 2.0, [0.0, 0.59, 0.24, 0.5]);
        let mut e = entity(
            t,
            "ekf_covariance",
            vec![],
            vec![("sigma_x_m", format!("{:.4}", sd[0])), ("sigma_y_m", format!("{:.4}", sd[1]))],
        );
        e.spheres.push(disc);
        rec.write("/ekf/covariance", t, &scene::scene(vec![e]));
    }
    let Some(m) = s.mount else { return };
    let mount =
        [f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0, f64::from(m.heading_mdeg).to_radians() / 1000.0];
    let mut cone = arc(0.0, 0.0, 0.0, half, r_max);
    cone.extend(arc(0.0, 0.0, 0.0, half, r_min).into_iter().rev());
    let chord = |r: f64| [(r, -r * half.tan()), (r, r * half.tan())];
    let mut lines = vec![line(LINE_LOOP, &cone, 1.0, [0.4, 0.4, 0.4, 0.6])];
    if let Some(p) = s.predicted_mm {
        lines.push(line(LINE_STRIP, &chord(f64::from(p) / 1000.0), 2.0, [0.2, 0.2, 0.9, 1.0]));
    }
    if let Some(o) = s.observed_mm {
        let c = verdict_color_named(s.verdict.as_deref());
        lines.push(line(LINE_STRIP, &chord(f64::from(o) / 1000.0), 4.0, c));
    }
    for l in &mut lines {
        l.pose = Some(scene::pose(mount));
    }
    let mut e = entity(
        t,
        &format!("sonar/{}", s.transducer),
        lines,
        vec![
            ("transducer", s.transducer.to_string()),
            ("verdict", s.verdict.clone().unwrap_or_else(|| "none".into())),
            ("predicted_mm", s.predicted_mm.map_or("none".into(), |v| v.to_string())),
            ("observed_mm", s.observed_mm.map_or("no echo".into(), |v| v.to_string())),
        ],
    );
    e.frame_id = frame.into();
    rec.write("/sonar", t, &scene::scene(vec![e]));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cloud_packs_each_particle_in_twenty_bytes() {
        let c = particle_cloud(5, &[[1.0, 2.0, 0.5], [-1.0, 0.25, -3.0]], &[0.75, 0.25]);
        assert_eq!((c.point_stride, c.data.len()), (20, 40));
        let f = |k: usize| f32::from_le_bytes(c.data[4 * k..4 * k + 4].try_into().unwrap());
        assert_eq!([f(0), f(1), f(2), f(3), f(4)], [1.0, 2.0, 0.0, 0.5, 0.75]);
        assert_eq!([f(5), f(6), f(8), f(9)], [-1.0, 0.25, -3.0, 0.25]);
        let names: Vec<_> = c.fields.iter().map(|f| (f.name.as_str(), f.offset)).collect();
        assert_eq!(names, [("x", 0), ("y", 4), ("z", 8), ("heading", 12), ("weight", 16)]);
    }

    #[test]
    fn clouds_come_no_closer_than_the_interval() {
        let mut c = Cycles::default();
        let due: Vec<bool> = [0.0, 0.1, 0.24, 0.25, 0.3, 0.6].iter().map(|&t| c.cloud_due(t)).collect();
        assert_eq!(due, [true, false, false, true, false, true]);
    }
}

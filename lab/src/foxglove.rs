//! Foxglove recordings out (`docs/foxglove.md`): a run (`simulate`,
//! `replay`) as an MCAP file a person opens in Foxglove and scrubs. Every
//! channel carries one of Foxglove's well-known schemas, JSON-encoded with
//! its JSON Schema (`jsonschema` schema encoding, `json` messages), stamped
//! with the run's own time.
//!
//! | topic | schema | one message |
//! |---|---|---|
//! | `/map` | `foxglove.SceneUpdate` | at the start: the true outlines (blue), the C-space buffers (green), unmapped objects (magenta, simulator only) as line primitives in `map` |
//! | `/tf` | `foxglove.FrameTransforms` | per reading: `map` → `ekf`, `dead_reckoning`, `threshold`, and `truth` where known |
//! | `/pose/ekf`, `/pose/dead_reckoning`, `/pose/threshold`, `/pose/truth` | `foxglove.PoseInFrame` | per reading (truth: per reading that has one) |
//! | `/ekf/covariance` | `foxglove.SceneUpdate` | per reading: the 2σ position ellipse around the EKF pose |
//! | `/sonar` | `foxglove.SceneUpdate` | per reading: the transducer's sensor window (entity `sonar/N`, replacing its last), the predicted range as an arc and the observed one as a thicker arc, coloured by verdict |
//! | `/state` | `foxglove.Log` | at the start and at each change: `EKF tracking` (INFO) or `EKF lost` (WARNING) |
//!
//! A particle cloud is not recorded: this build has no particle filter.
//!
//! [`record`] writes a run; [`Recording`] writes any message on a channel
//! of a well-known schema:
//!
//! ```
//! use echoloc_lab::foxglove::Recording;
//! use serde_json::json;
//!
//! let mut rec = Recording::new()?;
//! let t = 1_500_000_000; // ns
//! rec.write("/state", "foxglove.Log", t, &json!({"timestamp": {"sec": 1, "nsec": 500_000_000},
//!     "level": 2, "message": "EKF tracking", "name": "ekf", "file": "", "line": 0}))?;
//! let bytes = rec.finish()?;
//! // Read back with Foxglove's own reader.
//! let m = mcap::MessageStream::new(&bytes)?.next().unwrap()?;
//! assert_eq!(m.channel.schema.as_ref().unwrap().name, "foxglove.Log");
//! assert_eq!((m.channel.message_encoding.as_str(), m.log_time), ("json", t));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::BTreeMap;
use std::io::Cursor;

use echoloc::map::MapSource;
use echoloc::predict::Mount;
use echoloc::referencing::Reading;
use serde_json::{json, Value};

use crate::simulate::filters::{predict_params, Methods, Step, Trace};

/// The Foxglove schemas used, by name, as JSON Schemas.
pub mod schemas {
    use serde_json::{json, Value};

    fn vec3() -> Value {
        json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}})
    }
    fn quat() -> Value {
        json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}})
    }
    fn time() -> Value {
        json!({"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}})
    }
    fn pose() -> Value {
        json!({"type": "object", "properties": {"position": vec3(), "orientation": quat()}})
    }
    fn color() -> Value {
        json!({"type": "object", "properties": {"r": {"type": "number"}, "g": {"type": "number"}, "b": {"type": "number"}, "a": {"type": "number"}}})
    }

    /// `foxglove.FrameTransform`.
    pub fn frame_transform() -> Value {
        json!({"title": "foxglove.FrameTransform", "type": "object", "properties": {
            "timestamp": time(), "parent_frame_id": {"type": "string"}, "child_frame_id": {"type": "string"},
            "translation": vec3(), "rotation": quat()}})
    }

    /// `foxglove.FrameTransforms`.
    pub fn frame_transforms() -> Value {
        json!({"title": "foxglove.FrameTransforms", "type": "object", "properties": {
            "transforms": {"type": "array", "items": frame_transform()}}})
    }

    /// `foxglove.PoseInFrame`.
    pub fn pose_in_frame() -> Value {
        json!({"title": "foxglove.PoseInFrame", "type": "object", "properties": {
            "timestamp": time(), "frame_id": {"type": "string"}, "pose": pose()}})
    }

    /// `foxglove.Log`.
    pub fn log() -> Value {
        json!({"title": "foxglove.Log", "type": "object", "properties": {
            "timestamp": time(),
            "level": {"type": "integer", "oneOf": [
                {"title": "UNKNOWN", "const": 0}, {"title": "DEBUG", "const": 1}, {"title": "INFO", "const": 2},
                {"title": "WARNING", "const": 3}, {"title": "ERROR", "const": 4}, {"title": "FATAL", "const": 5}]},
            "message": {"type": "string"}, "name": {"type": "string"}, "file": {"type": "string"},
            "line": {"type": "integer", "minimum": 0}}})
    }

    fn line_primitive() -> Value {
        json!({"type": "object", "title": "foxglove.LinePrimitive", "properties": {
            "type": {"type": "integer", "oneOf": [
                {"title": "LINE_STRIP", "const": 0}, {"title": "LINE_LOOP", "const": 1}, {"title": "LINE_LIST", "const": 2}]},
            "pose": pose(), "thickness": {"type": "number", "minimum": 0}, "scale_invariant": {"type": "boolean"},
            "points": {"type": "array", "items": vec3()}, "color": color(),
            "colors": {"type": "array", "items": color()}, "indices": {"type": "array", "items": {"type": "integer", "minimum": 0}}}})
    }

    /// `foxglove.SceneUpdate` (entities with line primitives; the other
    /// primitive arrays are present and empty).
    pub fn scene_update() -> Value {
        let list = |title: &str| json!({"type": "array", "items": {"type": "object", "title": title}});
        json!({"title": "foxglove.SceneUpdate", "type": "object", "properties": {
            "deletions": {"type": "array", "items": {"type": "object", "title": "foxglove.SceneEntityDeletion",
                "properties": {"timestamp": time(), "type": {"type": "integer"}, "id": {"type": "string"}}}},
            "entities": {"type": "array", "items": {"type": "object", "title": "foxglove.SceneEntity", "properties": {
                "timestamp": time(), "frame_id": {"type": "string"}, "id": {"type": "string"},
                "lifetime": {"type": "object", "title": "duration", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
                "frame_locked": {"type": "boolean"},
                "metadata": {"type": "array", "items": {"type": "object", "properties": {"key": {"type": "string"}, "value": {"type": "string"}}}},
                "arrows": list("foxglove.ArrowPrimitive"), "cubes": list("foxglove.CubePrimitive"),
                "spheres": list("foxglove.SpherePrimitive"), "cylinders": list("foxglove.CylinderPrimitive"),
                "lines": {"type": "array", "items": line_primitive()},
                "triangles": list("foxglove.TriangleListPrimitive"), "texts": list("foxglove.TextPrimitive"),
                "models": list("foxglove.ModelPrimitive")}}}}})
    }
}

/// An MCAP recording being written, in memory (written to disk by the
/// caller with the run's other outputs, all or nothing).
pub struct Recording {
    w: mcap::Writer<Cursor<Vec<u8>>>,
    schemas: BTreeMap<&'static str, u16>,
    channels: BTreeMap<String, u16>,
    counts: BTreeMap<String, u64>,
}

/// Why a recording could not be written.
#[derive(Debug)]
pub enum RecordingError {
    /// The `mcap` writer refused (an I/O error in memory, a record too large).
    Mcap(mcap::McapError),
    /// A schema name this writer has no JSON Schema for.
    UnknownSchema(String),
}

impl std::fmt::Display for RecordingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Mcap(e) => write!(f, "MCAP: {e}"),
            Self::UnknownSchema(s) => write!(f, "no JSON Schema for {s}"),
        }
    }
}

impl std::error::Error for RecordingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Mcap(e) => Some(e),
            Self::UnknownSchema(_) => None,
        }
    }
}

fn mcap_err(e: mcap::McapError) -> RecordingError {
    RecordingError::Mcap(e)
}

impl Recording {
    /// An empty recording (profile empty, zstd chunks).
    pub fn new() -> Result<Self, RecordingError> {
        let w = mcap::WriteOptions::new().create(Cursor::new(Vec::new())).map_err(mcap_err)?;
        Ok(Self { w, schemas: BTreeMap::new(), channels: BTreeMap::new(), counts: BTreeMap::new() })
    }

    /// Writes `msg` on `topic` (created on first use with `schema`, a name
    /// from [`schemas`]) at `t_ns`.
    pub fn write(&mut self, topic: &str, schema: &'static str, t_ns: u64, msg: &Value) -> Result<(), RecordingError> {
        let channel = match self.channels.get(topic) {
            Some(&c) => c,
            None => {
                let sid = match self.schemas.get(schema) {
                    Some(&s) => s,
                    None => {
                        let body = match schema {
                            "foxglove.SceneUpdate" => schemas::scene_update(),
                            "foxglove.FrameTransforms" => schemas::frame_transforms(),
                            "foxglove.PoseInFrame" => schemas::pose_in_frame(),
                            "foxglove.Log" => schemas::log(),
                            other => return Err(RecordingError::UnknownSchema(other.into())),
                        };
                        let s =
                            self.w.add_schema(schema, "jsonschema", body.to_string().as_bytes()).map_err(mcap_err)?;
                        self.schemas.insert(schema, s);
                        s
                    }
                };
                let c = self.w.add_channel(sid, topic, "json", &BTreeMap::new()).map_err(mcap_err)?;
                self.channels.insert(topic.to_string(), c);
                c
            }
        };
        let n = self.counts.entry(topic.to_string()).or_insert(0);
        *n += 1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: *n as u32,
            log_time: t_ns,
            publish_time: t_ns,
        };
        self.w.write_to_known_channel(&header, msg.to_string().as_bytes()).map_err(mcap_err)
    }

    /// Messages written per topic.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// The file's bytes.
    pub fn finish(mut self) -> Result<Vec<u8>, RecordingError> {
        self.w.finish().map_err(mcap_err)?;
        Ok(self.w.into_inner().into_inner())
    }
}

/// A time as Foxglove's `{sec, nsec}`.
fn stamp(t_ns: u64) -> Value {
    json!({"sec": t_ns / 1_000_000_000, "nsec": t_ns % 1_000_000_000})
}

fn quat(yaw: f64) -> Value {
    json!({"x": 0.0, "y": 0.0, "z": (yaw / 2.0).sin(), "w": (yaw / 2.0).cos()})
}

fn pose(p: [f64; 3]) -> Value {
    json!({"position": {"x": p[0], "y": p[1], "z": 0.0}, "orientation": quat(p[2])})
}

fn color(c: [f64; 4]) -> Value {
    json!({"r": c[0], "g": c[1], "b": c[2], "a": c[3]})
}

/// A line primitive in its entity's frame (identity pose).
fn line(kind: u8, points: &[(f64, f64)], thickness: f64, c: [f64; 4]) -> Value {
    json!({
        "type": kind,
        "pose": pose([0.0; 3]),
        "thickness": thickness,
        "scale_invariant": true,
        "points": points.iter().map(|&(x, y)| json!({"x": x, "y": y, "z": 0.0})).collect::<Vec<_>>(),
        "color": color(c),
        "colors": [],
        "indices": [],
    })
}

const LINE_STRIP: u8 = 0;
const LINE_LOOP: u8 = 1;
const LINE_LIST: u8 = 2;

fn entity(t_ns: u64, id: &str, lines: Vec<Value>, metadata: Vec<(&str, String)>) -> Value {
    json!({
        "timestamp": stamp(t_ns),
        "frame_id": "map",
        "id": id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": false,
        "metadata": metadata.into_iter().map(|(k, v)| json!({"key": k, "value": v})).collect::<Vec<_>>(),
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [],
        "lines": lines,
        "triangles": [], "texts": [], "models": [],
    })
}

fn scene(entities: Vec<Value>) -> Value {
    json!({"deletions": [], "entities": entities})
}

/// An arc at range `r` (m) about `(x, y)` from heading `a - h` to `a + h` (rad).
fn arc(x: f64, y: f64, a: f64, h: f64, r: f64) -> Vec<(f64, f64)> {
    (0..=16).map(|k| a - h + 2.0 * h * f64::from(k) / 16.0).map(|b| (x + r * b.cos(), y + r * b.sin())).collect()
}

/// Records a run: the map, each reading's poses, covariance, sensor window
/// and verdict, and the lost/tracking changes. `steps` and `trace` are the
/// filters' input and output; `unmapped` the simulator's clutter outlines (m).
pub fn record<M: MapSource>(
    map: &M,
    mounts: &[Mount],
    steps: &[Step],
    trace: &Trace,
    unmapped: &[Vec<(f64, f64)>],
) -> Result<Recording, RecordingError> {
    let mut rec = Recording::new()?;
    let t_ns = |s: f64| (s.max(0.0) * 1e9).round() as u64;
    let t0 = steps.first().map_or(0, |s| t_ns(s.time_s));
    // The map.
    let mm = |p: &echoloc::geometry::Point| (f64::from(p.x) / 1000.0, f64::from(p.y) / 1000.0);
    let mut outline = Vec::new();
    let mut buffers = Vec::new();
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
    for p in map.pieces_iter() {
        let v: Vec<(f64, f64)> = p.buffered.vertices().iter().map(mm).collect();
        buffers.push(line(LINE_LOOP, &v, 1.0, [0.0, 0.67, 0.31, 0.8]));
    }
    let mut ents = vec![
        entity(t0, "map/outlines", vec![line(LINE_LIST, &outline, 2.0, [0.0, 0.35, 0.86, 1.0])], vec![]),
        entity(t0, "map/buffers", buffers, vec![]),
    ];
    if !unmapped.is_empty() {
        let l = unmapped.iter().map(|o| line(LINE_LOOP, o, 2.0, [0.9, 0.0, 0.63, 1.0])).collect();
        ents.push(entity(t0, "map/unmapped", l, vec![]));
    }
    rec.write("/map", "foxglove.SceneUpdate", t0, &scene(ents))?;

    let window = window_of(map.buffer_mm());
    let methods = [
        ("ekf", Some(Methods::Ekf)),
        ("dead_reckoning", Some(Methods::DeadReckoning)),
        ("threshold", Some(Methods::Threshold)),
        ("truth", None),
    ];
    let mut mode: Option<&'static str> = None;
    for (i, s) in steps.iter().enumerate() {
        let t = t_ns(s.time_s);
        let mut transforms = Vec::new();
        for (name, m) in methods {
            let p = match m {
                Some(m) => trace.poses(m).get(i).copied(),
                None => trace.truth.get(i).copied().flatten(),
            };
            let Some(p) = p else { continue };
            transforms.push(json!({"timestamp": stamp(t), "parent_frame_id": "map", "child_frame_id": name,
                "translation": {"x": p[0], "y": p[1], "z": 0.0}, "rotation": quat(p[2])}));
            rec.write(
                &format!("/pose/{name}"),
                "foxglove.PoseInFrame",
                t,
                &json!({"timestamp": stamp(t), "frame_id": "map", "pose": pose(p)}),
            )?;
        }
        rec.write("/tf", "foxglove.FrameTransforms", t, &json!({"transforms": transforms}))?;
        let Some(&x) = trace.ekf.get(i) else { continue };
        let j = trace.judged.get(i);
        let observed = match s.reading {
            Reading::Echo { range_mm } => Some(range_mm),
            _ => None,
        };
        let verdict = j.and_then(|j| j.verdict).map(|v| format!("{v:?}"));
        let at = At { t, pose: x, covariance: trace.position_covariance.get(i).copied() };
        let sonar = Sonar {
            mount: mounts.get(usize::from(s.transducer)),
            transducer: s.transducer,
            verdict,
            predicted_mm: j.and_then(|j| j.predicted_mm),
            observed_mm: observed,
        };
        reading_messages(&mut rec, &at, &sonar, window)?;
        // Lost or tracking, at the start and at each change.
        state(&mut rec, t, trace.modes.get(i).map_or("tracking", |m| m.name()), &mut mode)?;
    }
    Ok(rec)
}

/// The sensor window: R_min, R_max (m), half-angle (rad).
type Window = (f64, f64, f64);

fn window_of(buffer_mm: u32) -> Window {
    // R_min, R_max and θ_o do not depend on the map's lobe.
    let w = predict_params(buffer_mm, &echoloc::map::FieldView::EMPTY).window;
    (f64::from(w.r_min_mm) / 1000.0, f64::from(w.r_max_mm) / 1000.0, f64::from(w.half_angle_deg).to_radians())
}

/// When and where a reading left the filter.
struct At {
    t: u64,
    pose: [f64; 3],
    /// σ²x, σxy, σ²y.
    covariance: Option<[f32; 3]>,
}

/// One transducer's reading.
struct Sonar<'a> {
    mount: Option<&'a Mount>,
    transducer: u8,
    /// The verdict's name (`Confirmed`, …).
    verdict: Option<String>,
    predicted_mm: Option<u32>,
    observed_mm: Option<u32>,
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

/// The covariance ellipse and the sensor window of one reading.
fn reading_messages(
    rec: &mut Recording,
    at: &At,
    s: &Sonar<'_>,
    (r_min, r_max, half): Window,
) -> Result<(), RecordingError> {
    let (t, x) = (at.t, at.pose);
    // The 2σ ellipse of the position covariance.
    if let Some([sxx, sxy, syy]) = at.covariance {
        let (a, b, c) = (f64::from(sxx), f64::from(sxy), f64::from(syy));
        let d = ((a - c) * (a - c) / 4.0 + b * b).sqrt();
        let (l1, l2) = ((a + c) / 2.0 + d, ((a + c) / 2.0 - d).max(0.0));
        let th = 0.5 * (2.0 * b).atan2(a - c);
        let (r1, r2) = (2.0 * l1.max(0.0).sqrt(), 2.0 * l2.sqrt());
        let pts: Vec<(f64, f64)> = (0..32)
            .map(|k| {
                let u = std::f64::consts::TAU * f64::from(k) / 32.0;
                let (ex, ey) = (r1 * u.cos(), r2 * u.sin());
                (x[0] + ex * th.cos() - ey * th.sin(), x[1] + ex * th.sin() + ey * th.cos())
            })
            .collect();
        let e = entity(
            t,
            "ekf_covariance",
            vec![line(LINE_LOOP, &pts, 2.0, [0.0, 0.59, 0.24, 1.0])],
            vec![
                ("sigma_x_m", format!("{:.4}", a.max(0.0).sqrt())),
                ("sigma_y_m", format!("{:.4}", c.max(0.0).sqrt())),
            ],
        );
        rec.write("/ekf/covariance", "foxglove.SceneUpdate", t, &scene(vec![e]))?;
    }
    // The sensor window at the estimated pose, with its ranges.
    let Some(m) = s.mount else { return Ok(()) };
    let (sn, cs) = x[2].sin_cos();
    let (mx, my) = (f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0);
    let (sx, sy) = (x[0] + cs * mx - sn * my, x[1] + sn * mx + cs * my);
    let a = x[2] + f64::from(m.heading_mdeg).to_radians() / 1000.0;
    let mut cone = arc(sx, sy, a, half, r_max);
    cone.extend(arc(sx, sy, a, half, r_min).into_iter().rev());
    let mut lines = vec![line(LINE_LOOP, &cone, 1.0, [0.4, 0.4, 0.4, 0.6])];
    if let Some(p) = s.predicted_mm {
        lines.push(line(LINE_STRIP, &arc(sx, sy, a, half, f64::from(p) / 1000.0), 2.0, [0.2, 0.2, 0.9, 1.0]));
    }
    if let Some(o) = s.observed_mm {
        let c = verdict_color_named(s.verdict.as_deref());
        lines.push(line(LINE_STRIP, &arc(sx, sy, a, half, f64::from(o) / 1000.0), 4.0, c));
    }
    let e = entity(
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
    rec.write("/sonar", "foxglove.SceneUpdate", t, &scene(vec![e]))
}

/// A log line at the start and at each change of the lost flag.
fn state(
    rec: &mut Recording,
    t: u64,
    now: &'static str,
    last: &mut Option<&'static str>,
) -> Result<(), RecordingError> {
    if *last == Some(now) {
        return Ok(());
    }
    *last = Some(now);
    // INFO while tracking, WARNING while searching or lost.
    let level = if now == "tracking" { 2 } else { 3 };
    let message = format!("localizer {now}");
    rec.write(
        "/state",
        "foxglove.Log",
        t,
        &json!({"timestamp": stamp(t), "level": level, "message": message, "name": "localizer", "file": "", "line": 0}),
    )
}

/// Records what a controller sent over the link (`link --mcap`): per
/// reading, its pose (`/pose/controller`, `/tf` map → controller), its
/// covariance ellipse, the sensor window with its verdict, and the
/// lost/tracking changes; stamped with the controller's clock (µs,
/// unwrapped at 2³²). No map: the controller holds it.
pub fn record_link(readings: &[echoloc::link::ReadingReport], mounts: &[Mount]) -> Result<Recording, RecordingError> {
    let mut rec = Recording::new()?;
    // The window's ranges and half-angle do not depend on the buffer.
    let window = window_of(0);
    let (mut epoch, mut last_us) = (0u64, readings.first().map_or(0, |r| r.time_us));
    let mut mode = None;
    for r in readings {
        if r.time_us < last_us {
            epoch += 1 << 32;
        }
        last_us = r.time_us;
        let t = (epoch + u64::from(r.time_us)) * 1000;
        let p = r.pose.map(f64::from);
        rec.write(
            "/tf",
            "foxglove.FrameTransforms",
            t,
            &json!({"transforms": [{"timestamp": stamp(t), "parent_frame_id": "map", "child_frame_id": "controller",
                "translation": {"x": p[0], "y": p[1], "z": 0.0}, "rotation": quat(p[2])}]}),
        )?;
        rec.write(
            "/pose/controller",
            "foxglove.PoseInFrame",
            t,
            &json!({"timestamp": stamp(t), "frame_id": "map", "pose": pose(p)}),
        )?;
        let c = r.covariance;
        let observed = match r.outcome {
            echoloc::link::WireOutcome::Range(mm) => Some(mm),
            _ => None,
        };
        let at = At { t, pose: p, covariance: Some([c[0], c[1], c[3]]) };
        let sonar = Sonar {
            mount: mounts.get(usize::from(r.transducer)),
            transducer: r.transducer,
            verdict: Some(format!("{:?}", r.verdict)),
            predicted_mm: r.predicted_mm,
            observed_mm: observed,
        };
        reading_messages(&mut rec, &at, &sonar, window)?;
        let now = match r.mode {
            echoloc::link::WireMode::Searching => "searching",
            echoloc::link::WireMode::Tracking => "tracking",
            echoloc::link::WireMode::Lost => "lost",
        };
        state(&mut rec, t, now, &mut mode)?;
    }
    Ok(rec)
}

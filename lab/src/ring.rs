//! Rings: where each transducer sits on the robot. `pioneer16` is the
//! Pioneer ring the firmware ships ([`echoloc::predict::PIONEER16`]); any
//! other ring is a JSON file of `[x_m, y_m, heading_deg]` per transducer, in
//! the ring's index order (the file `predict --ring` takes):
//!
//! ```json
//! [[0.1, 0.0, 0.0], [0.0, 0.1, 90.0], [-0.1, 0.0, 180.0], [0.0, -0.1, -90.0]]
//! ```
//!
//! or an object with those as `transducers` and how the ring fires, which
//! a whole-ring PointCloud's firing times are rebuilt from ([`firing`],
//! `docs/bags.md`): `order`, the slots in firing order, each a transducer or
//! several fired at once, `period_s`, one ring cycle, and `slot_s`, the time
//! between two slots (default: the cycle spread evenly):
//!
//! ```json
//! {"transducers": [[0.1, 0.0, 0.0], [0.0, 0.1, 90.0], [-0.1, 0.0, 180.0], [0.0, -0.1, -90.0]],
//!  "order": [[0, 2], [1, 3]], "period_s": 0.08}
//! ```
//!
//! ```
//! let ring = echoloc_lab::ring::load("pioneer16").unwrap();
//! assert_eq!(ring.len(), 16);
//! let dir = std::env::temp_dir().join("echoloc-ring-doc.json");
//! std::fs::write(&dir, "[[0.1, 0, 0], [-0.1, 0, 180]]").unwrap();
//! let two = echoloc_lab::ring::load(dir.to_str().unwrap()).unwrap();
//! assert_eq!((two[1].x_mm, two[1].heading_mdeg), (-100, 180_000));
//! ```

use echoloc::predict::{Mount, PIONEER16};

use crate::error::LabError;

/// [`load`] for a command's `--ring`, its errors named so.
pub fn ring_mounts(spec: &str) -> Result<Vec<Mount>, LabError> {
    load(spec).map_err(|e| LabError(format!("--ring {e}")))
}

/// The ring named by `spec`: `pioneer16`, or the path of a JSON ring file.
/// Errors name the file and, where it is one transducer's fault, its index.
pub fn load(spec: &str) -> Result<Vec<Mount>, LabError> {
    if spec == "pioneer16" {
        return Ok(PIONEER16.to_vec());
    }
    let text = std::fs::read_to_string(spec).map_err(|e| LabError(format!("{spec}: {e}")))?;
    parse(spec, &text)
}

/// A ring file: the transducers alone, or with how the ring fires.
#[derive(serde::Deserialize)]
#[serde(untagged)]
enum RingFile {
    Mounts(Vec<[f64; 3]>),
    Timed {
        transducers: Vec<[f64; 3]>,
        #[serde(default)]
        order: Option<Vec<Slot>>,
        #[serde(default)]
        period_s: Option<f64>,
        #[serde(default)]
        slot_s: Option<f64>,
    },
}

/// A slot of the firing order: one transducer, or several fired at once.
#[derive(serde::Deserialize)]
#[serde(untagged)]
enum Slot {
    One(u8),
    Several(Vec<u8>),
}

/// How a ring fires, where its file says: the order (slots, each the
/// transducers it fires at once) and the period, s.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Firing {
    /// The slots in firing order.
    pub order: Option<Vec<Vec<u8>>>,
    /// One ring cycle, s.
    pub period_s: Option<f64>,
    /// One slot, s (default: the cycle spread evenly over the slots).
    pub slot_s: Option<f64>,
}

fn read_file(name: &str, text: &str) -> Result<RingFile, LabError> {
    serde_json::from_str(text).map_err(|e| {
        LabError(format!(
            "{name}: expected a JSON array of [x_m, y_m, heading_deg], or an object {{\"transducers\": [...], \
             \"order\": [0, [1, 9], ...], \"period_s\": 0.32}}: {e}"
        ))
    })
}

/// How the ring named by `spec` fires, as far as its file says
/// (`pioneer16` and a plain array say nothing).
///
/// ```
/// let dir = std::env::temp_dir().join("echoloc-ring-firing-doc.json");
/// std::fs::write(&dir, r#"{"transducers": [[0.1, 0, 0], [-0.1, 0, 180]], "order": [[1, 0]], "period_s": 0.04}"#).unwrap();
/// let f = echoloc_lab::ring::firing(dir.to_str().unwrap()).unwrap();
/// assert_eq!((f.order, f.period_s), (Some(vec![vec![1, 0]]), Some(0.04)));
/// ```
pub fn firing(spec: &str) -> Result<Firing, LabError> {
    if spec == "pioneer16" {
        return Ok(Firing::default());
    }
    let text = std::fs::read_to_string(spec).map_err(|e| LabError(format!("{spec}: {e}")))?;
    Ok(match read_file(spec, &text)? {
        RingFile::Mounts(_) => Firing::default(),
        RingFile::Timed { order, period_s, slot_s, .. } => Firing {
            order: order.map(|o| {
                o.into_iter()
                    .map(|s| match s {
                        Slot::One(t) => vec![t],
                        Slot::Several(v) => v,
                    })
                    .collect()
            }),
            period_s,
            slot_s: slot_s.filter(|s| s.is_finite()),
        },
    })
}

/// A ring file's text; `name` is used in errors.
pub fn parse(name: &str, text: &str) -> Result<Vec<Mount>, LabError> {
    let v = match read_file(name, text)? {
        RingFile::Mounts(v) | RingFile::Timed { transducers: v, .. } => v,
    };
    if v.is_empty() {
        return Err(LabError(format!("{name}: no transducers")));
    }
    if v.len() > 255 {
        return Err(LabError(format!("{name}: {} transducers; at most 255", v.len())));
    }
    v.iter()
        .enumerate()
        .map(|(i, [x, y, d])| {
            if !(x.is_finite() && y.is_finite() && d.is_finite()) || x.abs() > 100.0 || y.abs() > 100.0 {
                return Err(LabError(format!("{name}: transducer {i}: position beyond ±100 m or not finite")));
            }
            if d.abs() > 360.0 {
                return Err(LabError(format!("{name}: transducer {i}: heading {d}° beyond ±360°")));
            }
            Ok(Mount {
                x_mm: (x * 1000.0).round() as i32,
                y_mm: (y * 1000.0).round() as i32,
                heading_mdeg: (d * 1000.0).round() as i32,
            })
        })
        .collect()
}

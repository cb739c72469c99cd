//! Rings: where each transducer sits on the robot. `pioneer16` is the
//! Pioneer ring the firmware ships ([`echoloc::predict::PIONEER16`]); any
//! other ring is a JSON file of `[x_m, y_m, heading_deg]` per transducer, in
//! the ring's index order (the file `predict --ring` takes):
//!
//! ```json
//! [[0.1, 0.0, 0.0], [0.0, 0.1, 90.0], [-0.1, 0.0, 180.0], [0.0, -0.1, -90.0]]
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

use crate::map::LabError;

/// The ring named by `spec`: `pioneer16`, or the path of a JSON ring file.
/// Errors name the file and, where it is one transducer's fault, its index.
pub fn load(spec: &str) -> Result<Vec<Mount>, LabError> {
    if spec == "pioneer16" {
        return Ok(PIONEER16.to_vec());
    }
    let text = std::fs::read_to_string(spec).map_err(|e| LabError(format!("{spec}: {e}")))?;
    parse(spec, &text)
}

/// A ring file's text; `name` is used in errors.
pub fn parse(name: &str, text: &str) -> Result<Vec<Mount>, LabError> {
    let v: Vec<[f64; 3]> = serde_json::from_str(text)
        .map_err(|e| LabError(format!("{name}: expected a JSON array of [x_m, y_m, heading_deg]: {e}")))?;
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

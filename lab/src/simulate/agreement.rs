//! How well the predictor and the simulator's independent sonar agree:
//! every reading predicted again at the *true* pose, and compared where the
//! predictor is confident and the scene is clean. A measurement, not a
//! construction: the two share no geometry code (DESIGN §4.7).

use echoloc::credence::net::CredenceNet;
use echoloc::map::MapSource;
use echoloc::predict::{predict_mount, Mount, Pose, Prediction};
use serde_json::{json, Value};

use super::filters::predict_params_with;
use super::world::{EchoKind, EchoSource, SimReading};
use echoloc::map::FieldView;

/// The agreement counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Agreement {
    /// Clean readings (consistent with the map) whose prediction at the true
    /// pose has κ ≥ the confidence mark and is not ambiguous (no nearer
    /// mapped surface a sonar may hear, [`Prediction::nearer_mm`]).
    ///
    /// [`Prediction::nearer_mm`]: echoloc::predict::Prediction::nearer_mm
    pub confident: u64,
    /// ... of which the reading is within the prediction's tolerance.
    pub within: u64,
    /// ... of which nothing came back.
    pub silent: u64,
    /// ... of which a nearer echo came back, from a face of a mapped
    /// obstacle (one the predictor's δ or κ tests rejected) ...
    pub nearer_face: u64,
    /// ... from an inside corner ...
    pub nearer_corner: u64,
    /// ... from an outside edge (diffraction, which the predictor does not model).
    pub nearer_edge: u64,
    /// The nearer echoes (face, corner, edge) by the range they came from:
    /// under 1 m, 1–2 m, 2–3 m, 3 m and beyond.
    pub nearer_by_range: [u64; 4],
    /// ... of which the echo came from farther than predicted.
    pub farther: u64,
    /// Clean readings whose prediction has κ ≥ the mark but is ambiguous ...
    pub ambiguous: u64,
    /// ... of which the reading is within the prediction's tolerance ...
    pub ambiguous_within: u64,
    /// ... or from the nearer surface's range on (within tolerance) to the
    /// prediction's.
    pub ambiguous_nearer: u64,
    /// Clean readings with nothing predicted at the true pose.
    pub nothing_predicted: u64,
    /// ... of which nothing came back either.
    pub nothing_read: u64,
}

impl Agreement {
    /// `within / confident`.
    pub fn fraction(&self) -> Option<f64> {
        (self.confident > 0).then(|| self.within as f64 / self.confident as f64)
    }

    /// As JSON.
    pub fn json(&self) -> Value {
        json!({
            "confident": self.confident,
            "within_tolerance": self.within,
            "fraction": self.fraction().map(|f| (f * 1e4).round() / 1e4),
            "silent": self.silent,
            "nearer_face": self.nearer_face,
            "nearer_inside_corner": self.nearer_corner,
            "nearer_outside_edge": self.nearer_edge,
            "nearer_by_range": {
                "under_1m": self.nearer_by_range[0],
                "1_to_2m": self.nearer_by_range[1],
                "2_to_3m": self.nearer_by_range[2],
                "from_3m": self.nearer_by_range[3],
            },
            "farther": self.farther,
            "ambiguous": {
                "confident_but_nearer_surface": self.ambiguous,
                "within_tolerance": self.ambiguous_within,
                "from_the_nearer_surface": self.ambiguous_nearer,
            },
            "nothing_predicted": self.nothing_predicted,
            "nothing_read": self.nothing_read,
        })
    }
}

/// Predicts every clean reading at its true pose and counts agreement;
/// `kappa_min` is the confidence mark; `nearer_check`: whether predictions
/// carry the nearer-surface check (without it none is ambiguous).
pub fn measure<M: MapSource>(
    map: &M,
    field: &FieldView<'_>,
    mounts: &[Mount],
    readings: &[SimReading],
    kappa_min: f32,
    nearer_check: bool,
) -> Agreement {
    let net = CredenceNet::shipped();
    let params = predict_params_with(map.buffer_mm(), field, nearer_check);
    let mut a = Agreement::default();
    for r in readings.iter().filter(|r| r.consistent && !matches!(r.source, EchoSource::Crosstalk | EchoSource::Noise))
    {
        let Some(mount) = mounts.get(usize::from(r.transducer)) else { continue };
        let pose = Pose {
            x_mm: (r.truth.0 * 1000.0) as f32,
            y_mm: (r.truth.1 * 1000.0) as f32,
            heading_rad: r.truth.2 as f32,
        };
        let Ok((p, _)) = predict_mount(map, &pose, mount, &params, &net) else { continue };
        match p {
            Some(p @ Prediction { nearer_mm: Some(n), .. }) if p.kappa.to_num::<f32>() >= kappa_min => {
                a.ambiguous += 1;
                match r.range_mm {
                    Some(z) if z.abs_diff(p.range_mm) <= p.tolerance_mm + 1 => a.ambiguous_within += 1,
                    Some(z) if z < p.range_mm && z + p.tolerance_mm + 1 >= n => a.ambiguous_nearer += 1,
                    _ => {}
                }
            }
            Some(p) if p.kappa.to_num::<f32>() >= kappa_min => {
                a.confident += 1;
                match r.range_mm {
                    Some(z) if z.abs_diff(p.range_mm) <= p.tolerance_mm + 1 => a.within += 1,
                    None => a.silent += 1,
                    Some(z) if z > p.range_mm => a.farther += 1,
                    Some(z) => {
                        if let EchoSource::Mapped { kind, .. } = r.source {
                            match kind {
                                EchoKind::Face => a.nearer_face += 1,
                                EchoKind::InsideCorner => a.nearer_corner += 1,
                                EchoKind::OutsideEdge => a.nearer_edge += 1,
                            }
                            a.nearer_by_range[(z / 1000).min(3) as usize] += 1;
                        }
                    }
                }
            }
            Some(_) => {}
            None => {
                a.nothing_predicted += 1;
                if r.range_mm.is_none() {
                    a.nothing_read += 1;
                }
            }
        }
    }
    a
}

//! `predict --geometric`: the nearest obstacle point in a window, with no
//! sonar model.

use super::PredictError;
use crate::map::MapSource;
use crate::window::{CollectError, Window};

/// The nearest obstacle point in a window, geometrically.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Its distance from the transducer, mm.
    pub range_mm: f64,
    /// The point in the map, mm.
    pub point: (f64, f64),
    /// The piece it lies on.
    pub piece: u16,
}

/// `predict --geometric`: the nearest obstacle point in the wedge
/// `|φ| ≤ θ_o` within `R_max` (no δ, κ or `R_min`); `None` if there is none.
pub fn nearest_in_window<M: MapSource + ?Sized>(map: &M, window: &Window) -> Result<Option<Nearest>, PredictError> {
    let mut best: Option<Nearest> = None;
    map.for_each_candidate(window.sector.bbox(), |p| {
        if let Some((d, q)) = window.sector.nearest(p.shape) {
            if best.is_none_or(|b| d < b.range_mm) {
                best = Some(Nearest { range_mm: d, point: q, piece: p.id });
            }
        }
    })
    .map_err(|e| PredictError::Collect(CollectError::Map(e)))?;
    Ok(best)
}

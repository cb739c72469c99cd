//! The simulator's two figures, drawn with `plotters` ([`crate::figure`]):
//! the map with the true, dead-reckoned, threshold and EKF paths (and the
//! clutter), and the position and heading errors over time. Legends sit in
//! their own panels, clear of the data.

use echoloc::map::MapSource;
use plotters::prelude::*;

use super::filters::{Methods, Trace};
use crate::figure::{encode, err, legend, nice, rgb, Figure, Format, Root, FONT};
use crate::map::render::MapLayers;
use crate::map::Unknown;

const TRUTH: [u8; 3] = [0, 0, 0];
const DEAD_RECKONING: [u8; 3] = [220, 30, 30];
const THRESHOLD: [u8; 3] = [150, 60, 200];
const EKF: [u8; 3] = [0, 150, 60];
const CLUTTER: [u8; 3] = [230, 0, 160];
/// The particle clouds at the moments that matter: the start of a search,
/// just before a hand-off, at a wake-up, and at the times asked for (the
/// kidnaps).
const CLOUDS: [(&str, &str, [u8; 3]); 4] = [
    ("start", "particles at the start", [150, 150, 150]),
    ("handoff", "particles at a hand-off", [240, 140, 0]),
    ("wake", "particles at a wake-up", [30, 90, 230]),
    ("asked", "particles after a kidnap", [0, 180, 200]),
];

const SERIES: [(&str, [u8; 3], Option<Methods>); 4] = [
    ("truth", TRUTH, None),
    ("dead reckoning", DEAD_RECKONING, Some(Methods::DeadReckoning)),
    ("threshold method", THRESHOLD, Some(Methods::Threshold)),
    ("EKF (localizer)", EKF, Some(Methods::Ekf)),
];

const LEGEND_W: u32 = 230;

/// (time s, position error m, heading error °).
type ErrorAt = (f64, f64, f64);

/// The two PNGs: paths on the map (with the outlines of `unmapped`
/// objects, m), errors over time (against the true pose, where known).
pub fn draw<M: MapSource>(map: &M, unmapped: &[Vec<(f64, f64)>], t: &Trace) -> (Vec<u8>, Vec<u8>) {
    draw_as(map, unmapped, t, Format::Png).unwrap_or_default()
}

/// [`draw`] in `format`.
pub fn draw_as<M: MapSource>(
    map: &M,
    unmapped: &[Vec<(f64, f64)>],
    t: &Trace,
    format: Format,
) -> Result<(Vec<u8>, Vec<u8>), String> {
    Ok((paths(map, unmapped, t, format)?, errors(t, format)?))
}

fn track(t: &Trace, m: Option<Methods>) -> Vec<(f64, f64)> {
    let v: Vec<[f64; 3]> = match m {
        None => t.truth.iter().flatten().copied().collect(),
        Some(Methods::DeadReckoning) => t.dead_reckoning.clone(),
        Some(Methods::Threshold) => t.threshold.clone(),
        Some(Methods::Ekf) => t.ekf.clone(),
    };
    v.iter().map(|p| (p[0], p[1])).collect()
}

struct Paths<'a, M: MapSource> {
    layers: MapLayers<'a, M>,
    unmapped: &'a [Vec<(f64, f64)>],
    trace: &'a Trace,
    size: (u32, u32),
}

impl<M: MapSource> Figure for Paths<'_, M> {
    fn size(&self) -> (u32, u32) {
        self.size
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let (plot, side) = root.split_horizontally(self.size.0 - LEGEND_W);
        let mut chart = self.layers.chart(&plot, "Paths: truth, dead reckoning, threshold method, EKF")?;
        chart
            .draw_series(self.unmapped.iter().map(|o| {
                let mut v = o.clone();
                if let Some(&first) = v.first() {
                    v.push(first);
                }
                PathElement::new(v, rgb(CLUTTER).stroke_width(2))
            }))
            .map_err(err)?;
        // The clouds under the paths: one dot a particle.
        for (why, _, colour) in CLOUDS {
            for cloud in self.trace.clouds.iter().filter(|c| c.why == why) {
                chart
                    .draw_series(
                        cloud
                            .particles
                            .iter()
                            .map(|p| Circle::new((f64::from(p[0]), f64::from(p[1])), 1, rgb(colour).filled())),
                    )
                    .map_err(err)?;
            }
        }
        // One pixel wide: plotters joins wider polylines with mitres, which
        // spike far out where a jittery track turns back on itself.
        for (_, colour, m) in SERIES {
            chart.draw_series(LineSeries::new(track(self.trace, m), rgb(colour).stroke_width(1))).map_err(err)?;
        }
        let mut items: Vec<(&str, RGBColor)> = SERIES.iter().map(|&(l, c, _)| (l, rgb(c))).collect();
        items.push(("unmapped objects", rgb(CLUTTER)));
        for (why, label, colour) in CLOUDS {
            if self.trace.clouds.iter().any(|c| c.why == why) {
                items.push((label, rgb(colour)));
            }
        }
        items.extend(self.layers.legend());
        legend(&side.margin(60, 0, 0, 0), &items, false)
    }
}

fn paths<M: MapSource>(map: &M, unmapped: &[Vec<(f64, f64)>], t: &Trace, format: Format) -> Result<Vec<u8>, String> {
    let mut layers = MapLayers::new(map, None, Unknown::Free);
    // The paths may leave the map's bounds (a diverged filter): show them.
    for (_, _, m) in SERIES {
        for (x, y) in track(t, m) {
            let e = &mut layers.extent;
            *e = [e[0].min(x - 0.5), e[1].max(x + 0.5), e[2].min(y - 0.5), e[3].max(y + 0.5)];
        }
    }
    let (w, h, _, _) = layers.size(1200, LEGEND_W);
    encode(&Paths { layers, unmapped, trace: t, size: (w, h) }, format)
}

struct Errors<'a>(&'a Trace);

impl Figure for Errors<'_> {
    fn size(&self) -> (u32, u32) {
        (1200, 860)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let t = self.0;
        let root = root.titled("Position and heading error over time", (FONT, 24)).map_err(err)?;
        let (panels, foot) = root.split_vertically(760);
        let series: Vec<(&str, [u8; 3], Vec<ErrorAt>)> = SERIES[1..]
            .iter()
            .map(|&(label, colour, m)| (label, colour, t.error_series(m.unwrap_or(Methods::Ekf))))
            .collect();
        let t0 = t.times.first().copied().unwrap_or(0.0);
        let t1 = t.times.last().copied().unwrap_or(1.0).max(t0 + 1e-3);
        let areas = panels.split_evenly((2, 1));
        for (k, area) in areas.iter().enumerate() {
            let value = |e: &(f64, f64, f64)| if k == 0 { e.1 } else { e.2.abs() };
            let top = nice(series.iter().flat_map(|(_, _, s)| s.iter().map(value)).fold(0.0f64, f64::max).max(1e-3));
            let mut chart = ChartBuilder::on(area)
                .margin(14)
                .x_label_area_size(44)
                .y_label_area_size(76)
                .build_cartesian_2d(t0..t1, 0.0..top)
                .map_err(err)?;
            chart
                .configure_mesh()
                .light_line_style(WHITE)
                .bold_line_style(RGBColor(225, 225, 225))
                .x_desc("time (s)")
                .y_desc(if k == 0 { "position error (m)" } else { "heading error (°)" })
                .label_style((FONT, 15))
                .axis_desc_style((FONT, 16))
                .draw()
                .map_err(err)?;
            for (_, colour, s) in &series {
                chart
                    .draw_series(LineSeries::new(
                        s.iter().map(|e| (e.0, value(e).min(top))),
                        rgb(*colour).stroke_width(1),
                    ))
                    .map_err(err)?;
            }
        }
        let items: Vec<(&str, RGBColor)> = series.iter().map(|(l, c, _)| (*l, rgb(*c))).collect();
        legend(&foot.margin(10, 0, 90, 0), &items, true)
    }
}

fn errors(t: &Trace, format: Format) -> Result<Vec<u8>, String> {
    encode(&Errors(t), format)
}

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
    ("handoff", "particles at a hand-off", [220, 200, 0]),
    ("wake", "particles at a wake-up", [160, 110, 60]),
    ("asked", "particles after a kidnap", [0, 190, 210]),
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

/// A step longer than this, m, and faster than [`JUMP_M_S`] is a jump (a
/// kidnap, a hand-off to another place), not travel: the path breaks there.
const JUMP_M: f64 = 0.5;
/// ... m/s (no robot of these drives so fast).
const JUMP_M_S: f64 = 3.0;

/// The path of `m` (the truth for `None`) in pieces, broken where it
/// jumps or where the truth is not known.
fn track(t: &Trace, m: Option<Methods>) -> Vec<Vec<(f64, f64)>> {
    let at: Vec<Option<[f64; 3]>> = match m {
        None => t.truth.clone(),
        Some(Methods::DeadReckoning) => t.dead_reckoning.iter().copied().map(Some).collect(),
        Some(Methods::Threshold) => t.threshold.iter().copied().map(Some).collect(),
        Some(Methods::Ekf) => t.ekf.iter().copied().map(Some).collect(),
    };
    let mut pieces: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    let mut last: Option<(f64, f64, f64)> = None;
    for (k, p) in at.iter().enumerate() {
        let Some(p) = p else {
            last = None;
            if pieces.last().is_some_and(|v| !v.is_empty()) {
                pieces.push(Vec::new());
            }
            continue;
        };
        let time = t.times.get(k).copied().unwrap_or(k as f64);
        if let Some((x, y, t0)) = last {
            let d = (p[0] - x).hypot(p[1] - y);
            if d > JUMP_M && d > JUMP_M_S * (time - t0) {
                pieces.push(Vec::new());
            }
        }
        if let Some(v) = pieces.last_mut() {
            v.push((p[0], p[1]));
        }
        last = Some((p[0], p[1], time));
    }
    pieces.retain(|v| !v.is_empty());
    pieces
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
            for piece in track(self.trace, m) {
                chart.draw_series(LineSeries::new(piece, rgb(colour).stroke_width(1))).map_err(err)?;
            }
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
        for (x, y) in track(t, m).into_iter().flatten() {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_two_things_share_a_colour() {
        let mut all: Vec<(&str, [u8; 3])> = SERIES.iter().map(|&(l, c, _)| (l, c)).collect();
        all.push(("unmapped objects", CLUTTER));
        all.extend(CLOUDS.iter().map(|&(_, l, c)| (l, c)));
        all.extend(crate::map::render::COLOURS);
        for (i, (a, ca)) in all.iter().enumerate() {
            for (b, cb) in &all[i + 1..] {
                let d = ca.iter().zip(cb).map(|(&x, &y)| (f64::from(x) - f64::from(y)).powi(2)).sum::<f64>().sqrt();
                assert!(d >= 80.0, "{a} {ca:?} and {b} {cb:?} are {d:.0} apart in RGB");
            }
        }
    }

    #[test]
    fn a_path_breaks_where_it_jumps_not_where_it_drives() {
        // 0.04 s a reading: driving at 1 m/s, then a 6 m hand-off, then on;
        // the truth unknown for two readings.
        let mut t = Trace::default();
        for k in 0..20 {
            let x = 0.04 * f64::from(k) + if k >= 10 { 6.0 } else { 0.0 };
            t.times.push(0.04 * f64::from(k));
            t.ekf.push([x, 1.0, 0.0]);
            t.truth.push((!(4..6).contains(&k)).then_some([0.04 * f64::from(k), 1.0, 0.0]));
        }
        let ekf = track(&t, Some(Methods::Ekf));
        assert_eq!(ekf.iter().map(Vec::len).collect::<Vec<_>>(), [10, 10]);
        assert_eq!(ekf[1][0], (6.4, 1.0));
        let truth = track(&t, None);
        assert_eq!(truth.iter().map(Vec::len).collect::<Vec<_>>(), [4, 14]);
        // A slow big step (a robot parked for a minute, then 0.6 m on) is travel.
        t.times[10] = 60.0;
        for k in 11..20 {
            t.times[k] = 60.0 + 0.04 * (k - 10) as f64;
        }
        t.ekf[10][0] = t.ekf[9][0] + 0.6;
        for k in 11..20 {
            t.ekf[k][0] = t.ekf[10][0] + 0.04 * (k - 10) as f64;
        }
        assert_eq!(track(&t, Some(Methods::Ekf)).len(), 1);
    }
}

//! One firing drawn over the laser's returns (`simulate --from-scans …
//! --cone-plot OUT.png --cone-at T_s:TRANSDUCER`): the transducer's sensor
//! window (±θ_o) and main lobe (±12.7°), the laser's returns around the
//! robot at that moment, the map's outlines, and the observed and
//! predicted ranges as arcs, with the predicted echo point.

use echoloc::credence::net::CredenceNet;
use echoloc::map::MapSource;
use echoloc::predict::{predict_mount, Mount, Pose};
use plotters::prelude::*;

use crate::figure::{encode, Figure, Format, Root, FONT};
use crate::lidar::LidarRun;
use crate::simulate::filters::predict_params;
use crate::simulate::world::SimReading;

/// Half the area drawn round the transducer, m.
const HALF_M: f64 = 4.0;

struct Cone {
    apex: (f64, f64),
    axis: f64,
    half_window: f64,
    points: Vec<(f64, f64)>,
    outlines: Vec<Vec<(f64, f64)>>,
    observed: Option<f64>,
    predicted: Option<(f64, (f64, f64), f64)>,
    title: String,
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

impl Figure for Cone {
    fn size(&self) -> (u32, u32) {
        (900, 960)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let root = root.titled(&self.title, (FONT, 20)).map_err(err)?;
        let (x0, y0) = self.apex;
        let mut chart = ChartBuilder::on(&root)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d((x0 - HALF_M)..(x0 + HALF_M), (y0 - HALF_M)..(y0 + HALF_M))
            .map_err(err)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .bold_line_style(RGBColor(230, 230, 230))
            .x_desc("x (m)")
            .y_desc("y (m)")
            .label_style((FONT, 14))
            .draw()
            .map_err(err)?;
        let ray = |a: f64, r: f64| (x0 + r * a.cos(), y0 + r * a.sin());
        // The window and the main lobe.
        for (half, colour) in
            [(self.half_window, RGBColor(200, 200, 255)), (12.7f64.to_radians(), RGBColor(120, 120, 230))]
        {
            for s in [-1.0, 1.0] {
                chart
                    .draw_series(LineSeries::new([self.apex, ray(self.axis + s * half, 5.5)], colour.stroke_width(1)))
                    .map_err(err)?;
            }
        }
        chart
            .draw_series(
                self.outlines.iter().map(|o| PathElement::new(o.clone(), RGBColor(230, 120, 40).stroke_width(2))),
            )
            .map_err(err)?
            .label("map outline")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RGBColor(230, 120, 40).stroke_width(2)));
        chart
            .draw_series(self.points.iter().map(|&p| Circle::new(p, 2, BLACK.filled())))
            .map_err(err)?
            .label("laser returns")
            .legend(|(x, y)| Circle::new((x + 9, y), 3, BLACK.filled()));
        let arc = |r: f64| -> Vec<(f64, f64)> {
            (0..=60)
                .map(|k| ray(self.axis - self.half_window + 2.0 * self.half_window * f64::from(k) / 60.0, r))
                .collect()
        };
        if let Some(r) = self.observed {
            chart
                .draw_series([PathElement::new(arc(r), RGBColor(0, 150, 0).stroke_width(3))])
                .map_err(err)?
                .label(format!("observed {r:.3} m"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RGBColor(0, 150, 0).stroke_width(3)));
        }
        if let Some((r, p, k)) = self.predicted {
            chart
                .draw_series([PathElement::new(arc(r), RGBColor(200, 0, 0).stroke_width(2))])
                .map_err(err)?
                .label(format!("predicted {r:.3} m, κ {k:.2}"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RGBColor(200, 0, 0).stroke_width(2)));
            chart.draw_series([Circle::new(p, 6, RGBColor(200, 0, 0).stroke_width(2))]).map_err(err)?;
        }
        chart.draw_series([Circle::new(self.apex, 5, BLUE.filled())]).map_err(err)?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)
    }
}

/// Parses `T_s:TRANSDUCER`.
pub fn parse_at(s: &str) -> Result<(f64, u8), String> {
    let bad = || format!("--cone-at {s:?}: expected T_s:TRANSDUCER (a time in seconds on the run's clock, an index)");
    let (t, i) = s.split_once(':').ok_or_else(bad)?;
    let t: f64 = t.trim().parse().map_err(|_| bad())?;
    let i: u8 = i.trim().parse().map_err(|_| bad())?;
    if !t.is_finite() {
        return Err(bad());
    }
    Ok((t, i))
}

/// The figure of transducer `at.1`'s first kept reading at or after `at.0` s.
pub fn draw(
    map: &echoloc::map::MapView<'_>,
    mounts: &[Mount],
    run: &LidarRun,
    scan_times: &[f64],
    kept: &[SimReading],
    at: (f64, u8),
    format: Format,
) -> Result<Vec<u8>, String> {
    let r = kept
        .iter()
        .find(|r| r.transducer == at.1 && r.time_s >= at.0)
        .ok_or_else(|| format!("--cone-at {}:{}: no kept reading of that transducer from then on", at.0, at.1))?;
    let m = mounts.get(usize::from(r.transducer)).ok_or("no such transducer")?;
    let (x, y, h) = r.truth;
    let (mx, my, mh) =
        (f64::from(m.x_mm) / 1000.0, f64::from(m.y_mm) / 1000.0, (f64::from(m.heading_mdeg) / 1000.0).to_radians());
    let apex = (x + h.cos() * mx - h.sin() * my, y + h.sin() * mx + h.cos() * my);
    // The scans within a few seconds of the firing.
    let mut points = Vec::new();
    for (s, &t) in run.scans.iter().zip(scan_times) {
        if (t - r.time_s).abs() <= 3.0 {
            points.extend(s.points().filter(|p| (p.0 - apex.0).abs() <= HALF_M && (p.1 - apex.1).abs() <= HALF_M));
        }
    }
    let mm = |p: &echoloc::geometry::Point| (f64::from(p.x) / 1000.0, f64::from(p.y) / 1000.0);
    let outlines = map
        .pieces_iter()
        .map(|p| {
            let mut v: Vec<(f64, f64)> = p.shape.vertices().iter().map(mm).collect();
            if v.len() > 2 {
                v.push(v[0]);
            }
            v
        })
        // Pieces whose box meets the drawn square (a long wall's ends may both lie outside it).
        .filter(|v| {
            let (lo, hi) = v.iter().fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
                ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
            });
            lo.0 <= apex.0 + HALF_M && hi.0 >= apex.0 - HALF_M && lo.1 <= apex.1 + HALF_M && hi.1 >= apex.1 - HALF_M
        })
        .collect();
    let params = predict_params(map.buffer_mm(), map.field());
    let pose = Pose { x_mm: (x * 1000.0) as f32, y_mm: (y * 1000.0) as f32, heading_rad: h as f32 };
    let (p, _) = predict_mount(map, &pose, m, &params, &CredenceNet::shipped()).map_err(|e| format!("{e:?}"))?;
    let fig = Cone {
        apex,
        axis: h + mh,
        half_window: f64::from(params.window.half_angle_deg).to_radians(),
        points,
        outlines,
        observed: r.range_mm.map(|v| f64::from(v) / 1000.0),
        predicted: p.map(|p| (f64::from(p.range_mm) / 1000.0, mm(&p.point), p.kappa.to_num::<f64>())),
        title: format!(
            "Transducer {} at {:.2} s: the laser's returns, the window, observed and predicted",
            r.transducer, r.time_s
        ),
    };
    encode(&fig, format)
}

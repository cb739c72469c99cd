//! The scaling figure: time per window against the number of pieces, one
//! line per method, both axes logarithmic, drawn with `plotters`
//! ([`crate::figure`]).

use plotters::prelude::*;
use serde_json::Value;

use crate::figure::{encode, err, legend, rgb, Figure, Format, Root, FONT};

const COLOURS: [[u8; 3]; 12] = [
    [230, 97, 1],
    [253, 184, 99],
    [178, 171, 210],
    [94, 60, 153],
    [0, 109, 44],
    [116, 196, 118],
    [0, 0, 0],
    [31, 120, 180],
    [166, 206, 227],
    [227, 26, 28],
    [153, 153, 153],
    [177, 89, 40],
];

/// (method, [(pieces, ns per window)]) at the largest half-angle benchmarked.
type Lines = Vec<(String, Vec<(f64, f64)>)>;

struct Scaling {
    half: f64,
    series: Lines,
}

impl Figure for Scaling {
    fn size(&self) -> (u32, u32) {
        (1200, 760)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let root = root
            .titled(&format!("Time per window against map size (half-angle {}°)", self.half), (FONT, 24))
            .map_err(err)?;
        let (plot, side) = root.split_horizontally(930);
        let pts = self.series.iter().flat_map(|s| s.1.iter());
        let (x0, x1, y0, y1) = pts.fold((f64::MAX, f64::MIN, f64::MAX, f64::MIN), |(a, b, c, d), &(x, y)| {
            (a.min(x), b.max(x), c.min(y), d.max(y))
        });
        let (x0, x1, y0, y1) = if x0 > x1 { (1.0, 10.0, 1.0, 10.0) } else { (x0, x1, y0, y1) };
        let dec = |lo: f64, hi: f64| {
            let (a, b) = (10f64.powf(lo.log10().floor()), 10f64.powf(hi.log10().ceil()));
            (a, if b <= a { a * 10.0 } else { b })
        };
        let ((x0, x1), (y0, y1)) = (dec(x0, x1), dec(y0, y1));
        let mut c = ChartBuilder::on(&plot)
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(90)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(err)?;
        c.configure_mesh()
            .light_line_style(RGBColor(240, 240, 240))
            .bold_line_style(RGBColor(215, 215, 215))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .x_desc("convex pieces in the map")
            .y_desc("time per window (ns)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(err)?;
        for (k, (_, pts)) in self.series.iter().enumerate() {
            let colour = rgb(COLOURS[k % COLOURS.len()]);
            c.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(3))).map_err(err)?;
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 5, colour.filled()))).map_err(err)?;
        }
        let items: Vec<(&str, RGBColor)> =
            self.series.iter().enumerate().map(|(k, s)| (s.0.as_str(), rgb(COLOURS[k % COLOURS.len()]))).collect();
        legend(&side.margin(60, 0, 0, 0), &items, false)
    }
}

/// The figure for `results` (one `bench` result per map), at the largest
/// half-angle benchmarked, as PNG or SVG.
pub fn scaling_as(results: &[Value], format: Format) -> Result<Vec<u8>, String> {
    let half = results
        .iter()
        .flat_map(|r| r["methods"].as_array().into_iter().flatten())
        .filter_map(|m| m["half_angle_deg"].as_f64())
        .fold(0.0, f64::max);
    let mut series: Lines = Vec::new();
    for r in results {
        let pieces = r["pieces"].as_f64().unwrap_or(1.0).max(1.0);
        for m in r["methods"].as_array().into_iter().flatten().filter(|m| m["half_angle_deg"].as_f64() == Some(half)) {
            let (Some(name), Some(ns)) = (m["name"].as_str(), m["ns_per_window"].as_f64()) else { continue };
            match series.iter_mut().find(|s| s.0 == name) {
                Some(s) => s.1.push((pieces, ns.max(1.0))),
                None => series.push((name.to_string(), vec![(pieces, ns.max(1.0))])),
            }
        }
    }
    encode(&Scaling { half, series }, format)
}

//! The scaling figure: time per window against the number of pieces, one
//! line per method, both axes logarithmic (the lab's own canvas and font).

use serde_json::Value;

use crate::credence::plot::{legend, Canvas, Rgb};

const COLOURS: [Rgb; 7] =
    [[230, 97, 1], [253, 184, 99], [178, 171, 210], [94, 60, 153], [0, 109, 44], [116, 196, 118], [0, 0, 0]];
const GREY: Rgb = [210, 210, 210];
const BLACK: Rgb = [0, 0, 0];

/// The figure for `results` (one `bench` result per map), at the largest
/// half-angle benchmarked. An empty PNG-less result gives an empty canvas.
pub fn scaling(results: &[Value]) -> Vec<u8> {
    let half = results
        .iter()
        .flat_map(|r| r["methods"].as_array().into_iter().flatten())
        .filter_map(|m| m["half_angle_deg"].as_f64())
        .fold(0.0, f64::max);
    // name -> [(pieces, ns)]
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
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
    let pts = series.iter().flat_map(|s| s.1.iter());
    let (x0, x1, y0, y1) = pts.fold((f64::MAX, f64::MIN, f64::MAX, f64::MIN), |(a, b, c, d), &(x, y)| {
        (a.min(x), b.max(x), c.min(y), d.max(y))
    });
    let (lx0, lx1) = (x0.log10().floor(), x1.log10().ceil().max(x0.log10().floor() + 1.0));
    let (ly0, ly1) = (y0.log10().floor(), y1.log10().ceil().max(y0.log10().floor() + 1.0));
    let (w, h, px, py, pw, ph) = (1140i64, 720i64, 150i64, 70i64, 900i64, 520i64);
    let mut c = Canvas::new(w as usize, h as usize);
    c.text(px, 20, &format!("TIME PER WINDOW AGAINST MAP SIZE (HALF-ANGLE {half} DEG)"), 3, BLACK);
    let to_px = |x: f64, y: f64| {
        (
            px + ((x.log10() - lx0) / (lx1 - lx0) * pw as f64) as i64,
            py + ph - ((y.log10() - ly0) / (ly1 - ly0) * ph as f64) as i64,
        )
    };
    let mut e = ly0;
    while e <= ly1 + 1e-9 {
        let y = to_px(10f64.powf(lx0), 10f64.powf(e)).1;
        c.line((px, y), (px + pw, y), GREY, 1);
        let s = format!("{} NS", 10f64.powf(e));
        c.text(px - 10 - Canvas::text_width(&s, 2), y - 7, &s, 2, BLACK);
        e += 1.0;
    }
    let mut e = lx0;
    while e <= lx1 + 1e-9 {
        let x = to_px(10f64.powf(e), 10f64.powf(ly0)).0;
        c.line((x, py), (x, py + ph), GREY, 1);
        let s = format!("{}", 10f64.powf(e));
        c.text(x - Canvas::text_width(&s, 2) / 2, py + ph + 10, &s, 2, BLACK);
        e += 1.0;
    }
    for (a, b) in [
        ((px, py), (px + pw, py)),
        ((px, py + ph), (px + pw, py + ph)),
        ((px, py), (px, py + ph)),
        ((px + pw, py), (px + pw, py + ph)),
    ] {
        c.line(a, b, BLACK, 1);
    }
    c.text(px + pw / 2 - 120, py + ph + 34, "CONVEX PIECES IN THE MAP", 2, BLACK);
    for (k, (_, pts)) in series.iter().enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        let mut prev = None;
        for &(x, y) in pts {
            let p = to_px(x, y);
            c.rect(p.0 - 4, p.1 - 4, 9, 9, colour);
            if let Some(q) = prev {
                c.line(q, p, colour, 3);
            }
            prev = Some(p);
        }
    }
    let items: Vec<(&str, Rgb)> =
        series.iter().enumerate().map(|(k, s)| (s.0.as_str(), COLOURS[k % COLOURS.len()])).collect();
    legend(&mut c, px - 60, h - 50, &items[..items.len().min(4)]);
    if items.len() > 4 {
        legend(&mut c, px - 60, h - 26, &items[4..]);
    }
    c.png(std::path::Path::new("scaling.png")).unwrap_or_default()
}

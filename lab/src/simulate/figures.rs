//! The simulator's two figures: the map with the true, dead-reckoned,
//! threshold and EKF paths (and the clutter), and the position and heading
//! errors over time.

use echoloc::map::StandardMap;

use super::filters::{Methods, Trace};
use crate::credence::plot::{legend, Canvas, Rgb};
use crate::map::render::preview_canvas;
use crate::map::Unknown;

const TRUTH: Rgb = [0, 0, 0];
const DEAD_RECKONING: Rgb = [220, 30, 30];
const THRESHOLD: Rgb = [150, 60, 200];
const EKF: Rgb = [0, 150, 60];
const CLUTTER: Rgb = [230, 0, 160];
const BLACK: Rgb = [0, 0, 0];
const GREY: Rgb = [210, 210, 210];

const SERIES: [(&str, Rgb, Option<Methods>); 4] = [
    ("TRUTH", TRUTH, None),
    ("DEAD RECKONING", DEAD_RECKONING, Some(Methods::DeadReckoning)),
    ("THRESHOLD", THRESHOLD, Some(Methods::Threshold)),
    ("EKF", EKF, Some(Methods::Ekf)),
];

/// (time s, position error m, heading error °).
type ErrorAt = (f64, f64, f64);

fn mm(p: [f64; 3]) -> (f64, f64) {
    (p[0] * 1000.0, p[1] * 1000.0)
}

/// The two PNGs: paths on the map (with the outlines of `unmapped`
/// objects, m), errors over time (against the true pose, where known).
pub fn draw(map: &StandardMap, unmapped: &[Vec<(f64, f64)>], t: &Trace) -> (Vec<u8>, Vec<u8>) {
    (paths(map, unmapped, t), errors(t))
}

fn paths(map: &StandardMap, unmapped: &[Vec<(f64, f64)>], t: &Trace) -> Vec<u8> {
    let mut cv = preview_canvas(map, None, Unknown::Free);
    for outline in unmapped {
        let n = outline.len();
        for i in 0..n {
            let (a, b) = (outline[i], outline[(i + 1) % n]);
            cv.line((a.0 * 1000.0, a.1 * 1000.0), (b.0 * 1000.0, b.1 * 1000.0), CLUTTER, 2);
        }
    }
    for (_, colour, m) in SERIES {
        let track: Vec<[f64; 3]> = match m {
            None => t.truth.iter().flatten().copied().collect(),
            Some(Methods::DeadReckoning) => t.dead_reckoning.clone(),
            Some(Methods::Threshold) => t.threshold.clone(),
            Some(Methods::Ekf) => t.ekf.clone(),
        };
        for w in track.windows(2) {
            cv.line(mm(w[0]), mm(w[1]), colour, if m.is_none() { 3 } else { 2 });
        }
    }
    let mut y = 8;
    for (label, colour, _) in SERIES.iter().chain([("UNMAPPED OBJECTS", CLUTTER, None)].iter()) {
        cv.text(10, y, &format!("-- {label}"), 2, *colour);
        y += 20;
    }
    cv.png()
}

fn errors(t: &Trace) -> Vec<u8> {
    let (w, h) = (1200i64, 820i64);
    let mut c = Canvas::new(w as usize, h as usize);
    c.text(30, 14, "POSITION AND HEADING ERROR OVER TIME", 3, BLACK);
    let t_end = t.times.last().copied().unwrap_or(1.0).max(1e-3);
    let t0 = t.times.first().copied().unwrap_or(0.0);
    let series: Vec<(Rgb, Vec<ErrorAt>)> =
        SERIES[1..].iter().map(|&(_, colour, m)| (colour, t.error_series(m.unwrap_or(Methods::Ekf)))).collect();
    let panels: [(&str, usize, i64); 2] = [("POSITION ERROR (M)", 0, 70), ("HEADING ERROR (DEG)", 1, 430)];
    let (px, pw, ph) = (110i64, w - 160, 280i64);
    for (title, k, py) in panels {
        let top = series
            .iter()
            .flat_map(|(_, s)| s.iter().map(move |e| if k == 0 { e.1 } else { e.2.abs() }))
            .fold(0.0f64, f64::max)
            .max(1e-3);
        let top = nice(top);
        c.text(px, py - 24, title, 2, BLACK);
        for i in 0..=4 {
            let y = py + ph - (i as f64 / 4.0 * ph as f64) as i64;
            c.line((px, y), (px + pw, y), GREY, 1);
            let s = format!("{:.3}", top * i as f64 / 4.0);
            c.text(px - 10 - Canvas::text_width(&s, 2), y - 7, &s, 2, BLACK);
        }
        for i in 0..=5 {
            let x = px + (i as f64 / 5.0 * pw as f64) as i64;
            let s = format!("{:.0}", t0 + (t_end - t0) * i as f64 / 5.0);
            c.text(x - Canvas::text_width(&s, 2) / 2, py + ph + 8, &s, 2, BLACK);
        }
        c.text(px + pw / 2 - 30, py + ph + 30, "TIME (S)", 2, BLACK);
        for (colour, s) in &series {
            let mut prev = None;
            for &(time, p, h) in s {
                let v = if k == 0 { p } else { h.abs() };
                let x = px + ((time - t0) / (t_end - t0).max(1e-9) * pw as f64) as i64;
                let y = py + ph - ((v / top).min(1.0) * ph as f64) as i64;
                if let Some(q) = prev {
                    c.line(q, (x, y), *colour, 2);
                }
                prev = Some((x, y));
            }
        }
        c.line((px, py), (px, py + ph), BLACK, 1);
        c.line((px, py + ph), (px + pw, py + ph), BLACK, 1);
    }
    let items: Vec<(&str, Rgb)> = SERIES[1..].iter().map(|&(label, colour, _)| (label, colour)).collect();
    legend(&mut c, px, h - 40, &items);
    c.png(std::path::Path::new("error plot")).unwrap_or_default()
}

/// The next of 1, 2, 5 × 10ⁿ at or above `v`.
fn nice(v: f64) -> f64 {
    let e = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * e).find(|&x| x >= v).unwrap_or(10.0 * e)
}

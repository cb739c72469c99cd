//! PNG figures of κ surfaces, drawn pixel by pixel (no font files, no plotting
//! framework: a 5×7 bitmap font and the `png` encoder), like the paper's
//! Figs. 8–9: each surface in (R, θ) and in the sensor's (x, y) frame.

use std::path::Path;

use super::error::CredenceError;

/// An RGB canvas.
pub struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

pub type Rgb = [u8; 3];
const BLACK: Rgb = [0, 0, 0];
const GREY: Rgb = [200, 200, 200];

impl Canvas {
    /// A white canvas.
    pub fn new(w: usize, h: usize) -> Self {
        Self { w, h, px: vec![255; w * h * 3] }
    }

    fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = (y as usize * self.w + x as usize) * 3;
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    pub fn rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        for yy in y..y + h {
            for xx in x..x + w {
                self.set(xx, yy, c);
            }
        }
    }

    pub fn line(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: Rgb, thick: i64) {
        let n = (x1 - x0).abs().max((y1 - y0).abs()).max(1);
        for k in 0..=n {
            let x = x0 + (x1 - x0) * k / n;
            let y = y0 + (y1 - y0) * k / n;
            self.rect(x - thick / 2, y - thick / 2, thick, thick, c);
        }
    }

    /// Text at (x, y) top-left, `scale` pixels per font dot; returns its width.
    pub fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb) -> i64 {
        let mut cx = x;
        for ch in s.chars() {
            let g = glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        self.rect(cx + col * scale, y + row as i64 * scale, scale, scale, c);
                    }
                }
            }
            cx += 6 * scale;
        }
        cx - x
    }

    pub fn text_width(s: &str, scale: i64) -> i64 {
        s.chars().count() as i64 * 6 * scale
    }

    /// The canvas as an 8-bit RGB PNG, in memory; `path` (where it is meant
    /// to go) names the figure in an error.
    pub fn png(&self, path: &Path) -> Result<Vec<u8>, CredenceError> {
        let err = |e: png::EncodingError| CredenceError::io(path, std::io::Error::other(e));
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.w as u32, self.h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Best);
        let mut wr = enc.write_header().map_err(err)?;
        wr.write_image_data(&self.px).map_err(err)?;
        wr.finish().map_err(err)?;
        Ok(out)
    }
}

/// Viridis, by linear interpolation between five of its stops.
pub fn viridis(v: f64) -> Rgb {
    const STOPS: [[f64; 3]; 5] =
        [[68.0, 1.0, 84.0], [59.0, 82.0, 139.0], [33.0, 145.0, 140.0], [94.0, 201.0, 98.0], [253.0, 231.0, 37.0]];
    let v = v.clamp(0.0, 1.0) * 4.0;
    let i = (v.floor() as usize).min(3);
    let f = v - i as f64;
    core::array::from_fn(|c| (STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8)
}

/// A κ surface to draw: `None` outside the data (left white).
pub type Surface<'a> = &'a dyn Fn(f64, f64) -> Option<f64>;

const R_LO: f64 = 500.0;
const R_HI: f64 = 5500.0;
const T_HI: f64 = 45.0;

/// One figure: the surface in (R, θ) on the left and in the sensor frame
/// (x lateral, y along the axis, θ ∈ [−45°, 45°]) on the right, a colour bar.
pub fn surface_figure(title: &str, kappa: Surface<'_>) -> Canvas {
    let (w, h) = (1340usize, 560usize);
    let mut c = Canvas::new(w, h);
    c.text(30, 14, title, 3, BLACK);
    // Left panel: R across, θ up.
    let (lx, ly, lw, lh) = (90i64, 90i64, 440i64, 400i64);
    for py in 0..lh {
        let t = T_HI * (lh - 1 - py) as f64 / (lh - 1) as f64;
        for px in 0..lw {
            let r = R_LO + (R_HI - R_LO) * px as f64 / (lw - 1) as f64;
            if let Some(k) = kappa(r, t) {
                c.set(lx + px, ly + py, viridis(k));
            }
        }
    }
    frame(&mut c, lx, ly, lw, lh);
    for r in (500..=5500).step_by(1000) {
        let x = lx + ((f64::from(r) - R_LO) / (R_HI - R_LO) * (lw - 1) as f64) as i64;
        x_tick(&mut c, x, ly + lh, &r.to_string());
    }
    for t in (0..=45).step_by(15) {
        let y = ly + lh - 1 - (f64::from(t) / T_HI * (lh - 1) as f64) as i64;
        y_tick(&mut c, lx, y, &t.to_string());
    }
    c.text(lx + lw / 2 - 60, ly + lh + 34, "R (MM)", 2, BLACK);
    c.text(lx - 80, ly - 30, "θ (DEG)", 2, BLACK);
    c.text(lx + 120, ly - 30, "(A) R-θ", 2, BLACK);

    // Right panel: sensor frame, equal scale on both axes, wide enough for the
    // whole cone: x ∈ ±R_HI·sin 45° (±3.89 m), y ∈ [0, R_HI], with a margin.
    let (rx, ry, rw, rh) = (620i64, 90i64, 560i64, 400i64);
    let scale = f64::max(8000.0 / (rw - 1) as f64, 5600.0 / (rh - 1) as f64); // mm per pixel
    let x0 = rx + (rw - 1) / 2;
    for py in 0..rh {
        let ymm = (rh - 1 - py) as f64 * scale;
        for px in 0..rw {
            let xmm = (rx + px - x0) as f64 * scale;
            let r = (xmm * xmm + ymm * ymm).sqrt();
            let t = xmm.atan2(ymm).to_degrees();
            if (R_LO..=R_HI).contains(&r) && t.abs() <= T_HI {
                if let Some(k) = kappa(r, t.abs()) {
                    c.set(rx + px, ry + py, viridis(k));
                }
            }
        }
    }
    frame(&mut c, rx, ry, rw, rh);
    for xm in -4i32..=4 {
        let x = x0 + (f64::from(xm) * 1000.0 / scale).round() as i64;
        x_tick(&mut c, x, ry + rh, &xm.to_string());
    }
    for ym in 0..=5 {
        let y = ry + rh - 1 - (f64::from(ym) * 1000.0 / scale) as i64;
        y_tick(&mut c, rx, y, &ym.to_string());
    }
    c.text(rx + rw / 2 - 40, ry + rh + 34, "XS (M)", 2, BLACK);
    c.text(rx - 40, ry - 30, "YS (M)", 2, BLACK);
    c.text(rx + 120, ry - 30, "(B) SENSOR FRAME", 2, BLACK);

    colour_bar(&mut c, 1230, 90, 24, 400);
    c
}

/// A tick below the x axis at `axis_y`, labelled underneath.
fn x_tick(c: &mut Canvas, x: i64, axis_y: i64, label: &str) {
    c.line((x, axis_y), (x, axis_y + 6), BLACK, 1);
    c.text(x - Canvas::text_width(label, 2) / 2, axis_y + 10, label, 2, BLACK);
}

/// A tick left of the y axis at `axis_x`, labelled to its left.
fn y_tick(c: &mut Canvas, axis_x: i64, y: i64, label: &str) {
    c.line((axis_x - 6, y), (axis_x, y), BLACK, 1);
    c.text(axis_x - 10 - Canvas::text_width(label, 2), y - 7, label, 2, BLACK);
}

fn frame(c: &mut Canvas, x: i64, y: i64, w: i64, h: i64) {
    c.line((x - 1, y - 1), (x + w, y - 1), BLACK, 1);
    c.line((x - 1, y + h), (x + w, y + h), BLACK, 1);
    c.line((x - 1, y - 1), (x - 1, y + h), BLACK, 1);
    c.line((x + w, y - 1), (x + w, y + h), BLACK, 1);
}

fn colour_bar(c: &mut Canvas, x: i64, y: i64, w: i64, h: i64) {
    for py in 0..h {
        let v = (h - 1 - py) as f64 / (h - 1) as f64;
        c.rect(x, y + py, w, 1, viridis(v));
    }
    frame(c, x, y, w, h);
    for k in 0..=4 {
        let v = f64::from(k) / 4.0;
        let yy = y + h - 1 - (v * (h - 1) as f64) as i64;
        c.line((x + w, yy), (x + w + 5, yy), BLACK, 1);
        c.text(x + w + 8, yy - 7, &format!("{v:.2}"), 2, BLACK);
    }
    c.text(x - 4, y - 30, "κ", 3, BLACK);
}

/// A line series for [`profile_figure`].
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// Colour.
    pub colour: Rgb,
    /// κ(R, θ).
    pub kappa: Surface<'a>,
    /// Dots at the grid angles instead of a line.
    pub dots: bool,
}

/// κ against θ at a few ranges, one panel per range.
pub fn profile_figure(title: &str, ranges_mm: &[u32], series: &[Series<'_>]) -> Canvas {
    let (pw, ph) = (340i64, 300i64);
    let w = 60 + ranges_mm.len() as i64 * (pw + 90);
    let h = 500i64;
    let mut c = Canvas::new(w as usize, h as usize);
    c.text(30, 14, title, 3, BLACK);
    for (i, &r) in ranges_mm.iter().enumerate() {
        let (px, py) = (70 + i as i64 * (pw + 90), 80i64);
        for k in 0..=4 {
            let y = py + ph - 1 - (f64::from(k) / 4.0 * (ph - 1) as f64) as i64;
            c.line((px, y), (px + pw, y), GREY, 1);
            let s = format!("{:.2}", f64::from(k) / 4.0);
            c.text(px - 8 - Canvas::text_width(&s, 2), y - 7, &s, 2, BLACK);
        }
        for t in (0..=45).step_by(15) {
            let x = px + (f64::from(t) / T_HI * (pw - 1) as f64) as i64;
            c.line((x, py), (x, py + ph), GREY, 1);
            let s = t.to_string();
            c.text(x - Canvas::text_width(&s, 2) / 2, py + ph + 8, &s, 2, BLACK);
        }
        frame(&mut c, px, py, pw, ph);
        c.text(px + 90, py - 28, &format!("R = {r} MM"), 2, BLACK);
        c.text(px + pw / 2 - 40, py + ph + 32, "θ (DEG)", 2, BLACK);
        let to_px = |t: f64, k: f64| {
            (px + (t / T_HI * (pw - 1) as f64) as i64, py + ph - 1 - (k.clamp(0.0, 1.0) * (ph - 1) as f64) as i64)
        };
        for s in series {
            if s.dots {
                for k in 0..=18 {
                    let t = 2.5 * f64::from(k);
                    if let Some(v) = (s.kappa)(f64::from(r), t) {
                        let (x, y) = to_px(t, v);
                        c.rect(x - 4, y - 4, 9, 9, s.colour);
                    }
                }
            } else {
                let mut prev = None;
                for k in 0..=450 {
                    let t = 0.1 * f64::from(k);
                    if let Some(v) = (s.kappa)(f64::from(r), t) {
                        let p = to_px(t, v);
                        if let Some(q) = prev {
                            c.line(q, p, s.colour, 3);
                        }
                        prev = Some(p);
                    }
                }
            }
        }
    }
    let items: Vec<(&str, Rgb)> = series.iter().map(|s| (s.label, s.colour)).collect();
    legend(&mut c, 70, h - 40, &items);
    c
}

/// A legend row: a swatch and a label per item, left to right from `x`,
/// swatches' tops at `y`.
pub fn legend(c: &mut Canvas, x: i64, y: i64, items: &[(&str, Rgb)]) {
    let mut lx = x;
    for &(label, colour) in items {
        c.rect(lx, y, 24, 12, colour);
        lx += 32 + c.text(lx + 32, y - 3, label, 2, BLACK) + 30;
    }
}

/// A 5×7 glyph, one byte per row, bit 4 the leftmost dot. Lower case is
/// drawn as upper case; unknown characters as a blank.
pub fn glyph(ch: char) -> [u8; 7] {
    let rows: &str = match ch.to_ascii_uppercase() {
        '0' => "01110 10001 10011 10101 11001 10001 01110",
        '1' => "00100 01100 00100 00100 00100 00100 01110",
        '2' => "01110 10001 00001 00010 00100 01000 11111",
        '3' => "11111 00010 00100 00010 00001 10001 01110",
        '4' => "00010 00110 01010 10010 11111 00010 00010",
        '5' => "11111 10000 11110 00001 00001 10001 01110",
        '6' => "00110 01000 10000 11110 10001 10001 01110",
        '7' => "11111 00001 00010 00100 01000 01000 01000",
        '8' => "01110 10001 10001 01110 10001 10001 01110",
        '9' => "01110 10001 10001 01111 00001 00010 01100",
        'A' => "01110 10001 10001 11111 10001 10001 10001",
        'B' => "11110 10001 10001 11110 10001 10001 11110",
        'C' => "01110 10001 10000 10000 10000 10001 01110",
        'D' => "11100 10010 10001 10001 10001 10010 11100",
        'E' => "11111 10000 10000 11110 10000 10000 11111",
        'F' => "11111 10000 10000 11110 10000 10000 10000",
        'G' => "01110 10001 10000 10111 10001 10001 01111",
        'H' => "10001 10001 10001 11111 10001 10001 10001",
        'I' => "01110 00100 00100 00100 00100 00100 01110",
        'J' => "00111 00010 00010 00010 00010 10010 01100",
        'K' => "10001 10010 10100 11000 10100 10010 10001",
        'L' => "10000 10000 10000 10000 10000 10000 11111",
        'M' => "10001 11011 10101 10101 10001 10001 10001",
        'N' => "10001 10001 11001 10101 10011 10001 10001",
        'O' => "01110 10001 10001 10001 10001 10001 01110",
        'P' => "11110 10001 10001 11110 10000 10000 10000",
        'Q' => "01110 10001 10001 10001 10101 10010 01101",
        'R' => "11110 10001 10001 11110 10100 10010 10001",
        'S' => "01111 10000 10000 01110 00001 00001 11110",
        'T' => "11111 00100 00100 00100 00100 00100 00100",
        'U' => "10001 10001 10001 10001 10001 10001 01110",
        'V' => "10001 10001 10001 10001 10001 01010 00100",
        'W' => "10001 10001 10001 10101 10101 10101 01010",
        'X' => "10001 10001 01010 00100 01010 10001 10001",
        'Y' => "10001 10001 01010 00100 00100 00100 00100",
        'Z' => "11111 00001 00010 00100 01000 10000 11111",
        '.' => "00000 00000 00000 00000 00000 01100 01100",
        ',' => "00000 00000 00000 00000 01100 00100 01000",
        '-' | '−' | '–' => "00000 00000 00000 11111 00000 00000 00000",
        '+' => "00000 00100 00100 11111 00100 00100 00000",
        '(' => "00010 00100 01000 01000 01000 00100 00010",
        ')' => "01000 00100 00010 00010 00010 00100 01000",
        ':' => "00000 01100 01100 00000 01100 01100 00000",
        '/' => "00000 00001 00010 00100 01000 10000 00000",
        '=' => "00000 00000 11111 00000 11111 00000 00000",
        '°' => "01100 10010 10010 01100 00000 00000 00000",
        'κ' => "00000 00000 10010 10100 11000 10100 10010",
        'θ' => "01110 10001 10001 11111 10001 10001 01110",
        _ => "00000 00000 00000 00000 00000 00000 00000",
    };
    let mut g = [0u8; 7];
    for (i, r) in rows.split(' ').enumerate() {
        g[i] = u8::from_str_radix(r, 2).unwrap_or(0);
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_glyphs() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(2.0), viridis(1.0));
        assert_eq!(glyph('1'), [4, 12, 4, 4, 4, 4, 14]);
        assert_eq!(glyph('a'), glyph('A'));
    }

    #[test]
    fn the_sensor_frame_shows_the_whole_cone() {
        // A constant surface: the sensor-frame panel must show the full
        // annular sector 0.5…5.5 m × ±45°, (π/4)·(5.5² − 0.5²) m², unclipped.
        let c = surface_figure("T", &|_, _| Some(0.5));
        let colour = viridis(0.5);
        let mut n = 0usize;
        let (mut x_lo, mut x_hi, mut y_lo) = (usize::MAX, 0, usize::MAX);
        for y in 0..c.h {
            for x in 560..1200 {
                let i = (y * c.w + x) * 3;
                if c.px[i..i + 3] == colour {
                    n += 1;
                    (x_lo, x_hi, y_lo) = (x_lo.min(x), x_hi.max(x), y_lo.min(y));
                }
            }
        }
        let scale = 8000.0 / 559.0; // mm per pixel, as drawn
        let area = std::f64::consts::FRAC_PI_4 * (5500.0f64.powi(2) - 500.0f64.powi(2)) / (scale * scale);
        assert!((n as f64 / area - 1.0).abs() < 0.01, "{n} pixels, {area:.0} expected");
        // Neither side touches the panel's frame (x 620…1179), nor the top (y 90).
        let half = (3889.0 / scale) as usize;
        assert!(x_lo > 620 && x_hi < 1179 && x_hi - x_lo >= 2 * half, "{x_lo}…{x_hi}");
        assert!(y_lo > 90, "{y_lo}");
    }
}

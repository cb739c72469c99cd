//! Figures: every picture the lab draws goes through `plotters`, as PNG
//! (its bitmap backend, encoded by the `png` crate) or SVG (its SVG
//! backend), with text in DejaVu Sans (shipped in `lab/assets/` with its
//! licence, drawn by `ab_glyph`: no system font is needed).
//!
//! A figure is a type implementing [`Figure`]; [`encode`] draws it in a
//! [`Format`], chosen by the output file's extension with [`Format::of`].
//!
//! ```
//! use echoloc_lab::figure::{encode, Figure, Format, Root, FONT};
//! use plotters::prelude::*;
//!
//! struct Hello;
//! impl Figure for Hello {
//!     fn size(&self) -> (u32, u32) { (200, 100) }
//!     fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
//!         root.draw_text("Hello", &(FONT, 20).into_font().color(&BLACK), (10, 40)).map_err(|e| e.to_string())
//!     }
//! }
//! let png = encode(&Hello, Format::Png).unwrap();
//! assert_eq!(&png[1..4], b"PNG");
//! let svg = encode(&Hello, Format::Svg).unwrap();
//! assert!(String::from_utf8(svg).unwrap().contains("Hello"));
//! ```

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

/// The font family every figure uses.
pub const FONT: &str = "sans-serif";
/// DejaVu Sans 2.37 (Bitstream Vera licence: `lab/assets/DejaVuSans-LICENSE.txt`).
pub static DEJAVU_SANS: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// A drawing area of a figure.
pub type Root<DB> = DrawingArea<DB, Shift>;

/// An output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// RGB PNG.
    Png,
    /// SVG text.
    Svg,
}

impl Format {
    /// SVG for a path ending in `.svg` (any case), else PNG.
    pub fn of(path: &Path) -> Format {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("svg") => Format::Svg,
            _ => Format::Png,
        }
    }
}

/// Something to draw.
pub trait Figure {
    /// Width and height, pixels (SVG: user units).
    fn size(&self) -> (u32, u32);
    /// Draws onto `root`, already filled white.
    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String>;
}

fn fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in: it parses, or the build is broken.
        let _ = register_font(FONT, FontStyle::Normal, DEJAVU_SANS);
        let _ = register_font(FONT, FontStyle::Bold, DEJAVU_SANS);
    });
}

/// Draws `f` as `format`'s bytes.
pub fn encode<F: Figure>(f: &F, format: Format) -> Result<Vec<u8>, String> {
    fonts();
    let (w, h) = f.size();
    match format {
        Format::Png => {
            let mut buf = vec![255u8; w as usize * h as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
                root.fill(&WHITE).map_err(|e| e.to_string())?;
                f.draw(&root)?;
                root.present().map_err(|e| e.to_string())?;
            }
            png_rgb(w, h, &buf)
        }
        Format::Svg => {
            let mut s = String::new();
            {
                let root = SVGBackend::with_string(&mut s, (w, h)).into_drawing_area();
                root.fill(&WHITE).map_err(|e| e.to_string())?;
                f.draw(&root)?;
                root.present().map_err(|e| e.to_string())?;
            }
            Ok(s.into_bytes())
        }
    }
}

/// An RGB buffer as a PNG.
pub fn png_rgb(w: u32, h: u32, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Best);
    let mut wr = enc.write_header().map_err(|e| e.to_string())?;
    wr.write_image_data(rgb).map_err(|e| e.to_string())?;
    wr.finish().map_err(|e| e.to_string())?;
    Ok(out)
}

/// A plotters error as text.
pub fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// An `[r, g, b]` as a plotters colour.
pub fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// A legend of line swatches and labels in its own panel (so it never covers
/// data): one entry per row from the top, or in a row when `across`.
pub fn legend<DB: DrawingBackend>(area: &Root<DB>, items: &[(&str, RGBColor)], across: bool) -> Result<(), String> {
    let font = (FONT, 16).into_font().color(&BLACK);
    let (mut x, mut y) = (10i32, 14i32);
    for (label, c) in items {
        area.draw(&PathElement::new(vec![(x, y), (x + 28, y)], c.stroke_width(4))).map_err(err)?;
        area.draw_text(
            label,
            &font.clone().pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
            (x + 36, y),
        )
        .map_err(err)?;
        if across {
            let (w, _) = area.estimate_text_size(label, &font).map_err(err)?;
            x += 36 + w as i32 + 30;
        } else {
            y += 26;
        }
    }
    Ok(())
}

/// Viridis, by linear interpolation between five of its stops.
pub fn viridis(v: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] =
        [[68.0, 1.0, 84.0], [59.0, 82.0, 139.0], [33.0, 145.0, 140.0], [94.0, 201.0, 98.0], [253.0, 231.0, 37.0]];
    let v = v.clamp(0.0, 1.0) * 4.0;
    let i = (v.floor() as usize).min(3);
    let f = v - i as f64;
    core::array::from_fn(|c| (STOPS[i][c] + (STOPS[i + 1][c] - STOPS[i][c]) * f).round() as u8)
}

/// The next of 1, 2, 5 × 10ⁿ at or above `v`.
pub fn nice(v: f64) -> f64 {
    let e = 10f64.powf(v.log10().floor());
    [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * e).find(|&x| x >= v).unwrap_or(10.0 * e)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Text(&'static str);
    impl Figure for Text {
        fn size(&self) -> (u32, u32) {
            (120, 40)
        }
        fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
            root.draw_text(self.0, &(FONT, 24).into_font().color(&BLACK), (4, 8)).map_err(err)
        }
    }

    /// The shipped font draws: text makes dark pixels, and different text
    /// different pixels (no empty or placeholder glyphs).
    #[test]
    fn the_font_draws_glyphs() {
        let decode = |bytes: Vec<u8>| {
            let mut r = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
            let mut buf = vec![0; r.output_buffer_size()];
            r.next_frame(&mut buf).unwrap();
            buf
        };
        let a = decode(encode(&Text("κ θ 42"), Format::Png).unwrap());
        let b = decode(encode(&Text("x y 17"), Format::Png).unwrap());
        let dark = |v: &[u8]| v.iter().filter(|&&p| p < 100).count();
        assert!(dark(&a) > 50 && dark(&b) > 50, "{} {}", dark(&a), dark(&b));
        assert_ne!(a, b);
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(Format::of(Path::new("a/b.SVG")), Format::Svg);
        assert_eq!(Format::of(Path::new("a/b.png")), Format::Png);
    }
}

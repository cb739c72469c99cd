//! Figures of κ surfaces, drawn with `plotters` ([`crate::figure`]), like
//! the paper's Figs. 8–9: each surface in (R, θ) and in the sensor's (x, y)
//! frame with a colour bar, and κ against θ at a few ranges.

use plotters::prelude::*;

use crate::figure::{err, legend, rgb, viridis, Figure, Root, FONT};

/// A κ surface to draw: `None` outside the data (left white).
pub type Surface<'a> = &'a dyn Fn(f64, f64) -> Option<f64>;

const R_LO: f64 = 500.0;
const R_HI: f64 = 5500.0;
const T_HI: f64 = 45.0;
/// The sensor-frame panel's cell, m.
const CELL_M: f64 = 0.05;

/// One figure: the surface in (R, θ) on the left and in the sensor frame
/// (x lateral, y along the axis, θ ∈ [−45°, 45°]) on the right, a colour bar.
pub struct SurfaceFigure<'a> {
    title: String,
    kappa: Surface<'a>,
}

/// [`SurfaceFigure`] of `kappa`.
pub fn surface_figure<'a>(title: &str, kappa: Surface<'a>) -> SurfaceFigure<'a> {
    SurfaceFigure { title: title.to_string(), kappa }
}

/// A cell of the sensor-frame panel: corners (m) and κ.
pub type Cell = ((f64, f64), (f64, f64), f64);

/// The sensor-frame panel's cells: ((x0, y0), (x1, y1)) in metres and κ, for
/// every cell whose centre lies in the annular sector R_LO…R_HI, |θ| ≤ 45°.
pub fn sensor_cells(kappa: Surface<'_>) -> Vec<Cell> {
    let mut out = Vec::new();
    let nx = (R_HI / 1000.0 / CELL_M).ceil() as i64;
    let ny = (R_HI / 1000.0 / CELL_M).ceil() as i64;
    for i in -nx..nx {
        for j in 0..ny {
            let (x, y) = ((i as f64 + 0.5) * CELL_M, (j as f64 + 0.5) * CELL_M);
            let r = x.hypot(y) * 1000.0;
            let t = x.atan2(y).to_degrees();
            if (R_LO..=R_HI).contains(&r) && t.abs() <= T_HI {
                if let Some(k) = kappa(r, t.abs()) {
                    out.push((
                        (i as f64 * CELL_M, j as f64 * CELL_M),
                        ((i + 1) as f64 * CELL_M, (j + 1) as f64 * CELL_M),
                        k,
                    ));
                }
            }
        }
    }
    out
}

impl Figure for SurfaceFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (1340, 600)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let root = root.titled(&self.title, (FONT, 24)).map_err(err)?;
        let (left, rest) = root.split_horizontally(560);
        let (right, bar) = rest.split_horizontally(640);
        // (a) R across, θ up.
        let mut c = ChartBuilder::on(&left)
            .caption("(a) R–θ", (FONT, 18))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d(R_LO..R_HI, 0.0..T_HI)
            .map_err(err)?;
        c.configure_mesh()
            .disable_mesh()
            .x_labels(6)
            .y_labels(4)
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .x_desc("R (mm)")
            .y_desc("θ (°)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(err)?;
        let (dr, dt) = (50.0, 0.5);
        let mut cells = Vec::new();
        for i in 0..((R_HI - R_LO) / dr) as usize {
            for j in 0..(T_HI / dt) as usize {
                let (r, t) = (R_LO + i as f64 * dr, j as f64 * dt);
                if let Some(k) = (self.kappa)(r + dr / 2.0, t + dt / 2.0) {
                    cells.push(Rectangle::new([(r, t), (r + dr, t + dt)], rgb(viridis(k)).filled()));
                }
            }
        }
        c.draw_series(cells).map_err(err)?;
        // (b) The sensor frame, equal scale, the whole cone.
        let mut c = ChartBuilder::on(&right)
            .caption("(b) sensor frame", (FONT, 18))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(50)
            .build_cartesian_2d(-4.0..4.0, 0.0..5.6)
            .map_err(err)?;
        c.configure_mesh()
            .disable_mesh()
            .x_desc("x_s (m)")
            .y_desc("y_s (m)")
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(err)?;
        c.draw_series(
            sensor_cells(self.kappa).into_iter().map(|(a, b, k)| Rectangle::new([a, b], rgb(viridis(k)).filled())),
        )
        .map_err(err)?;
        // The colour bar.
        let mut c = ChartBuilder::on(&bar)
            .caption("κ", (FONT, 20))
            .margin_top(14)
            .margin_bottom(58)
            .margin_right(30)
            .y_label_area_size(48)
            .build_cartesian_2d(0.0..1.0, 0.0..1.0)
            .map_err(err)?;
        c.configure_mesh().disable_mesh().disable_x_axis().label_style((FONT, 15)).draw().map_err(err)?;
        c.draw_series((0..100).map(|k| {
            let v = f64::from(k) / 100.0;
            Rectangle::new([(0.0, v), (1.0, v + 0.01)], rgb(viridis(v + 0.005)).filled())
        }))
        .map_err(err)?;
        Ok(())
    }
}

/// A line series for [`profile_figure`].
pub struct Series<'a> {
    /// Legend text.
    pub label: &'a str,
    /// Colour.
    pub colour: [u8; 3],
    /// κ(R, θ).
    pub kappa: Surface<'a>,
    /// Dots at the grid angles instead of a line.
    pub dots: bool,
}

/// κ against θ at a few ranges, one panel per range.
pub struct ProfileFigure<'a> {
    title: String,
    ranges_mm: Vec<u32>,
    series: &'a [Series<'a>],
}

/// [`ProfileFigure`].
pub fn profile_figure<'a>(title: &str, ranges_mm: &[u32], series: &'a [Series<'a>]) -> ProfileFigure<'a> {
    ProfileFigure { title: title.to_string(), ranges_mm: ranges_mm.to_vec(), series }
}

impl Figure for ProfileFigure<'_> {
    fn size(&self) -> (u32, u32) {
        (60 + self.ranges_mm.len() as u32 * 430, 540)
    }

    fn draw<DB: DrawingBackend>(&self, root: &Root<DB>) -> Result<(), String> {
        let root = root.titled(&self.title, (FONT, 24)).map_err(err)?;
        let (panels, foot) = root.split_vertically(450);
        for (area, &r) in panels.split_evenly((1, self.ranges_mm.len().max(1))).iter().zip(&self.ranges_mm) {
            let mut c = ChartBuilder::on(area)
                .caption(format!("R = {r} mm"), (FONT, 18))
                .margin(14)
                .x_label_area_size(44)
                .y_label_area_size(52)
                .build_cartesian_2d(0.0..T_HI, 0.0..1.0)
                .map_err(err)?;
            c.configure_mesh()
                .light_line_style(WHITE)
                .bold_line_style(RGBColor(225, 225, 225))
                .x_labels(10)
                .x_label_formatter(&|v| format!("{v:.0}"))
                .x_desc("θ (°)")
                .y_desc("κ")
                .label_style((FONT, 15))
                .axis_desc_style((FONT, 16))
                .draw()
                .map_err(err)?;
            for s in self.series {
                let colour = rgb(s.colour);
                if s.dots {
                    let pts = (0..=18).filter_map(|k| {
                        let t = 2.5 * f64::from(k);
                        (s.kappa)(f64::from(r), t).map(|v| (t, v.clamp(0.0, 1.0)))
                    });
                    c.draw_series(pts.map(|p| Circle::new(p, 4, colour.filled()))).map_err(err)?;
                } else {
                    let pts = (0..=450).filter_map(|k| {
                        let t = 0.1 * f64::from(k);
                        (s.kappa)(f64::from(r), t).map(|v| (t, v.clamp(0.0, 1.0)))
                    });
                    c.draw_series(LineSeries::new(pts, colour.stroke_width(3))).map_err(err)?;
                }
            }
        }
        let items: Vec<(&str, RGBColor)> = self.series.iter().map(|s| (s.label, rgb(s.colour))).collect();
        legend(&foot.margin(20, 0, 70, 0), &items, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::figure::{encode, Format};

    #[test]
    fn the_sensor_frame_shows_the_whole_cone() {
        // A constant surface: the sensor-frame panel must cover the full
        // annular sector 0.5…5.5 m × ±45°, (π/4)·(5.5² − 0.5²) m², unclipped
        // by the panel's x range ±4 m and y range 0…5.6 m.
        let cells = sensor_cells(&|_, _| Some(0.5));
        let area: f64 = cells.iter().map(|(a, b, _)| (b.0 - a.0) * (b.1 - a.1)).sum();
        let sector = std::f64::consts::FRAC_PI_4 * (5.5f64.powi(2) - 0.5f64.powi(2));
        assert!((area / sector - 1.0).abs() < 0.01, "{area} m² against {sector}");
        let (xlo, xhi, yhi) =
            cells.iter().fold((0.0f64, 0.0f64, 0.0f64), |(l, h, y), (a, b, _)| (l.min(a.0), h.max(b.0), y.max(b.1)));
        assert!(xlo < -3.85 && xhi > 3.85 && xlo > -4.0 && xhi < 4.0 && yhi <= 5.55, "{xlo} {xhi} {yhi}");
        // And it draws, in both formats.
        let f = surface_figure("T", &|_, _| Some(0.5));
        assert!(encode(&f, Format::Png).unwrap().len() > 1000);
        let svg = String::from_utf8(encode(&f, Format::Svg).unwrap()).unwrap();
        assert!(svg.contains("sensor frame") && svg.contains("<rect"));
    }
}

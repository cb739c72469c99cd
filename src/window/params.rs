//! The sensor window's parameters and the pseudo-path layout, eq. (1)–(6) as
//! DESIGN §4.1 reads them.

/// Most pseudo-paths a window may have (the paper's Example 1 needs 175).
pub const MAX_PSEUDO_PATHS: usize = 256;
/// Largest `R_max`, mm (100 m): far beyond any sonar.
pub const MAX_RANGE_MM: u32 = 100_000;

/// Why window parameters were refused.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WindowError {
    /// `R_min ≥ R_max`, or `R_max` zero or above [`MAX_RANGE_MM`].
    BadRange,
    /// Half-angle `θ_o` not in `(0°, 90°)` (the window must be a convex wedge).
    BadHalfAngle,
    /// `δ_max` not in `[0°, 90°)`.
    BadDeltaMax,
    /// `d_s_min` is zero: no pseudo-path spacing can be derived.
    ZeroSurface,
    /// The layout needs more than [`MAX_PSEUDO_PATHS`] pseudo-paths.
    TooManyPseudoPaths(u32),
}

impl core::fmt::Display for WindowError {
    /// In words a person can act on.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BadRange => write!(
                f,
                "bad range: R_min must be below R_max, R_max within 1..={MAX_RANGE_MM} mm, and the window inside the map's coordinates"
            ),
            Self::BadHalfAngle => f.write_str("bad half-angle: θ_o must lie strictly between 0° and 90°"),
            Self::BadDeltaMax => f.write_str("bad δ_max: it must lie in [0°, 90°)"),
            Self::ZeroSurface => f.write_str("d_s_min is 0 mm: the pseudo-path spacing needs a smallest surface above 0"),
            Self::TooManyPseudoPaths(n) => write!(
                f,
                "the pseudo-path layout needs {n} paths, more than the {MAX_PSEUDO_PATHS} a window may have: \
                 raise d_s_min, lower R_max or θ_o, or use the exact strategy, which lays out no paths"
            ),
        }
    }
}

/// The pseudo-path layout of a window: eq. (2), (4), (5)–(6).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PathLayout {
    /// `N_pp`.
    pub n_pp: u32,
    /// `w`, mm.
    pub w_mm: f32,
    /// `w_min`, mm.
    pub w_min_mm: f32,
    /// `R_max tan θ_o`, mm.
    pub half_span_mm: f32,
    /// Whether the map is buffered (`t_b > 0`).
    pub buffered: bool,
}

impl PathLayout {
    /// The lateral coordinate of path `k`'s end point (`0 ≤ k < N_pp`), mm:
    /// unbuffered `R tan θ_o − k·w` (both cone edges included), buffered
    /// `R tan θ_o − (k+1)·w` (interior paths). Every end point lies at
    /// `y = R_max`.
    pub fn endpoint_x(&self, k: u32) -> f32 {
        // (Saturating is exact: `u32::MAX as f32` rounds to 2³² = `u32::MAX + 1`.)
        let n = if self.buffered { k.saturating_add(1) as f32 } else { k as f32 };
        self.half_span_mm - n * self.w_mm
    }
}

/// A sonar's window and the map's smallest detectable surface.
///
/// ```
/// use echoloc::window::WindowParams;
/// // The paper's Example 2: R_max 240 cm, θ_o 35°, d_s_min = t_b = 75 cm, δ_max 15°.
/// let p = WindowParams { r_min_mm: 0, r_max_mm: 2400, half_angle_deg: 35.0, delta_max_deg: 15.0, ds_min_mm: 750, tb_mm: 750 };
/// assert_eq!(p.n_pp().unwrap(), 4);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowParams {
    /// `R_min`: nearest range the sonar reports (blanking), mm.
    pub r_min_mm: u32,
    /// `R_max`: farthest range, mm.
    pub r_max_mm: u32,
    /// `θ_o`: the window's half-angle, degrees.
    pub half_angle_deg: f32,
    /// `δ_max`: largest cone arc deviation that still returns an echo, degrees.
    pub delta_max_deg: f32,
    /// `d_s_min`: smallest surface that must be detected, mm.
    pub ds_min_mm: u32,
    /// `t_b`: the C-space buffer of the map's pieces, mm (0: unbuffered).
    pub tb_mm: u32,
}

impl WindowParams {
    /// MARGE's sonar (paper §4.2): `R_min` 500 mm, `R_max` 5500 mm, `θ_o`
    /// 30°, with `δ_max` 15°, `d_s_min` and `t_b` both 300 mm.
    pub const MARGE: WindowParams = WindowParams {
        r_min_mm: 500,
        r_max_mm: 5500,
        half_angle_deg: 30.0,
        delta_max_deg: 15.0,
        ds_min_mm: 300,
        tb_mm: 300,
    };

    /// MARGE's window with `R_min` where a Polaroid 6500 ranging module
    /// starts to hear: its blanking, 2.38 ms, 408 mm at 20 °C (the modules
    /// of a Pioneer ring; the verdicts' `VerdictConfig::POLAROID` judges
    /// from the same range). The credence net's input domain starts at
    /// 500 mm: nearer ranges are rated as 500 mm, where an echo is weaker.
    pub const POLAROID_6500: WindowParams = WindowParams { r_min_mm: 408, ..WindowParams::MARGE };

    /// These parameters with the δ_max of the map whose localization
    /// field is `field`, when it has one: a building's faces echo within
    /// their own lobe (a painted wall is a mirror at 49 kHz, heard within
    /// about ±10° of its normal, DESIGN §4.9; `map import --walls lines`
    /// compiles real buildings with 8°), and the map says which.
    ///
    /// ```
    /// use echoloc::map::FieldView;
    /// use echoloc::window::WindowParams;
    /// // A map without a field keeps the window's own δ_max.
    /// let w = WindowParams::POLAROID_6500.with_map_lobe(&FieldView::EMPTY);
    /// assert_eq!(w.delta_max_deg, 15.0);
    /// ```
    pub fn with_map_lobe(self, field: &crate::map::FieldView<'_>) -> Self {
        match field.delta_max_deg() {
            Some(d) => WindowParams { delta_max_deg: d, ..self },
            None => self,
        }
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), WindowError> {
        if self.r_max_mm == 0 || self.r_max_mm > MAX_RANGE_MM || self.r_min_mm >= self.r_max_mm {
            return Err(WindowError::BadRange);
        }
        let h = self.half_angle_deg;
        if !(h > 0.0 && h < 90.0) {
            return Err(WindowError::BadHalfAngle);
        }
        let d = self.delta_max_deg;
        if !(0.0..90.0).contains(&d) {
            return Err(WindowError::BadDeltaMax);
        }
        if self.ds_min_mm == 0 {
            return Err(WindowError::ZeroSurface);
        }
        Ok(())
    }

    /// Eq. (1): `w_min = d_s_min · cos δ_max`, mm.
    pub fn w_min_mm(&self) -> f32 {
        self.ds_min_mm as f32 * crate::f32math::sin_cos(self.delta_max_deg.to_radians()).1
    }

    /// `I_b` of eq. (3): +1 unbuffered, −1 buffered.
    pub const fn i_b(&self) -> i32 {
        if self.tb_mm == 0 {
            1
        } else {
            -1
        }
    }

    fn span_mm(&self) -> f32 {
        // tan as sin/cos in f32 (libm's tanf works in f64, in software on an M4F).
        let (s, c) = crate::f32math::sin_cos(self.half_angle_deg.to_radians());
        2.0 * self.r_max_mm as f32 * (s / c)
    }

    /// The pseudo-path layout, computed once: eq. (2), (4) and what (5)–(6) need.
    pub fn layout(&self) -> Result<PathLayout, WindowError> {
        self.validate()?;
        let span = self.span_mm();
        let w_min = self.w_min_mm();
        let q = libm::ceilf(span / w_min) as i64;
        // A buffered window with ⌈…⌉ = 1 would get no path: keep one, the axis.
        let n = q.saturating_add(self.i_b() as i64).max(1);
        if n > MAX_PSEUDO_PATHS as i64 {
            return Err(WindowError::TooManyPseudoPaths(n.min(u32::MAX as i64) as u32));
        }
        let w = span / (n as i32 - self.i_b()).max(1) as f32;
        Ok(PathLayout { n_pp: n as u32, w_mm: w, w_min_mm: w_min, half_span_mm: span / 2.0, buffered: self.tb_mm > 0 })
    }

    /// Eq. (2): `N_pp = ⌈2 R_max tan θ_o / w_min⌉ + I_b`. When a buffered
    /// window would get no path at all (`⌈…⌉ = 1`), one path, the axis, is
    /// kept: a window must search somewhere (our erratum).
    pub fn n_pp(&self) -> Result<u32, WindowError> {
        Ok(self.layout()?.n_pp)
    }

    /// Eq. (4) without the misprinted ceiling: `w = 2 R_max tan θ_o / (N_pp − I_b)`, mm.
    pub fn w_mm(&self) -> Result<f32, WindowError> {
        Ok(self.layout()?.w_mm)
    }

    /// Eq. (5)–(6) as DESIGN reads them: the end point of pseudo-path `k`
    /// in the sensor frame (x lateral, y along the normal), mm; see
    /// [`PathLayout::endpoint_x`].
    pub fn endpoint(&self, k: u32) -> Result<(f32, f32), WindowError> {
        let l = self.layout()?;
        Ok((l.endpoint_x(k), self.r_max_mm as f32))
    }

    /// Whether the pseudo-path strategy is guaranteed to collect every piece
    /// whose true outline meets the window: every point of the window lies
    /// within `w` of some path (at the far end, between two paths or between
    /// the outermost path and the cone edge), so a buffer `t_b ≥ w` (plus
    /// 2 mm for rounding the window into integer millimetres) makes every such
    /// piece's buffered outline cross a path. Example 2 satisfies it
    /// (`t_b = d_s_min ≥ w_min ≥ w`).
    pub fn pseudo_paths_complete(&self) -> bool {
        match self.w_mm() {
            Ok(w) => self.tb_mm as f32 >= w + 2.0,
            Err(_) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example(ds: u32, tb: u32) -> WindowParams {
        WindowParams {
            r_min_mm: 0,
            r_max_mm: 2400,
            half_angle_deg: 35.0,
            delta_max_deg: 15.0,
            ds_min_mm: ds,
            tb_mm: tb,
        }
    }

    #[test]
    fn example_2_gives_four_pseudo_paths() {
        let p = example(750, 750);
        assert_eq!(p.n_pp().unwrap(), 4);
        let w = p.w_mm().unwrap();
        assert!((w - 3361.03 / 5.0).abs() < 0.1, "w = {w}");
        assert!(w <= p.w_min_mm());
        // Interior paths only, symmetric about the axis.
        let xs: [f32; 4] = core::array::from_fn(|k| p.endpoint(k as u32).unwrap().0);
        assert!((xs[0] + xs[3]).abs() < 0.01 && (xs[1] + xs[2]).abs() < 0.01);
        assert!((xs[0] - (1680.5 - w)).abs() < 0.2);
        assert!(p.pseudo_paths_complete(), "t_b = 750 ≥ w = {w}");
    }

    #[test]
    fn example_1_gives_175_by_eq_2_where_the_paper_prints_174() {
        // d_s_min 2 cm, t_b = 0: ⌈2·2400·tan 35° / (20·cos 15°)⌉ = ⌈173.98⌉ = 174,
        // plus I_b = +1. The paper's 174 leaves out I_b.
        let p = example(20, 0);
        let q = libm::ceilf(2.0 * 2400.0 * libm::tanf(35f32.to_radians()) / p.w_min_mm());
        assert_eq!(q, 174.0);
        assert_eq!(p.n_pp().unwrap(), 175);
        // Unbuffered: both cone edges are paths.
        let first = p.endpoint(0).unwrap().0;
        let last = p.endpoint(174).unwrap().0;
        assert!((first - 1680.5).abs() < 0.5 && (last + 1680.5).abs() < 0.5, "{first} {last}");
        assert!(!p.pseudo_paths_complete());
    }

    #[test]
    fn a_buffered_window_keeps_at_least_the_axis() {
        let p = WindowParams { ds_min_mm: 10_000, ..example(750, 750) };
        assert_eq!(p.n_pp().unwrap(), 1);
        assert!(p.endpoint(0).unwrap().0.abs() < 0.01);
    }

    #[test]
    fn bad_parameters_are_refused() {
        let ok = example(750, 750);
        assert_eq!(WindowParams { r_min_mm: 2400, ..ok }.validate(), Err(WindowError::BadRange));
        assert_eq!(WindowParams { half_angle_deg: 90.0, ..ok }.validate(), Err(WindowError::BadHalfAngle));
        assert_eq!(WindowParams { half_angle_deg: f32::NAN, ..ok }.validate(), Err(WindowError::BadHalfAngle));
        assert_eq!(WindowParams { delta_max_deg: -1.0, ..ok }.validate(), Err(WindowError::BadDeltaMax));
        assert_eq!(WindowParams { ds_min_mm: 0, ..ok }.validate(), Err(WindowError::ZeroSurface));
        assert!(matches!(
            WindowParams { ds_min_mm: 1, tb_mm: 0, ..ok }.n_pp(),
            Err(WindowError::TooManyPseudoPaths(_))
        ));
    }
}

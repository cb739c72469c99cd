//! The pose's Gaussian (x, y, φ and its covariance P) and the Kalman
//! filter's two steps on it: the odometry's propagation and one scalar
//! range correction, gated, Huber-weighted, in Joseph form.
//!
//! The tracker's [`super::Ekf`] wraps one with its counts, its lost
//! monitor, its recovery and its odometry calibration; each place the
//! localizer keeps as a hypothesis (`localize::place`) wraps one with its
//! evidence. One copy of the arithmetic, 48 bytes of state each.
//!
//! ```
//! use echoloc::referencing::gaussian::{Correction, PoseGaussian};
//! use echoloc::referencing::Motion;
//!
//! let mut g = PoseGaussian::new([0.0, 0.0, 0.0], [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.001]]);
//! g.propagate(&Motion { dx: 1.0, dy: 0.0, dphi: 0.0 }, [4e-4, 1e-4, 1e-4]).unwrap();
//! // A reading 2 cm longer than expected of a wall straight ahead (∂h/∂x = −1):
//! // the robot is 2 cm behind where it thought, less the prior's share.
//! let c = g.correct(0.02, [-1.0, 0.0, 0.0], 0.015 * 0.015, 6.63, f32::INFINITY);
//! assert!(matches!(c, Correction::Accepted { .. }));
//! assert!(g.x[0] < 1.0 && g.x[0] > 0.98);
//! ```

use super::model::{compose, wrap, Motion};

/// Why the filter (the tracker's EKF, or a place's) refused an input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EkfError {
    /// A non-finite or negative number where a finite one is needed.
    NotFinite,
    /// A position beyond ±[`MAX_POSITION_M`], where no map coordinate
    /// reaches: refused, the state left as it was.
    OutOfRange,
}

/// A 3×3 matrix, rows.
pub type M3 = [[f32; 3]; 3];

/// The largest position held, m: the map's coordinate range
/// (`geometry::COORD_MAX`, 2³⁰ − 1 mm ≈ 1 074 km) rounded down.
pub const MAX_POSITION_M: f32 = 1.0e6;

/// Every component finite and the position within ±[`MAX_POSITION_M`].
pub(crate) fn in_range(x: &[f32; 3]) -> bool {
    x.iter().all(|v| v.is_finite()) && x[0].abs() <= MAX_POSITION_M && x[1].abs() <= MAX_POSITION_M
}

fn mul(a: &M3, b: &M3) -> M3 {
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    r
}

fn mul_t(a: &M3, b: &M3) -> M3 {
    // a · bᵀ
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] = a[i][0] * b[j][0] + a[i][1] * b[j][1] + a[i][2] * b[j][2];
        }
    }
    r
}

/// The pose (x m, y m, φ rad) and its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseGaussian {
    /// The mean.
    pub x: [f32; 3],
    /// The covariance.
    pub p: M3,
}

/// What one correction did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Correction {
    /// Passed the gate; the state moved by `dx`.
    Accepted {
        /// Normalised innovation ν²/S.
        nis: f32,
        /// The state's change.
        dx: [f32; 3],
        /// `H P Hᵀ` before the correction ([`PoseGaussian::spread`]), so a
        /// caller can judge the reading at another variance.
        spread: f32,
    },
    /// The gate rejected it; nothing changed.
    Gated {
        /// Normalised innovation ν²/S.
        nis: f32,
    },
    /// Passed the gate, but the corrected state was out of range or not
    /// finite: refused, nothing changed.
    Refused {
        /// Normalised innovation ν²/S.
        nis: f32,
    },
    /// S was not a finite positive number: not tested.
    Unusable,
}

impl PoseGaussian {
    /// At `x` with covariance `p` (taken as given).
    pub const fn new(x: [f32; 3], p: M3) -> Self {
        Self { x, p }
    }

    /// `x ← x ⊕ u`, `P ← F P Fᵀ + G Q Gᵀ` with the motion noise `q`
    /// (forward m², sideways m², heading rad², in the robot's frame).
    /// Returns the column (∂x/∂φ, ∂y/∂φ) of F. Refused, nothing changed,
    /// when the new pose is out of range. P is not conditioned.
    pub fn propagate(&mut self, u: &Motion, q: [f32; 3]) -> Result<(f32, f32), EkfError> {
        let (next, f, g) = compose(&self.x, u);
        if !in_range(&next) {
            return Err(EkfError::OutOfRange);
        }
        // F = I but for column 2 (a, b): F P Fᵀ is a row and a column operation.
        let (a, b) = (f[0][2], f[1][2]);
        let p = &mut self.p;
        let r2 = p[2];
        for (j, v) in r2.iter().enumerate() {
            p[0][j] += a * v;
            p[1][j] += b * v;
        }
        for row in p.iter_mut() {
            row[0] += a * row[2];
            row[1] += b * row[2];
        }
        // G = rotation by φ (and 1): G Q Gᵀ for a diagonal Q.
        let (cs, sn) = (g[0][0], g[1][0]);
        let cross = cs * sn * (q[0] - q[1]);
        p[0][0] += cs * cs * q[0] + sn * sn * q[1];
        p[1][1] += sn * sn * q[0] + cs * cs * q[1];
        p[0][1] += cross;
        p[1][0] += cross;
        p[2][2] += q[2];
        self.x = next;
        Ok((a, b))
    }

    /// `H P Hᵀ` for the row `hj`: the prediction's own variance.
    pub fn spread(&self, hj: &[f32; 3]) -> f32 {
        let mut s = 0.0;
        for (i, row) in self.p.iter().enumerate() {
            s += hj[i] * (row[0] * hj[0] + row[1] * hj[1] + row[2] * hj[2]);
        }
        s
    }

    /// One scalar measurement: innovation `nu`, Jacobian row `hj`,
    /// variance `s2`. Gated at ν²/S > `gate`; past `robust_nis` (Huber's
    /// threshold) its variance grows until ν²/S is `robust_nis`, so one
    /// reading just inside the gate cannot pull the pose far. P is not
    /// conditioned.
    pub fn correct(&mut self, nu: f32, hj: [f32; 3], s2: f32, gate: f32, robust_nis: f32) -> Correction {
        // P Hᵀ and S = H P Hᵀ + R.
        let mut ph = [0.0f32; 3];
        for (i, row) in self.p.iter().enumerate() {
            ph[i] = row[0] * hj[0] + row[1] * hj[1] + row[2] * hj[2];
        }
        let spread = hj[0] * ph[0] + hj[1] * ph[1] + hj[2] * ph[2];
        let s = spread + s2;
        if !s.is_finite() || s <= 0.0 {
            return Correction::Unusable;
        }
        let nis = nu * nu / s;
        if nis.is_nan() || nis > gate {
            return Correction::Gated { nis };
        }
        let (s, s2) = if nis > robust_nis {
            let wide = nu * nu / robust_nis;
            (wide, s2 + (wide - s))
        } else {
            (s, s2)
        };
        let k = [ph[0] / s, ph[1] / s, ph[2] / s];
        // Joseph form: P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ.
        let mut ikh = [[0.0f32; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                ikh[i][j] = if i == j { 1.0 } else { 0.0 } - k[i] * hj[j];
            }
        }
        let a = mul_t(&mul(&ikh, &self.p), &ikh);
        let dx = [k[0] * nu, k[1] * nu, k[2] * nu];
        let mut next = self.x;
        for (xi, d) in next.iter_mut().zip(dx) {
            *xi += d;
        }
        next[2] = wrap(next[2]);
        if !in_range(&next) || !a.iter().flatten().all(|v| v.is_finite()) {
            // Overflow on absurd inputs: refuse the reading, keep the state.
            return Correction::Refused { nis };
        }
        for i in 0..3 {
            for j in 0..3 {
                self.p[i][j] = a[i][j] + k[i] * s2 * k[j];
            }
        }
        self.x = next;
        Correction::Accepted { nis, dx, spread }
    }

    /// Symmetric, the diagonal within `min_var..=max_var`, every
    /// correlation below 1, so P stays positive definite in `f32`.
    pub fn condition(&mut self, min_var: &[f32; 3], max_var: &[f32; 3]) {
        let p = &mut self.p;
        for i in 0..3 {
            let d = p[i][i];
            p[i][i] = if d.is_finite() { crate::f32math::clamp(d, min_var[i], max_var[i]) } else { max_var[i] };
        }
        for i in 0..3 {
            for j in (i + 1)..3 {
                let mut v = 0.5 * (p[i][j] + p[j][i]);
                if !v.is_finite() {
                    v = 0.0;
                }
                // |ρ| ≤ 0.999, compared in squares: the root only when clamping.
                let lim2 = 0.998 * p[i][i] * p[j][j];
                if v * v > lim2 {
                    v = if v < 0.0 { -crate::f32math::sqrt(lim2) } else { crate::f32math::sqrt(lim2) };
                }
                p[i][j] = v;
                p[j][i] = v;
            }
        }
        // Pairwise bounds do not make a 3×3 matrix definite: factor it as
        // L D Lᵀ and shrink the correlations until every pivot keeps a
        // margin of its variance (a determinant's sign is lost to rounding
        // when P is nearly singular; pivots with a margin are not).
        for _ in 0..8 {
            if pivots_ok(p) {
                return;
            }
            for (i, row) in p.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    if i != j {
                        *v *= 0.5;
                    }
                }
            }
        }
        for (i, row) in p.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                if i != j {
                    *v = 0.0;
                }
            }
        }
    }
}

/// Every pivot of P = L D Lᵀ at least 10⁻⁴ of its diagonal entry: P is
/// positive definite with room for `f32` rounding.
fn pivots_ok(p: &M3) -> bool {
    const MARGIN: f32 = 1e-4;
    let d0 = p[0][0];
    let (l10, l20) = (p[1][0] / d0, p[2][0] / d0);
    let d1 = p[1][1] - l10 * p[1][0];
    if d1.is_nan() || d1 <= MARGIN * p[1][1] {
        return false;
    }
    let l21 = (p[2][1] - l20 * p[1][0]) / d1;
    let d2 = p[2][2] - l20 * p[2][0] - l21 * l21 * d1;
    d0 > 0.0 && d2 > MARGIN * p[2][2]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn diag(v: [f32; 3]) -> M3 {
        [[v[0], 0.0, 0.0], [0.0, v[1], 0.0], [0.0, 0.0, v[2]]]
    }

    /// Facing +y, 1 m forward: x gains nothing, y 1 m; the forward noise
    /// lands on y's variance, the sideways on x's; the heading's variance
    /// spreads into x (∂x/∂φ = −1 m) — by hand.
    #[test]
    fn propagation_by_hand() {
        let half_pi = core::f32::consts::FRAC_PI_2;
        let mut g = PoseGaussian::new([0.0, 0.0, half_pi], diag([0.01, 0.02, 0.001]));
        let (a, b) = g.propagate(&Motion { dx: 1.0, dy: 0.0, dphi: 0.0 }, [4e-4, 1e-4, 2e-4]).unwrap();
        assert!((a + 1.0).abs() < 1e-6 && b.abs() < 1e-6, "{a} {b}");
        assert!(g.x[0].abs() < 1e-6 && (g.x[1] - 1.0).abs() < 1e-6);
        let p = g.p;
        // x: 0.01 + a²·0.001 + sideways 1e-4; y: 0.02 + forward 4e-4;
        // x–φ: a·0.001; φ: 0.001 + 2e-4.
        assert!((p[0][0] - (0.01 + 0.001 + 1e-4)).abs() < 1e-7, "{p:?}");
        assert!((p[1][1] - (0.02 + 4e-4)).abs() < 1e-7, "{p:?}");
        assert!((p[0][2] + 0.001).abs() < 1e-7 && (p[2][0] + 0.001).abs() < 1e-7, "{p:?}");
        assert!(p[0][1].abs() < 1e-7 && (p[2][2] - 0.0012).abs() < 1e-7, "{p:?}");
        // Out of range: refused, nothing changed.
        let before = g;
        assert_eq!(g.propagate(&Motion { dx: 2.0e6, dy: 0.0, dphi: 0.0 }, [0.0; 3]), Err(EkfError::OutOfRange));
        assert_eq!(g, before);
    }

    /// One reading of x alone (H = [1, 0, 0]): the scalar Kalman filter by
    /// hand, K = P/(P + R); the gate; Huber's weight beyond `robust_nis`.
    #[test]
    fn correction_by_hand() {
        let (px, r) = (0.04f32, 0.01f32);
        let mut g = PoseGaussian::new([1.0, 2.0, 0.0], diag([px, 0.09, 0.01]));
        let c = g.correct(0.1, [1.0, 0.0, 0.0], r, 6.63, f32::INFINITY);
        let k = px / (px + r);
        let Correction::Accepted { nis, dx, .. } = c else { panic!("{c:?}") };
        assert!((nis - 0.01 / 0.05).abs() < 1e-6);
        assert!((dx[0] - k * 0.1).abs() < 1e-7 && dx[1] == 0.0 && dx[2] == 0.0, "{dx:?}");
        assert!((g.x[0] - (1.0 + k * 0.1)).abs() < 1e-6 && g.x[1] == 2.0);
        assert!((g.p[0][0] - (1.0 - k) * px).abs() < 1e-7 && (g.p[1][1] - 0.09).abs() < 1e-9, "{:?}", g.p);
        // ν²/S = 0.25/0.018 ≈ 13.9 > 6.63: gated, nothing changed.
        let before = g;
        assert!(matches!(g.correct(0.5, [1.0, 0.0, 0.0], r, 6.63, f32::INFINITY), Correction::Gated { .. }));
        assert_eq!(g, before);
        // Huber at 1: ν = 0.3 with S = P + R = 0.05 is ν²/S = 1.8; the
        // variance grows until ν²/S = 1 (S' = 0.09), so the step is
        // P/S'·ν = 0.04/0.09·0.3, not 0.04/0.05·0.3.
        let mut h = PoseGaussian::new([0.0; 3], diag([px, 0.09, 0.01]));
        let Correction::Accepted { dx, .. } = h.correct(0.3, [1.0, 0.0, 0.0], r, 6.63, 1.0) else { panic!() };
        assert!((dx[0] - px / 0.09 * 0.3).abs() < 1e-6, "{dx:?}");
        // S not positive: unusable.
        assert_eq!(h.correct(0.1, [1.0, 0.0, 0.0], -1.0, 6.63, 1.0), Correction::Unusable);
    }

    /// Conditioning: a diagonal clamped to its bounds, a correlation of 1
    /// brought under it, symmetry restored.
    #[test]
    fn conditioning_keeps_p_definite() {
        let mut g = PoseGaussian::new([0.0; 3], [[1.0, 1.0, 0.0], [1.2, 1.0, 0.0], [0.0, 0.0, f32::NAN]]);
        g.condition(&[1e-6; 3], &[0.5, 10.0, 2.0]);
        let p = g.p;
        assert_eq!((p[0][0], p[1][1], p[2][2]), (0.5, 1.0, 2.0));
        assert_eq!(p[0][1], p[1][0]);
        assert!(p[0][1] * p[0][1] < p[0][0] * p[1][1], "{p:?}");
        assert!(pivots_ok(&p));
    }
}

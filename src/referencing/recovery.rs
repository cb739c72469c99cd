//! Recovery of a lost filter: the last readings, linearised about the
//! estimate and kept up to date as it moves, and a consensus search for the
//! pose correction most of them agree on.
//!
//! A Kalman filter that has accepted one wrong reading (in clutter, a person
//! walking into a beam near the predicted range) is confident in a wrong
//! pose and gates every right reading after it: it cannot recover by
//! itself, and the lost monitor only says so. Here each tested reading is
//! kept as its Jacobian `H` and residual `ν` against the current estimate
//! (both carried through odometry and every state change since), so that a
//! correction `δ` of the current pose predicts each reading's residual as
//! `ν − H δ`. The search counts, over a grid of corrections, how many
//! readings then agree within `k σ`; the best, refined by weighted least
//! squares on its inliers, is taken only when clearly more readings agree
//! with it than with the estimate (a consensus over several ring cycles, so
//! no single reading can move the pose).
//!
//! Fixed memory: [`RECENT`] readings of 20 bytes.
//!
//! ```
//! use echoloc::referencing::recovery::{Recent, RecoveryConfig};
//! let mut recent = Recent::new();
//! // Three walls (range falls as x grows, as y grows, and with a turn);
//! // the pose is 0.2 m short in x, so the first and third kinds of
//! // reading are off by H·δ and the second agrees with the estimate.
//! let walls = [[-1.0, 0.0, 0.3], [0.0, -1.0, 0.5], [0.7, -0.7, -1.0]];
//! for i in 0..12 {
//!     let h: [f32; 3] = walls[i % 3];
//!     recent.push(h, h[0] * 0.2, 0.02 * 0.02);
//! }
//! let found = recent.search(&RecoveryConfig::DEFAULT).unwrap();
//! assert!((found.dx[0] - 0.2).abs() < 1e-3 && found.dx[1].abs() < 1e-3 && found.dx[2].abs() < 1e-3);
//! assert_eq!((found.inliers, found.at_estimate), (12, 4));
//! ```

use crate::f32math::sqrt;

/// How many readings are kept.
pub const RECENT: usize = 64;

/// One reading, linearised about the current estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Residual {
    /// ∂range/∂(x, y, φ) for a correction of the *current* pose.
    h: [f32; 3],
    /// z − h(current estimate), m.
    nu: f32,
    /// The reading's variance, m².
    r: f32,
}

/// Search settings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecoveryConfig {
    /// Position corrections searched: ±this, m ...
    pub reach_m: f32,
    /// ... in steps of this, m.
    pub step_m: f32,
    /// Heading corrections searched: ±this, rad ...
    pub reach_rad: f32,
    /// ... in steps of this, rad.
    pub step_rad: f32,
    /// A reading agrees with a correction when its predicted residual is
    /// within this many standard deviations (its own, plus half a grid
    /// step in range, so that the grid cannot miss the right correction).
    pub k_sigma: f32,
    /// A correction is taken only when at least this many readings agree
    /// with it ...
    pub min_inliers: u16,
    /// ... and at least this many more than agree with the estimate ...
    pub margin: u16,
    /// ... and at least this many times as many ...
    pub ratio: f32,
    /// ... and they fix the position to this standard deviation, m ...
    pub max_sigma_m: f32,
    /// ... and the heading to this, rad (agreement alone is not enough:
    /// a few objects seen again and again agree among themselves).
    pub max_sigma_rad: f32,
}

impl RecoveryConfig {
    /// ±0.5 m in 5 cm steps, ±8° in 1° steps, 2.5 σ; taken with at least
    /// 8 readings agreeing, 6 more and twice as many as at the estimate.
    pub const DEFAULT: Self = Self {
        reach_m: 0.5,
        step_m: 0.05,
        reach_rad: 8.0 * core::f32::consts::PI / 180.0,
        step_rad: core::f32::consts::PI / 180.0,
        k_sigma: 2.5,
        min_inliers: 8,
        margin: 6,
        ratio: 2.0,
        max_sigma_m: 0.05,
        max_sigma_rad: core::f32::consts::PI / 180.0,
    };

    /// Never: no correction clears the bar.
    pub const OFF: Self = Self { min_inliers: u16::MAX, ..Self::DEFAULT };

    /// Steps each side of zero, position and heading (0 when a step is not
    /// positive and finite, or a reach is not).
    fn steps(&self) -> (i32, i32) {
        let n = |reach: f32, step: f32| {
            if reach.is_finite() && step.is_finite() && step > 0.0 && reach > 0.0 {
                // At most 100 steps each side: a bounded search (and a
                // negation that cannot overflow).
                i32::from(libm::floorf(reach / step).min(100.0) as u8)
            } else {
                0
            }
        };
        (n(self.reach_m, self.step_m), n(self.reach_rad, self.step_rad))
    }
}

/// The correction a search found.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Found {
    /// The correction of the current pose (x m, y m, φ rad).
    pub dx: [f32; 3],
    /// Readings that agree with it.
    pub inliers: u16,
    /// Readings that agree with the estimate as it is.
    pub at_estimate: u16,
    /// (Σ Hᵀ R⁻¹ H)⁻¹ over its inliers: how well they fix the pose.
    pub covariance: [[f32; 3]; 3],
}

/// What moved the estimate since the readings were last brought up to
/// date: odometry (the world displacement `o`) and state changes (their sum
/// `a`, and the heading changes weighted by the odometry displacement at
/// their time, `b`). Folding them into every reading at each change would
/// cost a pass over the buffer per reading; kept here, a change costs a few
/// operations and the pass happens once a cycle ([`Recent::rebase`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct Pending {
    o: [f32; 2],
    a: [f32; 3],
    b: [f32; 2],
}

/// The last [`RECENT`] readings, linearised about the current estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Recent {
    /// Each reading as of the last rebase.
    buf: [Residual; RECENT],
    len: u16,
    next: u16,
    pending: Pending,
}

impl Default for Recent {
    fn default() -> Self {
        Self::new()
    }
}

impl Recent {
    /// Empty.
    pub const fn new() -> Self {
        Self {
            buf: [Residual { h: [0.0; 3], nu: 0.0, r: 0.0 }; RECENT],
            len: 0,
            next: 0,
            pending: Pending { o: [0.0; 2], a: [0.0; 3], b: [0.0; 2] },
        }
    }

    /// How many readings are kept.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// Whether none are.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Forgets them all (a new pose was set).
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
        self.pending = Pending::default();
    }

    /// A reading with Jacobian `h`, residual `nu` (m) and variance `r`
    /// (m²) at the current estimate; the oldest goes when full. Non-finite
    /// or non-positive variances are not kept.
    pub fn push(&mut self, h: [f32; 3], nu: f32, r: f32) {
        if !(h.iter().all(|v| v.is_finite()) && nu.is_finite() && r.is_finite() && r > 0.0) {
            return;
        }
        // Stored as of the last rebase: the inverse of `current`.
        let q = &self.pending;
        let h2 = h[2] - h[0] * q.o[1] + h[1] * q.o[0];
        let nu = nu + h[0] * (q.a[0] + q.b[1]) + h[1] * (q.a[1] - q.b[0]) + h2 * q.a[2];
        if let Some(slot) = self.buf.get_mut(usize::from(self.next)) {
            *slot = Residual { h: [h[0], h[1], h2], nu, r };
        }
        self.next = if usize::from(self.next) + 1 >= RECENT { 0 } else { self.next + 1 };
        if usize::from(self.len) < RECENT {
            self.len += 1;
        }
    }

    fn kept(&self) -> &[Residual] {
        self.buf.get(..usize::from(self.len)).unwrap_or(&[])
    }

    /// The estimate moved by odometry whose Jacobian has column 2 `(a, b)`
    /// (∂(x', y')/∂φ, so the world displacement is `(b, −a)`): a correction
    /// of the new pose is a correction of the old one rotated about the new
    /// position, so each Jacobian is carried as `H F⁻¹`,
    /// `F⁻¹ = I − (a, b, 0) e₂ᵀ`. The motion's own noise is left out: over
    /// the few cycles kept it is small against a reading's.
    pub fn carry(&mut self, a: f32, b: f32) {
        self.pending.o[0] += b;
        self.pending.o[1] -= a;
    }

    /// The estimate moved by `dx` (an update or a recovery): every residual
    /// follows, `ν ← ν − H dx` with `H` as of now.
    pub fn shift(&mut self, dx: [f32; 3]) {
        let q = &mut self.pending;
        for (ai, d) in q.a.iter_mut().zip(dx) {
            *ai += d;
        }
        q.b[0] += dx[2] * q.o[0];
        q.b[1] += dx[2] * q.o[1];
    }

    /// Brings every reading up to date and clears what is pending (once a
    /// cycle, so that the pending sums stay small in `f32`).
    pub fn rebase(&mut self) {
        let n = usize::from(self.len);
        let q = self.pending;
        for e in self.buf.iter_mut().take(n) {
            let (h, nu) = current(&q, e);
            e.h = h;
            e.nu = nu;
        }
        self.pending = Pending::default();
    }

    /// How many readings agree with the correction `dx` within `k σ`.
    pub fn agreeing(&self, dx: [f32; 3], cfg: &RecoveryConfig) -> u16 {
        let k2 = cfg.k_sigma * cfg.k_sigma;
        let mut n = 0u16;
        for e in self.kept() {
            let (h, nu) = current(&self.pending, e);
            let res = nu - (h[0] * dx[0] + h[1] * dx[1] + h[2] * dx[2]);
            if res * res <= k2 * e.r {
                n = n.saturating_add(1);
            }
        }
        n
    }

    /// Squared tolerances for the grid: `k σ` widened by half a grid
    /// step's effect on each reading's range, so that the grid point
    /// nearest the right correction cannot miss its readings.
    fn grid_tolerances(&self, cfg: &RecoveryConfig) -> [f32; RECENT] {
        let mut t = [0.0f32; RECENT];
        for (e, ti) in self.kept().iter().zip(t.iter_mut()) {
            let abs = |v: f32| libm::fabsf(v);
            let half_step = 0.5 * (cfg.step_m * (abs(e.h[0]) + abs(e.h[1])) + cfg.step_rad * abs(e.h[2]));
            let tol = cfg.k_sigma * sqrt(e.r) + half_step;
            *ti = tol * tol;
        }
        t
    }

    /// The correction most readings agree with, refined by weighted least
    /// squares on its inliers, if it clears the config's bars; `None`
    /// otherwise (and when the inliers do not fix all three coordinates).
    /// Costs one pass over the readings per grid point: (2·reach/step + 1)²
    /// positions times (2·reach/step + 1) headings, 7 497 by default.
    /// Brings the readings up to date first ([`Recent::rebase`]).
    #[inline(never)]
    pub fn search(&mut self, cfg: &RecoveryConfig) -> Option<Found> {
        self.rebase();
        let (np, nh) = cfg.steps();
        let usable = cfg.k_sigma.is_finite() && cfg.k_sigma > 0.0;
        if self.len == 0 || usize::from(cfg.min_inliers) > self.len() || !usable {
            return None;
        }
        let wide = self.grid_tolerances(cfg);
        let at_estimate = self.agreeing([0.0; 3], cfg);
        // The grid point most readings agree with; on a tie, the smallest.
        let mut best = (0u16, [0.0f32; 3]);
        let mut base = [0.0f32; RECENT];
        for ih in -nh..=nh {
            let dphi = ih as f32 * cfg.step_rad;
            for ix in -np..=np {
                let x = ix as f32 * cfg.step_m;
                for (e, b) in self.kept().iter().zip(base.iter_mut()) {
                    *b = e.nu - e.h[2] * dphi - e.h[0] * x;
                }
                for iy in -np..=np {
                    let y = iy as f32 * cfg.step_m;
                    let mut n = 0u16;
                    for ((e, b), t) in self.kept().iter().zip(&base).zip(&wide) {
                        let res = b - e.h[1] * y;
                        if res * res <= *t {
                            n = n.saturating_add(1);
                        }
                    }
                    let dx = [x, y, dphi];
                    if n > best.0 || (n == best.0 && norm(dx, cfg) < norm(best.1, cfg)) {
                        best = (n, dx);
                    }
                }
            }
        }
        // Weighted least squares on that grid point's readings, then once
        // more on the readings that agree with the result within k σ
        // (the grid's widened tolerance lets in readings that bias it).
        let (cov, dx) = self.least_squares(best.1, &wide)?;
        let k2 = cfg.k_sigma * cfg.k_sigma;
        let mut exact = [0.0f32; RECENT];
        for (t, e) in exact.iter_mut().zip(self.kept()) {
            *t = k2 * e.r;
        }
        let (cov, dx) = self.least_squares(dx, &exact).unwrap_or((cov, dx));
        let inliers = self.agreeing(dx, cfg);
        let enough = inliers >= cfg.min_inliers
            && inliers >= at_estimate.saturating_add(cfg.margin)
            && inliers as f32 >= cfg.ratio * at_estimate as f32;
        let fixed = cov[0][0] <= cfg.max_sigma_m * cfg.max_sigma_m
            && cov[1][1] <= cfg.max_sigma_m * cfg.max_sigma_m
            && cov[2][2] <= cfg.max_sigma_rad * cfg.max_sigma_rad;
        let inside = libm::fabsf(dx[0]) <= cfg.reach_m + cfg.step_m
            && libm::fabsf(dx[1]) <= cfg.reach_m + cfg.step_m
            && libm::fabsf(dx[2]) <= cfg.reach_rad + cfg.step_rad;
        (enough && fixed && inside && dx.iter().all(|v| v.is_finite())).then_some(Found {
            dx,
            inliers,
            at_estimate,
            covariance: cov,
        })
    }

    /// The weighted least-squares correction from the readings whose
    /// residual at `at` is within `tol2`, and its covariance
    /// (Σ Hᵀ R⁻¹ H)⁻¹; `None` when they do not fix all three coordinates.
    fn least_squares(&self, at: [f32; 3], tol2: &[f32; RECENT]) -> Option<([[f32; 3]; 3], [f32; 3])> {
        let (mut a, mut b) = ([[0.0f32; 3]; 3], [0.0f32; 3]);
        for (e, t) in self.kept().iter().zip(tol2) {
            let res = e.nu - (e.h[0] * at[0] + e.h[1] * at[1] + e.h[2] * at[2]);
            if res * res > *t {
                continue;
            }
            for ((row, bi), hi) in a.iter_mut().zip(b.iter_mut()).zip(e.h) {
                for (v, hj) in row.iter_mut().zip(e.h) {
                    *v += hi * hj / e.r;
                }
                *bi += hi * e.nu / e.r;
            }
        }
        let cov = inverse(&a)?;
        let mut dx = [0.0f32; 3];
        for (i, row) in cov.iter().enumerate() {
            dx[i] = row[0] * b[0] + row[1] * b[1] + row[2] * b[2];
        }
        Some((cov, dx))
    }
}

/// A reading as of now: its Jacobian carried through the odometry since
/// the rebase, its residual moved by every state change since.
fn current(q: &Pending, e: &Residual) -> ([f32; 3], f32) {
    let h2 = e.h[2] + e.h[0] * q.o[1] - e.h[1] * q.o[0];
    let nu = e.nu - e.h[0] * (q.a[0] + q.b[1]) - e.h[1] * (q.a[1] - q.b[0]) - e.h[2] * q.a[2];
    ([e.h[0], e.h[1], h2], nu)
}

/// Size of a correction, heading weighted by the grid's steps.
fn norm(dx: [f32; 3], cfg: &RecoveryConfig) -> f32 {
    let h = if cfg.step_rad > 0.0 { dx[2] * cfg.step_m / cfg.step_rad } else { 0.0 };
    dx[0] * dx[0] + dx[1] * dx[1] + h * h
}

/// The inverse of a symmetric 3×3 matrix, if it is well conditioned.
fn inverse(a: &[[f32; 3]; 3]) -> Option<[[f32; 3]; 3]> {
    let c00 = a[1][1] * a[2][2] - a[1][2] * a[2][1];
    let c01 = a[1][2] * a[2][0] - a[1][0] * a[2][2];
    let c02 = a[1][0] * a[2][1] - a[1][1] * a[2][0];
    let det = a[0][0] * c00 + a[0][1] * c01 + a[0][2] * c02;
    let scale = a[0][0] * a[1][1] * a[2][2];
    if !(det.is_finite() && scale.is_finite() && scale > 0.0 && det > 1e-6 * scale) {
        return None;
    }
    let inv = 1.0 / det;
    let r = [
        [c00 * inv, (a[0][2] * a[2][1] - a[0][1] * a[2][2]) * inv, (a[0][1] * a[1][2] - a[0][2] * a[1][1]) * inv],
        [c01 * inv, (a[0][0] * a[2][2] - a[0][2] * a[2][0]) * inv, (a[0][2] * a[1][0] - a[0][0] * a[1][2]) * inv],
        [c02 * inv, (a[0][1] * a[2][0] - a[0][0] * a[2][1]) * inv, (a[0][0] * a[1][1] - a[0][1] * a[1][0]) * inv],
    ];
    r.iter().flatten().all(|v| v.is_finite()).then_some(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pending sums against the definition applied eagerly: each carry
    /// `h₂ −= a h₀ + b h₁` on every reading, each shift `ν −= H dx`, over
    /// random sequences of pushes, odometry, moves and rebases.
    #[test]
    fn pending_moves_equal_the_eager_definition() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move |lo: f32, hi: f32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            lo + (hi - lo) * ((seed >> 40) as f32 / (1u64 << 24) as f32)
        };
        for _ in 0..200 {
            let mut lazy = Recent::new();
            // The eager reference: (h, ν) of the kept readings, oldest first.
            let mut eager: [([f32; 3], f32); RECENT] = [([0.0; 3], 0.0); RECENT];
            let (mut len, mut next) = (0usize, 0usize);
            for _ in 0..150 {
                let op = rnd(0.0, 1.0);
                if op < 0.4 {
                    let h = [rnd(-1.0, 1.0), rnd(-1.0, 1.0), rnd(-3.0, 3.0)];
                    let nu = rnd(-0.5, 0.5);
                    lazy.push(h, nu, 1e-4);
                    eager[next] = (h, nu);
                    next = (next + 1) % RECENT;
                    len = (len + 1).min(RECENT);
                } else if op < 0.7 {
                    let (a, b) = (rnd(-0.2, 0.2), rnd(-0.2, 0.2));
                    lazy.carry(a, b);
                    for e in eager.iter_mut().take(len) {
                        e.0[2] -= a * e.0[0] + b * e.0[1];
                    }
                } else if op < 0.95 {
                    let dx = [rnd(-0.1, 0.1), rnd(-0.1, 0.1), rnd(-0.05, 0.05)];
                    lazy.shift(dx);
                    for e in eager.iter_mut().take(len) {
                        e.1 -= e.0[0] * dx[0] + e.0[1] * dx[1] + e.0[2] * dx[2];
                    }
                } else {
                    lazy.rebase();
                }
                assert_eq!(lazy.len(), len);
                for (e, want) in lazy.kept().iter().zip(eager.iter()) {
                    let (h, nu) = current(&lazy.pending, e);
                    for i in 0..3 {
                        assert!((h[i] - want.0[i]).abs() < 2e-4, "h {h:?} vs {:?}", want.0);
                    }
                    assert!((nu - want.1).abs() < 2e-4, "ν {nu} vs {}", want.1);
                }
            }
        }
    }
}

//! The baseline: the single-lobe Gaussian credence model the paper compares
//! its net with (§1, §4: "the Gaussian curve that is commonly used to model
//! pressure amplitude", Kuc 1990), fitted to the same data by the same
//! optimiser, so the comparison is of the models and not of the fitting.
//!
//! ```text
//! κ_G(R, θ) = A(R) · exp(−θ² / (2·s(R)²)),   A = σ(p₀ + p₁·x₀),   s = exp(p₂ + p₃·x₀) degrees
//! ```
//!
//! with `x₀` the net's range input. The range terms give the baseline every
//! chance: its height and width may both change with range; what it cannot
//! have is more than one lobe.

use super::train::{inputs, keep_best, sigmoid, Model, Rprop, Sample};

/// The four parameters `p₀ … p₃`.
#[derive(Clone, Debug, PartialEq)]
pub struct Gaussian {
    /// `[p₀, p₁, p₂, p₃]`.
    pub p: [f64; 4],
}

impl Model for Gaussian {
    fn eval(&self, r_mm: f64, theta_deg: f64) -> f64 {
        let (x0, _) = inputs(r_mm, theta_deg);
        let t = theta_deg.abs().min(45.0);
        let a = sigmoid(self.p[0] + self.p[1] * x0);
        let s = libm::exp(self.p[2] + self.p[3] * x0);
        a * libm::exp(-t * t / (2.0 * s * s))
    }
}

impl Gaussian {
    /// Height at range 3 m, and width (σ, degrees) at 3 m.
    pub fn describe(&self) -> (f64, f64) {
        (sigmoid(self.p[0]), libm::exp(self.p[2]))
    }

    fn loss_grad(&self, samples: &[Sample], total: f64, g: &mut [f64; 4]) -> f64 {
        g.fill(0.0);
        let mut loss = 0.0;
        for s in samples {
            let (x0, _) = inputs(f64::from(s.r_mm), s.theta_deg);
            let t = s.theta_deg.abs().min(45.0);
            let a = sigmoid(self.p[0] + self.p[1] * x0);
            let sd = libm::exp(self.p[2] + self.p[3] * x0);
            let q = t * t / (sd * sd);
            let gauss = libm::exp(-q / 2.0);
            let y = a * gauss;
            let w = s.readings / total;
            let e = y - s.kappa;
            loss += w * e * e;
            let dy = 2.0 * w * e;
            let da = dy * a * (1.0 - a) * gauss;
            let ds = dy * y * q; // ∂y/∂(ln s) = y·θ²/s²
            g[0] += da;
            g[1] += da * x0;
            g[2] += ds;
            g[3] += ds * x0;
        }
        loss
    }
}

/// Fits the baseline to `samples` from three starting widths (5°, 10°, 20°),
/// keeping the best: deterministic, no seed needed.
pub fn fit(samples: &[Sample], epochs: u32) -> (Gaussian, f64) {
    let total: f64 = samples.iter().map(|s| s.readings).sum::<f64>().max(1.0);
    let mut best: Option<(Gaussian, f64)> = None;
    for width in [5.0f64, 10.0, 20.0] {
        let mut m = Gaussian { p: [2.0, 0.0, width.ln(), 0.0] };
        let loss = Rprop::descend(&mut m.p, epochs, |p, g| Gaussian { p: *p }.loss_grad(samples, total, g), |_, _| {});
        keep_best(&mut best, m, loss);
    }
    best.expect("three starts")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::credence::train::rmse;

    #[test]
    fn recovers_a_gaussian() {
        let truth = Gaussian { p: [1.5, -0.5, 9f64.ln(), 0.2] };
        let samples: Vec<Sample> = (0..=20)
            .flat_map(|i| (0..=18).map(move |k| (500 + 250 * i, 2.5 * f64::from(k))))
            .map(|(r, t)| Sample { r_mm: r, theta_deg: t, kappa: truth.eval(f64::from(r), t), readings: 100.0 })
            .collect();
        let (fit, _) = fit(&samples, 2000);
        assert!(rmse(&fit, &samples) < 1e-3, "{:?}", fit);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let m = Gaussian { p: [0.3, -0.7, 2.1, 0.4] };
        let samples = [
            Sample { r_mm: 800, theta_deg: 7.5, kappa: 0.4, readings: 100.0 },
            Sample { r_mm: 4200, theta_deg: 15.0, kappa: 0.1, readings: 50.0 },
        ];
        let mut g = [0.0; 4];
        m.loss_grad(&samples, 150.0, &mut g);
        for (i, gi) in g.iter().enumerate() {
            let h = 1e-6;
            let (mut a, mut b) = (m.clone(), m.clone());
            a.p[i] += h;
            b.p[i] -= h;
            let mut t = [0.0; 4];
            let num = (a.loss_grad(&samples, 150.0, &mut t) - b.loss_grad(&samples, 150.0, &mut t)) / (2.0 * h);
            assert!((num - gi).abs() < 1e-7, "{i}: {num} vs {gi}");
        }
    }
}

//! The 2-10-1 credence net in `f64`, trained by full-batch iRprop⁻
//! (Igel & Hüsken, "Improving the Rprop learning algorithm", 2000; a variant
//! of Riedmiller & Braun's RPROP, 1993): every weight has its own adaptive
//! step, the paper's "adaptive learning rates" (§4.1).
//!
//! The loss is the readings-weighted mean squared error between the net and
//! each node's κ = correct / readings. Over several days it equals (up to a
//! constant) the loss against the pooled κ of each node, so training pools
//! the days first: the same optimum at a fraction of the cost.

use echoloc::credence::net::{FloatWeights, HIDDEN, R_CENTRE_MM, R_SCALE_LOG2, THETA_CENTRE_MDEG, THETA_SCALE_LOG2};

use super::rng::Rng;
use super::synth::Node;

/// Parameters of the 2-10-1 net: 3 per hidden unit, 10 output weights, 1 bias.
pub const PARAMS: usize = 4 * HIDDEN + 1;

/// iRprop⁻ constants (Igel & Hüsken 2000, Table 1: η⁺ 1.2, η⁻ 0.5, Δ₀ 0.0125,
/// Δ_max 50; Δ_min ours, small enough never to bind).
const ETA_PLUS: f64 = 1.2;
const ETA_MINUS: f64 = 0.5;
const STEP_INIT: f64 = 0.0125;
const STEP_MAX: f64 = 50.0;
const STEP_MIN: f64 = 1e-9;

/// One training example: a grid node with its pooled κ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Range, mm.
    pub r_mm: u32,
    /// |θ|, degrees.
    pub theta_deg: f64,
    /// Observed κ.
    pub kappa: f64,
    /// Readings behind it.
    pub readings: f64,
}

/// The net's inputs for (R, θ): exactly the firmware's normalisation.
pub fn inputs(r_mm: f64, theta_deg: f64) -> (f64, f64) {
    let r = r_mm.clamp(500.0, 5500.0);
    let t = (theta_deg.abs() * 1000.0).min(45_000.0);
    (
        (r - f64::from(R_CENTRE_MM)) / f64::from(1u32 << R_SCALE_LOG2),
        (t - f64::from(THETA_CENTRE_MDEG)) / f64::from(1u32 << THETA_SCALE_LOG2),
    )
}

/// Pools nodes of several days: κ = Σ correct / Σ readings per (R, |θ|).
pub fn pool<'a>(days: impl IntoIterator<Item = &'a [Node]>) -> Vec<Sample> {
    let mut acc: std::collections::BTreeMap<(u32, u64), (f64, f64)> = Default::default();
    for nodes in days {
        for n in nodes {
            let e = acc.entry((n.r_mm, n.theta_deg.abs().to_bits())).or_default();
            e.0 += f64::from(n.correct);
            e.1 += f64::from(n.readings);
        }
    }
    acc.into_iter()
        .map(|((r_mm, t), (c, n))| Sample { r_mm, theta_deg: f64::from_bits(t), kappa: c / n, readings: n })
        .collect()
}

/// Logistic σ, with `libm` so that training is the same on every platform.
pub fn sigmoid(z: f64) -> f64 {
    1.0 / (1.0 + libm::exp(-z))
}

/// A model of κ over (R, θ) on the host.
pub trait Model {
    /// κ at range `r_mm`, angle `theta_deg`.
    fn eval(&self, r_mm: f64, theta_deg: f64) -> f64;
}

/// Root mean squared error over nodes (each node counts once).
pub fn rmse(model: &dyn Model, samples: &[Sample]) -> f64 {
    let s: f64 = samples.iter().map(|s| (model.eval(f64::from(s.r_mm), s.theta_deg) - s.kappa).powi(2)).sum();
    (s / samples.len().max(1) as f64).sqrt()
}

/// The float 2-10-1 net. Layout of `p`: `[wⱼ₀, wⱼ₁, bⱼ]` for each hidden unit
/// `j`, then the output weights `vⱼ`, then the output bias.
#[derive(Clone, Debug, PartialEq)]
pub struct Net {
    /// The parameters.
    pub p: [f64; PARAMS],
}

impl Net {
    /// Random initial weights for one restart.
    pub fn random(rng: &mut Rng) -> Self {
        let mut p = [0.0; PARAMS];
        for j in 0..HIDDEN {
            p[3 * j] = rng.uniform(-2.0, 2.0);
            p[3 * j + 1] = rng.uniform(-4.0, 4.0);
            p[3 * j + 2] = rng.uniform(-2.0, 2.0);
            p[3 * HIDDEN + j] = rng.uniform(-1.0, 1.0);
        }
        Self { p }
    }

    /// As the firmware's float weights.
    pub fn to_weights(&self) -> FloatWeights {
        let p = &self.p;
        FloatWeights {
            w_hidden: core::array::from_fn(|j| [p[3 * j], p[3 * j + 1]]),
            b_hidden: core::array::from_fn(|j| p[3 * j + 2]),
            w_out: core::array::from_fn(|j| p[3 * HIDDEN + j]),
            b_out: p[4 * HIDDEN],
        }
    }

    /// Loss (weighted MSE) and its gradient over `samples`.
    fn loss_grad(&self, xs: &[(f64, f64, f64, f64)], grad: &mut [f64; PARAMS]) -> f64 {
        let p = &self.p;
        grad.fill(0.0);
        let mut loss = 0.0;
        let mut h = [0.0; HIDDEN];
        for &(x0, x1, k, w) in xs {
            let mut zo = p[4 * HIDDEN];
            for j in 0..HIDDEN {
                h[j] = sigmoid(p[3 * j] * x0 + p[3 * j + 1] * x1 + p[3 * j + 2]);
                zo += p[3 * HIDDEN + j] * h[j];
            }
            let y = sigmoid(zo);
            let e = y - k;
            loss += w * e * e;
            let dzo = 2.0 * w * e * y * (1.0 - y);
            grad[4 * HIDDEN] += dzo;
            for j in 0..HIDDEN {
                grad[3 * HIDDEN + j] += dzo * h[j];
                let dz = dzo * p[3 * HIDDEN + j] * h[j] * (1.0 - h[j]);
                grad[3 * j] += dz * x0;
                grad[3 * j + 1] += dz * x1;
                grad[3 * j + 2] += dz;
            }
        }
        loss
    }
}

impl Model for Net {
    fn eval(&self, r_mm: f64, theta_deg: f64) -> f64 {
        forward(&self.to_weights(), r_mm, theta_deg)
    }
}

/// The float forward pass of the firmware's net over its [`FloatWeights`].
pub fn forward(w: &FloatWeights, r_mm: f64, theta_deg: f64) -> f64 {
    let (x0, x1) = inputs(r_mm, theta_deg);
    let mut z = w.b_out;
    for j in 0..HIDDEN {
        z += w.w_out[j] * sigmoid(w.w_hidden[j][0] * x0 + w.w_hidden[j][1] * x1 + w.b_hidden[j]);
    }
    sigmoid(z)
}

/// iRprop⁻ state for `n` parameters.
pub struct Rprop<const N: usize> {
    step: [f64; N],
    prev: [f64; N],
}

impl<const N: usize> Default for Rprop<N> {
    fn default() -> Self {
        Self { step: [STEP_INIT; N], prev: [0.0; N] }
    }
}

impl<const N: usize> Rprop<N> {
    /// One update of `p` against gradient `g`.
    pub fn update(&mut self, p: &mut [f64; N], g: &[f64; N]) {
        for i in 0..N {
            let mut gi = g[i];
            let s = self.prev[i] * gi;
            if s > 0.0 {
                self.step[i] = (self.step[i] * ETA_PLUS).min(STEP_MAX);
            } else if s < 0.0 {
                self.step[i] = (self.step[i] * ETA_MINUS).max(STEP_MIN);
                gi = 0.0;
            }
            if gi > 0.0 {
                p[i] -= self.step[i];
            } else if gi < 0.0 {
                p[i] += self.step[i];
            }
            self.prev[i] = gi;
        }
    }
}

impl<const N: usize> Rprop<N> {
    /// Runs `epochs` updates of `p` with a fresh optimiser: `loss_grad(p, g)`
    /// returns the loss at `p` and fills its gradient; `on_epoch(epoch, loss)`
    /// hears each epoch's loss. Returns the loss of the final parameters.
    pub fn descend(
        p: &mut [f64; N],
        epochs: u32,
        mut loss_grad: impl FnMut(&[f64; N], &mut [f64; N]) -> f64,
        mut on_epoch: impl FnMut(u32, f64),
    ) -> f64 {
        let mut opt = Self::default();
        let mut g = [0.0; N];
        let mut loss = loss_grad(p, &mut g);
        for epoch in 0..epochs {
            opt.update(p, &g);
            loss = loss_grad(p, &mut g);
            on_epoch(epoch, loss);
        }
        loss
    }
}

/// Keeps `(m, loss)` when it is the first or strictly better than the best so far.
pub fn keep_best<M>(best: &mut Option<(M, f64)>, m: M, loss: f64) {
    if best.as_ref().is_none_or(|(_, b)| loss < *b) {
        *best = Some((m, loss));
    }
}

/// What training reports as it goes: (restart, epoch, loss).
pub type Progress<'a> = &'a mut dyn FnMut(u32, u32, f64);

/// Trains the net on `samples`: `restarts` random starts of `epochs` each,
/// keeping the one with the lowest loss. Deterministic for `seed`.
pub fn train(samples: &[Sample], seed: u64, epochs: u32, restarts: u32, progress: Progress<'_>) -> (Net, f64) {
    let total: f64 = samples.iter().map(|s| s.readings).sum::<f64>().max(1.0);
    let xs: Vec<(f64, f64, f64, f64)> = samples
        .iter()
        .map(|s| {
            let (x0, x1) = inputs(f64::from(s.r_mm), s.theta_deg);
            (x0, x1, s.kappa, s.readings / total)
        })
        .collect();
    let mut best: Option<(Net, f64)> = None;
    for restart in 0..restarts.max(1) {
        let mut rng = Rng::new(seed.wrapping_mul(0x2545_F491_4F6C_DD1D).wrapping_add(u64::from(restart)));
        let mut net = Net::random(&mut rng);
        let loss = Rprop::descend(
            &mut net.p,
            epochs,
            |p, g| Net { p: *p }.loss_grad(&xs, g),
            |epoch, loss| progress(restart, epoch, loss),
        );
        keep_best(&mut best, net, loss);
    }
    best.expect("at least one restart")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_matches_finite_differences() {
        let mut rng = Rng::new(3);
        let net = Net::random(&mut rng);
        let xs: Vec<_> =
            (0..20).map(|_| (rng.uniform(-1.2, 1.2), rng.uniform(-1.4, 1.4), rng.next_f64(), 0.05)).collect();
        let mut g = [0.0; PARAMS];
        net.loss_grad(&xs, &mut g);
        for (i, gi) in g.iter().enumerate() {
            let h = 1e-6;
            let mut a = net.clone();
            a.p[i] += h;
            let mut b = net.clone();
            b.p[i] -= h;
            let mut tmp = [0.0; PARAMS];
            let num = (a.loss_grad(&xs, &mut tmp) - b.loss_grad(&xs, &mut tmp)) / (2.0 * h);
            assert!((num - gi).abs() < 1e-6 * (1.0 + num.abs()), "param {i}: {num} vs {gi}");
        }
    }

    #[test]
    fn learns_a_smooth_surface_and_is_deterministic() {
        let samples: Vec<Sample> = (0..=20)
            .flat_map(|i| (0..=18).map(move |k| (500 + 250 * i, 2.5 * f64::from(k))))
            .map(|(r, t)| Sample { r_mm: r, theta_deg: t, kappa: (-t * t / 200.0).exp(), readings: 100.0 })
            .collect();
        let (net, loss) = train(&samples, 5, 400, 2, &mut |_, _, _| {});
        assert!(rmse(&net, &samples) < 0.05, "{}", rmse(&net, &samples));
        assert!(loss < 0.0025);
        let (again, _) = train(&samples, 5, 400, 2, &mut |_, _, _| {});
        assert_eq!(net, again);
    }
}

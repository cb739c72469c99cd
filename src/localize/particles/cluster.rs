//! The heaviest cluster of the weighted set: what the hand-off looks at.

use super::ParticleSet;
use crate::referencing::wrap;

/// The heaviest cluster of the weighted set.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Cluster {
    /// Its weighted mean (x m, y m, φ rad).
    pub mean: [f32; 3],
    /// Its weighted covariance.
    pub covariance: [[f32; 3]; 3],
    /// The weight within the cluster's radius and angle of its mean (0–1).
    pub weight: f32,
    /// The whole set's covariance about the mean (heading differences
    /// wrapped): how sure the set is.
    pub spread: [[f32; 3]; 3],
}

impl<const N: usize> ParticleSet<N> {
    /// The heaviest cluster: from the heaviest particle, the weighted mean of
    /// the particles within `radius_m` and `angle_rad` of it, three times
    /// over (a mean shift), and the weight and covariance of those
    /// particles; also the whole set's spread about that mean.
    pub fn cluster(&self, radius_m: f32, angle_rad: f32) -> Option<Cluster> {
        let poses = self.poses();
        let weights = self.weights();
        let r2 = radius_m * radius_m;
        let near = |p: &[f32; 3], c: &[f32; 3]| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            dx * dx + dy * dy <= r2 && wrap(p[2] - c[2]).abs() <= angle_rad
        };
        // A mean shift from `seed`: the cluster's mean and weight.
        let shift = |seed: [f32; 3]| {
            let (mut centre, mut weight) = (seed, 0.0f32);
            for _ in 0..3 {
                let (mut sw, mut sx, mut sy, mut sa) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
                for (p, &w) in poses.iter().zip(weights) {
                    if near(p, &centre) {
                        sw += w;
                        sx += w * (p[0] - centre[0]);
                        sy += w * (p[1] - centre[1]);
                        sa += w * wrap(p[2] - centre[2]);
                    }
                }
                if sw <= 0.0 {
                    break;
                }
                centre = [centre[0] + sx / sw, centre[1] + sy / sw, wrap(centre[2] + sa / sw)];
                weight = sw;
            }
            (centre, weight)
        };
        // Seeds at the weight's quantiles (the particles where the running
        // sum of the weights passes (j + ½)/SEEDS): a cluster holding a share
        // w of the weight holds about w·SEEDS of them, so the heaviest one is
        // found whatever single particle weighs most. Seeds inside a cluster
        // already found are skipped.
        const SEEDS: usize = 16;
        let mut found: heapless::Vec<([f32; 3], f32), SEEDS> = heapless::Vec::new();
        let (mut cum, mut j) = (0.0f32, 0usize);
        for (p, &w) in poses.iter().zip(weights) {
            cum += w;
            while j < SEEDS && cum >= (j as f32 + 0.5) / SEEDS as f32 {
                j += 1;
                if found.iter().any(|(c, _)| near(p, c)) {
                    continue;
                }
                let _ = found.push(shift(*p));
            }
        }
        if found.is_empty() {
            let _ = found.push(shift(*poses.first()?));
        }
        let (mut centre, mut weight) = (poses.first().copied()?, f32::NEG_INFINITY);
        for &(c, w) in &found {
            if w > weight {
                (centre, weight) = (c, w);
            }
        }
        let mut covariance = [[0.0f32; 3]; 3];
        let mut spread = [[0.0f32; 3]; 3];
        let mut sw = 0.0;
        for (p, &w) in poses.iter().zip(weights) {
            let d = [p[0] - centre[0], p[1] - centre[1], wrap(p[2] - centre[2])];
            let inside = near(p, &centre);
            if inside {
                sw += w;
            }
            for i in 0..3 {
                for j in 0..3 {
                    let v = w * d[i] * d[j];
                    spread[i][j] += v;
                    if inside {
                        covariance[i][j] += v;
                    }
                }
            }
        }
        if sw > 0.0 {
            for row in covariance.iter_mut() {
                for v in row.iter_mut() {
                    *v /= sw;
                }
            }
            weight = sw;
        }
        Some(Cluster { mean: centre, covariance, weight, spread })
    }
}

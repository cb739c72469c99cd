//! The clutter density that gives the asked-for inconsistency: a search on
//! pilot runs (every few firings of the whole route: the firings' draws are
//! their own, so a pilot reading is the full run's reading).

use super::setup::Setup;
use super::truth::{inconsistent_fraction, World};

/// Most pilot runs after the one at full density.
const STEPS: usize = 8;
/// A pilot this close to the target ends the search.
const PILOT_TOLERANCE: f64 = 0.01;
/// A pilot fires every `stride`-th firing, the stride at least this and
/// coprime to the ring size so that every transducer is sampled.
const MIN_STRIDE: usize = 5;

/// Work units of a calibration at most, in firings (for progress).
pub fn work(setup: &Setup) -> usize {
    (STEPS + 1) * setup.firings.len().div_ceil(stride(setup.plan.order.len()))
}

/// The density for `target`: 0 for 0; 1 if even full density falls short.
/// `tick` is called after each firing. The inconsistency grows with the
/// density from 0 at 0 (the world is then the map): regula falsi with the
/// Illinois modification brackets the target and narrows on it.
pub fn calibrate(setup: &Setup, target: f64, tick: &mut dyn FnMut()) -> f64 {
    if target <= 0.0 {
        return 0.0;
    }
    let s = stride(setup.plan.order.len());
    let mut pilot = |k: f64| {
        let w = World::new(setup, k);
        let readings: Vec<_> = (0..setup.firings.len())
            .step_by(s)
            .map(|i| {
                tick();
                w.fire(setup, i)
            })
            .collect();
        inconsistent_fraction(&readings) - target
    };
    // g(k) = inconsistency − target: g(0) = −target exactly.
    let (mut a, mut ga) = (0.0, -target);
    let (mut b, mut gb) = (1.0, pilot(1.0));
    if gb <= 0.0 {
        return 1.0;
    }
    let mut kept = 0i8;
    for _ in 0..STEPS {
        // Keep away from the ends so that a flat stretch still narrows.
        let k = (a - ga * (b - a) / (gb - ga)).clamp(a + 0.02 * (b - a), b - 0.02 * (b - a));
        let g = pilot(k);
        if g.abs() <= PILOT_TOLERANCE {
            return k;
        }
        if g < 0.0 {
            (a, ga) = (k, g);
            if kept == -1 {
                gb /= 2.0;
            }
            kept = -1;
        } else {
            (b, gb) = (k, g);
            if kept == 1 {
                ga /= 2.0;
            }
            kept = 1;
        }
    }
    a - ga * (b - a) / (gb - ga)
}

/// The smallest stride ≥ [`MIN_STRIDE`] coprime to `n`.
fn stride(n: usize) -> usize {
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    (MIN_STRIDE..).find(|&s| gcd(s, n) == 1).unwrap_or(MIN_STRIDE)
}

//! Shared by the `referencing_*` tests (each includes it with
//! `#[path = "common/referencing_oracle.rs"] mod oracle;`): an independent
//! `f64` re-implementation of the range models, the pose composition and
//! angle wrapping written from their definitions (DESIGN §4.6), numerical
//! differentiation, a Cholesky test for positive definiteness, and a seeded
//! random source with Gaussian samples. Nothing here calls echoloc's maths.
#![allow(dead_code, clippy::needless_range_loop)]

use std::f64::consts::PI;

use echoloc::predict::PIONEER16;
use echoloc::referencing::{MountM, Target};

/// `f32::EPSILON` as `f64`: the unit the f32 tolerances are written in.
pub const EPS32: f64 = f32::EPSILON as f64;

/// The Pioneer ring's mounts in metres, from DESIGN §5's table (not through
/// `MountM::from`, so the conversion is checked too).
pub fn pioneer_m() -> Vec<(f64, f64)> {
    PIONEER16.iter().map(|m| (m.x_mm as f64 / 1000.0, m.y_mm as f64 / 1000.0)).collect()
}

pub fn mount32(m: (f64, f64)) -> MountM {
    MountM { x: m.0 as f32, y: m.1 as f32 }
}

pub fn x64(x: &[f32; 3]) -> [f64; 3] {
    [x[0] as f64, x[1] as f64, x[2] as f64]
}

/// Transducer position: the mount offset rotated by φ and added to (x, y).
pub fn sensor64(x: &[f64; 3], m: (f64, f64)) -> [f64; 2] {
    let (s, c) = x[2].sin_cos();
    [x[0] + c * m.0 - s * m.1, x[1] + s * m.0 + c * m.1]
}

/// A target in f64: a line through `p` with normal `n` (need not be unit),
/// or a point.
#[derive(Clone, Copy, Debug)]
pub enum T64 {
    Line { p: [f64; 2], n: [f64; 2] },
    Point { p: [f64; 2] },
}

impl T64 {
    pub fn of(t: &Target) -> Self {
        match *t {
            Target::Plane { point, normal } => {
                T64::Line { p: [point[0] as f64, point[1] as f64], n: [normal[0] as f64, normal[1] as f64] }
            }
            Target::Point { point } => T64::Point { p: [point[0] as f64, point[1] as f64] },
        }
    }
}

/// h(x): perpendicular distance from the transducer to the line, or the
/// Euclidean distance to the point.
pub fn h64(x: &[f64; 3], m: (f64, f64), t: &T64) -> f64 {
    let s = sensor64(x, m);
    match *t {
        T64::Line { p, n } => ((s[0] - p[0]) * n[0] + (s[1] - p[1]) * n[1]).abs() / n[0].hypot(n[1]),
        T64::Point { p } => (s[0] - p[0]).hypot(s[1] - p[1]),
    }
}

/// Central differences of a scalar function of three variables.
pub fn grad<F: Fn(&[f64; 3]) -> f64>(f: F, x: &[f64; 3], step: f64) -> [f64; 3] {
    let mut g = [0.0; 3];
    for i in 0..3 {
        let (mut a, mut b) = (*x, *x);
        a[i] += step;
        b[i] -= step;
        g[i] = (f(&a) - f(&b)) / (2.0 * step);
    }
    g
}

/// An angle reduced to (−π, π] in f64.
pub fn wrap64(a: f64) -> f64 {
    let r = a - 2.0 * PI * ((a + PI) / (2.0 * PI)).floor();
    if r <= -PI {
        r + 2.0 * PI
    } else if r > PI {
        r - 2.0 * PI
    } else {
        r
    }
}

/// The signed angle from `b` to `a`, reduced to [−π, π].
pub fn angle_diff(a: f64, b: f64) -> f64 {
    let d = a - b;
    d - 2.0 * PI * (d / (2.0 * PI)).round()
}

/// `x ⊕ u`: move (dx forward, dy left) in the frame of `x`, then turn.
pub fn compose64(x: &[f64; 3], u: &[f64; 3]) -> [f64; 3] {
    let (s, c) = x[2].sin_cos();
    [x[0] + c * u[0] - s * u[1], x[1] + s * u[0] + c * u[1], wrap64(x[2] + u[2])]
}

/// Whether `p` (f32, read exactly into f64) is positive definite: a
/// Cholesky factorisation in f64 whose every pivot is positive.
pub fn cholesky_pd(p: &[[f32; 3]; 3]) -> bool {
    let a: Vec<Vec<f64>> = p.iter().map(|r| r.iter().map(|&v| v as f64).collect()).collect();
    let mut l = [[0.0f64; 3]; 3];
    for j in 0..3 {
        let mut d = a[j][j];
        for k in 0..j {
            d -= l[j][k] * l[j][k];
        }
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        l[j][j] = d.sqrt();
        for i in (j + 1)..3 {
            let mut v = a[i][j];
            for k in 0..j {
                v -= l[i][k] * l[j][k];
            }
            l[i][j] = v / l[j][j];
        }
    }
    true
}

/// SplitMix64: a small seeded generator, with uniform and Gaussian draws.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.unit();
        let u2 = self.unit();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

//! The last few cycles' readings, kept in the frame of the current cycle's
//! start, so that a pose can be scored on all of them at once: what a
//! single cycle cannot tell apart (a robot in one aisle or the next), a few
//! metres of driving do. The search verifies its proposals on them before
//! it lets them into the particle set in number.

use super::measure::{Measure, Sensed};
use crate::f32math::sin_cos;
use crate::referencing::{wrap, Reading};

/// Cycles kept.
pub const HISTORY_CYCLES: usize = 8;
/// Readings kept a cycle (the first ones that are not invalid).
pub const HISTORY_READINGS: usize = 16;

/// A kept reading in 8 bytes: the transducer's pose (mm, mm, mrad) in the
/// current cycle's frame, and its range (mm; 0 for no echo). Millimetres
/// are the map's own unit, and eight cycles of driving stay well within
/// ±32 m.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Kept {
    x_mm: i16,
    y_mm: i16,
    heading_mrad: i16,
    range_mm: u16,
}

impl Kept {
    fn of(r: &Sensed) -> Option<Self> {
        let range_mm = match r.reading {
            Reading::Echo { range_mm } => u16::try_from(range_mm).ok().filter(|&v| v > 0)?,
            Reading::NoEcho => 0,
            Reading::Invalid => return None,
        };
        let mm = |v: f32| libm::roundf(v * 1e3).clamp(-32_767.0, 32_767.0) as i16;
        Some(Self { x_mm: mm(r.pose[0]), y_mm: mm(r.pose[1]), heading_mrad: mm(wrap(r.pose[2])), range_mm })
    }

    fn sensed(&self) -> Sensed {
        Sensed {
            pose: [f32::from(self.x_mm) * 1e-3, f32::from(self.y_mm) * 1e-3, f32::from(self.heading_mrad) * 1e-3],
            reading: if self.range_mm == 0 {
                Reading::NoEcho
            } else {
                Reading::Echo { range_mm: u32::from(self.range_mm) }
            },
        }
    }
}

/// The readings of the last [`HISTORY_CYCLES`] cycles.
#[derive(Clone, Copy, Debug)]
pub struct History {
    readings: [[Kept; HISTORY_READINGS]; HISTORY_CYCLES],
    counts: [u8; HISTORY_CYCLES],
    /// Per cycle, its frame in the current cycle's: a kept pose `q` is
    /// `frame ⊕ q` now. Moving the frames, not the readings, makes a
    /// cycle's rebase eight compositions.
    frames: [[f32; 3]; HISTORY_CYCLES],
    /// The slot the next cycle goes to.
    head: usize,
    /// Cycles held.
    len: usize,
}

impl Default for History {
    fn default() -> Self {
        Self::new()
    }
}

impl History {
    /// Empty.
    pub const fn new() -> Self {
        const NONE: Kept = Kept { x_mm: 0, y_mm: 0, heading_mrad: 0, range_mm: 0 };
        Self {
            readings: [[NONE; HISTORY_READINGS]; HISTORY_CYCLES],
            counts: [0; HISTORY_CYCLES],
            frames: [[0.0; 3]; HISTORY_CYCLES],
            head: 0,
            len: 0,
        }
    }

    /// Forgets every cycle.
    pub fn clear(&mut self) {
        self.len = 0;
        self.head = 0;
        self.counts = [0; HISTORY_CYCLES];
    }

    /// Cycles held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether none are held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Keeps the cycle that just ended (its readings in its start's frame),
    /// the oldest going when full.
    pub fn push(&mut self, sensed: &[Sensed]) {
        let (Some(slot), Some(count)) = (self.readings.get_mut(self.head), self.counts.get_mut(self.head)) else {
            return;
        };
        let mut k = 0usize;
        for kept in sensed.iter().filter_map(Kept::of) {
            let Some(s) = slot.get_mut(k) else { break };
            *s = kept;
            k += 1;
        }
        *count = k as u8;
        if let Some(f) = self.frames.get_mut(self.head) {
            *f = [0.0; 3];
        }
        // Compared before adding: the compiler sees neither can overflow.
        self.head = if self.head >= HISTORY_CYCLES - 1 { 0 } else { self.head + 1 };
        if self.len < HISTORY_CYCLES {
            self.len += 1;
        }
    }

    /// Re-expresses every kept reading in the frame of the next cycle's
    /// start, `offset` (x m, y m, φ rad) from this one's: `offset⁻¹ ⊕ pose`.
    pub fn rebase(&mut self, offset: &[f32; 3]) {
        let (s, c) = sin_cos(offset[2]);
        for f in self.frames.iter_mut() {
            let (dx, dy) = (f[0] - offset[0], f[1] - offset[1]);
            *f = [c * dx + s * dy, -s * dx + c * dy, wrap(f[2] - offset[2])];
        }
    }

    /// The log-likelihood under `m` of every kept reading, and of
    /// `current`, at pose `p` (in the current cycle's start frame).
    pub fn score(&self, p: &[f32; 3], current: &[Sensed], m: &Measure<'_>) -> f32 {
        let mut ll = 0.0;
        self.each_cycle(p, current, m, |v| ll += v);
        ll
    }

    /// [`History::score`] cycle by cycle: `current`'s first, then each kept
    /// cycle's in the order they are stored (0 past the kept ones).
    pub fn score_cycles(&self, p: &[f32; 3], current: &[Sensed], m: &Measure<'_>) -> [f32; HISTORY_CYCLES + 1] {
        let mut out = [0.0; HISTORY_CYCLES + 1];
        let mut slots = out.iter_mut();
        self.each_cycle(p, current, m, |v| {
            if let Some(o) = slots.next() {
                *o = v;
            }
        });
        out
    }

    /// Calls `f` with `current`'s log-likelihood at `p`, then each stored
    /// cycle's (a closure, not an array: `score` is the search's inner loop
    /// and stays what it was).
    #[inline(always)]
    fn each_cycle(&self, p: &[f32; 3], current: &[Sensed], m: &Measure<'_>, mut f: impl FnMut(f32)) {
        f(m.log_likelihood(p, current));
        for ((cycle, &n), fr) in self.readings.iter().zip(&self.counts).zip(&self.frames) {
            let mut rs = [Sensed { pose: [0.0; 3], reading: Reading::Invalid }; HISTORY_READINGS];
            let (s, c) = sin_cos(fr[2]);
            for (d, k) in rs.iter_mut().zip(cycle.iter().take(usize::from(n))) {
                let v = k.sensed();
                let q = v.pose;
                *d = Sensed {
                    pose: [fr[0] + c * q[0] - s * q[1], fr[1] + s * q[0] + c * q[1], fr[2] + q[2]],
                    reading: v.reading,
                };
            }
            if let Some(rs) = rs.get(..usize::from(n)) {
                f(m.log_likelihood(p, rs));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn compose(a: &[f32; 3], b: &[f32; 3]) -> [f32; 3] {
        let (s, c) = (libm::sinf(a[2]), libm::cosf(a[2]));
        [a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]]
    }

    /// A robot driving an arc: every kept reading, put back into the world
    /// through the current true pose, lands where the transducer was.
    #[test]
    fn rebased_readings_stay_where_they_were_taken() {
        let mut h = History::new();
        let mut pose = [1.0f32, 2.0, 0.3];
        let mut world: std::vec::Vec<[f32; 3]> = std::vec::Vec::new();
        extern crate std;
        for cycle in 0..12 {
            // Two readings a cycle, the robot moving between them.
            let start = pose;
            let mut sensed = [Sensed { pose: [0.0; 3], reading: Reading::NoEcho }; 2];
            for (k, s) in sensed.iter_mut().enumerate() {
                let step = [0.1f32, 0.02, 0.05 + 0.01 * cycle as f32];
                pose = compose(&pose, &step);
                let mount = [0.15f32, -0.1 * k as f32, 0.5 * k as f32];
                let t = compose(&pose, &mount);
                world.push(t);
                // In the cycle's start frame.
                let (sn, cs) = (libm::sinf(start[2]), libm::cosf(start[2]));
                let (dx, dy) = (t[0] - start[0], t[1] - start[1]);
                s.pose = [cs * dx + sn * dy, -sn * dx + cs * dy, t[2] - start[2]];
            }
            h.push(&sensed);
            // The offset from this cycle's start to the next one's.
            let (sn, cs) = (libm::sinf(start[2]), libm::cosf(start[2]));
            let (dx, dy) = (pose[0] - start[0], pose[1] - start[1]);
            h.rebase(&[cs * dx + sn * dy, -sn * dx + cs * dy, pose[2] - start[2]]);
        }
        // Every kept reading, through the current pose (the next cycle's start).
        let kept = HISTORY_CYCLES.min(12) * 2;
        let mut found = 0;
        for ((cycle, &n), f) in h.readings.iter().zip(&h.counts).zip(&h.frames) {
            for r in cycle.iter().take(usize::from(n)) {
                // Kept in whole millimetres and milliradians, in its cycle's frame.
                let w = compose(&pose, &compose(f, &r.sensed().pose));
                assert!(
                    world.iter().any(|t| (t[0] - w[0]).abs() < 6e-3
                        && (t[1] - w[1]).abs() < 6e-3
                        && wrap(t[2] - w[2]).abs() < 6e-3),
                    "{w:?}"
                );
                found += 1;
            }
        }
        assert_eq!(found, kept);
    }
}

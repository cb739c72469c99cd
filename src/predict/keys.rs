//! The window's candidate keys: each piece's box distance from the
//! transducer and its id in one `u32`, and their sort (nearest first).

use heapless::Vec;

use crate::geometry::{Point, Rect};

/// Sorts the candidate keys ascending without a panic path (the firmware's
/// panic-never link check; `sort_unstable` keeps one, its check for an
/// inconsistent `Ord`): a Shell sort on Ciura's gaps, in place, moving a
/// hole rather than swapping. Tested against `sort_unstable` below.
pub(super) fn sort_keys(keys: &mut [u32]) {
    const GAPS: [usize; 6] = [132, 57, 23, 10, 4, 1];
    let n = keys.len();
    for gap in GAPS {
        for i in gap..n {
            let Some(&v) = keys.get(i) else { break };
            let mut j = i;
            while j >= gap {
                let Some(&u) = keys.get(j - gap) else { break };
                if u <= v {
                    break;
                }
                if let Some(slot) = keys.get_mut(j) {
                    *slot = u;
                }
                j -= gap;
            }
            if let Some(slot) = keys.get_mut(j) {
                *slot = v;
            }
        }
    }
}

/// The `N` smallest keys of those offered (the window's nearest candidates),
/// sorted, and the smallest key left out: a window of more candidates than
/// it holds is searched in batches, nearest first. Offered more than `N`,
/// it keeps them as a max-heap and a smaller key replaces the largest.
pub(super) struct NearestKeys<const N: usize> {
    keys: Vec<u32, N>,
    heap: bool,
    dropped: Option<u32>,
}

impl<const N: usize> NearestKeys<N> {
    pub(super) const fn new() -> Self {
        Self { keys: Vec::new(), heap: false, dropped: None }
    }

    pub(super) fn clear(&mut self) {
        self.keys.clear();
        self.heap = false;
        self.dropped = None;
    }

    pub(super) fn offer(&mut self, key: u32) {
        if !self.heap {
            if self.keys.push(key).is_ok() {
                return;
            }
            self.heap = true;
            let n = self.keys.len();
            for i in (0..n / 2).rev() {
                sift_down(&mut self.keys, i);
            }
        }
        let left_out = match self.keys.first_mut() {
            Some(top) if key < *top => {
                let old = *top;
                *top = key;
                sift_down(&mut self.keys, 0);
                old
            }
            _ => key,
        };
        self.dropped = Some(self.dropped.map_or(left_out, |d| d.min(left_out)));
    }

    /// Sorts what is held, nearest first; call once the offers are over.
    pub(super) fn sort(&mut self) {
        sort_keys(&mut self.keys);
        self.heap = false;
    }

    pub(super) fn held(&self) -> &[u32] {
        &self.keys
    }

    /// The smallest key offered and not held: every key below it is held.
    pub(super) fn dropped(&self) -> Option<u32> {
        self.dropped
    }
}

/// Restores the max-heap order below `i` (indices checked: no panic path).
fn sift_down(h: &mut [u32], mut i: usize) {
    while let Some(l) = i.checked_mul(2).and_then(|x| x.checked_add(1)) {
        let (Some(&top), Some(&left)) = (h.get(i), h.get(l)) else { break };
        // `l` indexes the slice, so `l + 1` cannot wrap.
        let r = l.wrapping_add(1);
        let (c, child) = match h.get(r) {
            Some(&right) if right > left => (r, right),
            _ => (l, left),
        };
        if child <= top {
            break;
        }
        if let Some(s) = h.get_mut(i) {
            *s = child;
        }
        if let Some(s) = h.get_mut(c) {
            *s = top;
        }
        i = c;
    }
}

/// The squared distance (mm²) from `o` to the box, exact, with each gap
/// clamped at 2²⁴ mm (far beyond any `R_max`): a lower bound of the squared
/// distance to any point of the piece it holds.
pub(super) fn box_distance2(o: Point, b: &Rect) -> u64 {
    // In-range coordinates differ by less than 2³¹: the gaps are taken in
    // 32 bits (as `Point::sub` does), so each square is one 32 × 32 → 64-bit
    // multiply on a Cortex-M4.
    let gap = |lo: i32, v: i32, hi: i32| lo.wrapping_sub(v).max(v.wrapping_sub(hi)).clamp(0, 1 << 24) as u32 as u64;
    let (dx, dy) = (gap(b.min.x, o.x, b.max.x), gap(b.min.y, o.y, b.max.y));
    dx * dx + dy * dy
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::{sort_keys, NearestKeys};

    /// xorshift64 from `seed`: the tests' fixed stream of keys.
    fn xorshift(mut x: u64) -> impl FnMut() -> u64 {
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        }
    }

    /// Against a full sort: the `N` smallest of the offered keys, sorted,
    /// and the next smallest as the one left out, for counts on both sides
    /// of `N`, keys offered in random order with long runs of close values.
    #[test]
    fn nearest_keys_are_the_smallest_of_a_full_sort() {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let mut near = NearestKeys::<16>::new();
        for case in 0..3_000 {
            let count = (next() % 60) as usize;
            let modulus = if case % 2 == 0 { 64 } else { u32::MAX as u64 };
            let mut offered: std::vec::Vec<u32> = std::vec::Vec::new();
            while offered.len() < count {
                // Keys are unique (a piece id in the low bits).
                let k = (next() % modulus) as u32;
                if !offered.contains(&k) {
                    offered.push(k);
                }
            }
            near.clear();
            for &k in &offered {
                near.offer(k);
            }
            near.sort();
            let mut want = offered.clone();
            want.sort_unstable();
            let held = want.len().min(16);
            assert_eq!(near.held(), &want[..held], "case {case}");
            assert_eq!(near.dropped(), want.get(16).copied(), "case {case}");
        }
    }

    /// Against `sort_unstable` on random lengths on both sides of the
    /// insertion/heap switch, with many repeated keys.
    #[test]
    fn sort_keys_matches_sort_unstable() {
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
        for case in 0..5_000 {
            let len = (next() % 300) as usize;
            let modulus = if case % 3 == 0 { 7 } else { u32::MAX as u64 };
            let mut keys = [0u32; 300];
            for k in keys[..len].iter_mut() {
                *k = (next() % modulus) as u32;
            }
            let mut want = keys;
            want[..len].sort_unstable();
            sort_keys(&mut keys[..len]);
            assert_eq!(keys[..len], want[..len], "case {case}, length {len}");
        }
    }
}

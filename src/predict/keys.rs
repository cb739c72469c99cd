//! The window's candidate keys: each piece's box distance from the
//! transducer and its id in one `u32`, and their sort (nearest first).

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
    use super::sort_keys;

    /// Against `sort_unstable` on random lengths on both sides of the
    /// insertion/heap switch, with many repeated keys.
    #[test]
    fn sort_keys_matches_sort_unstable() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
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

//! The integer square root every part of the crate uses (buffers, the speed
//! of sound, range reports).

/// ⌊√n⌋, bit by bit: no float, no division, 32 iterations at most.
pub const fn isqrt(n: u64) -> u64 {
    let mut rem = n;
    let mut root = 0u64;
    let mut bit = 1u64 << 62;
    while bit > n {
        bit >>= 2;
    }
    while bit != 0 {
        // `root + bit` never carries: `root` has no bit at or below `bit`'s
        // position here (the digit-by-digit invariant), so `|` is the sum.
        if rem >= root | bit {
            rem -= root | bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isqrt_is_the_floor() {
        for n in [0u64, 1, 2, 3, 4, 15, 16, 17, 99, 100, u32::MAX as u64, u64::MAX] {
            let r = isqrt(n);
            assert!(r * r <= n);
            assert!((r + 1).checked_mul(r + 1).is_none_or(|s| s > n), "n={n} r={r}");
        }
    }
}

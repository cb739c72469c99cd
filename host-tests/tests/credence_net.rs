//! The firmware's quantised credence net (`echoloc::credence::net`) against
//! (1) an integer reference written here from the documented algorithm,
//! bit for bit, and (2) the float net it was rounded from, within 1/256, over
//! the dense grid 0.5° × 10 mm of the whole input domain (DESIGN §4.4), and
//! (3) the data it was trained on: the generated `weights.rs` names each
//! data file's CRC-32 and the float net's RMSE on them, both checked here
//! against `docs/credence-data`.

use echoloc::credence::net::{
    CredenceNet, KappaBounds, QuantWeights, BOUND_R_SHIFT, BOUND_THETA_SHIFT, FLOAT_WEIGHTS, HIDDEN, SHIPPED_WEIGHTS,
    SIGMOID_TAIL,
};
use echoloc::credence::{Credence, EchoGeometry, Kappa};
use fixed::types::I16F16;

/// The logistic function in f64 (std's exp).
fn logistic(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

/// The σ table as the docs define it: round(2¹⁶·(1 − σ(k/16))), k = 0..=256.
fn table() -> Vec<i128> {
    (0..=256).map(|k| ((1.0 - logistic(k as f64 / 16.0)) * 65536.0).round() as i128).collect()
}

/// `floor(v / 2^s)`, spelled with Euclidean division rather than a shift.
fn floor_div_pow2(v: i128, s: u32) -> i128 {
    v.div_euclid(1i128 << s)
}

/// σ of a Q16.16 pre-activation, Q0.16 — the reference's own spelling.
fn sigma_ref(lut: &[i128], z: i128) -> i128 {
    let z = z.clamp(-(16 << 16), 16 << 16);
    let a = z.abs();
    let i = (a / 4096) as usize;
    let f = a % 4096;
    let u = if i == 256 { lut[256] } else { lut[i] - floor_div_pow2((lut[i] - lut[i + 1]) * f + 2048, 12) };
    if z >= 0 {
        65536 - u
    } else {
        u
    }
}

/// κ bits (U1F15) by the algorithm of `net.rs`'s docs, in i128 throughout.
fn kappa_ref(w: &QuantWeights, lut: &[i128], range_mm: u32, theta_mdeg: i32) -> u16 {
    let r = i128::from(range_mm).clamp(500, 5500);
    let t = i128::from(theta_mdeg).abs().min(45_000);
    let x0 = (r - 3000) * 32; // (R − 3000)/2048 in Q16.16
    let x1 = (t - 22_500) * 4; // (|θ| − 22.5°)/16.384° in Q16.16
    let mut acc = 0i128;
    for j in 0..HIDDEN {
        let s = i128::from(w.w_hidden[j][0].to_bits()) * x0 + i128::from(w.w_hidden[j][1].to_bits()) * x1;
        let z = i128::from(w.b_hidden[j].to_bits()) + floor_div_pow2(s + 32_768, 16);
        acc += i128::from(w.w_out[j].to_bits()) * sigma_ref(lut, z);
    }
    let z = i128::from(w.b_out.to_bits()) + floor_div_pow2(acc + 32_768, 16);
    let k = sigma_ref(lut, z);
    u16::try_from(floor_div_pow2(k + 1, 1)).expect("κ ≤ 1")
}

/// The float net of `net.rs`'s docs over `FLOAT_WEIGHTS`.
fn kappa_float(range_mm: f64, theta_deg: f64) -> f64 {
    let w = &FLOAT_WEIGHTS;
    let x0 = (range_mm.clamp(500.0, 5500.0) - 3000.0) / 2048.0;
    let x1 = (theta_deg.abs().min(45.0) - 22.5) / 16.384;
    let mut z = w.b_out;
    for j in 0..HIDDEN {
        z += w.w_out[j] * logistic(w.w_hidden[j][0] * x0 + w.w_hidden[j][1] * x1 + w.b_hidden[j]);
    }
    logistic(z)
}

/// The dense grid: R 500..=5500 mm step 10, θ −45..=45° step 0.5°.
fn dense_grid() -> impl Iterator<Item = (u32, i32)> {
    (500..=5500).step_by(10).flat_map(|r| (-90..=90).map(move |k| (r, k * 500)))
}

/// Points outside the domain and at integer extremes: clamping must agree too.
fn edge_points() -> Vec<(u32, i32)> {
    let mut v = Vec::new();
    for r in [0, 1, 499, 500, 501, 2999, 3000, 5499, 5500, 5501, 10_000, u32::MAX] {
        for t in [i32::MIN, -90_000, -45_001, -45_000, -1, 0, 1, 12_700, 44_999, 45_000, 45_001, 180_000, i32::MAX] {
            v.push((r, t));
        }
    }
    v
}

/// Pseudo-random points over and around the domain (xorshift, fixed seed).
fn random_points(n: usize) -> Vec<(u32, i32)> {
    let mut s: u64 = 0x2545_F491_4F6C_DD1D;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s % 7000) as u32, ((s >> 20) % 120_001) as i32 - 60_000)
        })
        .collect()
}

#[test]
fn sigmoid_table_is_the_rounded_logistic_tail() {
    let lut = table();
    for (k, (&shipped, &want)) in SIGMOID_TAIL.iter().zip(&lut).enumerate() {
        assert_eq!(i128::from(shipped.to_bits()), want, "L[{k}]");
    }
    assert_eq!(SIGMOID_TAIL.len(), 257);
}

#[test]
fn shipped_weights_are_the_float_weights_rounded_to_q16_16() {
    let q = |v: f64| (v * 65536.0).round() as i32;
    let (f, s) = (&FLOAT_WEIGHTS, &SHIPPED_WEIGHTS);
    for j in 0..HIDDEN {
        assert_eq!(s.w_hidden[j][0].to_bits(), q(f.w_hidden[j][0]), "w_hidden[{j}][0]");
        assert_eq!(s.w_hidden[j][1].to_bits(), q(f.w_hidden[j][1]), "w_hidden[{j}][1]");
        assert_eq!(s.b_hidden[j].to_bits(), q(f.b_hidden[j]), "b_hidden[{j}]");
        assert_eq!(s.w_out[j].to_bits(), q(f.w_out[j]), "w_out[{j}]");
    }
    assert_eq!(s.b_out.to_bits(), q(f.b_out));
}

#[test]
fn bit_exact_against_the_integer_reference() {
    let lut = table();
    let net = CredenceNet::shipped();
    let mut n = 0;
    let points = dense_grid().chain(edge_points()).chain(random_points(200_000));
    for (r, t) in points {
        let got = net.kappa_at(r, t).to_bits();
        let want = kappa_ref(&SHIPPED_WEIGHTS, &lut, r, t);
        assert_eq!(got, want, "κ({r} mm, {t} mdeg): firmware {got}, reference {want}");
        n += 1;
    }
    assert!(n > 245_000);
}

#[test]
fn the_reference_comparison_notices_a_one_bit_change() {
    // The bit-exact test must be able to fail: change one weight by one LSB
    // and the firmware net must differ from the reference somewhere.
    let lut = table();
    let mut w = SHIPPED_WEIGHTS;
    // One LSB of Q16.16, away from zero (b_out is not zero in any trained net).
    w.b_out += w.b_out.signum() >> 16u32;
    assert_eq!((w.b_out.to_bits() - SHIPPED_WEIGHTS.b_out.to_bits()).abs(), 1);
    let net = CredenceNet::new(&w);
    let differs = dense_grid().any(|(r, t)| net.kappa_at(r, t).to_bits() != kappa_ref(&SHIPPED_WEIGHTS, &lut, r, t));
    assert!(differs);
}

#[test]
fn within_1_256_of_the_float_net_over_the_dense_grid() {
    let net = CredenceNet::shipped();
    let mut worst = (0.0f64, 0, 0);
    for (r, t) in dense_grid() {
        let q = net.kappa_at(r, t).to_num::<f64>();
        let e = (q - kappa_float(f64::from(r), f64::from(t) / 1000.0)).abs();
        if e > worst.0 {
            worst = (e, r, t);
        }
    }
    println!("max |quantised − float| = {:.6} at ({} mm, {} mdeg)", worst.0, worst.1, worst.2);
    assert!(worst.0 <= 1.0 / 256.0, "max |quantised − float| = {} at {:?}", worst.0, (worst.1, worst.2));
}

#[test]
fn trait_ignores_delta_and_the_sign_of_theta() {
    let net = CredenceNet::shipped();
    let model: &dyn Credence = &net;
    for (r, t) in random_points(2_000) {
        let a = EchoGeometry { range_mm: r, theta_mdeg: t, delta_mdeg: 0 };
        let b = EchoGeometry { range_mm: r, theta_mdeg: t.saturating_neg(), delta_mdeg: 60_000 };
        assert_eq!(model.kappa(&a), model.kappa(&b));
        assert_eq!(model.kappa(&a), net.kappa_at(r, t));
        assert!(model.kappa(&a) <= Kappa::ONE);
    }
}

#[test]
fn the_shipped_net_has_the_three_lobes() {
    // Paper §4.2: "all three lobes be considered". At 1 m: high on the axis,
    // a ravine at the first null (12.7°), the first side lobe (17.2°), the
    // second null (23.8°), the second side lobe (29°), nothing at 45°.
    let k = |r: u32, deg: f64| CredenceNet::shipped().kappa_at(r, (deg * 1000.0) as i32).to_num::<f64>();
    let r = 1000;
    assert!(k(r, 0.0) > 0.85, "axis {}", k(r, 0.0));
    assert!(k(r, 12.5) < k(r, 17.5) - 0.2, "first null {} vs lobe {}", k(r, 12.5), k(r, 17.5));
    assert!(k(r, 17.5) > 0.7, "first side lobe {}", k(r, 17.5));
    assert!(k(r, 23.8) < k(r, 29.0) - 0.2, "second null {} vs lobe {}", k(r, 23.8), k(r, 29.0));
    assert!(k(r, 45.0) < 0.1, "45° {}", k(r, 45.0));
    // The side lobes fade with range faster than the main lobe.
    assert!(k(5500, 17.5) < k(1000, 17.5) - 0.3 && k(5500, 0.0) > 0.6);
}

/// The generated weights file, as compiled into `FLOAT_WEIGHTS`.
const WEIGHTS_SOURCE: &str = include_str!("../../src/credence/weights.rs");

/// The text between the first pair of backticks after `key` in `line`.
fn quoted_after<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    let rest = &line[line.find(key)? + key.len()..];
    let rest = &rest[rest.find('`')? + 1..];
    Some(&rest[..rest.find('`')?])
}

#[test]
fn the_weights_header_matches_the_checked_in_data() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    // `//! - `docs/credence-data/day1.csv`: 39900 readings, CRC-32 `3bae1577``
    let files: Vec<(&str, u64, u32)> = WEIGHTS_SOURCE
        .lines()
        .filter_map(|l| l.strip_prefix("//! - `"))
        .map(|l| {
            let path = &l[..l.find('`').expect("closing backtick")];
            let readings = l.split(": ").nth(1).and_then(|r| r.split(' ').next()).and_then(|r| r.parse().ok());
            let crc = quoted_after(l, "CRC-32").and_then(|c| u32::from_str_radix(c, 16).ok());
            (path, readings.expect("readings"), crc.expect("CRC-32"))
        })
        .collect();
    let rmse_line =
        WEIGHTS_SOURCE.lines().find_map(|l| l.strip_prefix("//! RMSE of the float net on the pooled data: "));
    let header_rmse: f64 = rmse_line.and_then(|r| r.trim_end_matches('.').parse().ok()).expect("RMSE line");

    // Every checked-in day is listed, and nothing else.
    let mut on_disk: Vec<String> = std::fs::read_dir(root.join("docs/credence-data"))
        .unwrap()
        .map(|e| format!("docs/credence-data/{}", e.unwrap().file_name().to_string_lossy()))
        .filter(|p| p.ends_with(".csv"))
        .collect();
    on_disk.sort();
    assert_eq!(files.iter().map(|f| f.0).collect::<Vec<_>>(), on_disk, "weights.rs was trained on other files");

    // Pool the days per node (R, |θ|): κ = Σ correct / Σ readings.
    let mut pooled = std::collections::BTreeMap::<(u32, u64), (u64, u64)>::new();
    for &(path, readings, crc) in &files {
        let bytes = std::fs::read(root.join(path)).unwrap();
        assert_eq!(
            crc32fast::hash(&bytes),
            crc,
            "{path} changed since weights.rs was generated: retrain (docs/credence.md, Exact commands)"
        );
        let text = std::str::from_utf8(&bytes).unwrap();
        let mut total = 0;
        for line in text.lines().skip(1).filter(|l| !l.is_empty()) {
            let f: Vec<&str> = line.split(',').collect();
            let (r, t): (u32, f64) = (f[0].parse().unwrap(), f[1].parse().unwrap());
            let (n, c): (u64, u64) = (f[2].parse().unwrap(), f[3].parse().unwrap());
            let e = pooled.entry((r, t.abs().to_bits())).or_default();
            e.0 += c;
            e.1 += n;
            total += n;
        }
        assert_eq!(total, readings, "{path}: readings");
    }
    assert_eq!(pooled.len(), 399, "the paper's grid");
    let sq: f64 = pooled
        .iter()
        .map(|(&(r, t), &(c, n))| (kappa_float(f64::from(r), f64::from_bits(t)) - c as f64 / n as f64).powi(2))
        .sum();
    let rmse = (sq / pooled.len() as f64).sqrt();
    println!("pooled RMSE of FLOAT_WEIGHTS: {rmse:.6} (header {header_rmse})");
    // The header prints six decimals.
    assert!((rmse - header_rmse).abs() < 2e-6, "pooled RMSE {rmse} vs header {header_rmse}");
}

/// `may_reach` false must mean κ below τ, checked against the independent
/// integer reference: every bin's corners and a lattice of 8 mm × 16 mdeg
/// inside it (about 1.8 M points), the dense grid, the edge points and
/// random points, each at several τ.
#[test]
fn kappa_bounds_never_skip_a_credible_echo() {
    let lut = table();
    let net = CredenceNet::shipped();
    let bounds = net.bounds().expect("the shipped net has bounds");
    assert_eq!(bounds, &KappaBounds::of(&SHIPPED_WEIGHTS));
    let taus = [0u16, 1, 8192, 16384, 29491, 32767, 32768].map(Kappa::from_bits);
    let lattice = (500..=5500 + 7).step_by(8).flat_map(|r: u32| (0..=45_000 + 15).step_by(16).map(move |t| (r, t)));
    let corners = (0..=20u32).flat_map(|k| {
        (0..=88u32).flat_map(move |m| {
            let (r, t) = (500 + (k << BOUND_R_SHIFT), (m << BOUND_THETA_SHIFT) as i32);
            [(r, t), (r + 255, t), (r, t + 511), (r + 255, t + 511)]
        })
    });
    let (mut n, mut skipped) = (0u64, 0u64);
    for (r, t) in lattice.chain(corners).chain(dense_grid()).chain(edge_points()).chain(random_points(100_000)) {
        let kappa = Kappa::from_bits(kappa_ref(&SHIPPED_WEIGHTS, &lut, r, t));
        let upper = u32::from(bounds.upper_255(r, t));
        assert!(u32::from(kappa.to_bits()) * 255 <= upper << 15, "κ({r}, {t}) = {kappa} above its bound {upper}/255");
        for tau in taus {
            let echo = EchoGeometry { range_mm: r, theta_mdeg: t, delta_mdeg: 0 };
            if !net.may_reach(&echo, tau) {
                assert!(kappa < tau, "κ({r}, {t}) = {kappa} reaches τ = {tau} but was skipped");
                skipped += 1;
            }
        }
        n += 1;
    }
    assert!(n > 1_800_000, "{n} points");
    // τ = 0 never skips; the others must skip somewhere, or the test says nothing.
    assert!(skipped > n, "only {skipped} skips over {n} points");
}

/// The bounds are tight enough to matter: of the bins where no lattice point
/// reaches 0.4, at most a few percent are not skipped at τ = 0.5 (the
/// predictor's default).
#[test]
fn kappa_bounds_skip_most_bins_far_below_tau() {
    let net = CredenceNet::shipped();
    let tau = Kappa::from_num(0.5);
    let (mut far_below, mut kept) = (0, 0);
    for k in 0..20u32 {
        for m in 0..88u32 {
            let (r0, t0) = (500 + (k << BOUND_R_SHIFT), m << BOUND_THETA_SHIFT);
            let max = (r0..(r0 + 256).min(5501))
                .step_by(16)
                .flat_map(|r| (t0..(t0 + 512).min(45_001)).step_by(32).map(move |t| (r, t as i32)))
                .map(|(r, t)| net.kappa_at(r, t))
                .max()
                .expect("a bin has points");
            if max < Kappa::from_num(0.4) {
                far_below += 1;
                let echo = EchoGeometry { range_mm: r0, theta_mdeg: t0 as i32, delta_mdeg: 0 };
                kept += usize::from(net.may_reach(&echo, tau));
            }
        }
    }
    assert!(far_below > 500, "{far_below} bins far below τ");
    assert!(kept * 20 <= far_below, "{kept} of {far_below} bins far below τ are not skipped");
}

proptest::proptest! {
    /// Bounds of any weights hold: random nets (weights up to ±64, the
    /// shipped net's steep unit too), random points.
    #[test]
    fn kappa_bounds_hold_for_random_weights(seed in proptest::prelude::any::<u64>(), steep in 0usize..HIDDEN) {
        let mut s = seed | 1;
        let mut next = move |scale: i64| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            I16F16::from_bits((((s >> 11) as i64 % (2 * scale + 1)) - scale) as i32)
        };
        let mut w = SHIPPED_WEIGHTS;
        for j in 0..HIDDEN {
            w.w_hidden[j] = [next(64 << 16), next(64 << 16)];
            w.b_hidden[j] = next(32 << 16);
            w.w_out[j] = next(16 << 16);
        }
        w.w_hidden[steep][1] = next(6000 << 16);
        w.b_out = next(8 << 16);
        let lut = table();
        let bounds = KappaBounds::of(&w);
        for (r, t) in random_points(4000).into_iter().chain(edge_points()) {
            let kappa = u32::from(kappa_ref(&w, &lut, r, t));
            let upper = u32::from(bounds.upper_255(r, t));
            proptest::prop_assert!(kappa * 255 <= upper << 15, "κ({}, {}) = {} above {}/255", r, t, kappa, upper);
        }
    }
}

//! Issue #30 item 4: every public function is correct for every argument its
//! types allow, or refuses it with a typed error. Host tests build with
//! overflow checks on, so an overflow anywhere below is a failing panic, not
//! a silent wrap. Each answer is compared with an oracle in wider integers
//! (`i128`, `u128`) or a brute force, never with the code's own output.

use echoloc::buffer::{grow, octagon, octagon_s, BufferError, MAX_BUFFER_MM};
use echoloc::driver::{ConfigError, Eeruf, ModuleConfig, RingConfig, RingTiming, Schedule, SpeedOfSound};
use echoloc::geometry::{cross, dot, isqrt, Convex, Point, COORD_MAX, MAX_BUFFERED_VERTICES, MAX_PIECE_VERTICES, U256};
use echoloc::link::frame::max_frame_len;
use proptest::prelude::*;

/// A strictly convex polygon with `n` vertices, counter-clockwise: a regular
/// `n`-gon of radius `r` rounded to millimetres (strictly convex for the
/// radii used here; checked by `Convex::new`).
fn regular(n: usize, r: f64, c: (i32, i32)) -> Vec<Point> {
    (0..n)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / n as f64 + 0.1;
            Point::new(c.0 + (r * a.cos()).round() as i32, c.1 + (r * a.sin()).round() as i32)
        })
        .collect()
}

/// The front surfaces by brute force: edge `i` faces `p` when `p` is strictly
/// right of it (outside), orientation in `i128`.
fn front_oracle(v: &[Point], p: Point) -> u64 {
    let n = v.len();
    let mut bits = 0u64;
    for i in 0..n {
        let (a, b) = (v[i], v[(i + 1) % n]);
        let o = (b.x as i128 - a.x as i128) * (p.y as i128 - a.y as i128)
            - (b.y as i128 - a.y as i128) * (p.x as i128 - a.x as i128);
        if o < 0 {
            bits |= 1 << i;
        }
    }
    bits
}

#[test]
fn front_surfaces_at_every_vertex_count_up_to_the_buffered_maximum() {
    assert_eq!(MAX_BUFFERED_VERTICES, 32);
    for n in 2..=MAX_BUFFERED_VERTICES {
        let v = regular(n, 1.0e6, (0, 0));
        let piece = Convex::new(&v).unwrap_or_else(|e| panic!("{n}-gon: {e:?}"));
        // Points all round it, near and far: each edge's bit exactly as the oracle.
        for k in 0..360 {
            for r in [1.0e6 + 10.0, 2.0e6, 5.0e7] {
                let a = (k as f64).to_radians();
                let p = Point::new((r * a.cos()).round() as i32, (r * a.sin()).round() as i32);
                let t = piece.tvector(p);
                assert_eq!(u64::from(piece.front_surfaces(t)), front_oracle(&v, p), "n {n} point {p:?}");
            }
        }
        // From inside: no front surface.
        assert_eq!(piece.front_surfaces(piece.tvector(Point::new(0, 0))), 0, "n {n}");
    }
}

#[test]
fn a_24_vertex_piece_buffered_to_32_vertices_keeps_its_last_edge() {
    // The case of the issue: 24 vertices, buffered, 32 (the octagon adds 8).
    let v = regular(MAX_PIECE_VERTICES, 5.0e5, (0, 0));
    let grown = grow(Convex::new(&v).unwrap(), 150).unwrap();
    let g = Convex::new(&grown).unwrap();
    assert_eq!(g.len(), MAX_BUFFERED_VERTICES, "the buffered piece has the maximum count");
    let mut seen = 0u64;
    for k in 0..3600 {
        let a = (k as f64 / 10.0).to_radians();
        let p = Point::new((6.0e5 * a.cos()).round() as i32, (6.0e5 * a.sin()).round() as i32);
        let f = g.front_surfaces(g.tvector(p));
        assert_eq!(u64::from(f), front_oracle(&grown, p), "point {p:?}");
        seen |= u64::from(f);
    }
    assert_eq!(seen, u64::from(u32::MAX), "every one of the 32 edges faces some point, edge 31 included");
}

/// The ring's firing time by its formula, in `u128` with the whole `slot`,
/// reduced modulo 2³² at the end (the documented wrap).
fn offset_oracle<const N: usize>(rt: &RingTiming<N>, cycle: u32, slot: usize) -> u32 {
    let (c, s) = (u128::from(cycle), slot as u128);
    let odd = u128::from(cycle % 2 == 1);
    let t =
        c * u128::from(rt.period_us()) + s * u128::from(rt.slot_us()) + odd * (s + 1) * u128::from(rt.alternating_us());
    (t % (1u128 << 32)) as u32
}

fn ring_timing() -> RingTiming<24> {
    let module = ModuleConfig::polaroid_6500(SpeedOfSound::at_centi_celsius(2_000).unwrap()).timing().unwrap();
    RingConfig { ring_down_us: 3_000, eeruf: Some(Eeruf { alternating_us: 1_000, tolerance_mm: 50 }) }
        .timing::<24>(&module)
        .unwrap()
}

#[test]
fn fire_offset_at_every_slot_of_many_cycles_and_at_the_extremes() {
    let rt = ring_timing();
    let extremes = [0usize, 1, 23, 24, u32::MAX as usize - 1, u32::MAX as usize, u32::MAX as usize + 1, usize::MAX];
    let cycles = (0..2_000u32).chain([u32::MAX - 1, u32::MAX, 1 << 31, (1 << 31) + 1]);
    for cycle in cycles {
        for slot in (0..24).chain(extremes) {
            assert_eq!(rt.fire_offset_us(cycle, slot), offset_oracle(&rt, cycle, slot), "cycle {cycle} slot {slot}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    #[test]
    fn fire_offset_for_any_cycle_and_slot(cycle in any::<u32>(), slot in any::<usize>()) {
        let rt = ring_timing();
        prop_assert_eq!(rt.fire_offset_us(cycle, slot), offset_oracle(&rt, cycle, slot));
    }

    /// `cross` and `dot` are exact over their documented domain (components
    /// within ±(2³¹ − 1)), against `i128`.
    #[test]
    fn cross_and_dot_exact_over_their_domain(
        a in -(i32::MAX as i64)..=i32::MAX as i64, b in -(i32::MAX as i64)..=i32::MAX as i64,
        c in -(i32::MAX as i64)..=i32::MAX as i64, d in -(i32::MAX as i64)..=i32::MAX as i64,
    ) {
        let w = |x: i64| x as i128;
        prop_assert_eq!(cross((a, b), (c, d)) as i128, w(a) * w(d) - w(b) * w(c));
        prop_assert_eq!(dot((a, b), (c, d)) as i128, w(a) * w(c) + w(b) * w(d));
    }

    /// `octagon_s` for any `u32` against the definition: the least `s` with
    /// `(a + s)² ≥ 2a²`, found by bisection in `u128`.
    #[test]
    fn octagon_s_for_any_u32(a in any::<u32>()) {
        prop_assert_eq!(u128::from(octagon_s(a)), octagon_s_oracle(a));
    }

    #[test]
    fn isqrt_for_any_u64(n in any::<u64>()) {
        let r = u128::from(isqrt(n));
        prop_assert!(r * r <= u128::from(n) && (r + 1) * (r + 1) > u128::from(n));
    }

    /// `U256` products order like the numbers: for 64-bit factors the
    /// products fit `u128`, the oracle.
    #[test]
    fn u256_products_order_like_the_numbers(a in any::<u64>(), b in any::<u64>(), c in any::<u64>(), d in any::<u64>()) {
        // Products of 64-bit values fit u128: U256 must order them the same.
        let (p, q) = (u128::from(a) * u128::from(b), u128::from(c) * u128::from(d));
        prop_assert_eq!(U256::mul(u128::from(a), u128::from(b)).cmp(&U256::mul(u128::from(c), u128::from(d))), p.cmp(&q));
    }
}

fn octagon_s_oracle(a: u32) -> u128 {
    let a = u128::from(a);
    let target = 2 * a * a;
    let (mut lo, mut hi) = (0u128, a + 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if (a + mid) * (a + mid) >= target {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

#[test]
fn octagon_s_near_every_boundary() {
    for a in (0..200_000u32).chain(u32::MAX - 100_000..=u32::MAX).chain((1u32 << 31) - 1000..(1u32 << 31) + 1000) {
        assert_eq!(u128::from(octagon_s(a)), octagon_s_oracle(a), "a {a}");
    }
}

#[test]
fn octagon_and_grow_refuse_a_buffer_beyond_the_limit() {
    assert_eq!(octagon(MAX_BUFFER_MM + 1), Err(BufferError::BufferTooLarge));
    assert_eq!(octagon(u32::MAX), Err(BufferError::BufferTooLarge));
    let o = octagon(MAX_BUFFER_MM).unwrap();
    assert!(o.iter().all(|p| p.in_range()) && Convex::new(&o).is_ok());
    let v = regular(8, 1_000.0, (0, 0));
    assert_eq!(grow(Convex::new(&v).unwrap(), u32::MAX), Err(BufferError::BufferTooLarge));
    // A piece at the edge of the coordinate range cannot grow past it.
    let edge = regular(8, 1_000.0, (COORD_MAX - 1_000, 0));
    assert_eq!(grow(Convex::new(&edge).unwrap(), 10), Err(BufferError::CoordinateOutOfRange));
}

#[test]
fn convex_refuses_more_vertices_than_a_t_vector_holds() {
    let v = regular(MAX_BUFFERED_VERTICES + 1, 1.0e6, (0, 0));
    assert!(Convex::new(&v).is_err());
}

#[test]
fn speed_of_sound_at_every_temperature_and_time() {
    for t in i16::MIN..=i16::MAX {
        match SpeedOfSound::at_centi_celsius(t) {
            Ok(s) => {
                assert!((SpeedOfSound::MIN_CENTI_CELSIUS..=SpeedOfSound::MAX_CENTI_CELSIUS).contains(&t));
                // c = 331.3 m/s · √(T / 273.15 K), to the µm/s.
                let tk = f64::from(t) / 100.0 + 273.15;
                let c = 331_300_000.0 * (tk / 273.15).sqrt();
                assert!((f64::from(s.um_per_s()) - c).abs() <= 1.0, "t {t}: {} vs {c}", s.um_per_s());
            }
            Err(e) => {
                assert_eq!(e, ConfigError::Temperature);
                assert!(!(SpeedOfSound::MIN_CENTI_CELSIUS..=SpeedOfSound::MAX_CENTI_CELSIUS).contains(&t));
            }
        }
    }
    for um in [0, 299_999_999, 400_000_001, u32::MAX] {
        assert_eq!(SpeedOfSound::from_um_per_s(um), Err(ConfigError::SpeedOfSound));
    }
    for um in [300_000_000, 343_000_000, 400_000_000] {
        let s = SpeedOfSound::from_um_per_s(um).unwrap();
        for x in [0, 1, 1_000, 1 << 20, u32::MAX - 1, u32::MAX] {
            // Range: round(x · c / 2·10⁹); time: ⌈x · 2·10⁹ / c⌉ capped at u32::MAX.
            let c = u128::from(um);
            let range = (u128::from(x) * c + 1_000_000_000) / 2_000_000_000;
            assert_eq!(u128::from(s.range_mm(x)), range, "range_mm({x}) at {um}");
            let tof = (u128::from(x) * 2_000_000_000).div_ceil(c).min(u128::from(u32::MAX));
            assert_eq!(u128::from(s.tof_us(x)), tof, "tof_us({x}) at {um}");
            let beyond = ((2 * u128::from(x) + 1) * 1_000_000_000).div_ceil(c).min(u128::from(u32::MAX));
            assert_eq!(u128::from(s.tof_us_beyond(x)), beyond, "tof_us_beyond({x}) at {um}");
        }
    }
}

#[test]
fn schedules_for_any_stride() {
    for stride in (0..100usize).chain([usize::MAX - 1, usize::MAX, 1 << 40]) {
        let gcd = |mut a: usize, mut b: usize| {
            while b != 0 {
                (a, b) = (b, a % b);
            }
            a
        };
        let ok = stride != 0 && gcd(stride % 24, 24) == 1;
        assert_eq!(Schedule::<24>::stride(stride).is_ok(), ok, "stride {stride}");
    }
}

#[test]
fn frame_sizes_saturate_beyond_memory() {
    // A payload of n bytes: 2 delimiters + COBS of n + 5 bytes (one
    // overhead byte per started 254, the COBS specification's bound).
    for n in [0usize, 1, 100, 248, 249, 250, 503, 504, 1 << 20, usize::MAX / 2 - 5] {
        let m = n + 5;
        assert_eq!(max_frame_len(n), 2 + m + m.div_ceil(254), "n {n}");
    }
    assert_eq!(max_frame_len(usize::MAX), usize::MAX);
    assert_eq!(max_frame_len(usize::MAX - 3), usize::MAX);
}

/// Extreme values of every numeric type a constructor or function takes.
const U32S: [u32; 8] = [0, 1, 2, 499, 5_500, 100_000, u32::MAX - 1, u32::MAX];
const F32S: [f32; 12] =
    [0.0, -0.0, 1e-30, 0.5, 29.99, 89.999, 90.0, 1e30, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];

#[test]
fn window_params_for_any_fields() {
    use echoloc::window::{WindowError, WindowParams, MAX_PSEUDO_PATHS};
    for r_min_mm in U32S {
        for r_max_mm in U32S {
            for half_angle_deg in F32S {
                for delta_max_deg in [0.0, 15.0, 89.9, 90.0, -1.0, f32::NAN] {
                    for ds_min_mm in [0, 1, 300, u32::MAX] {
                        for tb_mm in [0, 300, u32::MAX] {
                            let w =
                                WindowParams { r_min_mm, r_max_mm, half_angle_deg, delta_max_deg, ds_min_mm, tb_mm };
                            let valid = r_max_mm > 0
                                && r_max_mm <= echoloc::window::MAX_RANGE_MM
                                && r_min_mm < r_max_mm
                                && half_angle_deg > 0.0
                                && half_angle_deg < 90.0
                                && (0.0..90.0).contains(&delta_max_deg)
                                && ds_min_mm > 0;
                            assert_eq!(w.validate().is_ok(), valid, "{w:?}");
                            match w.layout() {
                                Ok(l) => {
                                    assert!(valid && l.n_pp >= 1 && l.n_pp as usize <= MAX_PSEUDO_PATHS, "{w:?}");
                                    for k in [0, l.n_pp - 1, u32::MAX] {
                                        assert!(!l.endpoint_x(k).is_nan(), "{w:?} k {k}");
                                    }
                                }
                                Err(WindowError::TooManyPseudoPaths(_)) => assert!(valid),
                                Err(_) => assert!(!valid, "{w:?}"),
                            }
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn sectors_at_any_apex_heading_and_range() {
    use echoloc::window::Sector;
    let coords = [0, 1, -1, 1 << 20, COORD_MAX - 6_000, COORD_MAX, -COORD_MAX, i32::MAX, i32::MIN];
    for x in coords {
        for y in [0, COORD_MAX, i32::MIN] {
            for heading in F32S {
                for half in [1e-6f32, 0.26, 1.5, std::f32::consts::FRAC_PI_2, 2.0, f32::NAN] {
                    for (r_min, r_max) in [(0, 1), (408, 5_500), (0, u32::MAX), (u32::MAX, u32::MAX), (5_499, 5_500)] {
                        let apex = Point::new(x, y);
                        // Every argument: a sector or a typed error, never a panic.
                        let Ok(s) = Sector::new(apex, heading, half, r_min, r_max) else { continue };
                        // A sector made: its box and its membership tests run, and
                        // the apex plus R_max stays in range.
                        let reach = i64::from(r_max) + 2;
                        assert!(i64::from(x).abs() + reach <= i64::from(COORD_MAX), "{s:?}");
                        let b = s.bbox();
                        assert!(b.min.x <= x && x <= b.max.x && b.min.y <= y && y <= b.max.y);
                        let _ = s.contains(Point::new(x.saturating_add(1_000), y));
                        let _ = s.to_map(f32::MAX, f32::MIN);
                    }
                }
            }
        }
    }
}

#[test]
fn kappa_for_any_range_and_angle() {
    use echoloc::credence::net::CredenceNet;
    let net = CredenceNet::shipped();
    let mut last = None;
    for r in U32S.into_iter().chain([500, 2_000, 8_000]) {
        for t in [i32::MIN, -90_000, -1, 0, 1, 45_000, 90_000, i32::MAX] {
            let k = net.kappa_at(r, t);
            // κ is in [0, 1]; the sign of the angle does not matter.
            assert!(k.to_num::<f32>() >= 0.0 && k.to_num::<f32>() <= 1.0);
            if t != i32::MIN {
                assert_eq!(k, net.kappa_at(r, -t), "r {r} θ {t}");
            }
            last = Some(k);
        }
    }
    assert!(last.is_some());
}

#[test]
fn points_and_predicates_at_the_coordinate_limits() {
    use echoloc::geometry::{orient, point_on_segment, segments_intersect};
    let m = COORD_MAX;
    let corners = [Point::new(-m, -m), Point::new(m, -m), Point::new(m, m), Point::new(-m, m), Point::new(0, 0)];
    for &a in &corners {
        for &b in &corners {
            // dist2 exact against i128 at the limits of the range.
            let (dx, dy) = (i128::from(a.x) - i128::from(b.x), i128::from(a.y) - i128::from(b.y));
            assert_eq!(i128::from(a.dist2(b)), dx * dx + dy * dy);
            for &c in &corners {
                let o = (i128::from(b.x) - i128::from(a.x)) * (i128::from(c.y) - i128::from(a.y))
                    - (i128::from(b.y) - i128::from(a.y)) * (i128::from(c.x) - i128::from(a.x));
                assert_eq!(i128::from(orient(a, b, c)), o);
                let _ = point_on_segment(a, b, c);
                for &d in &corners {
                    let _ = segments_intersect(a, b, c, d);
                }
            }
        }
    }
    // Outside the range the predicates answer (they wrap, as documented),
    // and the constructors that take points refuse them.
    let far = [Point::new(i32::MIN, i32::MIN), Point::new(i32::MAX, 0)];
    let _ = far[0].dist2(far[1]);
    let _ = far[0].dist2(Point::new(0, 0));
    let _ = orient(far[0], far[1], Point::new(0, 0));
    assert!(Convex::new(&[far[0], far[1], Point::new(0, 0)]).is_err());
}

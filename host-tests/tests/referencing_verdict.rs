//! Verdicts (`referencing::verdict`): the edges the unit tests in
//! `verdict.rs` leave out (the blanking and κ_high boundaries exactly,
//! saturating tolerances, extreme ranges, guard order), and `judge` against
//! an independent table in i128 over random inputs; counts saturate.

use echoloc::credence::Kappa;
use echoloc::geometry::Point;
use echoloc::predict::{Case, Prediction};
use echoloc::referencing::{judge, Reading, Verdict, VerdictConfig, VerdictCounts};
use proptest::prelude::*;

const CFG: VerdictConfig = VerdictConfig::POLAROID;

fn pred(range_mm: u32, kappa: Kappa, tolerance_mm: u32) -> Prediction {
    Prediction {
        range_mm,
        kappa,
        theta_mdeg: 0,
        delta_mdeg: 0,
        piece: 0,
        obstacle: 0,
        edge: 0,
        point: Point::new(0, 0),
        tolerance_mm,
        case: Case::II,
        nearer_mm: None,
    }
}

/// The table as DESIGN §4.6 words it, in i128 so nothing overflows.
fn oracle(reading: Reading, p: Option<&Prediction>, cfg: &VerdictConfig) -> Verdict {
    let Some(p) = p else {
        return match reading {
            Reading::Invalid => Verdict::Inconclusive,
            Reading::Echo { .. } => Verdict::Unpredicted,
            Reading::NoEcho => Verdict::NothingAsPredicted,
        };
    };
    if matches!(reading, Reading::Invalid) || (p.range_mm as i128) < cfg.min_range_mm as i128 {
        return Verdict::Inconclusive;
    }
    match reading {
        Reading::Echo { range_mm } => {
            let d = range_mm as i128 - p.range_mm as i128;
            if d.abs() <= p.tolerance_mm as i128 + cfg.timing_mm as i128 {
                Verdict::Confirmed
            } else if d < 0 {
                // Short, but no shorter than a nearer mapped surface less the tolerance.
                match p.nearer_mm {
                    Some(n) if range_mm as i128 + p.tolerance_mm as i128 + cfg.timing_mm as i128 >= n as i128 => {
                        Verdict::Inconclusive
                    }
                    _ => Verdict::UnknownObstacle,
                }
            } else {
                Verdict::RemovedOrMissed
            }
        }
        _ if p.kappa.to_bits() >= cfg.kappa_high.to_bits() => Verdict::RemovedOrMissed,
        _ => Verdict::Inconclusive,
    }
}

#[test]
fn blanking_boundary() {
    let hi = Kappa::from_num(0.9);
    let at = pred(CFG.min_range_mm, hi, 20);
    let below = pred(CFG.min_range_mm - 1, hi, 20);
    // A prediction exactly at the nearest range is judged, one mm nearer is not.
    assert_eq!(judge(Reading::Echo { range_mm: CFG.min_range_mm }, Some(&at), &CFG), Verdict::Confirmed);
    assert_eq!(judge(Reading::NoEcho, Some(&at), &CFG), Verdict::RemovedOrMissed);
    assert_eq!(judge(Reading::Echo { range_mm: CFG.min_range_mm }, Some(&below), &CFG), Verdict::Inconclusive);
    // Blanking wins over a confident missing echo and over a far echo.
    assert_eq!(judge(Reading::NoEcho, Some(&below), &CFG), Verdict::Inconclusive);
    assert_eq!(judge(Reading::Echo { range_mm: 5000 }, Some(&below), &CFG), Verdict::Inconclusive);
}

#[test]
fn kappa_high_boundary() {
    let at = pred(2000, CFG.kappa_high, 50);
    let below = pred(2000, Kappa::from_bits(CFG.kappa_high.to_bits() - 1), 50);
    assert_eq!(judge(Reading::NoEcho, Some(&at), &CFG), Verdict::RemovedOrMissed);
    assert_eq!(judge(Reading::NoEcho, Some(&below), &CFG), Verdict::Inconclusive);
    // κ does not matter to an echo.
    let zero = pred(2000, Kappa::ZERO, 50);
    assert_eq!(judge(Reading::Echo { range_mm: 2000 }, Some(&zero), &CFG), Verdict::Confirmed);
    assert_eq!(judge(Reading::Echo { range_mm: 1000 }, Some(&zero), &CFG), Verdict::UnknownObstacle);
    // κ_high = 0: every missing echo counts.
    let cfg = VerdictConfig { kappa_high: Kappa::ZERO, ..CFG };
    assert_eq!(judge(Reading::NoEcho, Some(&zero), &cfg), Verdict::RemovedOrMissed);
}

#[test]
fn invalid_is_inconclusive_whatever_the_prediction() {
    assert_eq!(judge(Reading::Invalid, None, &CFG), Verdict::Inconclusive);
    assert_eq!(judge(Reading::Invalid, Some(&pred(100, Kappa::MAX, 0)), &CFG), Verdict::Inconclusive);
}

#[test]
fn extreme_ranges_and_tolerances_do_not_overflow() {
    let hi = Kappa::from_num(0.9);
    // The tolerance plus the timing saturates instead of wrapping to a
    // tiny window.
    let wide = pred(2000, hi, u32::MAX);
    for r in [0, 1, 2000, u32::MAX] {
        assert_eq!(judge(Reading::Echo { range_mm: r }, Some(&wide), &CFG), Verdict::Confirmed, "{r}");
    }
    let cfg = VerdictConfig { timing_mm: u32::MAX, ..CFG };
    assert_eq!(judge(Reading::Echo { range_mm: u32::MAX }, Some(&pred(2000, hi, 50)), &cfg), Verdict::Confirmed);
    // Zero tolerance and zero timing: only the exact range confirms.
    let exact = VerdictConfig { timing_mm: 0, ..CFG };
    let p = pred(2000, hi, 0);
    assert_eq!(judge(Reading::Echo { range_mm: 2000 }, Some(&p), &exact), Verdict::Confirmed);
    assert_eq!(judge(Reading::Echo { range_mm: 1999 }, Some(&p), &exact), Verdict::UnknownObstacle);
    assert_eq!(judge(Reading::Echo { range_mm: 2001 }, Some(&p), &exact), Verdict::RemovedOrMissed);
    // Echoes at the ends of the u32 range.
    let far = pred(u32::MAX, hi, 10);
    assert_eq!(judge(Reading::Echo { range_mm: 0 }, Some(&far), &CFG), Verdict::UnknownObstacle);
    assert_eq!(judge(Reading::Echo { range_mm: u32::MAX }, Some(&far), &CFG), Verdict::Confirmed);
    assert_eq!(
        judge(Reading::Echo { range_mm: u32::MAX }, Some(&pred(CFG.min_range_mm, hi, 10)), &CFG),
        Verdict::RemovedOrMissed
    );
    assert_eq!(judge(Reading::Echo { range_mm: 0 }, None, &CFG), Verdict::Unpredicted);
    // min_range 0: nothing is too near.
    let cfg = VerdictConfig { min_range_mm: 0, ..CFG };
    assert_eq!(judge(Reading::Echo { range_mm: 0 }, Some(&pred(0, hi, 0)), &cfg), Verdict::Confirmed);
}

#[test]
fn counts_saturate_and_land_in_their_own_field() {
    let all = [
        Verdict::Confirmed,
        Verdict::UnknownObstacle,
        Verdict::RemovedOrMissed,
        Verdict::Unpredicted,
        Verdict::NothingAsPredicted,
        Verdict::Inconclusive,
    ];
    let fields = |c: &VerdictCounts| {
        [c.confirmed, c.unknown_obstacle, c.removed_or_missed, c.unpredicted, c.nothing_as_predicted, c.inconclusive]
    };
    for (i, v) in all.iter().enumerate() {
        let mut c = VerdictCounts::default();
        c.add(*v);
        let f = fields(&c);
        assert_eq!(f.iter().sum::<u32>(), 1);
        assert_eq!(f[i], 1, "{v:?}");
        assert_eq!(c.total(), 1);
        assert_eq!(c.judged(), u32::from(*v != Verdict::Inconclusive));
    }
    let full = VerdictCounts {
        confirmed: u32::MAX,
        unknown_obstacle: u32::MAX,
        removed_or_missed: u32::MAX,
        unpredicted: u32::MAX,
        nothing_as_predicted: u32::MAX,
        inconclusive: u32::MAX,
    };
    let mut c = full;
    for v in all {
        c.add(v);
    }
    c += full;
    assert_eq!(c, full);
    assert_eq!((c.judged(), c.total()), (u32::MAX, u32::MAX));
}

fn reading() -> impl Strategy<Value = Reading> {
    prop_oneof![
        Just(Reading::Invalid),
        Just(Reading::NoEcho),
        any::<u32>().prop_map(|r| Reading::Echo { range_mm: r }),
        (0u32..6000).prop_map(|r| Reading::Echo { range_mm: r }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    #[test]
    fn judge_matches_the_table(
        r in reading(),
        has in any::<bool>(),
        range in prop_oneof![0u32..6000, any::<u32>()],
        kappa in any::<u16>(),
        tol in prop_oneof![0u32..300, any::<u32>()],
        timing in prop_oneof![0u32..5, any::<u32>()],
        min_range in prop_oneof![Just(408u32), 0u32..1000],
        kappa_high in any::<u16>(),
        near in -400i64..400,
        nearer in prop_oneof![Just(None), (0u32..6000).prop_map(Some), any::<u32>().prop_map(Some)],
    ) {
        let p = Prediction { nearer_mm: nearer, ..pred(range, Kappa::from_bits(kappa), tol) };
        let cfg = VerdictConfig { timing_mm: timing, kappa_high: Kappa::from_bits(kappa_high), min_range_mm: min_range };
        // Often put the echo near the prediction's tolerance edges.
        let r = match r {
            // ... or the nearer surface's.
            Reading::Echo { range_mm } if range_mm % 3 == 1 && nearer.is_some() => {
                let n = nearer.unwrap_or(0) as i64;
                let edge = n - (tol as i64 + timing as i64) + near / 100;
                Reading::Echo { range_mm: edge.clamp(0, u32::MAX as i64) as u32 }
            }
            Reading::Echo { range_mm } if range_mm % 2 == 0 => {
                let edge = range as i64 + near.signum() * (tol as i64 + timing as i64) + near / 100;
                Reading::Echo { range_mm: edge.clamp(0, u32::MAX as i64) as u32 }
            }
            r => r,
        };
        let pp = if has { Some(&p) } else { None };
        prop_assert_eq!(judge(r, pp, &cfg), oracle(r, pp, &cfg));
    }
}

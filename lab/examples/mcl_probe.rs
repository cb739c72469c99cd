//! How well the particles' measurement model (the beam model on the
//! compiled map's field) tells the true pose from others, on a simulated
//! run: per cycle, the truth's log-likelihood against random poses and
//! poses near it; over cycles, the truth's trajectory against random
//! trajectories carried by the same motion (docs/localization.md), and its
//! lead over the best wrong place (a start beyond 1 m or 20°) every 10
//! cycles and the distance travelled by then (issue #36 item 1's
//! "before").
//!
//! ```text
//! cargo run --release -p echoloc-lab --example mcl_probe -- ../shared/data/maps/depot.yaml 1 0.5
//! ```
//! Environment: `SIG`, `REL` (the hit's σ, mm and fraction), `USC`,
//! `MISS`, `UNP`, `HIT` (the beam model's other settings), `NTRAJ` (random
//! trajectories), `V` (per-cycle lines), `DIAG` (after 40 cycles, the
//! readings by what they are at the truth, hit, short, long, unpredicted,
//! miss, nothing, and the truth's lead over the best wrong place on each),
//! `CLIP`, `NULL_MEMORY`, `HYBRID` (the null hypothesis's settings, and
//! with `HYBRID` a reading where a place expects nothing scores as the
//! null scores it; every 10 cycles, the truth's and the best wrong
//! place's summed lead over the null).
#![allow(clippy::needless_range_loop)]
use echoloc::localize::{FieldLookup, McConfig, ParticleSet, Rng, Sensed};
use echoloc::referencing::Reading;
use echoloc_lab::simulate::{filters, to_records, world};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let map_path = std::path::Path::new(&args[1]);
    let seed: u64 = args[2].parse().unwrap();
    let inc: f64 = args[3].parse().unwrap();
    let loaded = echoloc_lab::predict::load_map_with_field(map_path, 100).unwrap();
    let map = loaded.view().unwrap();
    let mounts = echoloc_lab::predict::ring_mounts("pioneer16").unwrap();
    let cfg = world::WorldConfig::new(seed, 40.0, inc, mounts.clone());
    let run = world::simulate_world(&map, &cfg, &mut |_| {}).unwrap();
    let records = to_records(&run.readings).unwrap();
    let lookup = FieldLookup::new(map.field());
    let mut mc = McConfig::DEFAULT;
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    mc.beam.sigma_mm = env("SIG", mc.beam.sigma_mm);
    mc.beam.sigma_rel = env("REL", mc.beam.sigma_rel);
    mc.beam.unsure_sigma_scale = env("USC", mc.beam.unsure_sigma_scale);
    mc.beam.p_miss_sure = env("MISS", mc.beam.p_miss_sure);
    mc.beam.p_unpredicted = env("UNP", mc.beam.p_unpredicted);
    let hit = env("HIT", mc.beam.sure_mix[0]);
    mc.beam.sure_mix = [hit, (1.0 - hit) * 0.66, (1.0 - hit) * 0.34];
    let mut kept: Vec<(Vec<Sensed>, [f32; 3])> = Vec::new();
    let mut kept_null: Vec<Vec<f32>> = Vec::new();
    let mut best40: Option<[f32; 3]> = None;
    let mut stats = (0usize, 0usize, 0f64, 0f64, 0f64, 0f64);
    let sound = echoloc::driver::SpeedOfSound::from_um_per_s(run.sound.um_per_s()).unwrap();
    let mut rng = Rng::new(5);
    let randoms: Vec<[f32; 3]> = (0..4096).map(|_| ParticleSet::<0>::free_pose(&mut rng, &lookup).unwrap()).collect();
    let ntraj: usize = std::env::var("NTRAJ").ok().and_then(|v| v.parse().ok()).unwrap_or(20000);
    // Random starting poses, each carried by the truth's own motion relative to the truth's start.
    let starts: Vec<[f32; 3]> = (0..ntraj).map(|_| ParticleSet::<0>::free_pose(&mut rng, &lookup).unwrap()).collect();
    let mut acc = vec![0f32; ntraj];
    // Displaced starts: (d m, δ deg) around the true start, 8 directions each.
    let disp: Vec<(f32, f32)> = vec![
        (0.1, 0.0),
        (0.2, 0.0),
        (0.3, 0.0),
        (0.5, 0.0),
        (0.8, 0.0),
        (0.0, 3.0),
        (0.0, 6.0),
        (0.0, 10.0),
        (0.0, 15.0),
        (0.3, 6.0),
    ];
    let mut dacc = vec![[0f32; 8]; disp.len()];
    let mut acc_truth = 0f32;
    let truth0 = records[0].truth;
    // ALIAS=cx,cy: the truth's half-turn about (cx, cy), carried by the
    // same motion, against the truth cycle by cycle (a symmetric map).
    let alias: Option<[f32; 3]> = std::env::var("ALIAS").ok().map(|v| {
        let c: Vec<f32> = v.split(',').map(|x| x.parse().unwrap()).collect();
        [2.0 * c[0] - truth0[0], 2.0 * c[1] - truth0[1], truth0[2] + std::f32::consts::PI]
    });
    let mut acc_alias = 0f32;
    // The null hypothesis (issue #48): the readings scored by their own
    // recent mix; the truth's summed lead over it, raw and with each
    // reading's log-ratio clipped to ±CLIP nats.
    let mut null =
        echoloc::localize::NullModel::new(mc.beam.r_min_mm, mc.beam.r_max_mm, env("NULL_MEMORY", 400.0)).unwrap();
    let clip = env("CLIP", 2.0);
    let hybrid = std::env::var("HYBRID").is_ok();
    let (mut acc_null, mut truth_null_clipped) = (0f32, 0f32);
    // A plainer null beside it: the echo rate so far (the same estimator
    // over two bins), an echo's range uniform over the window.
    let (mut echoes, mut misses, mut acc_plain) = (0f32, 0f32, 0f32);
    let span_m = (mc.beam.r_max_mm - mc.beam.r_min_mm) * 1e-3;
    let temper = env("TEMPER", 1.0);
    // The distance the truth has travelled, m (the leads' x axis in metres).
    let (mut travelled, mut last) = (0f32, truth0);
    // Group by cycle.
    let mut c = 0;
    while c < run.cycles {
        let recs: Vec<_> = records.iter().filter(|r| r.cycle == c as u32).collect();
        if recs.is_empty() {
            break;
        }
        let t0 = recs[0].truth;
        travelled += ((t0[0] - last[0]).powi(2) + (t0[1] - last[1]).powi(2)).sqrt();
        last = t0;
        let sensed: Vec<Sensed> = recs
            .iter()
            .map(|r| {
                let m = &mounts[r.transducer as usize];
                let (s, co) = (t0[2].sin(), t0[2].cos());
                // transducer pose in truth frame at cycle start, from true poses
                let mx = m.x_mm as f32 / 1000.0;
                let my = m.y_mm as f32 / 1000.0;
                let tx = r.truth[0] + r.truth[2].cos() * mx - r.truth[2].sin() * my;
                let ty = r.truth[1] + r.truth[2].sin() * mx + r.truth[2].cos() * my;
                let (dx, dy) = (tx - t0[0], ty - t0[1]);
                let pose = [
                    co * dx + s * dy,
                    -s * dx + co * dy,
                    r.truth[2] - t0[2] + (m.heading_mdeg as f32 / 1000.0).to_radians(),
                ];
                let reading = match r.echo_us {
                    Some(us) => Reading::Echo { range_mm: sound.range_mm(us) },
                    None => Reading::NoEcho,
                };
                Sensed { pose, reading }
            })
            .collect();
        let mut null_lls = Vec::with_capacity(sensed.len());
        for r in &sensed {
            let n = null.log_likelihood(r.reading);
            null_lls.push(n);
            acc_null += n;
            match r.reading {
                Reading::Echo { range_mm } if (range_mm as f32) <= mc.beam.r_max_mm => {
                    acc_plain += ((echoes + 0.5) / (echoes + misses + 1.0) / span_m).ln();
                    echoes += 1.0;
                }
                Reading::Invalid => {}
                _ => {
                    acc_plain += ((misses + 0.5) / (echoes + misses + 1.0)).ln();
                    misses += 1.0;
                }
            }
        }
        // Each reading's log-likelihood at pose `p` (`None`: invalid). With
        // HYBRID a reading where the place expects nothing scores as the
        // null scores it (the place neither gains nor loses on it).
        let each = |p: [f32; 3]| {
            let (s, co) = (p[2].sin(), p[2].cos());
            sensed.iter().zip(&null_lls).map(move |(r, &n)| {
                let tx = p[0] + co * r.pose[0] - s * r.pose[1];
                let ty = p[1] + s * r.pose[0] + co * r.pose[1];
                let e = lookup.expected(tx * 1e3, ty * 1e3, p[2] + r.pose[2]);
                (r.reading != Reading::Invalid).then(|| {
                    if hybrid && e == Some(echoloc::map::field::Expected::Nothing) {
                        n
                    } else {
                        mc.beam.likelihood(r.reading, e).ln()
                    }
                })
            })
        };
        let ll = |p: &[f32; 3]| -> f32 { each(*p).flatten().sum() };
        let lt = ll(&t0);
        for (own, &n) in each(t0).zip(&null_lls) {
            if let Some(own) = own {
                truth_null_clipped += (own - n).clamp(-clip, clip);
            }
        }
        kept.push((sensed.clone(), t0));
        kept_null.push(null_lls.clone());
        // The truth's motion since the start, in the start's frame, applied to each random start.
        let (s0, c0) = (truth0[2].sin(), truth0[2].cos());
        let (gx, gy) = (t0[0] - truth0[0], t0[1] - truth0[1]);
        let rel = [c0 * gx + s0 * gy, -s0 * gx + c0 * gy, t0[2] - truth0[2]];
        acc_truth += temper * lt;
        if let Some(st) = alias {
            let (s1, c1) = (st[2].sin(), st[2].cos());
            let p = [st[0] + c1 * rel[0] - s1 * rel[1], st[1] + s1 * rel[0] + c1 * rel[1], st[2] + rel[2]];
            let la = ll(&p);
            acc_alias += la;
            println!(
                "cycle {c}: truth {:?} {lt:.1}, alias {la:.1}; summed truth - alias {:.1}",
                t0,
                acc_truth - acc_alias
            );
        }
        for (k, st) in starts.iter().enumerate() {
            let (s1, c1) = (st[2].sin(), st[2].cos());
            let p = [st[0] + c1 * rel[0] - s1 * rel[1], st[1] + s1 * rel[0] + c1 * rel[1], st[2] + rel[2]];
            acc[k] += temper * ll(&p);
        }
        for (di, &(d, deg)) in disp.iter().enumerate() {
            for k in 0..8 {
                let a = k as f32 * 0.785;
                let sgn = if k % 2 == 0 { 1.0 } else { -1.0 };
                let st = [truth0[0] + d * a.cos(), truth0[1] + d * a.sin(), truth0[2] + sgn * deg.to_radians()];
                let (s1, c1) = (st[2].sin(), st[2].cos());
                let p = [st[0] + c1 * rel[0] - s1 * rel[1], st[1] + s1 * rel[0] + c1 * rel[1], st[2] + rel[2]];
                dacc[di][k] += temper * ll(&p);
            }
        }
        if c % 10 == 9 {
            for (di, &(d, deg)) in disp.iter().enumerate() {
                let mean: f32 = dacc[di].iter().sum::<f32>() / 8.0;
                print!("  [{d} m {deg}°: {:.0}]", mean - acc_truth);
            }
            println!();
            let mut order: Vec<usize> = (0..ntraj).collect();
            order.sort_by(|&a, &b| acc[b].partial_cmp(&acc[a]).unwrap());
            let better = acc.iter().filter(|&&a| a > acc_truth).count();
            let best = order[0];
            let st = starts[best];
            let dist = ((st[0] - truth0[0]).powi(2) + (st[1] - truth0[1]).powi(2)).sqrt();
            println!("after {} cycles: truth acc {:.1}; {} of {} random starts better; best {:.1} at {:.2} m from the true start", c+1, acc_truth, better, ntraj, acc[best], dist);
            // The best wrong place: a start beyond a metre or 20° of the
            // true one (the localizer's "same place", SAME_PLACE_*).
            let wrong = order.iter().find(|&&k| {
                let st = starts[k];
                let d = ((st[0] - truth0[0]).powi(2) + (st[1] - truth0[1]).powi(2)).sqrt();
                let a =
                    (st[2] - truth0[2] + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU) - std::f32::consts::PI;
                d > 1.0 || a.abs() > 20f32.to_radians()
            });
            if c + 1 == 40 {
                best40 = wrong.map(|&k| starts[k]);
            }
            println!(
                "null after {} cycles: truth - null {:.1} nats ({:.1} clipped at {clip}); best wrong place - null {:.1}; against the plain null: truth {:.1}, best wrong place {:.1}; travelled {travelled:.1} m",
                c + 1,
                acc_truth - acc_null,
                truth_null_clipped,
                wrong.map_or(f32::NAN, |&k| acc[k] - acc_null),
                acc_truth - acc_plain,
                wrong.map_or(f32::NAN, |&k| acc[k] - acc_plain)
            );
            if let Some(&k) = wrong {
                println!(
                    "lead after {} cycles: {:.1} nats over the best wrong place ({:.1} nats); travelled {travelled:.1} m",
                    c + 1,
                    acc_truth - acc[k],
                    acc[k]
                );
            }
        }
        let mut lr: Vec<f32> = randoms.iter().map(ll).collect();
        lr.sort_by(|a, b| b.partial_cmp(a).unwrap());
        let better = lr.iter().filter(|&&x| x >= lt).count();
        // near-truth perturbations
        let near: Vec<f32> = (0..8)
            .map(|k| {
                let a = k as f32 * 0.785;
                ll(&[t0[0] + 0.15 * a.cos(), t0[1] + 0.15 * a.sin(), t0[2]])
            })
            .collect();
        stats.0 += 1;
        if lt >= lr[0] {
            stats.1 += 1;
        }
        stats.2 += (lt - lr[0]) as f64;
        stats.3 += (lt - lr[40]) as f64;
        let nmin = near.iter().cloned().fold(f32::INFINITY, f32::min);
        stats.4 += (lt - nmin) as f64;
        stats.5 += (better as f64).ln_1p();
        if std::env::var("V").is_ok() && c % 5 == 0 {
            println!("cycle {c}: truth {lt:.1}  best-random {:.1} p99 {:.1} median {:.1}  randoms>=truth {better}/4096  near(0.15m) {:.1}..{:.1}", lr[0], lr[40], lr[2048], near.iter().cloned().fold(f32::INFINITY, f32::min), near.iter().cloned().fold(f32::NEG_INFINITY, f32::max));
        }
        c += 1;
    }
    let n = stats.0 as f64;
    println!("cycles {} truth>=best {:.2} mean(truth-best) {:.1} mean(truth-p99) {:.1} mean(truth-near0.15min) {:.1} mean ln(1+#better) {:.2}", stats.0, stats.1 as f64 / n, stats.2 / n, stats.3 / n, stats.4 / n, stats.5 / n);
    if let (Some(st), true) = (best40, std::env::var("DIAG").is_ok()) {
        // Per category of the reading at the truth: count, Σ(ll truth − ll wrong).
        let names = ["hit", "short", "long", "unpredicted", "miss", "none", "off"];
        let mut agg = [(0usize, 0f64); 7];
        // Over every cycle: the truth's lead over the null by category.
        let mut agg_null = [(0usize, 0f64); 7];
        let (s0, c0) = (truth0[2].sin(), truth0[2].cos());
        let b = &mc.beam;
        for (ci, (sensed, t0)) in kept.iter().enumerate() {
            let (gx, gy) = (t0[0] - truth0[0], t0[1] - truth0[1]);
            let rel = [c0 * gx + s0 * gy, -s0 * gx + c0 * gy, t0[2] - truth0[2]];
            let (s1, c1) = (st[2].sin(), st[2].cos());
            let pw = [st[0] + c1 * rel[0] - s1 * rel[1], st[1] + s1 * rel[0] + c1 * rel[1], st[2] + rel[2]];
            for (ri, r) in sensed.iter().enumerate() {
                if r.reading == Reading::Invalid {
                    continue;
                }
                let ex = |p: &[f32; 3]| {
                    let (s, co) = (p[2].sin(), p[2].cos());
                    let tx = p[0] + co * r.pose[0] - s * r.pose[1];
                    let ty = p[1] + s * r.pose[0] + co * r.pose[1];
                    lookup.expected(tx * 1e3, ty * 1e3, p[2] + r.pose[2])
                };
                let (et, ew) = (ex(t0), ex(&pw));
                let d = (b.likelihood(r.reading, et).ln() - b.likelihood(r.reading, ew).ln()) as f64;
                use echoloc::map::field::Expected as E;
                let z = match r.reading {
                    Reading::Echo { range_mm } if range_mm as f32 <= b.r_max_mm => Some(range_mm as f32),
                    _ => None,
                };
                let cat = match (et, z) {
                    (None, _) => 6,
                    (Some(E::Nothing), None) => 5,
                    (Some(E::Nothing), Some(_)) => 3,
                    (Some(E::Echo { .. }), None) => 4,
                    (Some(E::Echo { range_mm: rr, .. }), Some(z)) => {
                        let sg = 3.0 * (b.sigma_mm + b.sigma_rel * rr) * 2.0;
                        if (z - rr).abs() <= sg {
                            0
                        } else if z < rr {
                            1
                        } else {
                            2
                        }
                    }
                };
                agg_null[cat].0 += 1;
                agg_null[cat].1 += (b.likelihood(r.reading, et).ln() - kept_null[ci][ri]) as f64;
                if ci < 40 {
                    agg[cat].0 += 1;
                    agg[cat].1 += d;
                }
            }
        }
        for (k, n) in names.iter().enumerate() {
            println!(
                "diag {n:12} {:5} readings  truth - wrong {:8.1} nats; every cycle: {:5} readings, truth - null {:8.1} nats",
                agg[k].0, agg[k].1, agg_null[k].0, agg_null[k].1
            );
        }
    }
    let _ = filters::PARTICLES;
}

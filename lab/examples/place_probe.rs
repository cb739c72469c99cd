//! Places that track themselves (issue #48, step 2), on a simulated run:
//! `cargo run --release -p echoloc-lab --example place_probe -- MAP SEED CLUTTER`
//! (`echoloc_lab::simulate::places`). A row every 10 m of the truth's
//! travel: the place started at the truth displaced by `DISP` (forward m,
//! left m, turn rad; σ `START_SIGMA`), its errors, the same place carried
//! by the odometry alone, its evidence over the null, the best evidence of
//! `N` places started at random free poses now more than 1 m or 20° from
//! the truth, how many are within 0.5 m of it, and the tracked place's
//! accepted share. With `BANK=A`: instead, a bank of 8 places proposed by
//! the particles' cluster (and `SWEEP` of the node sweep's best places a
//! cycle), deciding at A nats: where a place first led, how far off, and then
//! the evidence of a living place near the truth, where a proposal first
//! came near it, and the particles' cluster (`scripts/bank-runs.sh`). `CLIP`, `NULL_MEMORY`, `DIST` (m, default 60), `EVERY`
//! (m between rows, default 10).
use echoloc_lab::simulate::places::{places_run, PlacesConfig};
use echoloc_lab::simulate::world::WorldConfig;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (map_path, seed, clutter) =
        (std::path::Path::new(&args[1]), args[2].parse::<u64>().unwrap(), args[3].parse::<f64>().unwrap());
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let env3 = |k: &str, d: [f32; 3]| {
        std::env::var(k).ok().map_or(d, |v| {
            let p: Vec<f32> = v.split(',').map(|x| x.parse().unwrap()).collect();
            [p[0], p[1], p[2]]
        })
    };
    let d = PlacesConfig::DEFAULT;
    let cfg = PlacesConfig {
        displaced: env3("DISP", d.displaced),
        sigma: env3("START_SIGMA", d.sigma),
        random: env("N", d.random as f32) as usize,
        random_sigma: env3("RAND_SIGMA", d.random_sigma),
        clip: env("CLIP", d.clip),
        null_memory: env("NULL_MEMORY", d.null_memory),
        every_m: env("EVERY", d.every_m),
        hit_share: env("HIT_SHARE", d.hit_share),
        ekf: {
            let mut e = d.ekf;
            e.var_heading_per_m *= env("HEAD_VAR", 1.0);
            e.var_heading_per_rad *= env("HEAD_VAR", 1.0);
            e
        },
    };
    let loaded = echoloc_lab::predict::load_map_with_field(map_path, 100).unwrap();
    let map = loaded.view().unwrap();
    let mounts = echoloc_lab::predict::ring_mounts("pioneer16").unwrap();
    let world = WorldConfig::new(seed, f64::from(env("DIST", 60.0)), clutter, mounts.clone());
    if let Ok(bound) = std::env::var("BANK") {
        let o = echoloc_lab::simulate::places::bank_run(
            &map,
            &world,
            &mounts,
            &cfg,
            bound.parse().unwrap(),
            env("SWEEP", 0.0) as usize,
        )
        .unwrap();
        let e = o.handoff_error.map_or("-\t-".into(), |(m, d)| format!("{m:.3}\t{d:.1}"));
        let h = o.handoff_m.map_or("-".into(), |m| format!("{m:.1}"));
        let opt = |v: Option<f32>| v.map_or("-".into(), |v| format!("{v:.1}"));
        let (cw, cd) =
            o.cluster_at_handoff.map_or(("-".into(), "-".into()), |(w, d)| (format!("{w:.2}"), format!("{d:.2}")));
        println!(
            "handoff_m\terr_m\terr_deg\tmost_living\ttravelled_m\ttruth_ev\ttruth_proposed_m\tcluster_w\tcluster_d\n{h}\t{e}\t{}\t{:.0}\t{}\t{}\t{cw}\t{cd}",
            o.most_living,
            o.travelled_m,
            opt(o.truth_alive),
            opt(o.truth_proposed_m)
        );
        return;
    }
    println!("m\ttruth_err_m\ttruth_dphi_deg\tdead_err_m\ttruth_ev\tbest_wrong_ev\tnear_truth\taccept");
    for r in places_run(&map, &world, &mounts, &cfg).unwrap() {
        println!(
            "{:.0}\t{:.3}\t{:.2}\t{:.3}\t{:.0}\t{:.0}\t{}\t{:.2}",
            r.travelled_m, r.error.0, r.error.1, r.dead_reckoning_m, r.evidence, r.best_wrong, r.near_truth, r.accepted
        );
    }
}

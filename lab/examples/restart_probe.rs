//! A search begun mid-run, as `/initialpose` or the global localization
//! service begins one (issue #50; how soon it finds itself is #48's): the
//! QEMU board's depot scenario replayed through the controller on the host
//! exactly as the `link` board runs it (the driver, 1 024 particles, seed
//! 1), the localizer restarted after reading `k` for each `k` asked, and
//! what became of it: where it tracked again and how far off, the worst
//! error while tracking after `k`, and the mode at the end.
//!
//! `cargo run --release -p echoloc-lab --example restart_probe -- FROM TO STEP [HOW]`
//!
//! `HOW`: `unknown` (the whole map), or `DX,SIGMA,SIGMA_YAW[,DY]`: a search
//! around the estimate at `k` moved by (DX, DY) m, σ SIGMA m and SIGMA_YAW
//! rad (default `2,2.5,0.5`: the ROS 2 test's `/initialpose`). `PT=B` turns
//! on the place test at bound B nats. A restart the localizer refuses (a
//! pose outside the free space) is said and the run goes on untouched.
use echoloc::controller::replay::{localizer, run, scenario_odometry, start, ReplaySetup};
use echoloc::credence::net::CredenceNet;
use echoloc::localize::localizer::{PlaceTest, Start};
use echoloc::localize::Mode;
use echoloc::map::{MapSource, MapView};
use echoloc::predict::{Mount, PredictParams};
use echoloc::scenario::replay::Bench;
use echoloc::scenario::Scenario;
use echoloc::window::WindowParams;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n = |i: usize| args.get(i).and_then(|a| a.parse::<usize>().ok()).expect("FROM TO STEP [HOW]");
    let (from, to, step) = (n(1), n(2), n(3).max(1));
    let how = args.get(4).cloned().unwrap_or_else(|| "2,2.5,0.5".into());
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let bytes = std::fs::read(root.join("boards/qemu-mps2-an386/depot.map")).expect("the board's depot map");
    let mut words = vec![0u64; bytes.len().div_ceil(8)];
    bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
    let map = MapView::new(&bytemuck::cast_slice::<u64, u8>(&words)[..bytes.len()]).expect("a map blob");
    let sb = std::fs::read(root.join("boards/qemu-mps2-an386/depot.scn")).expect("the board's scenario");
    let s = Scenario::parse(&sb).expect("a scenario");
    let truth: Vec<[f32; 3]> = s.records().map(|r| r.truth).collect();
    // As the board sets its ring up (qemu_mps2_an386::replay::setup).
    let window = WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::POLAROID_6500 }.with_map_lobe(map.field());
    let mut setup: ReplaySetup<16> = ReplaySetup::standard(PredictParams::new(window)).expect("the ring");
    if let Some(b) = std::env::var("PT").ok().and_then(|b| b.parse().ok()) {
        setup.localizer.place_test = Some(PlaceTest { bound: b, ..PlaceTest::DEFAULT });
    }
    let mounts: Vec<Mount> = (0..s.transducers()).filter_map(|i| s.mount(i)).collect();
    let net = CredenceNet::shipped();
    println!("k,how,refused,tracked_again_at,error_then_m,worst_tracking_error_after_m,final_mode,final_error_m");
    let (mut found, mut runs, mut wrong) = (0, 0, 0);
    for k in (from..=to).step_by(step) {
        let bench = Bench::new(s, 1_000);
        let mut loc = localizer::<1024, 16>(&setup, 1);
        start(&mut loc, &bench, map.field(), None).expect("the scenario's start");
        let (mut i, mut refused, mut again, mut worst, mut fin) = (0usize, false, None, 0f32, (Mode::Tracking, 0f32));
        let result = run::<_, _, 4, 16, 1024>(
            &bench,
            &map,
            map.field(),
            &mounts,
            &net,
            &setup,
            &mut loc,
            scenario_odometry,
            |c, _, _, _| {
                let p = c.state();
                if i == k {
                    let start = if how == "unknown" {
                        Start::Unknown
                    } else {
                        let v: Vec<f32> = how.split(',').filter_map(|x| x.parse().ok()).collect();
                        let at = |j: usize| v.get(j).copied().unwrap_or(0.0);
                        Start::Around { pose: [p[0] + at(0), p[1] + at(3), p[2]], sigma: [at(1), at(1), at(2)] }
                    };
                    refused = c.restart(start).is_err();
                }
                let (m, p) = (c.mode(), c.state());
                let e = (p[0] - truth[i][0]).hypot(p[1] - truth[i][1]);
                if i > k && m == Mode::Tracking {
                    worst = worst.max(e);
                    if again.is_none() {
                        again = Some((i, e));
                    }
                }
                fin = (m, e);
                i += 1;
            },
        );
        if let Err(e) = result {
            println!("{k},{},the loop stopped: {e}", how.replace(',', ";"));
            continue;
        }
        runs += 1;
        found += usize::from(!refused && fin.0 == Mode::Tracking && fin.1 < 0.3);
        wrong += usize::from(worst > 0.5);
        let again = again.map_or(",".into(), |(i, e)| format!("{i},{e:.3}"));
        println!("{k},{},{refused},{again},{worst:.3},{},{:.3}", how.replace(',', ";"), fin.0.name(), fin.1);
    }
    eprintln!("{runs} runs: {found} end tracking within 0.3 m; {wrong} tracked more than 0.5 m off after the restart");
}

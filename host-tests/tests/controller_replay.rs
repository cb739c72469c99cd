//! The whole loop on the host, as the QEMU board runs it: the committed
//! depot scenario (made by the lab's independent simulator) through the
//! replay bench, the real ring driver and the controller.
//!
//! - Differential: the driver path gives the filter, reading by reading, the
//!   very estimate a direct loop over the records gives (ranges from the
//!   scenario's echo times by the speed of sound, no driver): so the driver
//!   times every echo to the microsecond and fires in the scenario's order.
//! - Against the truth: the estimate meets the scenario's bounds; the same
//!   scenario with its truth shifted by 1 m fails them.
//! - Mismatches are refused with typed errors: another map, another ring
//!   timing, a record whose transducer the driver would not fire.

use echoloc::controller::replay::{
    check, localizer, run, scenario_odometry, start, ReplayError, ReplaySetup, ReplaySummary, Score,
};
use echoloc::credence::net::CredenceNet;
use echoloc::driver::SpeedOfSound;
use echoloc::map::{crc32, MapSource, MapView};
use echoloc::predict::{Mount, PredictParams};
use echoloc::referencing::{Ekf, Motion, Reading, Referencer};
use echoloc::scenario::replay::{Bench, BenchFault};
use echoloc::scenario::{write, Record, Scenario, ScenarioError};
use echoloc::window::WindowParams;

fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The file's bytes in 8-byte-aligned storage, as the compiled map needs.
fn aligned(path: &str) -> Vec<u64> {
    let bytes = std::fs::read(root().join(path)).unwrap();
    let mut words = vec![0u64; bytes.len().div_ceil(8)];
    bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
    words
}

fn scenario_bytes() -> Vec<u8> {
    std::fs::read(root().join("boards/qemu-mps2-an386/depot.scn")).unwrap()
}

struct Fixture {
    words: Vec<u64>,
    len: usize,
}

impl Fixture {
    fn new() -> Self {
        let len = std::fs::metadata(root().join("boards/qemu-mps2-an386/depot.map")).unwrap().len() as usize;
        Self { words: aligned("boards/qemu-mps2-an386/depot.map"), len }
    }
    fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice::<u64, u8>(&self.words)[..self.len]
    }
}

fn setup(map: &MapView<'_>) -> ReplaySetup<16> {
    ReplaySetup::standard(PredictParams::new(WindowParams { tb_mm: map.buffer_mm(), ..WindowParams::POLAROID_6500 }))
        .unwrap()
}

fn mounts(s: &Scenario<'_>) -> Vec<Mount> {
    (0..s.transducers()).map(|i| s.mount(i).unwrap()).collect()
}

#[test]
fn driver_path_equals_direct_loop_and_meets_the_bounds() {
    let fx = Fixture::new();
    let map = MapView::new(fx.bytes()).unwrap();
    let bytes = scenario_bytes();
    let scenario = Scenario::parse(&bytes).unwrap();
    let setup = setup(&map);
    let mounts = mounts(&scenario);
    let net = CredenceNet::shipped();
    let bench = Bench::new(scenario, 1_000);
    check(&bench, crc32(fx.bytes()), &setup).unwrap();
    let mut via_driver = Vec::new();
    let mut loc = localizer::<0, 16>(&setup, 1);
    start(&mut loc, &bench, map.field(), None).unwrap();
    let summary = run::<_, _, 4, 16, 0>(
        &bench,
        &map,
        map.field(),
        &mounts,
        &net,
        &setup,
        &mut loc,
        scenario_odometry,
        |c, r, rec, _| {
            via_driver.push((r.transducer, rec.cycle, c.state()));
        },
    )
    .unwrap();
    assert!(bench.done() && bench.fault().is_none());
    assert_eq!(via_driver.len(), scenario.len());

    // The direct loop: the lab's way, no driver.
    let header = scenario.header();
    let sound = SpeedOfSound::from_um_per_s(header.speed_um_per_s).unwrap();
    let ekf = Ekf::new(header.start, header.start_sigma, setup.ekf).unwrap();
    let mut referencer = Referencer::new(ekf, setup.verdicts);
    let mut score = Score::default();
    let mut cycle = None;
    for (k, rec) in scenario.records().enumerate() {
        if cycle.is_some_and(|c| c != rec.cycle) {
            referencer.end_cycle();
        }
        cycle = Some(rec.cycle);
        referencer.odometry(&Motion { dx: rec.odometry[0], dy: rec.odometry[1], dphi: rec.odometry[2] }).unwrap();
        let reading = rec.echo_us.map_or(Reading::NoEcho, |us| Reading::Echo { range_mm: sound.range_mm(us) });
        referencer.reading(&map, &mounts[usize::from(rec.transducer)], &setup.params, &net, reading).unwrap();
        score.add(referencer.ekf.state(), rec.truth);
        assert_eq!(via_driver[k], (rec.transducer, rec.cycle, referencer.ekf.state()), "reading {k}");
    }
    assert_eq!(summary.score, score);
    assert!(summary.passed, "{summary:?}");
    // Not a vacuous pass: the filter corrected the pose from echoes.
    assert!(summary.accepted > 200 && summary.counts.echoes > 1000, "{summary:?}");
    // Every echo the simulator wrote is one the driver accepts (none inside
    // blanking, none untimed).
    assert_eq!(summary.counts.invalid, 0, "{summary:?}");
    assert!(score.position_rmse_m < header.bound_position_m);
}

/// `bytes` replayed through the driver with the scenario's own odometry.
fn replay(bytes: &[u8], map: &MapView<'_>, setup: &ReplaySetup<16>) -> Result<ReplaySummary, ReplayError> {
    let scenario = Scenario::parse(bytes).unwrap();
    let bench = Bench::new(scenario, 1_000);
    let mut loc = localizer::<0, 16>(setup, 1);
    start(&mut loc, &bench, map.field(), None)?;
    run::<_, _, 4, 16, 0>(
        &bench,
        map,
        map.field(),
        &mounts(&scenario),
        &CredenceNet::shipped(),
        setup,
        &mut loc,
        scenario_odometry,
        |_, _, _, _| {},
    )
}

/// The scenario rewritten with each record changed by `f`.
fn rewritten(f: impl Fn(&mut Record)) -> Vec<u8> {
    let bytes = scenario_bytes();
    let s = Scenario::parse(&bytes).unwrap();
    let records: Vec<Record> = s
        .records()
        .map(|mut r| {
            f(&mut r);
            r
        })
        .collect();
    let mut out = Vec::new();
    write(s.header(), &mounts(&s), &records, |b| out.extend_from_slice(b)).unwrap();
    out
}

#[test]
fn truth_shifted_by_a_metre_fails_the_bounds() {
    let fx = Fixture::new();
    let map = MapView::new(fx.bytes()).unwrap();
    let bytes = rewritten(|r| r.truth[0] += 1.0);
    let setup = setup(&map);
    check(&Bench::new(Scenario::parse(&bytes).unwrap(), 1_000), crc32(fx.bytes()), &setup).unwrap();
    let s = replay(&bytes, &map, &setup).unwrap();
    assert!(!s.passed && s.score.position_rmse_m > 0.9, "{s:?}");
}

#[test]
fn mismatches_are_refused() {
    let fx = Fixture::new();
    let map = MapView::new(fx.bytes()).unwrap();
    let bytes = scenario_bytes();
    let scenario = Scenario::parse(&bytes).unwrap();
    let setup = setup(&map);

    // Another map.
    let bench = Bench::new(scenario, 1_000);
    assert!(matches!(
        check(&bench, 0x1234_5678, &setup),
        Err(ReplayError::Scenario(ScenarioError::MapMismatch { .. }))
    ));

    // Another ring timing: EERUF off changes the period.
    let mut other = setup;
    let module = setup.timing;
    other.ring = echoloc::driver::RingConfig { ring_down_us: 5_000, eeruf: None }.timing::<16>(&module).unwrap();
    assert!(matches!(
        check(&bench, crc32(fx.bytes()), &other),
        Err(ReplayError::Scenario(ScenarioError::Driver { .. }))
    ));

    // A record whose transducer is not the one the schedule fires there.
    let bytes = rewritten(|r| {
        if r.cycle == 2 && r.slot == 5 {
            r.transducer = (r.transducer + 1) % 16;
        }
    });
    let e = replay(&bytes, &map, &setup).unwrap_err();
    // The driver selected the schedule's transducer; the record says the next one.
    let changed = Scenario::parse(&bytes).unwrap().record(37).unwrap().transducer;
    let fault = BenchFault::Transducer { record: 37, expected: changed, selected: (changed + 15) % 16 };
    assert_eq!(e, ReplayError::Bench(fault));

    // A record fired late in the scenario but on time by the driver.
    let bytes = rewritten(|r| {
        if r.cycle >= 3 {
            r.time_us += 7;
        }
    });
    let e = replay(&bytes, &map, &setup).unwrap_err();
    assert!(matches!(e, ReplayError::Bench(BenchFault::Schedule { record: 48, .. })), "{e:?}");
}

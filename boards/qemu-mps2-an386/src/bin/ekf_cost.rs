//! The cost of the EKF on QEMU's `mps2-an386` (Cortex-M4F): one odometry
//! prediction, one range update (plane and point targets, accepted and
//! gated), and one ring cycle of the Pioneer ring (16 predictions and 16
//! updates and the lost monitor), and one recovery search over a full
//! buffer of readings, in instructions, with the stack one update and one
//! search use, and the filter's size. Prediction of the readings themselves is the predictor's
//! cost, measured by the main firmware.
//!
//! Each figure times `N` calls with SysTick (deterministic under the
//! runner's `-icount shift=0`) and subtracts the same loop without the call.
//! Checks on the way that the filter corrects towards a reading and that a
//! planted outlier is gated. Exits 0 when every check passed, 1 otherwise.
//!
//! `cargo run -p qemu-mps2-an386 --bin ekf_cost --target thumbv7em-none-eabihf --release`
#![no_std]
#![no_main]

use core::hint::black_box;

use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use echoloc::predict::PIONEER16;
use echoloc::referencing::recovery::RECENT;
use echoloc::referencing::{
    compose, range_model, Ekf, EkfConfig, Motion, MountM, Recent, RecoveryConfig, Target, Update,
};
use qemu_mps2_an386::{
    calibrate, elapsed, exit, first_unpainted, paint_free_stack, stack_bounds, start_systick, ticks,
};

const N: u32 = 256;

/// Readings of a corridor: walls at y = ±1.5 m, a corner ahead.
fn target(i: u32) -> Target {
    match i % 3 {
        0 => Target::Plane { point: [0.0, 1.5], normal: [0.0, -1.0] },
        1 => Target::Plane { point: [0.0, -1.5], normal: [0.0, 1.0] },
        _ => Target::Point { point: [4.0, 1.5] },
    }
}

fn fresh() -> Ekf {
    match Ekf::new([0.0, 0.0, 0.0], [0.05, 0.05, 0.03], EkfConfig::DEFAULT) {
        Ok(e) => e,
        Err(_) => exit(false),
    }
}

/// The range `target` would give from the truth (0.02 m ahead of the estimate).
fn truth_range(i: u32, mount: MountM) -> f32 {
    let truth = [0.02, 0.0, 0.0];
    echoloc::referencing::range_model(&truth, mount, &target(i)).map_or(1.0, |(h, _)| h)
}

#[entry]
fn main() -> ! {
    let mut ok = true;
    let syst = start_systick();
    hprintln!("echoloc {} EKF cost on mps2-an386 (Cortex-M4F)", env!("CARGO_PKG_VERSION"));
    let per_tick = calibrate(&syst);
    let mounts: [MountM; 16] = core::array::from_fn(|k| MountM::from(&PIONEER16[k]));
    let u = Motion { dx: 0.02, dy: 0.0, dphi: 0.005 };

    // Odometry prediction.
    let mut ekf = fresh();
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(&mut ekf).predict(black_box(&u)).ok();
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for _ in 0..N {
        black_box(&mut ekf);
        black_box(&u);
    }
    let base = elapsed(t0, ticks(&syst));
    let predict = with.saturating_sub(base) * per_tick / N;
    hprintln!("metric ekf_predict_insns {}", predict);

    // Updates from readings of the truth, 2 cm ahead of the estimate.
    let mut ekf = fresh();
    let mut accepted = 0u32;
    let t0 = ticks(&syst);
    for i in 0..N {
        let m = mounts[(i % 16) as usize];
        let z = truth_range(i, m);
        if let Update::Accepted { .. } = black_box(&mut ekf).update(black_box(z), 0.9, m, &target(i)) {
            accepted += 1;
        }
    }
    let with = elapsed(t0, ticks(&syst));
    let mut ekf2 = fresh();
    let t0 = ticks(&syst);
    for i in 0..N {
        let m = mounts[(i % 16) as usize];
        black_box(truth_range(i, m));
        black_box(&mut ekf2);
        black_box(&target(i));
    }
    let base = elapsed(t0, ticks(&syst));
    let update = with.saturating_sub(base) * per_tick / N;
    hprintln!("metric ekf_update_insns {} ({} of {} accepted)", update, accepted, N);
    // Every reading agreed with a truth 2 cm ahead: the estimate must be there.
    if accepted < N / 2 || (ekf.state()[0] - 0.02).abs() > 0.005 {
        hprintln!("FAIL: {} accepted, estimate x = {} m (truth 0.02 m)", accepted, ekf.state()[0]);
        ok = false;
    }

    // A planted outlier is gated and leaves the state alone.
    let mut ekf = fresh();
    let before = ekf.state();
    let r = ekf.update(5.0, 1.0, mounts[3], &Target::Plane { point: [2.0, 0.0], normal: [-1.0, 0.0] });
    if !matches!(r, Update::Gated { .. }) || ekf.state() != before {
        hprintln!("FAIL: an outlier of 3 m passed the gate: {:?}", r);
        ok = false;
    }

    // A ring cycle: 16 × (odometry prediction + update), then the lost
    // monitor. The truth moves with the odometry here.
    let mut ekf = fresh();
    let t0 = ticks(&syst);
    for c in 0..N / 16 {
        for k in 0..16u32 {
            let i = c * 16 + k;
            let m = mounts[k as usize];
            black_box(&mut ekf).predict(&u).ok();
            let z = truth_range(i, m) - 0.02 * (i + 1) as f32 * (i % 3 / 2) as f32;
            black_box(black_box(&mut ekf).update(z, 0.9, m, &target(i)));
        }
        black_box(black_box(&mut ekf).end_cycle());
    }
    let with = elapsed(t0, ticks(&syst));
    let t0 = ticks(&syst);
    for c in 0..N / 16 {
        for k in 0..16u32 {
            let i = c * 16 + k;
            black_box(truth_range(i, mounts[k as usize]) - 0.02 * (i + 1) as f32 * (i % 3 / 2) as f32);
            black_box(&target(i));
        }
    }
    let base = elapsed(t0, ticks(&syst));
    let cycle = with.saturating_sub(base) * per_tick / (N / 16);
    hprintln!("metric ekf_cycle_insns {} (16 odometry predictions, 16 updates, lost monitor)", cycle);

    // Stack of one update, below the caller's frame.
    let (_, bottom) = stack_bounds();
    let sp = paint_free_stack(bottom);
    let mut ekf = fresh();
    black_box(update_call(&mut ekf, truth_range(0, mounts[0]), mounts[0], &target(0)));
    let stack = sp - first_unpainted(bottom, sp);
    hprintln!("metric ekf_update_stack_bytes {}", stack);
    if stack == 0 {
        ok = false;
    }
    // Recovery while lost: the search over a full buffer of readings,
    // taken on a drive past the corridor's walls and corner by an estimate
    // (0.2, 0.15) m off the truth. It runs once per lost cycle.
    let mut recent = Recent::new();
    let mut x = [0.0f32; 3];
    for i in 0..RECENT as u32 {
        let m = mounts[(i * 5 % 16) as usize];
        let t = target(i);
        let truth = [x[0] + 0.2, x[1] + 0.15, x[2]];
        if let (Some((h, hj)), Some((z, _))) = (range_model(&x, m, &t), range_model(&truth, m, &t)) {
            recent.push(hj, z - h, 0.015 * 0.015);
        }
        let (next, f, _) = compose(&x, &u);
        recent.carry(f[0][2], f[1][2]);
        x = next;
    }
    const S: u32 = 4;
    let t0 = ticks(&syst);
    let mut found = None;
    for _ in 0..S {
        found = black_box(black_box(&mut recent).search(&RecoveryConfig::DEFAULT));
    }
    let search = elapsed(t0, ticks(&syst)) * per_tick / S;
    hprintln!("metric ekf_recovery_search_insns {} ({} readings)", search, recent.len());
    match found {
        Some(f) if (f.dx[0] - 0.2).abs() < 0.02 && (f.dx[1] - 0.15).abs() < 0.02 => {}
        other => {
            hprintln!("FAIL: the recovery search found {:?}, not the (0.2, 0.15) m planted", other.map(|f| f.dx));
            ok = false;
        }
    }
    let (_, bottom) = stack_bounds();
    let sp = paint_free_stack(bottom);
    black_box(search_call(&mut recent));
    let stack = sp - first_unpainted(bottom, sp);
    hprintln!("metric ekf_recovery_stack_bytes {}", stack);
    hprintln!("metric ekf_state_bytes {}", core::mem::size_of::<Ekf>());
    hprintln!("budget: <= 2000 instructions per reading update: {}", if update <= 2000 { "met" } else { "MISSED" });
    exit(ok);
}

/// One recovery search through a call that is never inlined.
#[inline(never)]
fn search_call(r: &mut Recent) -> Option<echoloc::referencing::Found> {
    black_box(r).search(&RecoveryConfig::DEFAULT)
}

/// One update through a call that is never inlined, so its frame lies below
/// the caller's stack pointer.
#[inline(never)]
fn update_call(ekf: &mut Ekf, z: f32, m: MountM, t: &Target) -> Update {
    black_box(ekf).update(z, 0.9, m, t)
}

//! `echoloc-lab board`: a robot's log or ROS 2 bag on the emulated board,
//! end to end, in one command. The map is compiled (a `.yaml` or `.geojson`
//! imported, a `.map` taken as it is), the log converted into a scenario for
//! the board's driver ([`crate::scenario::from_log`]), the same log replayed
//! on the host ([`crate::replay`]), then QEMU started with the QEMU board's
//! `replay` firmware and both files in its flash partitions (map at
//! `0x0020_0000`, scenario at `0x0030_0000`). Prints the board's figures
//! beside the host's and their difference.
//!
//! ```sh
//! cargo build -p qemu-mps2-an386 --bin replay --target thumbv7em-none-eabihf --release
//! echoloc-lab board --map ../shared/data/maps/bookstore.yaml --bag run/ --json
//! ```

use std::path::PathBuf;
use std::process::Command;

use clap::Args;
use serde_json::{json, Value};

use crate::map::LabError;
use crate::replay::{parse_pose, start, steps_of_log};
use crate::simulate::{filters, report};

/// The board's ring size (`qemu_mps2_an386::replay::TRANSDUCERS`).
pub const BOARD_TRANSDUCERS: usize = 16;

/// `board`.
#[derive(Args)]
pub struct BoardArgs {
    /// The run and its map.
    #[command(flatten)]
    pub input: crate::run_input::RunInput,
    /// Readings the board's driver could not report.
    #[command(flatten)]
    pub unreportable: crate::scenario::DriverArgs,
    /// The board's `replay` firmware.
    #[arg(long, default_value = "target/thumbv7em-none-eabihf/release/replay")]
    pub firmware: PathBuf,
    /// Give QEMU this many seconds.
    #[arg(long = "timeout-s", default_value_t = 300)]
    pub timeout_s: u64,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    pub json: bool,
}

/// What the board printed, parsed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoardRun {
    /// Its exit code (0: within the scenario's bounds).
    pub exit_code: Option<i32>,
    /// The final estimate, m, m, rad.
    pub final_pose: Option<[f64; 3]>,
    /// Position RMSE against the scenario's truth, m.
    pub position_rmse_m: Option<f64>,
    /// Heading RMSE, degrees.
    pub heading_rmse_deg: Option<f64>,
    /// Readings the loop took.
    pub readings: Option<u64>,
    /// Of them: the driver's invalid readings (untimed, faults), and the
    /// EKF's accepted and gated ones.
    pub invalid: Option<u64>,
    pub ekf_accepted: Option<u64>,
    pub ekf_gated: Option<u64>,
    /// Where the map came from.
    pub map_line: Option<String>,
    /// Every line the firmware printed.
    pub console: Vec<String>,
}

/// The numbers in `s` (a line of the firmware's), in order.
fn numbers(s: &str) -> Vec<f64> {
    s.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .filter(|t| !t.is_empty() && t.chars().any(|c| c.is_ascii_digit()))
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// Parses the `replay` firmware's console (boards/qemu-mps2-an386/src/replay.rs).
pub fn parse_console(out: &str, exit_code: Option<i32>) -> BoardRun {
    let mut r = BoardRun { exit_code, console: out.lines().map(str::to_string).collect(), ..BoardRun::default() };
    for l in out.lines() {
        if let Some(rest) = l.strip_prefix("pose error against the ground truth: ") {
            // RMSE p m and h deg, max m m, final f m and g deg; final estimate (x, y) m, t rad
            let n = numbers(rest);
            if n.len() >= 8 {
                r.position_rmse_m = Some(n[0]);
                r.heading_rmse_deg = Some(n[1]);
                r.final_pose = Some([n[5], n[6], n[7]]);
            }
        } else if let Some(rest) = l.strip_prefix("loop: ") {
            if rest.contains("readings in") {
                // N readings in C cycles: E echoes (U not confirmed by
                // EERUF), S no echo, I invalid; EKF accepted A, gated G; …
                let n = numbers(rest);
                r.readings = n.first().map(|&v| v as u64);
                if n.len() >= 8 && rest.contains("invalid; EKF accepted") {
                    (r.invalid, r.ekf_accepted, r.ekf_gated) =
                        (Some(n[5] as u64), Some(n[6] as u64), Some(n[7] as u64));
                }
            }
        } else if l.starts_with("map: ") {
            r.map_line = Some(l.to_string());
        }
    }
    r
}

pub fn board_cmd(a: &BoardArgs) -> Result<String, LabError> {
    if !a.firmware.is_file() {
        return Err(LabError(format!(
            "--firmware {}: no such file (build it: cargo build -p qemu-mps2-an386 --bin replay --target \
             thumbv7em-none-eabihf --release)",
            a.firmware.display()
        )));
    }
    let given = a.input.initial_pose.as_deref().map(|s| parse_pose(s, "--initial-pose")).transpose()?;
    let crate::run_input::Run { mounts, mut log, source, .. } = a.input.read_run()?;
    if mounts.len() != BOARD_TRANSDUCERS {
        return Err(LabError(format!(
            "{}: a ring of {} transducers; the QEMU board drives {BOARD_TRANSDUCERS}",
            source.display(),
            mounts.len()
        )));
    }
    // A recording stopped mid-ring: its last, partial, ring dropped.
    let partial = crate::log::drop_partial_last_ring(&mut log, mounts.len());
    if let Some(p) = partial {
        eprintln!("echoloc-lab: note: {}: {}", source.display(), p.note(mounts.len()));
    }
    // What the board's driver could not have reported, as it would report
    // it: the host replays the same, so that the figures compare.
    let unreportable = crate::scenario::as_the_driver_reports(&mut log, mounts.len(), &a.unreportable)
        .map_err(|e| LabError(format!("{}: {e}", source.display())))?;
    let loaded = a.input.load_map()?;
    let (map, blob, crc) = (loaded.view()?, loaded.blob(), loaded.crc());
    // The scenario for the board.
    let (header, records) = crate::scenario::from_log(&log, &mounts, crc, given)
        .map_err(|e| LabError(format!("{}: {e}", source.display())))?;
    let mut scn = Vec::new();
    echoloc::scenario::write(&header, &mounts, &records, |b| scn.extend_from_slice(b))
        .map_err(|e| LabError(format!("the scenario: {e}")))?;
    // The host's replay of the readings as the board's driver takes them:
    // in its firing order, at its ranges (the EKF's path depends on both).
    let fired = crate::scenario::as_the_board_reads(&log, mounts.len()).map_err(LabError)?;
    let steps = steps_of_log(&fired);
    let trace = filters::run(&map, map.field(), &mounts, &start(&log, given), &steps, &mut |_| {})
        .map_err(|e| LabError(format!("{}: {e}", source.display())))?;
    let host = report(&trace, None);
    // The board.
    let dir = std::env::temp_dir().join(format!("echoloc-board-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| LabError(format!("{}: {e}", dir.display())))?;
    let (map_file, scn_file) = (dir.join("map.map"), dir.join("run.scn"));
    let written = std::fs::write(&map_file, blob).and_then(|_| std::fs::write(&scn_file, &scn));
    let out = written.and_then(|_| {
        Command::new("timeout")
            .arg(a.timeout_s.to_string())
            .args(["qemu-system-arm", "-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic", "-monitor", "none"])
            .args(["-serial", "none", "-icount", "shift=0", "-semihosting-config", "enable=on,target=native"])
            .arg("-device")
            .arg(format!("loader,file={},addr=0x00200000", map_file.display()))
            .arg("-device")
            .arg(format!("loader,file={},addr=0x00300000", scn_file.display()))
            .arg("-kernel")
            .arg(&a.firmware)
            .output()
    });
    let _ = std::fs::remove_dir_all(&dir);
    let out = out.map_err(|e| LabError(format!("cannot run qemu-system-arm: {e} (scripts/setup.sh installs it)")))?;
    let text = String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    let b = parse_console(&text, out.status.code());
    let Some(bp) = b.final_pose else {
        return Err(LabError(format!(
            "the board did not finish the run (exit {:?}):\n{}",
            b.exit_code,
            b.console
                .iter()
                .filter(|l| l.contains("FAIL") || l.starts_with("map:"))
                .cloned()
                .collect::<Vec<_>>()
                .join("\n")
        )));
    };
    let hp = trace.final_pose(filters::Methods::Ekf).unwrap_or_default();
    let d = (bp[0] - hp[0]).hypot(bp[1] - hp[1]);
    let dh = crate::angle::wrap(bp[2] - hp[2]);
    let r6 = |v: f64| (v * 1e6).round() / 1e6;
    let v: Value = json!({
        "map": {"path": a.input.map.display().to_string(), "crc": format!("{crc:#010x}"), "bytes": blob.len()},
        "scenario": {"records": records.len(), "bytes": scn.len(), "cycles": records.last().map_or(0, |r| r.cycle + 1)},
        "unreportable": unreportable.json(),
        "partial_last_ring": partial.map(|p| p.json()),
        "host": {
            "final_pose": hp.map(r6),
            "position_rmse_m": host["ekf"]["position_rmse_m"],
            "heading_rmse_deg": host["ekf"]["heading_rmse_deg"],
            "readings": host["readings"],
            "ekf_accepted": host["ekf"]["accepted"],
            "ekf_gated": host["ekf"]["gated"],
        },
        "board": {
            "final_pose": bp,
            "position_rmse_m": b.position_rmse_m,
            "heading_rmse_deg": b.heading_rmse_deg,
            "readings": b.readings,
            "invalid": b.invalid,
            "ekf_accepted": b.ekf_accepted,
            "ekf_gated": b.ekf_gated,
            "exit_code": b.exit_code,
            "map": b.map_line,
        },
        "difference": {"position_mm": r6(d * 1000.0), "heading_mrad": r6(dh.abs() * 1000.0)},
    });
    Ok(if a.json { v.to_string() } else { serde_json::to_string_pretty(&v).unwrap_or_default() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_consoles_figures() {
        let out = "map: 41032 bytes from the partition at 0x00200000\n\
            loop: 2272 readings in 142 cycles: 2100 echoes (3 not confirmed by EERUF), 172 no echo, 0 invalid; EKF accepted 700, gated 30; lost 0 times, 0 cycles\n\
            pose error against the ground truth: RMSE 0.037300 m and 0.512000 deg, max 0.1 m, final 0.02 m and 0.3 deg; final estimate (-1.250000, 3.500000) m, -0.250000 rad\n";
        let r = parse_console(out, Some(0));
        assert_eq!(r.final_pose, Some([-1.25, 3.5, -0.25]));
        assert_eq!((r.position_rmse_m, r.heading_rmse_deg, r.readings), (Some(0.0373), Some(0.512), Some(2272)));
        assert!(r.map_line.unwrap().contains("from the partition"));
        assert_eq!((r.invalid, r.ekf_accepted, r.ekf_gated), (Some(0), Some(700), Some(30)));
    }
}

//! A robot's own map on the board (#28 item 4): a bag recorded on
//! `bookstore` (written by the independent `scripts/fixture-bag.py` from a
//! simulated bookstore run) runs on the emulated board through one command,
//! `echoloc-lab board`, with the map in the board's flash partition; the
//! board's final pose equals the host replay's within 1 mm and 1 mrad.
//! Without the map partition the same scenario is refused by the board,
//! which then holds only the depot.
//!
//! Needs `qemu-system-arm` and PyPI's `rosbags` (scripts/setup.sh installs
//! both) and builds the `replay` firmware.

mod common;

use std::process::Command;

use common::{board_binary, lab, root, run_json, s, shared_map, tmp};
use serde_json::Value;

/// How far apart two final poses (`[x m, y m, θ rad]` as JSON) are: mm, mrad.
fn apart(a: &Value, b: &Value) -> (f64, f64) {
    let f = |x: &Value, i: usize| x[i].as_f64().unwrap();
    ((f(a, 0) - f(b, 0)).hypot(f(a, 1) - f(b, 1)) * 1000.0, (f(a, 2) - f(b, 2)).abs() * 1000.0)
}

#[test]
fn a_bag_recorded_on_bookstore_runs_on_the_board_as_on_the_host() {
    let elf = board_binary("replay");
    let map = shared_map("bookstore.yaml");
    let log = tmp("board", "bookstore.csv");
    run_json(&["simulate", "--json", "--map", s(&map), "--seed", "1", "--distance-m", "30", "--log", s(&log)]);
    let bag = tmp("board", "bookstore-bag");
    let o = Command::new("python3")
        .arg(root().join("scripts/fixture-bag.py"))
        .arg(&log)
        .arg(&bag)
        .args(["--form", "range"])
        .output()
        .unwrap();
    assert!(o.status.success(), "fixture-bag.py: {}", String::from_utf8_lossy(&o.stderr));

    let v = run_json(&["board", "--json", "--map", s(&map), "--bag", s(&bag), "--firmware", s(&elf)]);
    assert_eq!(v["board"]["exit_code"], 0, "{v}");
    assert!(v["board"]["map"].as_str().unwrap().contains("from the partition at 0x00200000"), "{v}");
    assert_eq!(v["board"]["readings"], v["host"]["readings"]);
    // The host's side is replay --bag's own figure.
    let host = run_json(&["replay", "--json", "--map", s(&map), "--bag", s(&bag)]);
    assert_eq!(v["host"]["final_pose"], host["ekf"]["final_pose"]);
    let (b, h) = (&v["board"]["final_pose"], &host["ekf"]["final_pose"]);
    let (d_mm, d_mrad) = apart(b, h);
    assert!(d_mm <= 1.0 && d_mrad <= 1.0, "board {b} against host {h}: {d_mm} mm, {d_mrad} mrad");
    // And it is the bookstore's run: the EKF tracked it.
    assert!(v["board"]["position_rmse_m"].as_f64().unwrap() < 0.1, "{v}");

    // Without the map in the partition the board has only the depot, and refuses.
    let csv = tmp("board", "from-bag.csv");
    let ring = tmp("board", "from-bag-ring.json");
    run_json(&["log", "--from-bag", s(&bag), "-o", s(&csv), "--ring-out", s(&ring)]);
    let scn = tmp("board", "bookstore.scn");
    run_json(&["scenario", "--from-log", s(&csv), "--map", s(&map), "--ring", s(&ring), "-o", s(&scn)]);
    let o = Command::new("timeout")
        .args([
            "120",
            "qemu-system-arm",
            "-cpu",
            "cortex-m4",
            "-machine",
            "mps2-an386",
            "-nographic",
            "-monitor",
            "none",
        ])
        .args(["-serial", "none", "-icount", "shift=0", "-semihosting-config", "enable=on,target=native"])
        .arg("-device")
        .arg(format!("loader,file={},addr=0x00300000", scn.display()))
        .arg("-kernel")
        .arg(&elf)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(out.contains("map: the depot, linked into the image"), "{out}");
    assert!(out.contains("FAIL: scenario refused: scenario: made on the map with CRC"), "{out}");
}

#[test]
fn a_ring_the_board_does_not_drive_is_refused() {
    let dir = tmp("board", "ring8");
    std::fs::create_dir_all(&dir).unwrap();
    let ring = dir.join("ring8.json");
    let mounts: Vec<[f64; 3]> = (0..8).map(|i| [0.2, 0.0, f64::from(i) * 45.0 - 180.0]).collect();
    std::fs::write(&ring, serde_json::to_string(&mounts).unwrap()).unwrap();
    let fw = dir.join("replay.elf");
    std::fs::write(&fw, b"not run").unwrap();
    let log = dir.join("ring8.csv");
    std::fs::write(
        &log,
        "time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad\n0,0,1000,0,0,0\n0.04,7,,0,0,0\n",
    )
    .unwrap();
    let o = lab()
        .args(["board", "--map", s(&shared_map("depot.yaml")), "--log", s(&log)])
        .args(["--ring", s(&ring), "--firmware", s(&fw)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("ring8.csv: a ring of 8 transducers; the QEMU board drives 16"), "{err}");
    let o = lab()
        .args(["board", "--map", s(&shared_map("depot.yaml")), "--log", "x.csv", "--firmware", "/nonexistent/replay"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("--firmware /nonexistent/replay: no such file (build it"));
}

/// A log from another driver (#37 item 7): readings nearer than this
/// driver's blanking reach the board as this driver would report them (no
/// echo), counted, and the host replays the same; the board's final pose
/// is the host's. Asked to refuse, the board names the line.
#[test]
fn a_foreign_logs_near_readings_reach_the_board_as_no_echo() {
    let elf = board_binary("replay");
    let map = shared_map("bookstore.yaml");
    let log = tmp("board", "near.csv");
    run_json(&["simulate", "--json", "--map", s(&map), "--seed", "2", "--distance-m", "10", "--log", s(&log)]);
    // Every 40th reading with an echo becomes 379 mm, as another driver
    // with a shorter blanking would have logged.
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let col = lines[0].split(',').position(|c| c == "range_mm").unwrap();
    let (mut near, mut first) = (0, None);
    for (i, l) in lines.iter_mut().enumerate().skip(1) {
        let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
        if i % 40 == 0 && !f[col].is_empty() {
            f[col] = "379".into();
            near += 1;
            first.get_or_insert(i + 1);
            *l = f.join(",");
        }
    }
    assert!(near >= 3);
    let foreign = tmp("board", "near-foreign.csv");
    std::fs::write(&foreign, lines.join("\n") + "\n").unwrap();

    let v = run_json(&["board", "--json", "--map", s(&map), "--log", s(&foreign), "--firmware", s(&elf)]);
    assert_eq!(v["unreportable"]["inside_blanking"], near, "{v}");
    assert_eq!(v["unreportable"]["beyond_window"], 0, "{v}");
    assert_eq!(v["board"]["readings"], v["host"]["readings"], "{v}");
    let (b, h) = (&v["board"]["final_pose"], &v["host"]["final_pose"]);
    let (d_mm, d_mrad) = apart(b, h);
    assert!(d_mm <= 1.0 && d_mrad <= 1.0, "board {b} against host {h}");

    let o = lab()
        .args([
            "board",
            "--json",
            "--map",
            s(&map),
            "--log",
            s(&foreign),
            "--firmware",
            s(&elf),
            "--refuse-unreportable",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && err.contains(&format!("line {}: range 379 mm is inside the driver's blanking", first.unwrap())),
        "{err}"
    );
    let o = lab()
        .args(["board", "--map", s(&map), "--log", s(&foreign), "--firmware", s(&elf), "--blanking-mm", "300"])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("BINH"));
}

/// A log from another simulator, as #47 found one: its ring fires 0, 1, 2,
/// … 15 (the board's driver fires 0, 3, 6, …), and the recording stops
/// mid-ring. Made from a simulated bookstore log: within each ring the
/// readings are put in transducer order, each row keeping its place's
/// time and odometry, and the last 5 lines are cut.
fn foreign_log(seed: &str, distance_m: &str) -> std::path::PathBuf {
    let map = shared_map("bookstore.yaml");
    let log = tmp("board", &format!("seq-{seed}.csv"));
    run_json(&["simulate", "--json", "--map", s(&map), "--seed", seed, "--distance-m", distance_m, "--log", s(&log)]);
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<Vec<String>> = text.lines().map(|l| l.split(',').map(str::to_string).collect()).collect();
    let head = lines.remove(0);
    let (t, r) =
        (head.iter().position(|c| c == "transducer").unwrap(), head.iter().position(|c| c == "range_mm").unwrap());
    let mut out = vec![head.join(",")];
    for ring in lines.chunks(16) {
        assert_eq!(ring.len(), 16);
        let mut sorted: Vec<&Vec<String>> = ring.iter().collect();
        sorted.sort_by_key(|l| l[t].parse::<u8>().unwrap());
        for (place, reading) in ring.iter().zip(sorted) {
            let mut l = place.clone();
            (l[t], l[r]) = (reading[t].clone(), reading[r].clone());
            out.push(l.join(","));
        }
    }
    out.truncate(out.len() - 5);
    let foreign = tmp("board", &format!("seq-{seed}-foreign.csv"));
    std::fs::write(&foreign, out.join("\n") + "\n").unwrap();
    foreign
}

#[test]
fn a_foreign_log_cut_mid_ring_runs_on_the_board_as_on_the_host() {
    let elf = board_binary("replay");
    let map = shared_map("bookstore.yaml");
    let foreign = foreign_log("1", "30");
    let o = lab()
        .args(["board", "--json", "--map", s(&map), "--log", s(&foreign), "--firmware", s(&elf)])
        .output()
        .unwrap();
    let note = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{note}");
    assert!(note.contains("the log ends mid-ring") && note.contains("has 11 of the 16 readings, dropped"), "{note}");
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["partial_last_ring"]["readings"], 11, "{v}");
    assert_eq!(v["board"]["readings"], v["host"]["readings"], "{v}");
    // Every reading the host took, the board's driver took (none refused
    // as inside its blanking), and the EKF judged each alike.
    assert_eq!(v["board"]["invalid"], 0, "{v}");
    assert_eq!(
        (&v["board"]["ekf_accepted"], &v["board"]["ekf_gated"]),
        (&v["host"]["ekf_accepted"], &v["host"]["ekf_gated"])
    );
    // Every reading but the 11 dropped reached both.
    let rows = std::fs::read_to_string(&foreign).unwrap().lines().count() as u64 - 1;
    assert_eq!(v["host"]["readings"].as_u64(), Some(rows - 11), "{v}");
    let (b, h) = (&v["board"]["final_pose"], &v["host"]["final_pose"]);
    let (d_mm, d_mrad) = apart(b, h);
    assert!(d_mm <= 1.0 && d_mrad <= 1.0, "board {b} against host {h}: {d_mm} mm, {d_mrad} mrad");
    assert!(v["board"]["position_rmse_m"].as_f64().unwrap() < 0.1, "{v}");
    // The host's own replay, in the log's order, is another run (the EKF
    // takes readings one at a time): the board is compared with the host
    // replaying the readings as the board's driver fires them.
    let own = run_json(&["replay", "--json", "--map", s(&map), "--log", s(&foreign)]);
    let o = &own["ekf"]["final_pose"];
    let (d_own, _) = apart(b, o);
    eprintln!(
        "foreign log: board to host in the driver's order {d_mm:.3} mm, to host in the log's order {d_own:.3} mm"
    );
}

//! What the lab's CLI tests share: the binary, the repository root, a
//! per-process scratch folder, and the check that a checked-in firmware
//! blob is what the importer makes today. Each test binary uses a part.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// A map from the project's shared data, checked out beside the repository.
pub fn shared_map(name: &str) -> PathBuf {
    root().join("../shared/data/maps").join(name)
}

/// Runs `simulate --json` with `args`, checks it printed one JSON object,
/// and returns it.
pub fn simulate(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["simulate", "--json"];
    all.extend_from_slice(args);
    let o = lab().args(&all).output().unwrap();
    assert!(o.status.success(), "simulate {args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(text.trim_end().lines().count(), 1, "--json prints one line: {text}");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert!(v.is_object(), "{v}");
    v
}

/// The number at a dotted `path` of a JSON report.
pub fn num(v: &serde_json::Value, path: &str) -> f64 {
    let x = path.split('.').fold(v, |v, k| &v[k]);
    x.as_f64().unwrap_or_else(|| panic!("{path} is not a number: {x}"))
}

/// A path as the `&str` a command line takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs the lab with `args`, checks it succeeded, and returns the JSON it
/// printed.
pub fn run_json(args: &[&str]) -> serde_json::Value {
    let o = lab().args(args).output().unwrap();
    assert!(o.status.success(), "{args:?} failed: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The `echoloc-lab` binary under test.
pub fn lab() -> Command {
    Command::new(env!("CARGO_BIN_EXE_echoloc-lab"))
}

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `name` in a scratch folder `echoloc-<prefix>-<pid>` (created) under the
/// system's temporary directory.
pub fn tmp(prefix: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("echoloc-{prefix}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Asserts that the freshly imported blob `fresh` equals the checked-in
/// `shipped` (a path from the repository root), naming the command that
/// regenerates it.
pub fn assert_blob_fresh(fresh: &Path, shipped: &str, regenerate: &str) {
    let fresh = std::fs::read(fresh).unwrap();
    let shipped_bytes = std::fs::read(root().join(shipped)).unwrap();
    assert!(fresh == shipped_bytes, "{shipped} is stale: re-run `{regenerate}`");
}

/// Builds one binary of the QEMU board (release, thumbv7em) and returns its ELF.
pub fn board_binary(bin: &str) -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let o = Command::new(cargo)
        .current_dir(root())
        .args(["build", "-q", "-p", "qemu-mps2-an386", "--bin", bin, "--target", "thumbv7em-none-eabihf", "--release"])
        .output()
        .unwrap();
    assert!(o.status.success(), "building the {bin} firmware: {}", String::from_utf8_lossy(&o.stderr));
    let dir = std::env::var("CARGO_TARGET_DIR").map_or_else(|_| root().join("target"), PathBuf::from);
    dir.join("thumbv7em-none-eabihf/release").join(bin)
}

/// The building of `two-rooms.geojson`, by hand: two 5 m × 5 m rooms, a
/// corridor between them from y = 1.7 to 3.3 m, and the niche above the
/// corridor (x 5.4–6.0, y 3.3–3.9). Open rectangles (x0, x1, y0, y1), m;
/// a point on a wall is not inside.
const BUILDING: [(f64, f64, f64, f64); 4] =
    [(0.0, 5.0, 0.0, 5.0), (7.0, 12.0, 0.0, 5.0), (4.9, 7.1, 1.7, 3.3), (5.4, 6.0, 3.2, 3.9)];

/// The four boxes standing in it.
const BOXES: [(f64, f64, f64, f64); 4] =
    [(1.0, 2.2, 3.2, 4.0), (9.8, 11.0, 1.0, 1.8), (3.0, 3.6, 0.8, 1.4), (8.4, 9.0, 3.6, 4.2)];

fn within(r: &(f64, f64, f64, f64), x: f64, y: f64) -> bool {
    x > r.0 && x < r.1 && y > r.2 && y < r.3
}

/// In the building of `data/two-rooms.geojson` and in no box (the rectangles overlap only where the
/// corridor and the niche meet the rooms' open sides).
pub fn in_two_rooms(x: f64, y: f64) -> bool {
    BUILDING.iter().any(|r| within(r, x, y)) && !BOXES.iter().any(|r| within(r, x, y))
}

/// Runs the lab with `args` and `--ros2 --ros2-localhost --ros2-wait-s 60`
/// beside Cyclone DDS peers (`scripts/ros2-peer.py`, each with its
/// arguments), all inside a network namespace of their own (`unshare -n`,
/// the loopback brought up: no other interface exists, so nothing leaves
/// the machine). Returns the lab's output and each peer's JSON summary.
pub fn beside_ros2_peers(args: &[String], peers: &[&[&str]]) -> (std::process::Output, Vec<serde_json::Value>) {
    static RUN: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = RUN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("echoloc-ros2-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let q = |s: &str| format!("'{}'", s.replace('\'', r"'\''"));
    let mut script = String::from("set -e\nip link set lo up\n");
    for (i, p) in peers.iter().enumerate() {
        let a: Vec<String> = p.iter().map(|a| q(a)).collect();
        let peer = root().join("scripts/ros2-peer.py");
        let d = dir.display();
        script +=
            &format!("python3 {} {} > {d}/peer{i}.json 2> {d}/peer{i}.err &\n", q(peer.to_str().unwrap()), a.join(" "));
    }
    let a: Vec<String> = args.iter().map(|a| q(a)).collect();
    let lab = env!("CARGO_BIN_EXE_echoloc-lab");
    script += &format!("{} {} --ros2 --ros2-localhost --ros2-wait-s 60\nwait\n", q(lab), a.join(" "));
    let o = Command::new("unshare").args(["-n", "bash", "-c", &script]).output().unwrap();
    let errs = || {
        (0..peers.len())
            .map(|i| std::fs::read_to_string(dir.join(format!("peer{i}.err"))).unwrap_or_default())
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert!(o.status.success(), "the lab or a peer failed: {}\n{}", String::from_utf8_lossy(&o.stderr), errs());
    let summaries = (0..peers.len())
        .map(|i| {
            let text = std::fs::read_to_string(dir.join(format!("peer{i}.json"))).unwrap();
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("peer {i}: {e}: {text} {}", errs()))
        })
        .collect();
    (o, summaries)
}

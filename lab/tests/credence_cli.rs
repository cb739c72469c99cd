//! `echoloc-lab synth` and `echoloc-lab train` end to end: synthesis is
//! deterministic for a seed and matches the checked-in data, bad CSVs fail
//! naming file, line and field, a short training run reports and writes
//! the weights' source, and a failing command writes nothing.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{lab, root};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("echoloc-credence-test-{}", std::process::id())).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn ok(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "stderr: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

fn synth(dir: &Path, seed: &str) -> serde_json::Value {
    ok(&lab().args(["synth", "--out"]).arg(dir).args(["--seed", seed]).output().unwrap())
}

#[test]
fn synth_is_deterministic_for_a_seed_and_matches_the_checked_in_data() {
    let (a, b, c) = (tmp("synth-a"), tmp("synth-b"), tmp("synth-c"));
    let ja = synth(&a, "1");
    synth(&b, "1");
    synth(&c, "2");
    assert_eq!(ja["files"].as_array().unwrap().len(), 5);
    let mut differs = false;
    for day in 1..=5 {
        let name = format!("day{day}.csv");
        let fa = std::fs::read_to_string(a.join(&name)).unwrap();
        assert_eq!(fa, std::fs::read_to_string(b.join(&name)).unwrap(), "{name}: same seed, same bytes");
        differs |= fa != std::fs::read_to_string(c.join(&name)).unwrap();
        let mut lines = fa.lines();
        assert_eq!(lines.next(), Some("r_mm,theta_deg,readings,correct"));
        let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|f| f.parse().unwrap()).collect()).collect();
        assert_eq!(rows.len(), 399, "{name}: 21 ranges × 19 angles");
        assert!(rows.iter().all(|r| r[2] == 100.0 && r[3] <= r[2]));
        // The checked-in data are this command's output.
        let shipped = std::fs::read_to_string(root().join("docs/credence-data").join(&name)).unwrap();
        assert!(
            fa == shipped,
            "docs/credence-data/{name} is stale: re-run `cargo run --release -p echoloc-lab -- synth --out docs/credence-data --seed 1`"
        );
    }
    assert!(differs, "another seed gives other data");
}

fn train_fails(name: &str, csv: &str, expect: &[&str]) {
    let dir = tmp(name);
    std::fs::write(dir.join("good.csv"), "r_mm,theta_deg,readings,correct\n500,0,100,90\n").unwrap();
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, csv).unwrap();
    let o = lab().arg("train").arg(&dir).args(["--epochs", "5", "--restarts", "1"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{name}: should fail");
    assert!(o.stdout.is_empty(), "{name}: no report on failure");
    assert!(err.contains(bad.to_str().unwrap()), "{name}: names the file: {err}");
    for e in expect {
        assert!(err.contains(e), "{name}: says {e:?}: {err}");
    }
}

#[test]
fn bad_csv_names_file_line_and_field() {
    let h = "r_mm,theta_deg,readings,correct\n";
    train_fails("field", &format!("{h}500,0,100,90\n750,2.5,lots,3\n"), &[":3: field `readings`", "`lots`"]);
    train_fails("correct", &format!("{h}500,0,10,11\n"), &[":2: field `correct`", "11 correct of only 10"]);
    train_fails("header", "range,angle,n,k\n500,0,10,1\n", &[":1: header is `range,angle,n,k`", "expected `r_mm"]);
    train_fails("columns", &format!("{h}500,0,10\n"), &[":2: 3 fields; expected 4"]);
    train_fails("domain", &format!("{h}500,60,10,1\n"), &[":2: field `theta_deg`", "outside"]);
    train_fails("empty", "", &[":1: the file is empty"]);
    train_fails("duplicate", &format!("{h}500,0,10,1\n500,0,10,2\n"), &[":3: node (500 mm, 0°) appears twice"]);
}

#[test]
fn train_needs_two_days_for_leave_one_day_out_and_missing_files_are_named() {
    let dir = tmp("one-day");
    let f = dir.join("only.csv");
    std::fs::write(&f, "r_mm,theta_deg,readings,correct\n500,0,100,90\n").unwrap();
    let o = lab().arg("train").arg(&f).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("at least two data sets"));
    let missing = dir.join("nope.csv");
    let o = lab().arg("train").arg(&missing).arg(&f).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains(missing.to_str().unwrap()));
}

#[test]
fn short_training_reports_leave_one_day_out_and_writes_weights_and_figures() {
    let data = tmp("train-data");
    synth(&data, "3");
    let out = tmp("train-out");
    let weights = out.join("weights.rs");
    let o = lab()
        .arg("train")
        .arg(&data)
        .args(["--epochs", "300", "--restarts", "1", "--seed", "4", "--weights-out"])
        .arg(&weights)
        .arg("--figures")
        .arg(&out)
        .output()
        .unwrap();
    let report = ok(&o);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("train: fold 1/5 (held out day1)"), "progress on stderr: {stderr}");
    let folds = report["leave_one_day_out"]["folds"].as_array().unwrap();
    assert_eq!(folds.len(), 5);
    for f in folds {
        let (n, g) = (f["net_rmse"].as_f64().unwrap(), f["gaussian_rmse"].as_f64().unwrap());
        assert!(n > 0.0 && n < 0.5 && g > 0.0 && g < 0.6, "{f}");
    }
    let q = report["final"]["quantised_max_abs_error"].as_f64().unwrap();
    assert!(q <= 1.0 / 256.0, "{q}");
    let src = std::fs::read_to_string(&weights).unwrap();
    assert!(src.starts_with("//! The credence net's weights and σ table. GENERATED by `echoloc-lab train`"));
    assert!(src.contains("--seed 4") && src.contains("day5.csv") && src.contains("CRC-32"));
    assert!(src.contains("pub static SHIPPED_WEIGHTS: QuantWeights") && src.contains("pub static SIGMOID_TAIL"));
    for png in ["kappa_observed.png", "kappa_net.png", "kappa_gaussian.png", "kappa_profiles.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{png}");
    }
}

/// The names in `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

#[test]
fn a_failing_train_leaves_the_weights_untouched() {
    // The figures directory cannot be created (a file is in the way): the
    // weights, rendered before the figures, must not be written either.
    let out = tmp("all-or-nothing-train");
    let weights = out.join("weights.rs");
    std::fs::write(&weights, "// the previous weights\n").unwrap();
    let blocker = out.join("figures");
    std::fs::write(&blocker, "not a directory").unwrap();
    let o = lab()
        .arg("train")
        .arg(root().join("docs/credence-data"))
        .args(["--epochs", "5", "--restarts", "1", "--no-cv", "--weights-out"])
        .arg(&weights)
        .arg("--figures")
        .arg(blocker.join("sub"))
        .output()
        .unwrap();
    assert!(!o.status.success(), "should fail");
    assert!(o.stdout.is_empty(), "no report on failure");
    assert!(String::from_utf8_lossy(&o.stderr).contains(blocker.to_str().unwrap()), "names the directory");
    assert_eq!(std::fs::read_to_string(&weights).unwrap(), "// the previous weights\n");
    assert_eq!(listing(&out), ["figures", "weights.rs"], "no temporary file left");
}

#[test]
fn a_failing_synth_writes_no_day() {
    // day3.csv cannot be written (a directory is in the way): days 1, 2, 4
    // and 5 must not be written either.
    let out = tmp("all-or-nothing-synth");
    std::fs::create_dir(out.join("day3.csv")).unwrap();
    let o = lab().args(["synth", "--out"]).arg(&out).output().unwrap();
    assert!(!o.status.success(), "should fail");
    assert!(o.stdout.is_empty(), "no report on failure");
    assert!(String::from_utf8_lossy(&o.stderr).contains("day3.csv"), "names the file");
    assert_eq!(listing(&out), ["day3.csv"], "nothing written, no temporary file left");
}

#[test]
fn train_figures_as_svg() {
    let out = tmp("train-svg");
    let o = lab()
        .arg("train")
        .arg(root().join("docs/credence-data"))
        .args(["--epochs", "5", "--restarts", "1", "--no-cv", "--svg", "--figures"])
        .arg(&out)
        .output()
        .unwrap();
    ok(&o);
    for (svg, words) in [
        ("kappa_net.svg", ["2-10-1 net κ", "sensor frame", "R (mm)"]),
        ("kappa_profiles.svg", ["observed", "Gaussian", "R = 2500 mm"]),
    ] {
        let text = std::fs::read_to_string(out.join(svg)).unwrap();
        assert!(text.starts_with("<svg"), "{svg}");
        for w in words {
            assert!(text.contains(w), "{svg}: {w:?}");
        }
    }
    assert!(!out.join("kappa_net.png").exists());
}

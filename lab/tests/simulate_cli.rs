//! `echoloc-lab simulate` and `scenario replay` end to end: the JSON report,
//! determinism, the replay round trip, refused scenarios, bad inputs that
//! fail clearly without writing, the figures, a custom ring and the
//! inconsistency knob. Routes are short (10–30 m): a debug run takes about
//! a second.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{lab, root, s, shared_map, simulate};
use serde_json::Value;

fn office() -> PathBuf {
    root().join("maps/office.geojson")
}

/// A fresh, empty scratch folder for one test.
fn scratch(test: &str) -> PathBuf {
    let d = common::tmp("simulate-test", test);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    lab().args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn f(v: &Value, path: &str) -> f64 {
    common::num(v, path)
}

fn u(v: &Value, path: &str) -> u64 {
    let x = path.split('.').fold(v, |v, k| &v[k]);
    x.as_u64().unwrap_or_else(|| panic!("{path} is not a non-negative integer: {x}"))
}

fn round4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

/// Asserts that a failed command exited non-zero, printed nothing on
/// stdout, said each of `expect` on stderr, and left none of `never`
/// (nor their `.partial` siblings) behind.
fn assert_refused(o: &Output, what: &str, expect: &[&str], never: &[&Path]) {
    let err = stderr(o);
    assert!(!o.status.success(), "{what}: should fail");
    assert!(o.stdout.is_empty(), "{what}: nothing on stdout: {}", String::from_utf8_lossy(&o.stdout));
    for e in expect {
        assert!(err.contains(e), "{what}: the error should say {e:?}: {err}");
    }
    assert!(!err.contains("panicked"), "{what}: a message, not a panic: {err}");
    for p in never {
        assert!(!p.exists(), "{what}: {} written", p.display());
        assert!(!p.with_extension("partial").exists(), "{what}: {} left", p.with_extension("partial").display());
    }
}

const METHOD_KEYS: [&str; 4] =
    ["position_rmse_m", "heading_rmse_deg", "max_position_error_m", "final_position_error_m"];

// 1. The report's shape, types and ranges.
#[test]
fn json_report_has_every_figure_in_range() {
    let map = shared_map("tb3_sandbox.yaml");
    let v = simulate(&["--map", s(&map), "--seed", "3", "--distance-m", "20"]);
    let readings = u(&v, "readings");
    assert!(readings > 0);
    assert!((f(&v, "distance_m") - 20.0).abs() < 0.1, "route length: {}", v["distance_m"]);
    for m in ["dead_reckoning", "threshold", "ekf"] {
        for k in METHOD_KEYS {
            let x = f(&v, &format!("{m}.{k}"));
            assert!(x.is_finite() && x >= 0.0, "{m}.{k} = {x}");
        }
        // No error along the run exceeds the largest.
        let max = f(&v, &format!("{m}.max_position_error_m"));
        assert!(f(&v, &format!("{m}.position_rmse_m")) <= max + 1e-4, "{m}: RMSE above the max");
        assert!(f(&v, &format!("{m}.final_position_error_m")) <= max + 1e-4, "{m}: final above the max");
    }
    // Verdicts: counts of the finished cycles' readings.
    let verdicts =
        ["confirmed", "unknown_obstacle", "removed_or_missed", "unpredicted", "nothing_as_predicted", "inconclusive"];
    let total: u64 = verdicts.iter().map(|k| u(&v, &format!("verdicts.{k}"))).sum();
    assert!(total <= readings && readings - total < 16, "verdicts {total} of {readings} readings");
    assert_eq!(f(&v, "verdicts.confirmed_fraction"), round4(u(&v, "verdicts.confirmed") as f64 / total as f64));
    // Detection against the simulator's truth.
    for d in ["unknown_obstacle", "removed_obstacle"] {
        let (tp, fp, fne) = (
            u(&v, &format!("detection.{d}.true_positives")),
            u(&v, &format!("detection.{d}.false_positives")),
            u(&v, &format!("detection.{d}.false_negatives")),
        );
        assert!(tp + fp + fne <= readings, "{d}: more outcomes than readings");
        for (k, n, dd) in [("precision", tp, tp + fp), ("recall", tp, tp + fne)] {
            let x = &v["detection"][d][k];
            if dd == 0 {
                assert!(x.is_null(), "{d}.{k} with nothing to count is null: {x}");
            } else {
                let x = x.as_f64().unwrap_or_else(|| panic!("{d}.{k}: {x}"));
                assert!((0.0..=1.0).contains(&x), "{d}.{k} = {x}");
                assert_eq!(x, round4(n as f64 / dd as f64), "{d}.{k}");
            }
        }
    }
    // Lost counts, in both places they are reported.
    for k in ["raised", "cleared", "cycles_lost", "recoveries"] {
        u(&v, &format!("lost.{k}"));
    }
    assert_eq!(v["lost"]["recoveries"], v["ekf"]["recoveries"]);
    // A recovery happens only while lost.
    assert!(u(&v, "lost.recoveries") <= u(&v, "lost.cycles_lost"));
    let off = simulate(&["--map", s(&map), "--seed", "3", "--distance-m", "20", "--no-recovery"]);
    assert_eq!(u(&off, "lost.recoveries"), 0);
    // Without Huber's down-weighting: the same world and the same other
    // methods, another EKF (its covariance is the filter's own state).
    let rough = simulate(&["--map", s(&map), "--seed", "3", "--distance-m", "20", "--no-robust"]);
    assert_eq!(rough["dead_reckoning"], v["dead_reckoning"]);
    assert_eq!(rough["threshold"], v["threshold"]);
    assert_ne!(rough["ekf"]["covariance"], v["ekf"]["covariance"]);
    // The clutter oracle: the same world, the readings inconsistent with the
    // map silenced for the filters; dead reckoning is the same, and the
    // verdicts see far fewer unmapped objects (those left are echoes of
    // mapped surfaces the predictor does not predict: the agreement misses).
    let oracle = simulate(&["--map", s(&map), "--seed", "3", "--distance-m", "20", "--only-consistent"]);
    assert_eq!(oracle["dead_reckoning"], v["dead_reckoning"]);
    assert_eq!(oracle["inconsistent_fraction"], v["inconsistent_fraction"]);
    let unknown = |v: &serde_json::Value| u(v, "verdicts.unknown_obstacle") + u(v, "verdicts.unpredicted");
    assert!(unknown(&v) > 0 && unknown(&oracle) * 2 < unknown(&v), "{} then {}", unknown(&v), unknown(&oracle));
    assert_eq!(v["lost"]["raised"], v["ekf"]["lost_raised"]);
    assert_eq!(v["lost"]["cleared"], v["ekf"]["lost_cleared"]);
    assert_eq!(v["lost"]["cycles_lost"], v["ekf"]["cycles_lost"]);
    assert!(u(&v, "lost.cleared") <= u(&v, "lost.raised"));
    assert!(u(&v, "lost.cycles_lost") <= u(&v, "cycles"));
    // Agreement of the predictor with the simulated sonar.
    let (conf, within) = (u(&v, "agreement.confident"), u(&v, "agreement.within_tolerance"));
    assert!(conf > 0 && within + u(&v, "agreement.silent") <= conf);
    assert!(u(&v, "agreement.nothing_read") <= u(&v, "agreement.nothing_predicted"));
    // The nearer echoes by range add up to the nearer echoes by kind.
    let by_range: u64 = ["under_1m", "1_to_2m", "2_to_3m", "from_3m"]
        .iter()
        .map(|k| u(&v, &format!("agreement.nearer_by_range.{k}")))
        .sum();
    let by_kind: u64 = ["nearer_face", "nearer_inside_corner", "nearer_outside_edge"]
        .iter()
        .map(|k| u(&v, &format!("agreement.{k}")))
        .sum();
    assert_eq!(by_range, by_kind);
    let fr = f(&v, "agreement.fraction");
    assert!((0.0..=1.0).contains(&fr) && fr == round4(within as f64 / conf as f64), "agreement.fraction {fr}");
    let inc = f(&v, "inconsistent_fraction");
    assert!((0.0..=1.0).contains(&inc));
    for k in ["cycles", "removed_obstacles", "unmapped_objects", "people", "ekf.accepted", "ekf.gated"] {
        u(&v, k);
    }
}

// 2. Determinism.
#[test]
fn a_seed_gives_the_same_run_byte_for_byte() {
    let d = scratch("determinism");
    let map = office();
    let go = |seed: &str, scn: &Path| {
        let o =
            run(&["simulate", "--json", "--map", s(&map), "--seed", seed, "--distance-m", "12", "--scenario", s(scn)]);
        assert!(o.status.success(), "{}", stderr(&o));
        (o.stdout, std::fs::read(scn).unwrap())
    };
    let (out_a, scn_a) = go("7", &d.join("a.scn"));
    let (out_b, scn_b) = go("7", &d.join("b.scn"));
    let (out_c, scn_c) = go("8", &d.join("c.scn"));
    assert!(out_a == out_b, "the same seed printed different reports");
    assert!(scn_a == scn_b, "the same seed wrote different scenarios");
    assert!(out_a != out_c, "another seed printed the same report");
    assert!(scn_a != scn_c, "another seed wrote the same scenario");
}

// 3. The replay runs the very same records through the very same filters.
fn assert_replay_matches(map: &Path, args: &[&str], d: &Path) -> Value {
    let scn = d.join("run.scn");
    let mut all = vec!["--map", s(map), "--scenario", s(&scn)];
    all.extend_from_slice(args);
    let sim = simulate(&all);
    let o = run(&["scenario", "replay", s(&scn), "--map", s(map), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rep: Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["dead_reckoning", "threshold", "ekf", "verdicts", "lost", "readings"] {
        assert!(rep.get(k).is_some(), "the replay reports {k}: {rep}");
    }
    for (k, x) in rep.as_object().unwrap() {
        assert_eq!(x, &sim[k], "replay's {k} differs from simulate's");
    }
    // Without the simulator's truth the replay cannot score detection.
    assert!(rep.get("detection").is_none() && rep.get("agreement").is_none());
    sim
}

#[test]
fn replay_gives_what_simulate_printed() {
    let d = scratch("roundtrip");
    assert_replay_matches(&shared_map("tb3_sandbox.yaml"), &["--seed", "3", "--distance-m", "20"], &d);
}

// 4. Refused scenarios.
#[test]
fn replay_refuses_another_map_and_damaged_files() {
    let d = scratch("refused");
    let map = office();
    let scn = d.join("office.scn");
    simulate(&["--map", s(&map), "--seed", "2", "--distance-m", "10", "--scenario", s(&scn)]);
    let good = std::fs::read(&scn).unwrap();
    let replay = |file: &Path, map: &Path, extra: &[&str]| {
        let mut a = vec!["scenario", "replay", s(file), "--map", s(map), "--json"];
        a.extend_from_slice(extra);
        run(&a)
    };
    let depot = shared_map("depot.yaml");
    let o = replay(&scn, &depot, &[]);
    assert_refused(&o, "another map", &["office.scn", "another map", "depot.yaml", "MapMismatch"], &[]);
    // The same map with another C-space buffer is another blob.
    let o = replay(&scn, &map, &["--buffer-mm", "150"]);
    assert_refused(&o, "another buffer", &["another map", "MapMismatch"], &[]);

    let damaged = |name: &str, bytes: &[u8], expect: &[&str]| {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let o = replay(&p, &map, &[]);
        let mut e = vec![name, "not a valid scenario"];
        e.extend_from_slice(expect);
        assert_refused(&o, name, &e, &[]);
    };
    damaged("half.scn", &good[..good.len() / 2], &[]);
    damaged("short.scn", &good[..good.len() - 1], &[]);
    damaged("header.scn", &good[..40], &[]);
    damaged("empty.scn", &[], &[]);
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    damaged("flipped.scn", &flipped, &["damaged: CRC"]);
    let mut magic = good.clone();
    magic[0] ^= 0x01;
    damaged("magic.scn", &magic, &[]);
    let o = replay(&d.join("missing.scn"), &map, &[]);
    assert_refused(&o, "missing scenario", &["missing.scn"], &[]);
}

// 5. Bad input: a clear error, non-zero exit, nothing written.
#[test]
fn bad_inputs_fail_clearly_and_write_nothing() {
    let d = scratch("bad");
    let (scn, png) = (d.join("out.scn"), d.join("out.png"));
    let err_png = d.join("out-error.png");
    let never = [scn.as_path(), png.as_path(), err_png.as_path()];
    let map = office();
    let fails = |what: &str, args: &[&str], expect: &[&str]| {
        let mut a = vec!["simulate", "--json", "--scenario", s(&scn), "--plot", s(&png)];
        a.extend_from_slice(args);
        assert_refused(&run(&a), what, expect, &never);
    };

    // A closed corridor 0.6 m wide cannot hold 0.45 m of clearance either side.
    let narrow = d.join("narrow.geojson");
    std::fs::write(
        &narrow,
        r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"name":"corridor"},
            "geometry":{"type":"LineString","coordinates":[[0,0],[3,0],[3,0.6],[0,0.6],[0,0]]}}]}"#,
    )
    .unwrap();
    fails("no room", &["--map", s(&narrow), "--distance-m", "10"], &["narrow.geojson", "0.45 m clearance"]);
    // A closed 1.3 m box holds the clearance only in a spot too small to drive.
    let small = d.join("small.geojson");
    std::fs::write(
        &small,
        r#"{"type":"FeatureCollection","features":[{"type":"Feature",
            "geometry":{"type":"LineString","coordinates":[[0,0],[1.3,0],[1.3,1.3],[0,1.3],[0,0]]}}]}"#,
    )
    .unwrap();
    fails("tiny room", &["--map", s(&small), "--distance-m", "10"], &["small.geojson", "too small"]);

    // Ring files.
    let ring = |name: &str, text: &str| {
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let r = ring("notjson.json", "pioneer, sixteen of them");
    fails("ring not JSON", &["--map", s(&map), "--distance-m", "10", "--ring", s(&r)], &["--ring", "notjson.json"]);
    let r = ring("empty.json", "[]");
    fails("empty ring", &["--map", s(&map), "--distance-m", "10", "--ring", s(&r)], &["--ring", "no transducers"]);
    let r = ring("pairs.json", "[[0.1, 0.0]]");
    fails("ring of pairs", &["--map", s(&map), "--distance-m", "10", "--ring", s(&r)], &["--ring", "[x_m, y_m"]);
    let r = ring("inf.json", "[[1e999, 0, 0]]");
    fails("infinite x", &["--map", s(&map), "--distance-m", "10", "--ring", s(&r)], &["--ring", "inf.json"]);
    let r = ring("huge.json", "[[0.2, 0, 0], [0, 1e6, 90]]");
    fails(
        "huge y",
        &["--map", s(&map), "--distance-m", "10", "--ring", s(&r)],
        &["--ring", "transducer 1", "beyond ±100 m"],
    );
    fails("missing ring", &["--map", s(&map), "--distance-m", "10", "--ring", s(&d.join("no.json"))], &["--ring"]);

    // Numbers.
    fails(
        "--inconsistent 1.5",
        &["--map", s(&map), "--distance-m", "10", "--inconsistent", "1.5"],
        &["--inconsistent"],
    );
    fails("--inconsistent -0.1", &["--map", s(&map), "--distance-m", "10", "--inconsistent=-0.1"], &["--inconsistent"]);
    for bad in ["-1", "0", "NaN", "inf"] {
        let arg = format!("--distance-m={bad}");
        fails(&arg, &["--map", s(&map), &arg], &["--distance-m", "must be a positive number"]);
    }
    // A negative number as a separate word is refused too (by the parser).
    fails("--distance-m -1", &["--map", s(&map), "--distance-m", "-1"], &["-1"]);

    // Targets and sources.
    let o = run(&[
        "simulate",
        "--json",
        "--map",
        s(&map),
        "--distance-m",
        "10",
        "--scenario",
        s(&scn),
        "--plot",
        s(&d.join("nowhere/out.png")),
    ]);
    assert_refused(&o, "plot folder missing", &["nowhere", "does not exist"], &never);
    assert!(!d.join("nowhere").exists());
    let o = run(&[
        "simulate",
        "--json",
        "--map",
        s(&map),
        "--distance-m",
        "10",
        "--plot",
        s(&png),
        "--scenario",
        s(&d.join("nowhere/out.scn")),
    ]);
    assert_refused(&o, "scenario folder missing", &["nowhere", "does not exist"], &never);
    fails("missing map", &["--map", s(&d.join("no-such-map.yaml")), "--distance-m", "10"], &["no-such-map.yaml"]);
}

// 6. Figures.
fn png_size(p: &Path) -> (u32, u32) {
    let bytes = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}: PNG signature", p.display());
    assert_eq!(&bytes[12..16], b"IHDR", "{}: IHDR first", p.display());
    let be = |o: usize| u32::from_be_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    let (w, h) = (be(16), be(20));
    // The whole image decodes (chunk CRCs, zlib stream, size).
    let mut r = png::Decoder::new(std::io::Cursor::new(&bytes)).read_info().unwrap();
    assert_eq!((r.info().width, r.info().height), (w, h));
    let mut buf = vec![0; r.output_buffer_size()];
    r.next_frame(&mut buf).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    (w, h)
}

#[test]
fn plot_writes_two_valid_pngs() {
    let d = scratch("plot");
    let out = d.join("run.png");
    simulate(&["--map", s(&office()), "--seed", "4", "--distance-m", "10", "--plot", s(&out)]);
    for p in [out.clone(), d.join("run-error.png")] {
        let (w, h) = png_size(&p);
        assert!(w > 100 && h > 100, "{}: {w} x {h}", p.display());
    }
    let mut left: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
    left.sort();
    assert_eq!(left, ["run-error.png", "run.png"], "only the two figures");
}

#[test]
fn plot_writes_svg_for_an_svg_name() {
    let d = scratch("plot-svg");
    let out = d.join("run.svg");
    simulate(&["--map", s(&office()), "--seed", "4", "--distance-m", "10", "--plot", s(&out)]);
    for (p, words) in
        [(out.clone(), ["truth", "EKF", "x (m)"]), (d.join("run-error.svg"), ["EKF", "time (s)", "heading error"])]
    {
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.trim_start().starts_with("<svg") && text.trim_end().ends_with("</svg>"), "{}", p.display());
        assert!(text.contains("<polyline"), "{}: the tracks are lines", p.display());
        for w in words {
            assert!(text.contains(w), "{}: {w:?} in the text", p.display());
        }
    }
}

// 7. A custom ring.
#[test]
fn a_ring_file_of_eight_transducers_works() {
    let d = scratch("ring8");
    let ring = d.join("ring8.json");
    let mounts: Vec<[f64; 3]> = (0..8)
        .map(|i| {
            let a = f64::from(i) * 45.0;
            [0.2 * a.to_radians().cos(), 0.2 * a.to_radians().sin(), if a > 180.0 { a - 360.0 } else { a }]
        })
        .collect();
    std::fs::write(&ring, serde_json::to_string(&mounts).unwrap()).unwrap();
    let v = assert_replay_matches(&office(), &["--seed", "5", "--distance-m", "10", "--ring", s(&ring)], &d);
    let n = u(&v, "readings");
    assert!(n > 0 && n.is_multiple_of(8), "{n} readings from an 8-transducer ring");
    assert_eq!(n, 8 * u(&v, "cycles"), "one reading per transducer per cycle");
    // The same run with the default ring reads 16 per cycle.
    let p = simulate(&["--map", s(&office()), "--seed", "5", "--distance-m", "10"]);
    assert_eq!(u(&p, "readings"), 16 * u(&p, "cycles"));
}

// 8. The inconsistency knob.
#[test]
fn inconsistent_fraction_follows_the_knob() {
    let depot = shared_map("depot.yaml");
    let clean = simulate(&["--map", s(&depot), "--seed", "1", "--distance-m", "30", "--inconsistent", "0"]);
    assert_eq!(f(&clean, "inconsistent_fraction"), 0.0);
    for k in ["removed_obstacles", "unmapped_objects", "people"] {
        assert_eq!(u(&clean, k), 0, "{k} with --inconsistent 0");
    }
    for k in ["unknown_obstacle", "removed_obstacle"] {
        assert_eq!(u(&clean, &format!("detection.{k}.true_positives")), 0, "{k}: nothing to find");
        assert_eq!(u(&clean, &format!("detection.{k}.false_negatives")), 0, "{k}: nothing to miss");
    }
    let half = simulate(&["--map", s(&depot), "--seed", "1", "--distance-m", "30", "--inconsistent", "0.5"]);
    let x = f(&half, "inconsistent_fraction");
    assert!((0.4..=0.6).contains(&x), "--inconsistent 0.5 gave {x}");
    assert!(u(&half, "removed_obstacles") + u(&half, "unmapped_objects") + u(&half, "people") > 0);
}

// Regressions: defects found while writing these tests, since fixed.

/// `--plot` naming an existing folder fails only when the figure is renamed
/// into place, after the scenario has been written.
#[test]
fn plot_onto_a_folder_writes_nothing() {
    let d = scratch("plotdir");
    let (scn, folder) = (d.join("out.scn"), d.join("figs"));
    std::fs::create_dir(&folder).unwrap();
    let o = run(&[
        "simulate",
        "--json",
        "--map",
        s(&office()),
        "--distance-m",
        "10",
        "--scenario",
        s(&scn),
        "--plot",
        s(&folder),
    ]);
    assert_refused(&o, "--plot onto a folder", &["figs"], &[scn.as_path(), d.join("figs-error.png").as_path()]);
}

/// The ring file bounds positions but not headings: a huge heading is
/// saturated to i32::MAX m° (another angle) and, without `--scenario`,
/// simulated silently; any heading beyond ±360° (which the scenario format
/// refuses) is found only when the scenario is written, after the whole
/// run, as a bare `--scenario OUT: Mount(0)`.
#[test]
fn ring_headings_out_of_range_are_refused_up_front() {
    let d = scratch("ringheading");
    let scn = d.join("out.scn");
    for (name, text) in [("huge.json", "[[0.2, 0, 1e12]]"), ("over.json", "[[0.2, 0, 400]]")] {
        let r = d.join(name);
        std::fs::write(&r, text).unwrap();
        let o = run(&[
            "simulate",
            "--json",
            "--map",
            s(&office()),
            "--distance-m",
            "10",
            "--ring",
            s(&r),
            "--scenario",
            s(&scn),
        ]);
        assert_refused(&o, name, &["--ring", name, "transducer 0"], &[scn.as_path()]);
    }
}

/// A ring transducer 50 m from the centre passes the ring file's ±100 m
/// check and is refused by the simulator, but the message blames the map.
#[test]
fn a_far_transducer_is_blamed_on_the_ring() {
    let d = scratch("ringfar");
    let r = d.join("far.json");
    std::fs::write(&r, "[[50, 0, 0]]").unwrap();
    let o = run(&["simulate", "--json", "--map", s(&office()), "--distance-m", "10", "--ring", s(&r)]);
    assert_refused(&o, "far transducer", &["--ring", "far.json", "2 m"], &[]);
}

/// `--distance-m -1` (the value as its own word) is taken by the argument
/// parser for an unknown flag: "unexpected argument '-1' found", exit 2,
/// instead of the command's own message.
#[test]
fn a_negative_distance_as_its_own_word_gets_the_clear_message() {
    let o = run(&["simulate", "--json", "--map", s(&office()), "--distance-m", "-1"]);
    assert_refused(&o, "--distance-m -1", &["--distance-m -1: must be a positive number"], &[]);
}

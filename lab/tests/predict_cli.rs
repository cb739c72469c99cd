//! `echoloc-lab window` and `predict` as DESIGN §7 specifies them.

use std::process::Command;

mod common;
use common::root;

use serde_json::Value;

fn lab(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_echoloc-lab")).args(args).output().unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn json_lines(s: &str) -> Vec<Value> {
    s.lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn window_example_2() {
    let (ok, out, err) = lab(&[
        "window",
        "--rmax-mm",
        "2400",
        "--half-angle-deg",
        "35",
        "--ds-min-mm",
        "750",
        "--delta-max-deg",
        "15",
        "--tb-mm",
        "750",
    ]);
    assert!(ok, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["n_pp"], 4);
    assert_eq!(v["endpoints_mm"].as_array().unwrap().len(), 4);
    let w = v["w_mm"].as_f64().unwrap();
    assert!((w - 672.2).abs() < 0.1 && w <= v["w_min_mm"].as_f64().unwrap());
    for e in v["endpoints_mm"].as_array().unwrap() {
        assert_eq!(e[1].as_f64().unwrap(), 2400.0);
    }
}

#[test]
fn window_example_1_and_bad_input() {
    let (ok, out, _) =
        lab(&["window", "--rmax-mm", "2400", "--half-angle-deg", "35", "--ds-min-mm", "20", "--delta-max-deg", "15"]);
    assert!(ok);
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["n_pp"], 175);
    let (ok, _, err) =
        lab(&["window", "--rmax-mm", "2400", "--half-angle-deg", "95", "--ds-min-mm", "20", "--delta-max-deg", "15"]);
    assert!(!ok && err.contains("bad half-angle") && err.contains("between 0° and 90°"), "{err}");
}

#[test]
fn predict_a_ring_and_a_sensor() {
    let map = root().join("boards/qemu-mps2-an386/office.map");
    let map = map.to_str().unwrap();
    let (ok, out, err) = lab(&["predict", "--map", map, "--pose", "4,4,0"]);
    assert!(ok, "{err}");
    let lines = json_lines(&out);
    assert_eq!(lines.len(), 16, "one line per Pioneer transducer");
    for (i, l) in lines.iter().enumerate() {
        assert_eq!(l["sensor"], i);
        for k in ["range_m", "kappa", "theta_deg", "delta_deg", "point"] {
            assert!(l.get(k).is_some(), "{k} missing");
        }
    }
    // Transducer 3 looks 10° left of forward from (4.17, 4.025): through the
    // door gap its nearest credible echo is the partition's door jamb (7, 4.5).
    assert_eq!(lines[3]["point"], serde_json::json!([7.0, 4.5]));
    // One sensor looking at the table's left face (x = 2 m) from (1, 2.4).
    let (ok, out, err) = lab(&["predict", "--map", map, "--sensor", "1,2.4,0", "--credence", "crisp"]);
    assert!(ok, "{err}");
    let l = &json_lines(&out)[0];
    assert_eq!(l["range_m"], 1.0);
    assert_eq!(l["delta_deg"], 0.0);
    assert_eq!(l["point"], serde_json::json!([2.0, 2.4]));
    // --geometric ignores R_min: a table face 0.3 m away is reported.
    let (ok, out, _) = lab(&["predict", "--map", map, "--sensor", "1.7,2.4,0", "--geometric"]);
    assert!(ok);
    let l = &json_lines(&out)[0];
    assert!((l["range_m"].as_f64().unwrap() - 0.3).abs() < 1e-9);
    assert_eq!(l["kappa"], Value::Null);
    // Without --geometric that face is inside R_min (0.5 m): no credible echo from it.
    let (ok, out, _) = lab(&["predict", "--map", map, "--sensor", "1.7,2.4,0", "--credence", "crisp"]);
    assert!(ok);
    assert_ne!(json_lines(&out)[0]["range_m"], 0.3);
}

#[test]
fn predict_reads_geojson_and_refuses_bad_input() {
    let geo = root().join("maps/office.geojson");
    let (ok, out, err) =
        lab(&["predict", "--map", geo.to_str().unwrap(), "--sensor", "1,2.4,0", "--credence", "crisp"]);
    assert!(ok, "{err}");
    assert_eq!(json_lines(&out)[0]["range_m"], 1.0);
    let (ok, _, err) = lab(&["predict", "--map", geo.to_str().unwrap(), "--sensor", "1,2"]);
    assert!(!ok && err.contains("X,Y,DEG"), "{err}");
    let (ok, _, err) = lab(&["predict", "--map", "/nonexistent.map", "--sensor", "1,2,3"]);
    assert!(!ok && err.contains("/nonexistent.map"), "{err}");
    let (ok, _, err) = lab(&["predict", "--map", geo.to_str().unwrap(), "--sensor", "1,2,3", "--tau", "2"]);
    assert!(!ok && err.contains("--tau"), "{err}");
    let (ok, _, err) =
        lab(&["predict", "--map", geo.to_str().unwrap(), "--pose", "1,2,3", "--ring", "/nonexistent.json"]);
    assert!(!ok && err.contains("--ring"), "{err}");
}

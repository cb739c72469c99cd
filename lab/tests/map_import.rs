//! `echoloc-lab map import` end to end: the checked-in firmware blob is what
//! the importer makes today, and bad inputs fail clearly without writing.

mod common;

use std::path::PathBuf;

use common::{assert_blob_fresh, lab, root};

fn tmp(name: &str) -> PathBuf {
    common::tmp("lab-test", name)
}

#[test]
fn checked_in_firmware_blob_is_fresh() {
    let out = tmp("office.map");
    // The office map serves the firmware's queries, not localization: no field.
    let o = lab()
        .args(["map", "import", "--no-field"])
        .arg(root().join("maps/office.geojson"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(summary["polygons"], 9);
    assert_eq!(summary["convex_pieces"], 15);
    assert_eq!(summary["bytes"], std::fs::metadata(&out).unwrap().len());
    assert_blob_fresh(
        &out,
        "boards/qemu-mps2-an386/office.map",
        "cargo run -p echoloc-lab -- map import --no-field maps/office.geojson -o boards/qemu-mps2-an386/office.map",
    );
    // `map info` loads it as the firmware does and reports the same figures.
    let o = lab().args(["map", "info"]).arg(&out).output().unwrap();
    assert!(o.status.success());
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["convex_pieces", "edges", "bytes", "buffer_mm", "cell_mm", "grid", "grid_refs"] {
        assert_eq!(info[k], summary[k], "{k}");
    }
}

fn import_fails(name: &str, text: &str, expect: &str) {
    let input = tmp(name);
    std::fs::write(&input, text).unwrap();
    let out = tmp(&format!("{name}.map"));
    let _ = std::fs::remove_file(&out);
    let o = lab().args(["map", "import"]).arg(&input).arg("-o").arg(&out).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{name}: should fail");
    assert!(err.contains(input.to_str().unwrap()), "{name}: error names the file: {err}");
    assert!(err.contains(expect), "{name}: error says {expect:?}: {err}");
    assert!(!out.exists(), "{name}: nothing written");
    assert!(!out.with_extension("partial").exists(), "{name}: no partial file left");
}

#[test]
fn bad_inputs_fail_clearly_and_write_nothing() {
    import_fails("notjson.geojson", "{ nope", "not JSON");
    import_fails("notype.geojson", "{}", "no \"type\"");
    import_fails("point.geojson", r#"{"type":"Point","coordinates":[1,2]}"#, "unsupported geometry type \"Point\"");
    import_fails(
        "hole.geojson",
        r#"{"type":"Polygon","coordinates":[[[0,0],[4,0],[4,4],[0,4],[0,0]],[[5,1],[6,1],[6,2],[5,1]]]}"#,
        "HoleOutside: hole 0",
    );
    import_fails(
        "touch.geojson",
        r#"{"type":"Polygon","coordinates":[[[0,0],[4,0],[4,4],[0,4],[0,0]],[[0,1],[2,1],[2,2],[0,1]]]}"#,
        "RingsMeet",
    );
    import_fails(
        "shorthole.geojson",
        r#"{"type":"Polygon","coordinates":[[[0,0],[4,0],[4,4],[0,4],[0,0]],[[1,1],[2,1],[1,1]]]}"#,
        "coordinates[1]: hole 0 needs at least three distinct vertices",
    );
    import_fails(
        "far.geojson",
        r#"{"type":"LineString","coordinates":[[0,0],[2000000,0]]}"#,
        "x = 2000000 m is beyond",
    );
    import_fails(
        "bowtie.geojson",
        r#"{"type":"Polygon","coordinates":[[[0,0],[1,1],[1,0],[0,1],[0,0]]]}"#,
        "NotSimple",
    );
    import_fails(
        "nan.geojson",
        r#"{"type":"LineString","coordinates":[[0,0],["a",0]]}"#,
        "not GeoJSON (RFC 7946): invalid type: string \"a\", expected f64 at line 1 column 46",
    );
    let o = lab().args(["map", "import", "/nonexistent/x.geojson", "-o", "/tmp/never.map"]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("/nonexistent/x.geojson"));
}

/// The field's fallback lobe (issue #36): refused below the face lobe, at
/// 90° and beyond, with nothing written; a good one is recorded in the
/// blob's field header and measured by `map field-check` under the same rule.
#[test]
fn a_field_fallback_lobe_is_checked_recorded_and_measured() {
    let input = tmp("fallback.geojson");
    std::fs::write(&input, r#"{"type":"Polygon","coordinates":[[[0,0],[6,0],[6,4],[0,4],[0,0]],[[2,1.5],[3,1.5],[3,2.5],[2,2.5],[2,1.5]]]}"#).unwrap();
    let out = tmp("fallback.map");
    for bad in ["10", "15", "90", "-5", "nan"] {
        let _ = std::fs::remove_file(&out);
        let o = lab()
            .args(["map", "import"])
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .arg(format!("--field-fallback-deg={bad}"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{bad}: should fail");
        assert!(err.contains("fallback"), "{bad}: {err}");
        assert!(!out.exists(), "{bad}: nothing written");
    }
    let o = lab()
        .args(["map", "import"])
        .arg(&input)
        .arg("-o")
        .arg(&out)
        .args(["--field-fallback-deg", "60"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&out).unwrap();
    let mut words = vec![0u64; bytes.len().div_ceil(8)];
    bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(&bytes);
    let view = echoloc::map::MapView::new(&bytemuck::cast_slice::<u64, u8>(&words)[..bytes.len()]).unwrap();
    assert_eq!(view.field().fallback_deg(), Some(60.0));
    let o = lab().args(["map", "field-check", "--robots", "50"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["from_the_fallback_lobe"].as_f64().is_some(), "{v}");
}

fn squares(n: usize) -> String {
    squares_at(n, 2.0)
}

/// `n` unit squares, 150 to a row, `pitch` m apart.
fn squares_at(n: usize, pitch: f64) -> String {
    let mut feats = Vec::new();
    for i in 0..n {
        let (x, y) = ((i % 150) as f64 * pitch, (i / 150) as f64 * pitch);
        feats.push(format!(
            r#"{{"type":"Feature","geometry":{{"type":"Polygon","coordinates":[[[{x},{y}],[{},{y}],[{},{}],[{x},{}],[{x},{y}]]]}}}}"#,
            x + 1.0,
            x + 1.0,
            y + 1.0,
            y + 1.0
        ));
    }
    format!(r#"{{"type":"FeatureCollection","features":[{}]}}"#, feats.join(","))
}

#[test]
fn a_map_beyond_the_old_ram_map_imports_and_validates() {
    // 1100 separate squares: more than the 1024 obstacles the RAM-built
    // StandardMap holds; the compiled map has no such limit.
    let input = tmp("big.geojson");
    std::fs::write(&input, squares(1100)).unwrap();
    let out = tmp("big.map");
    let o = lab().args(["map", "import"]).arg(&input).arg("-o").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = lab().args(["map", "info"]).arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(info["convex_pieces"], 1100);
}

#[test]
fn a_map_beyond_the_compiler_capacity_is_refused() {
    // More pieces than the host's compiler holds (32 768).
    import_fails("huge.geojson", &squares(33_000), "exceeds the compiler's capacity");
}

#[test]
fn a_wall_with_a_repeated_first_position_is_its_own_obstacle() {
    // Two walls; the second starts with a repeated position. It must import
    // as a second obstacle, not fail and not merge into the first.
    let input = tmp("walls.geojson");
    std::fs::write(
        &input,
        r#"{"type":"FeatureCollection","features":[
            {"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,5],[3,5]]}},
            {"type":"Feature","geometry":{"type":"LineString","coordinates":[[0,0],[0,0],[2,0]]}}]}"#,
    )
    .unwrap();
    let out = tmp("walls.map");
    let o = lab().args(["map", "import"]).arg(&input).arg("-o").arg(&out).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = lab().args(["map", "info"]).arg(&out).output().unwrap();
    let info: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(info["polygons"], 2, "two obstacles: {info}");
    assert_eq!(info["convex_pieces"], 2);
    import_fails("allsame.geojson", r#"{"type":"LineString","coordinates":[[1,1],[1,1],[1,1]]}"#, "has no segment");
}

#[test]
fn every_command_takes_a_map_beyond_the_old_ram_map() {
    // Issue #35: predict, simulate and replay refused any map of more than
    // 1 024 convex pieces ("Capacity(Pieces)"), which `map import` makes.
    let input = tmp("big-cmds.geojson");
    // 2 m gaps: room for the simulator's route.
    std::fs::write(&input, squares_at(1100, 3.0)).unwrap();
    let blob = tmp("big-cmds.map");
    let o = lab().args(["map", "import"]).arg(&input).arg("-o").arg(&blob).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The robot in the gaps between the squares: both forms predict the
    // same, and each echo point lies on a square's outline (sides at
    // x, y = 3k and 3k + 1 m), a fact of the input, not of the predictor.
    let mut outputs = Vec::new();
    for map in [&blob, &input] {
        let o = lab().args(["predict", "--pose", "2,2,20", "--map"]).arg(map).output().unwrap();
        assert!(o.status.success(), "{}: {}", map.display(), String::from_utf8_lossy(&o.stderr));
        outputs.push(o.stdout);
    }
    assert_eq!(outputs[0], outputs[1]);
    let lines: Vec<serde_json::Value> =
        String::from_utf8_lossy(&outputs[0]).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 16);
    let seen: Vec<&serde_json::Value> = lines.iter().filter(|l| !l["range_m"].is_null()).collect();
    assert!(seen.len() >= 4, "{lines:?}");
    for l in seen {
        let (x, y) = (l["point"][0].as_f64().unwrap(), l["point"][1].as_f64().unwrap());
        let on_side = |v: f64| (v - v.round()).abs() < 1e-3;
        let inside = |v: f64| v.rem_euclid(3.0) <= 1.0 + 1e-3;
        let on_side = |v: f64| on_side(v) && inside(v);
        assert!((on_side(x) && inside(y)) || (on_side(y) && inside(x)), "{l}");
    }
    let log = tmp("big-cmds.csv");
    let o = lab()
        .args(["simulate", "--json", "--distance-m", "6", "--inconsistent", "0", "--map"])
        .arg(&blob)
        .arg("--log")
        .arg(&log)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sim: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let o = lab().args(["replay", "--json", "--map"]).arg(&blob).arg("--log").arg(&log).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rep: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rep["readings"], sim["readings"]);
    assert!(sim["readings"].as_u64().unwrap() > 16);
}

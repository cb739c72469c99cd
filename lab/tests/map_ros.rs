//! ROS map_server import on the real maps (depot, tb3_sandbox): the polygons
//! are within the simplification tolerance plus one cell of the occupied
//! cells both ways, checked cell by cell against a classification made here
//! independently; GeoJSON with holes; export and preview; bad inputs fail
//! clearly, naming file and field, and write nothing; the depot blob the
//! QEMU firmware includes is fresh.

mod common;

use std::path::{Path, PathBuf};

use common::{assert_blob_fresh, lab, root};

fn tmp(name: &str) -> PathBuf {
    common::tmp("lab-ros", name)
}

fn data(name: &str) -> PathBuf {
    root().join("../shared/data/maps").join(name)
}

fn run_ok(args: &[&str], paths: &[&Path]) -> serde_json::Value {
    let mut c = lab();
    c.args(args);
    for p in paths {
        c.arg(p);
    }
    let o = c.output().unwrap();
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Convex pieces (mm, counter-clockwise) of an exported GeoJSON.
fn pieces_of(geojson: &Path) -> Vec<Vec<(f64, f64)>> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(geojson).unwrap()).unwrap();
    let mut out = Vec::new();
    for f in v["features"].as_array().unwrap() {
        assert_eq!(f["geometry"]["type"], "MultiPolygon");
        for poly in f["geometry"]["coordinates"].as_array().unwrap() {
            let ring = poly[0].as_array().unwrap();
            let mut pts: Vec<(f64, f64)> = ring
                .iter()
                .map(|p| ((p[0].as_f64().unwrap() * 1000.0).round(), (p[1].as_f64().unwrap() * 1000.0).round()))
                .collect();
            pts.pop();
            out.push(pts);
        }
    }
    out
}

/// Distance from `p` to a convex counter-clockwise piece (0 inside).
fn dist_to_piece(piece: &[(f64, f64)], p: (f64, f64)) -> f64 {
    let n = piece.len();
    let inside = (0..n).all(|i| {
        let (a, b) = (piece[i], piece[(i + 1) % n]);
        (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) >= 0.0
    });
    if inside {
        return 0.0;
    }
    (0..n)
        .map(|i| {
            let (a, b) = (piece[i], piece[(i + 1) % n]);
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let t = (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
            (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
        })
        .fold(f64::MAX, f64::min)
}

/// An 8-bit P5 PGM, read here (not with the lab's reader).
fn read_p5(path: &Path) -> (usize, usize, Vec<u8>) {
    let b = std::fs::read(path).unwrap();
    let mut tokens = Vec::new();
    let mut pos = 2;
    while tokens.len() < 3 {
        while b[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if b[pos] == b'#' {
            while b[pos] != b'\n' {
                pos += 1;
            }
            continue;
        }
        let s = pos;
        while b[pos].is_ascii_digit() {
            pos += 1;
        }
        tokens.push(std::str::from_utf8(&b[s..pos]).unwrap().parse::<usize>().unwrap());
    }
    assert_eq!(tokens[2], 255);
    let (w, h) = (tokens[0], tokens[1]);
    (w, h, b[pos + 1..pos + 1 + w * h].to_vec())
}

/// Imports a real map and checks the error bound both ways, cell by cell.
fn check_bound(name: &str, origin: (f64, f64), occupied_thresh: f64, simplify_mm: u32) -> serde_json::Value {
    let out = tmp(&format!("{name}-{simplify_mm}.map"));
    let s = simplify_mm.to_string();
    let summary = run_ok(&["map", "import", "--simplify-mm", &s, "-o"], &[&out, &data(&format!("{name}.yaml"))]);
    let gj = tmp(&format!("{name}-{simplify_mm}.geojson"));
    run_ok(&["map", "export", "-o"], &[&gj, &out]);
    let pieces = pieces_of(&gj);
    assert_eq!(pieces.len() as u64, summary["convex_pieces"].as_u64().unwrap());
    let boxes: Vec<(f64, f64, f64, f64)> = pieces
        .iter()
        .map(|p| {
            p.iter().fold((f64::MAX, f64::MAX, f64::MIN, f64::MIN), |b, q| {
                (b.0.min(q.0), b.1.min(q.1), b.2.max(q.0), b.3.max(q.1))
            })
        })
        .collect();

    let (w, h, px) = read_p5(&data(&format!("{name}.pgm")));
    let res = 50.0; // both maps: 0.05 m
    let occupied: Vec<bool> = px.iter().map(|&v| (255.0 - v as f64) / 255.0 > occupied_thresh).collect();
    let centre = |c: usize, r: usize| {
        (origin.0 * 1000.0 + (c as f64 + 0.5) * res, origin.1 * 1000.0 + ((h - 1 - r) as f64 + 0.5) * res)
    };
    let bound = simplify_mm as f64 + res;
    let reach = (bound / res).ceil() as i64 + 1;
    let (mut worst_occ, mut worst_free, mut covered_free) = (0.0f64, 0.0f64, 0usize);
    for r in 0..h {
        for c in 0..w {
            let p = centre(c, r);
            if occupied[r * w + c] {
                // Every occupied cell within the bound of the polygons.
                let d = pieces.iter().map(|q| dist_to_piece(q, p)).fold(f64::MAX, f64::min);
                worst_occ = worst_occ.max(d);
                assert!(d <= bound, "{name}: occupied cell ({c}, {r}) at {p:?} is {d:.1} mm from the polygons");
            } else {
                // A non-occupied cell inside a polygon: an occupied cell within the bound.
                let inside = pieces
                    .iter()
                    .zip(&boxes)
                    .any(|(q, b)| p.0 >= b.0 && p.0 <= b.2 && p.1 >= b.1 && p.1 <= b.3 && dist_to_piece(q, p) == 0.0);
                if !inside {
                    continue;
                }
                covered_free += 1;
                let mut best = f64::MAX;
                for dr in -reach..=reach {
                    for dc in -reach..=reach {
                        let (cc, rr) = (c as i64 + dc, r as i64 + dr);
                        if cc >= 0
                            && rr >= 0
                            && (cc as usize) < w
                            && (rr as usize) < h
                            && occupied[rr as usize * w + cc as usize]
                        {
                            let q = centre(cc as usize, rr as usize);
                            best = best.min((p.0 - q.0).hypot(p.1 - q.1));
                        }
                    }
                }
                worst_free = worst_free.max(best);
                assert!(best <= bound, "{name}: free cell ({c}, {r}) covered, {best:.1} mm from any occupied cell");
            }
        }
    }
    eprintln!(
        "{name} simplify {simplify_mm} mm: worst occupied-cell distance {worst_occ:.1} mm, {covered_free} free cells covered, worst {worst_free:.1} mm from an occupied one (bound {bound} mm)"
    );
    summary
}

#[test]
fn depot_polygons_stay_within_the_bound() {
    let s = check_bound("depot", (0.0, 0.0), 0.65, 50);
    assert_eq!(s["unknown_as"], "free");
    assert_eq!(s["source"], "ros_map_server");
    assert!(s["holes"].as_u64().unwrap() > 0, "the depot's walls enclose rooms: {s}");
    assert!(s["convex_pieces"].as_u64().unwrap() <= 1024);
}

#[test]
fn tb3_sandbox_polygons_stay_within_the_bound() {
    let s = check_bound("tb3_sandbox", (-10.0, -10.0), 0.65, 50);
    assert!(s["cells"]["unknown"].as_u64().unwrap() > 100_000);
}

#[test]
fn tighter_and_looser_tolerances_keep_their_bounds() {
    let fine = check_bound("tb3_sandbox", (-10.0, -10.0), 0.65, 10);
    let coarse = check_bound("tb3_sandbox", (-10.0, -10.0), 0.65, 100);
    assert!(fine["edges"].as_u64() > coarse["edges"].as_u64(), "{fine} vs {coarse}");
}

#[test]
fn unknown_as_occupied_wraps_the_known_area() {
    let out = tmp("tb3-unknown-occ.map");
    let s = run_ok(&["map", "import", "--unknown", "occupied", "-o"], &[&out, &data("tb3_sandbox.yaml")]);
    assert_eq!(s["unknown_as"], "occupied");
    // The unknown surroundings are one polygon whose hole is the arena.
    assert!(s["holes"].as_u64().unwrap() >= 1, "{s}");
}

#[test]
fn checked_in_depot_blob_is_fresh() {
    let out = tmp("depot.map");
    let s = run_ok(&["map", "import", "-o"], &[&out, &data("depot.yaml")]);
    assert_eq!(s["bytes"], std::fs::metadata(&out).unwrap().len());
    assert_blob_fresh(
        &out,
        "boards/qemu-mps2-an386/depot.map",
        "cargo run -p echoloc-lab -- map import ../shared/data/maps/depot.yaml -o boards/qemu-mps2-an386/depot.map",
    );
}

#[test]
fn geojson_holes_export_and_reimport() {
    // A 4 m square with a 2 m square hole: 12 m² in convex pieces.
    let src = tmp("frame.geojson");
    std::fs::write(
        &src,
        r#"{"type":"FeatureCollection","features":[{"type":"Feature","geometry":{"type":"Polygon","coordinates":[[[0,0],[4,0],[4,4],[0,4],[0,0]],[[1,1],[1,3],[3,3],[3,1],[1,1]]]}},{"type":"Feature","geometry":{"type":"LineString","coordinates":[[6,0],[6,4]]}}]}"#,
    )
    .unwrap();
    let map = tmp("frame.map");
    let preview = tmp("frame.png");
    let s = run_ok(&["map", "import", "-o"], &[&map, &src, Path::new("--preview"), &preview]);
    assert_eq!(s["polygons"], 2);
    assert!(preview.exists());
    let gj = tmp("frame-out.geojson");
    run_ok(&["map", "export", "-o"], &[&gj, &map]);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&gj).unwrap()).unwrap();
    assert_eq!(v["features"][1]["geometry"]["type"], "MultiLineString");
    let area: f64 = pieces_of_solids(&v)
        .iter()
        .map(|p| {
            (0..p.len()).map(|i| p[i].0 * p[(i + 1) % p.len()].1 - p[(i + 1) % p.len()].0 * p[i].1).sum::<f64>() / 2.0
        })
        .sum();
    assert!((area - 12.0).abs() < 1e-9, "area {area}");
    // Re-importing the export gives the same pieces and edges.
    let again = tmp("frame-again.map");
    let s2 = run_ok(&["map", "import", "-o"], &[&again, &gj]);
    assert_eq!(s2["convex_pieces"], s["convex_pieces"]);
    assert_eq!(s2["edges"], s["edges"]);
    // `map preview` over the grid it came from.
    let png = tmp("depot-preview.png");
    let dm = tmp("depot-for-preview.map");
    run_ok(&["map", "import", "-o"], &[&dm, &data("depot.yaml")]);
    run_ok(&["map", "preview", "-o"], &[&png, &dm, Path::new("--grid"), &data("depot.yaml")]);
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
}

fn pieces_of_solids(v: &serde_json::Value) -> Vec<Vec<(f64, f64)>> {
    let mut out = Vec::new();
    for f in v["features"].as_array().unwrap() {
        if f["geometry"]["type"] == "MultiPolygon" {
            for poly in f["geometry"]["coordinates"].as_array().unwrap() {
                let mut r: Vec<(f64, f64)> = poly[0]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
                    .collect();
                r.pop();
                out.push(r);
            }
        }
    }
    out
}

const YAML: &str =
    "image: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

/// Writes `yaml` and `image` (if any) into a fresh directory, imports with a
/// preview, and checks the failure: names the YAML file and `expect`, and
/// nothing is written.
fn ros_fails(name: &str, yaml: &str, image: Option<(&str, &[u8])>, expect: &[&str]) {
    let dir = tmp(name);
    std::fs::create_dir_all(&dir).unwrap();
    let y = dir.join("m.yaml");
    std::fs::write(&y, yaml).unwrap();
    if let Some((file, bytes)) = image {
        std::fs::write(dir.join(file), bytes).unwrap();
    }
    let out = dir.join("out.map");
    let png = dir.join("out.png");
    let o = lab().args(["map", "import"]).arg(&y).arg("-o").arg(&out).arg("--preview").arg(&png).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{name}: should fail");
    assert!(err.contains(y.to_str().unwrap()), "{name}: error names the file: {err}");
    for e in expect {
        assert!(err.contains(e), "{name}: error says {e:?}: {err}");
    }
    for f in [&out, &png] {
        assert!(!f.exists(), "{name}: {} written", f.display());
        assert!(!f.with_extension("partial").exists(), "{name}: partial file left");
    }
}

fn pgm(w: usize, h: usize, f: impl Fn(usize, usize) -> u8) -> Vec<u8> {
    let mut b = format!("P5\n{w} {h}\n255\n").into_bytes();
    for r in 0..h {
        for c in 0..w {
            b.push(f(c, r));
        }
    }
    b
}

#[test]
fn bad_ros_maps_fail_clearly_and_write_nothing() {
    let small = pgm(8, 8, |c, r| if (2..6).contains(&c) && (2..6).contains(&r) { 0 } else { 254 });
    let img = Some(("m.pgm", small.as_slice()));
    ros_fails("missing-image", YAML, None, &["image:", "m.pgm", "cannot read"]);
    ros_fails("no-resolution", &YAML.replace("resolution: 0.05\n", ""), img, &["resolution: missing"]);
    ros_fails("bad-resolution", &YAML.replace("0.05", "0.05m"), img, &["resolution: expected a number"]);
    ros_fails("no-negate", &YAML.replace("negate: 0\n", ""), img, &["negate: missing"]);
    ros_fails("bad-origin", &YAML.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0]"), img, &["origin: expected three numbers"]);
    ros_fails("yaw", &YAML.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0, 1.57]"), img, &["origin[2]: yaw"]);
    ros_fails("bad-mode", &format!("{YAML}mode: fancy\n"), img, &["mode: expected trinary, scale or raw"]);
    ros_fails("thresholds", &YAML.replace("0.196", "0.9"), img, &["free_thresh: 0.9 must be below"]);
    ros_fails(
        "garbage-line",
        &format!("{YAML}just words\n"),
        img,
        &["line 7: not YAML", "(expected `key: value` lines)"],
    );
    // Coordinates that would overflow.
    ros_fails(
        "far-origin",
        &YAML.replace("[0.0, 0.0, 0.0]", "[2000000.0, 0.0, 0.0]"),
        img,
        &["origin[0]: 2000000 m is beyond", "overflow"],
    );
    ros_fails(
        "far-extent",
        &YAML.replace("[0.0, 0.0, 0.0]", "[1073741.0, 0.0, 0.0]").replace("0.05", "1000"),
        img,
        &["resolution:", "overflow"],
    );
    // Unsupported depths: 16-bit PGM and 16-bit PNG.
    let mut deep = b"P5\n2 2\n65535\n".to_vec();
    deep.extend([0u8; 8]);
    ros_fails("pgm16", YAML, Some(("m.pgm", &deep)), &["image:", "unsupported image depth", "16-bit PGM"]);
    let mut png16 = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png16, 2, 2);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        enc.write_header().unwrap().write_image_data(&[0u8; 8]).unwrap();
    }
    ros_fails(
        "png16",
        &YAML.replace("m.pgm", "m.png"),
        Some(("m.png", &png16)),
        &["image:", "m.png", "unsupported image depth", "16-bit PNG"],
    );
    ros_fails("truncated", YAML, Some(("m.pgm", &small[..small.len() - 5])), &["image:", "P5 data"]);
    ros_fails("not-an-image", YAML, Some(("m.pgm", b"hello")), &["image:", "not a PGM"]);
    // A P5 pixel above maxval, and a header promising far more pixels than the file holds.
    let mut over = b"P5\n2 2\n100\n".to_vec();
    over.extend([0u8, 50, 200, 100]);
    ros_fails("over-maxval", YAML, Some(("m.pgm", &over)), &["image:", "pixel 2 = 200 exceeds maxval 100"]);
    ros_fails("lying-p2", YAML, Some(("m.pgm", b"P2\n4000 4000\n255\n0 0 0\n")), &["image:", "P2 data: pixel 3"]);
    // A header past the 2^26-cell limit is refused before any pixel is read or a buffer allocated.
    ros_fails(
        "huge-p2",
        YAML,
        Some(("m.pgm", b"P2\n16000 16000\n255\n0 0 0\n")),
        &["image:", "PGM header: 16000x16000 is too large"],
    );
    // Larger than the compiler's capacity (32 768): 34 596 separate occupied cells.
    let dots = pgm(372, 372, |c, r| if c % 2 == 0 && r % 2 == 0 { 0 } else { 254 });
    ros_fails("capacity", YAML, Some(("m.pgm", &dots)), &["exceeds the compiler's capacity", "34596 obstacles"]);
}

#[test]
fn png_maps_and_modes_import() {
    // The same 8×8 map as PNG (RGB), negated, in raw mode.
    let dir = tmp("png-ok");
    std::fs::create_dir_all(&dir).unwrap();
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, 8, 8);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut data = Vec::new();
        for r in 0..8 {
            for c in 0..8 {
                // negate: 1 → white (255) is occupied.
                let v = if (2..6).contains(&c) && (2..6).contains(&r) { 255 } else { 0 };
                data.extend([v, v, v]);
            }
        }
        enc.write_header().unwrap().write_image_data(&data).unwrap();
    }
    std::fs::write(dir.join("m.png"), &bytes).unwrap();
    let y = dir.join("m.yaml");
    std::fs::write(&y, YAML.replace("m.pgm", "m.png").replace("negate: 0", "negate: 1")).unwrap();
    let s = run_ok(&["map", "import", "--simplify-mm", "0", "-o"], &[&dir.join("a.map"), &y]);
    assert_eq!(s["polygons"], 1);
    assert_eq!(s["cells"]["occupied"], 16);
    // Raw mode: the value is a percentage; 100 → occupied, 0 → free.
    let raw = pgm(8, 8, |c, _| if c == 3 { 100 } else { 0 });
    std::fs::write(dir.join("r.pgm"), raw).unwrap();
    let y = dir.join("r.yaml");
    std::fs::write(&y, format!("{}mode: raw\n", YAML.replace("m.pgm", "r.pgm"))).unwrap();
    let s = run_ok(&["map", "import", "-o"], &[&dir.join("r.map"), &y]);
    assert_eq!(s["cells"]["occupied"], 8);
    assert_eq!(s["polygons"], 1);
}

/// ROS map_server's documented reading of the YAML (wiki.ros.org/map_server,
/// "Value Interpretation"), on what the old line splitter could not read: a
/// quoted image name with spaces, `origin` as a flow list over two lines,
/// `mode: scale` with `negate: 1`. With negate, a pixel of value x has
/// occupancy p = x / 255; p > occupied_thresh is occupied, p < free_thresh
/// free, and scale mode maps the values between to a gradient (neither an
/// obstacle nor known free space in a polygon map). The oracle counts the
/// cells from that formula; the import must count the same.
#[test]
fn map_server_semantics_of_the_yaml() {
    let dir = tmp("semantics");
    std::fs::create_dir_all(&dir).unwrap();
    let img = pgm(16, 16, |c, r| (r * 16 + c) as u8);
    std::fs::write(dir.join("my map.pgm"), &img).unwrap();
    let y = dir.join("m.yaml");
    std::fs::write(
        &y,
        "image: \"my map.pgm\"\nmode: scale\nresolution: 0.05\norigin: [-1.0,\n         2.0, 0.0]\nnegate: 1\n\
         occupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .unwrap();
    let s = run_ok(&["map", "import", "-o"], &[&dir.join("m.map"), &y]);
    let (mut occupied, mut free) = (0, 0);
    for x in 0..=255u32 {
        let p = f64::from(x) / 255.0;
        if p > 0.65 {
            occupied += 1;
        } else if p < 0.196 {
            free += 1;
        }
    }
    assert_eq!((occupied, free), (90, 50), "x ≥ 166 and x ≤ 49");
    assert_eq!(s["cells"]["occupied"], occupied, "{s}");
    assert_eq!(s["cells"]["free"], free, "{s}");
    assert_eq!(s["cells"]["unknown"], 256 - occupied - free, "{s}");
    // The same image without negate: p = (255 - x) / 255.
    std::fs::write(&y, std::fs::read_to_string(&y).unwrap().replace("negate: 1", "negate: 0")).unwrap();
    let s = run_ok(&["map", "import", "-o"], &[&dir.join("n.map"), &y]);
    let occupied_plain = (0..=255u32).filter(|x| f64::from(255 - x) / 255.0 > 0.65).count();
    assert_eq!(s["cells"]["occupied"], occupied_plain, "{s}");
    // The origin of the two-line flow list places the map: its export's
    // obstacle (the image's bottom rows) starts at x = -1.0 m, y = 2.0 m.
    let out = dir.join("m.geojson");
    run_ok(&["map", "export", "-o"], &[&out, &dir.join("m.map")]);
    let g: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let coords = &g["features"][0]["geometry"]["coordinates"][0][0];
    let (minx, miny) = coords
        .as_array()
        .unwrap()
        .iter()
        .fold((f64::MAX, f64::MAX), |(a, b), p| (a.min(p[0].as_f64().unwrap()), b.min(p[1].as_f64().unwrap())));
    assert!((-1.0..=-0.95).contains(&minx) && (2.0..=2.05).contains(&miny), "({minx}, {miny})");
}

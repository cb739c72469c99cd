//! `echoloc-lab bench` end to end on the real depot map (a small run: the
//! timings of a test mean nothing, what is checked is what the run says
//! about correctness): the exact reference agrees with the brute force, the
//! reference is complete by definition and the other methods are measured
//! against it, every method reports its memory, and bad arguments are
//! refused before any work.

mod common;

use common::{lab, root};

fn run(args: &[&str]) -> serde_json::Value {
    let o = lab().args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn depot_bench_reports_every_method_against_a_checked_reference() {
    let map = root().join("boards/qemu-mps2-an386/depot.map");
    let v = run(&["bench", "--map", map.to_str().unwrap(), "--poses", "300", "--rounds", "1", "--json"]);
    assert_eq!(v["pieces"], 428);
    for c in v["reference_check"].as_array().unwrap() {
        let (n, agree, grazing) =
            (c["sampled"].as_u64().unwrap(), c["agree"].as_u64().unwrap(), c["boundary_grazing"].as_u64().unwrap());
        assert!(n >= 300 && agree + grazing == n && grazing <= n / 100, "{c}");
    }
    let methods = v["methods"].as_array().unwrap();
    let names = [
        "bresenham_1deg",
        "bresenham_1deg_pruned",
        "bresenham_0.25deg",
        "ray_marching_1deg",
        "ray_marching_1deg_pruned",
        "parry2d_1deg",
        "parry2d_polyline_1deg",
        "cddt_1deg",
        "echoloc_exact",
        "echoloc_pseudo_paths",
        "echoloc_full",
    ];
    assert_eq!(methods.len(), 2 * names.len());
    let blob = std::fs::metadata(&map).unwrap().len();
    let grid = v["grid"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).product::<u64>();
    for m in methods {
        let name = m["name"].as_str().unwrap();
        assert!(names.contains(&name), "{m}");
        assert!(m["ns_per_window"].as_f64().unwrap() > 0.0, "{m}");
        let bytes = m["bytes"].as_u64().unwrap();
        match name {
            n if n.starts_with("echoloc") => assert_eq!(bytes, blob),
            n if n.starts_with("bresenham") => assert_eq!(bytes, grid),
            n if n.starts_with("ray_marching") => {
                assert_eq!(bytes, 5 * grid, "grid bytes and an f32 distance per cell")
            }
            "cddt_1deg" => {
                assert_eq!(bytes, v["cddt"]["bytes"].as_u64().unwrap());
                assert!(bytes > grid + 4 * v["cddt"]["zero_points"].as_u64().unwrap(), "{m}");
            }
            _ => assert!(bytes > 0),
        }
        let c = m["completeness"].as_f64();
        match name {
            "echoloc_exact" => assert_eq!(c, Some(1.0)),
            "echoloc_full" => assert_eq!(c, None, "the full prediction answers another question"),
            // Fans miss obstacles between their rays; the pseudo-paths too.
            _ => assert!(c.is_some_and(|c| c > 0.8 && c < 1.0), "{m}"),
        }
    }
    // The finer Bresenham fan costs more than the coarse one.
    let ns = |n: &str, h: f64| {
        methods.iter().find(|m| m["name"] == n && m["half_angle_deg"] == h).unwrap()["ns_per_window"].as_f64().unwrap()
    };
    assert!(ns("bresenham_0.25deg", 30.0) > ns("bresenham_1deg", 30.0));
    // The pruned fans answer as the unpruned ones: the same completeness.
    let complete = |n: &str, h: f64| {
        methods.iter().find(|m| m["name"] == n && m["half_angle_deg"] == h).unwrap()["completeness"].as_f64().unwrap()
    };
    for h in [15.0, 30.0] {
        assert_eq!(complete("bresenham_1deg", h), complete("bresenham_1deg_pruned", h));
        assert_eq!(complete("ray_marching_1deg", h), complete("ray_marching_1deg_pruned", h));
        assert_eq!(complete("parry2d_1deg", h), complete("parry2d_polyline_1deg", h));
    }
    assert_eq!(v["cddt"]["theta_discretization"], 108, "range_libc's default");
    // The summary: the full prediction against the fastest peer, parry2d and the 1° Bresenham fan.
    let summary = v["summary"].as_array().unwrap();
    assert_eq!(summary.len(), 2);
    for s in summary {
        let h = s["half_angle_deg"].as_f64().unwrap();
        let full = s["echoloc_full_ns_per_window"].as_f64().unwrap();
        assert_eq!(full, ns("echoloc_full", h));
        for (key, prefix) in [("fastest_peer", ""), ("parry2d", "parry2d"), ("bresenham_1deg", "bresenham_1deg")] {
            let (name, t) = (s[key]["method"].as_str().unwrap(), s[key]["ns_per_window"].as_f64().unwrap());
            assert!(name.starts_with(prefix) && !name.starts_with("echoloc"), "{s}");
            let peers = names.iter().filter(|n| n.starts_with(prefix) && !n.starts_with("echoloc"));
            for n in peers {
                assert!(t <= ns(n, h), "{key} {name} is not faster than {n}: {s}");
            }
            let ratio = s[key]["ratio"].as_f64().unwrap();
            assert!((ratio - t / full).abs() <= 0.01 * ratio, "{s}");
        }
    }
}

#[test]
fn bad_arguments_are_refused() {
    let map = root().join("boards/qemu-mps2-an386/depot.map");
    let m = map.to_str().unwrap();
    for (args, expect) in [
        (vec!["bench", "--map", m, "--poses", "0"], "must be positive"),
        (vec!["bench", "--map", m, "--half-angles-deg", "95"], "each in (0, 90)"),
        (vec!["bench", "--map", m, "--plot", "x.jpg"], "must end in .png or .svg"),
        (vec!["bench", "--map", "/nonexistent.map"], "nonexistent"),
    ] {
        let o = lab().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(expect), "{args:?}: {err}");
    }
}

/// `--from-json` redraws the scaling figure from an earlier run's JSON
/// (docs/figures/bench-scaling.json, the run docs/benchmarks.md quotes).
#[test]
fn the_scaling_figure_redraws_from_json() {
    let dir = std::env::temp_dir().join(format!("echoloc-bench-json-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (png, svg) = (dir.join("s.png"), dir.join("s.svg"));
    let json = root().join("docs/figures/bench-scaling.json");
    for out in [&png, &svg] {
        let o = lab().args(["bench", "--from-json"]).arg(&json).arg("--plot").arg(out).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    let text = std::fs::read_to_string(&svg).unwrap();
    for name in ["echoloc_full", "parry2d_1deg", "convex pieces in the map"] {
        assert!(text.contains(name), "{name} in the SVG");
    }
    let empty = dir.join("empty.json");
    std::fs::write(&empty, r#"{"maps":[]}"#).unwrap();
    let o = lab().args(["bench", "--from-json"]).arg(&empty).arg("--plot").arg(dir.join("e.png")).output().unwrap();
    assert!(String::from_utf8_lossy(&o.stderr).contains("no \"methods\" with results"));
    assert!(!dir.join("e.png").exists());
}

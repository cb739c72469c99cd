//! `echoloc-lab window` and `echoloc-lab predict` (DESIGN §7).

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use echoloc::credence::crisp::Crisp;
use echoloc::credence::gaussian::GaussianLobe;
use echoloc::credence::net::CredenceNet;
use echoloc::credence::Credence;
use echoloc::geometry::{Point, COORD_MAX};
use echoloc::map::MapSource;
use echoloc::predict::{nearest_in_window, place_sensor, predict, Pose, PredictParams};
use echoloc::window::{Strategy, Window, WindowParams};
use serde_json::{json, Value};

use crate::map::{self, LabError};

/// `window`: the pseudo-path layout of eq. (1)–(6).
#[derive(Args)]
pub struct WindowArgs {
    /// R_max, mm.
    #[arg(long = "rmax-mm", allow_hyphen_values = true)]
    rmax_mm: u32,
    /// Half-angle θ_o, degrees.
    #[arg(long = "half-angle-deg", allow_hyphen_values = true)]
    half_angle_deg: f32,
    /// Smallest detectable surface d_s_min, mm.
    #[arg(long = "ds-min-mm", allow_hyphen_values = true)]
    ds_min_mm: u32,
    /// Largest cone arc deviation δ_max, degrees.
    #[arg(long = "delta-max-deg", allow_hyphen_values = true)]
    delta_max_deg: f32,
    /// C-space buffer t_b, mm (0: unbuffered).
    #[arg(long = "tb-mm", default_value_t = 0, allow_hyphen_values = true)]
    tb_mm: u32,
}

pub fn window_cmd(a: &WindowArgs) -> Result<String, LabError> {
    let p = WindowParams {
        r_min_mm: 0,
        r_max_mm: a.rmax_mm,
        half_angle_deg: a.half_angle_deg,
        delta_max_deg: a.delta_max_deg,
        ds_min_mm: a.ds_min_mm,
        tb_mm: a.tb_mm,
    };
    // The layout once: N_pp, w, w_min and every end point from it.
    let l = p.layout().map_err(|e| LabError(format!("window parameters: {e}")))?;
    let y = round3(p.r_max_mm as f64);
    let ends: Vec<Value> = (0..l.n_pp).map(|k| json!([round3(l.endpoint_x(k) as f64), y])).collect();
    Ok(json!({
        "n_pp": l.n_pp,
        "w_mm": round3(l.w_mm as f64),
        "w_min_mm": round3(l.w_min_mm as f64),
        "endpoints_mm": ends,
        "pseudo_paths_complete": p.pseudo_paths_complete(),
    })
    .to_string())
}

fn round3(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Model {
    /// The quantised 2-10-1 credence net shipped in the firmware.
    Net,
    /// κ = 1 inside θ_o with δ ≤ δ_max, else 0.
    Crisp,
    /// Single-lobe Gaussian, σ = 14.8° (the baseline's width at 3 m).
    Gaussian,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum Collect {
    /// Exact true-outline ∩ sector.
    Exact,
    /// The paper's pseudo-paths against buffered outlines.
    PseudoPaths,
}

/// `predict`: what each transducer should read.
#[derive(Args)]
pub struct PredictArgs {
    /// The map: a blob (.map), a GeoJSON (.geojson) or a ROS map_server .yaml.
    #[arg(long)]
    map: PathBuf,
    /// One transducer at X,Y (m), heading DEG in the map frame.
    #[arg(long, value_name = "X,Y,DEG", conflicts_with_all = ["pose", "ring"], required_unless_present = "pose", allow_hyphen_values = true)]
    sensor: Option<String>,
    /// The robot at X,Y (m), heading DEG; every transducer of --ring.
    #[arg(long, value_name = "X,Y,DEG", allow_hyphen_values = true)]
    pose: Option<String>,
    /// The ring: `pioneer16` or a JSON file of [[x_m, y_m, heading_deg], …].
    #[arg(long, default_value = "pioneer16", requires = "pose")]
    ring: String,
    /// R_min, mm.
    #[arg(long = "rmin-mm", default_value_t = 500, allow_hyphen_values = true)]
    rmin_mm: u32,
    /// R_max, mm.
    #[arg(long = "rmax-mm", default_value_t = 5500, allow_hyphen_values = true)]
    rmax_mm: u32,
    /// Half-angle θ_o, degrees.
    #[arg(long = "half-angle-deg", default_value_t = 30.0, allow_hyphen_values = true)]
    half_angle_deg: f32,
    /// δ_max, degrees.
    #[arg(long = "delta-max-deg", default_value_t = 15.0, allow_hyphen_values = true)]
    delta_max_deg: f32,
    /// d_s_min for the pseudo-path layout, mm.
    #[arg(long = "ds-min-mm", default_value_t = 300, allow_hyphen_values = true)]
    ds_min_mm: u32,
    /// C-space buffer when MAP is imported here (a .map blob carries its own), mm.
    #[arg(long = "buffer-mm", default_value_t = 100, allow_hyphen_values = true)]
    buffer_mm: u32,
    /// How a .yaml map's walls are drawn.
    #[command(flatten)]
    grid: crate::map::load::GridArgs,
    /// Credence model.
    #[arg(long, value_enum, default_value = "net")]
    credence: Model,
    /// τ_κ, the least credence of a prediction.
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    tau: f32,
    /// Beacon collection strategy.
    #[arg(long, value_enum, default_value = "exact")]
    collect: Collect,
    /// Nearest obstacle point in |φ| ≤ θ_o, r ≤ R_max: no δ, κ or R_min.
    #[arg(long)]
    geometric: bool,
}

fn triple(s: &str, what: &str) -> Result<(f64, f64, f64), LabError> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| LabError(format!("--{what} {s:?}: expected X,Y,DEG (numbers)")))?;
    let (x, y, d) = match v[..] {
        [x, y, d] if v.iter().all(|t| t.is_finite()) => (x, y, d),
        _ => return Err(LabError(format!("--{what} {s:?}: expected three finite numbers X,Y,DEG"))),
    };
    // The map's coordinates are integer mm within ±COORD_MAX: a position
    // beyond them cannot be placed, and is a mistake, not a far window.
    let lim = f64::from(COORD_MAX) / 1000.0;
    for (k, c) in [("X", x), ("Y", y)] {
        if c.abs() > lim {
            return Err(LabError(format!("--{what} {s:?}: {k} is beyond ±{lim:.0} m, the map's coordinate range")));
        }
    }
    // Beyond a million degrees the number is surely a mistake (and past
    // 2^53 not even the integer typed); within, it is reduced exactly in f64
    // before the conversion to radians.
    if d.abs() > 1e6 {
        return Err(LabError(format!("--{what} {s:?}: DEG is not a heading (beyond ±1000000°)")));
    }
    Ok((x, y, d.rem_euclid(360.0)))
}

/// Loads MAP in any of its forms, without a localization field (none is
/// needed to predict): [`crate::map::load::load`].
pub fn load_map(path: &Path, buffer_mm: u32) -> Result<map::LoadedMap, LabError> {
    map::load::load(path, &map::LoadOptions::buffer(buffer_mm).without_field())
}

/// Loads MAP in any of its forms with the default localization field.
pub fn load_map_with_field(path: &Path, buffer_mm: u32) -> Result<map::LoadedMap, LabError> {
    map::load::load(path, &map::LoadOptions::buffer(buffer_mm))
}

/// The ring of `--ring SPEC` ([`crate::ring::load`]), its errors naming the option.
pub use crate::ring::ring_mounts;

pub fn predict_cmd(a: &PredictArgs) -> Result<String, LabError> {
    let loaded = map::load::load(&a.map, &a.grid.options(a.buffer_mm, false))?;
    let map = loaded.view()?;
    let window = WindowParams {
        r_min_mm: a.rmin_mm,
        r_max_mm: a.rmax_mm,
        half_angle_deg: a.half_angle_deg,
        delta_max_deg: a.delta_max_deg,
        ds_min_mm: a.ds_min_mm,
        // Pseudo-paths search the buffered outlines the map was finished with.
        tb_mm: map.buffer_mm(),
    };
    window.validate().map_err(|e| LabError(format!("window parameters: {e}")))?;
    if !(0.0..=1.0).contains(&a.tau) {
        return Err(LabError(format!("--tau {}: must be within 0..=1", a.tau)));
    }
    let mut params = PredictParams::new(window);
    params.tau_kappa = echoloc::credence::Kappa::saturating_from_num(a.tau);
    params.strategy = match a.collect {
        Collect::Exact => Strategy::Exact,
        Collect::PseudoPaths => Strategy::PseudoPaths,
    };
    // (apex, heading) per transducer.
    let sensors: Vec<(Point, f32)> = if let Some(s) = &a.sensor {
        let (x, y, d) = triple(s, "sensor")?;
        vec![(Point::new((x * 1000.0).round() as i32, (y * 1000.0).round() as i32), (d as f32).to_radians())]
    } else {
        let (x, y, d) = triple(a.pose.as_deref().unwrap_or_default(), "pose")?;
        let pose = Pose { x_mm: (x * 1000.0) as f32, y_mm: (y * 1000.0) as f32, heading_rad: (d as f32).to_radians() };
        ring_mounts(&a.ring)?.iter().map(|m| place_sensor(&pose, m)).collect()
    };
    let delta_mdeg = (a.delta_max_deg * 1000.0).round() as i32;
    let half_mdeg = (a.half_angle_deg * 1000.0).round() as i32;
    let model: Box<dyn Credence> = match a.credence {
        Model::Net => Box::new(CredenceNet::shipped()),
        Model::Crisp => Box::new(Crisp { half_angle_mdeg: half_mdeg, delta_max_mdeg: delta_mdeg }),
        Model::Gaussian => Box::new(GaussianLobe { peak: 1.0, sigma_deg: 14.8, delta_max_mdeg: delta_mdeg }),
    };
    let mut lines = Vec::new();
    for (i, &(apex, heading)) in sensors.iter().enumerate() {
        // The geometric search reads no pseudo-paths: lay them out only where that strategy runs.
        let strategy = if a.geometric { Strategy::Exact } else { params.strategy };
        let w = Window::place_for(&params.window, apex, heading, strategy).map_err(|e| {
            LabError(format!("sensor {i} at ({}, {}) m: {e}", f64::from(apex.x) / 1000.0, f64::from(apex.y) / 1000.0))
        })?;
        let line = if a.geometric {
            let n = nearest_in_window(&map, &w).map_err(|e| LabError(format!("sensor {i}: {e}")))?;
            match n {
                Some(n) => {
                    let (dx, dy) = (n.point.0 - apex.x as f64, n.point.1 - apex.y as f64);
                    let theta = dy.atan2(dx) - heading as f64;
                    json!({"sensor": i, "range_m": n.range_mm / 1000.0, "kappa": null,
                           "theta_deg": wrap_deg(theta.to_degrees()), "delta_deg": null,
                           "point": [n.point.0 / 1000.0, n.point.1 / 1000.0]})
                }
                None => {
                    json!({"sensor": i, "range_m": null, "kappa": null, "theta_deg": null, "delta_deg": null, "point": null})
                }
            }
        } else {
            let (p, _) = predict(&map, &w, &params, &*model).map_err(|e| LabError(format!("sensor {i}: {e}")))?;
            match p {
                Some(p) => json!({"sensor": i, "range_m": p.range_mm as f64 / 1000.0, "kappa": p.kappa.to_num::<f64>(),
                                  "theta_deg": p.theta_mdeg as f64 / 1000.0, "delta_deg": p.delta_mdeg as f64 / 1000.0,
                                  "point": [p.point.x as f64 / 1000.0, p.point.y as f64 / 1000.0]}),
                None => {
                    json!({"sensor": i, "range_m": null, "kappa": 0.0, "theta_deg": null, "delta_deg": null, "point": null})
                }
            }
        };
        lines.push(line.to_string());
    }
    Ok(lines.join("\n"))
}

fn wrap_deg(d: f64) -> f64 {
    round3((d + 180.0).rem_euclid(360.0) - 180.0)
}

//! `echoloc-lab synth` and `echoloc-lab train`: the credence κ(R, θ) of the
//! paper's §4 (DESIGN §4.4, §6), from data to the firmware's weights.
//!
//! - `synth --out DIR [--seed N]` runs the physical model of [`synth`] as the
//!   paper's experiment and writes one CSV per day (`r_mm,theta_deg,readings,correct`).
//! - `train DATA… [--seed N] [--weights-out FILE] [--figures DIR]` reads any
//!   CSVs in that format (a real transducer's too), evaluates the 2-10-1 net
//!   and the single-lobe Gaussian baseline leave-one-day-out, trains the net
//!   on every day, quantises it, and writes the core's `weights.rs` and the
//!   figures. Progress goes to stderr; the report is JSON on stdout.
//!
//! Both write all or nothing: every output is rendered in memory, and files
//! are written only when the whole command has succeeded (`Outputs`).

pub mod data;
pub mod error;
pub mod gaussian;
pub mod plot;
pub mod quantise;
pub mod rng;
pub mod synth;
pub mod train;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use echoloc::credence::net::CredenceNet;
use serde_json::{json, Value};

use crate::figure::{encode, Format};
pub use error::CredenceError;
use train::{Model, Sample};

/// `echoloc-lab synth`.
#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Directory for the CSV files (created if missing); one `dayN.csv` per day.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of every random draw: the same seed gives the same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Data sets ("days") to record.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub days: u64,
    /// Readings per grid node.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub readings: u32,
}

/// `echoloc-lab train`.
#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Data sets: CSV files, or directories whose `*.csv` files are read (one file per day).
    #[arg(required = true)]
    pub data: Vec<PathBuf>,
    /// Seed of the initial weights.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Epochs (full-batch iRprop⁻ steps) per restart.
    #[arg(long, default_value_t = 20_000, value_parser = clap::value_parser!(u32).range(1..))]
    pub epochs: u32,
    /// Random restarts per training; the lowest training loss is kept.
    #[arg(long, default_value_t = 6, value_parser = clap::value_parser!(u32).range(1..))]
    pub restarts: u32,
    /// Write the quantised net as Rust source here (the core's `src/credence/weights.rs`).
    #[arg(long = "weights-out")]
    pub weights_out: Option<PathBuf>,
    /// Write PNG figures of the observed, net and Gaussian κ surfaces into this directory.
    #[arg(long)]
    pub figures: Option<PathBuf>,
    /// The figures as SVG instead of PNG.
    #[arg(long, requires = "figures")]
    pub svg: bool,
    /// Skip the leave-one-day-out evaluation (train the final net only).
    #[arg(long = "no-cv")]
    pub no_cv: bool,
}

/// Runs `synth`; returns the JSON summary. All or nothing: every file is
/// rendered first and written by `Outputs::commit`.
pub fn synth_cmd(a: &SynthArgs) -> Result<String, CredenceError> {
    let grid = synth::Grid { readings: a.readings, ..synth::PAPER_GRID };
    let mut out = Outputs::default();
    let mut files = Vec::new();
    for (day, nodes) in synth::run(a.seed, a.days as usize, &grid) {
        let path = a.out.join(format!("{}.csv", day.name));
        let mean = nodes.iter().map(|n| f64::from(n.correct) / f64::from(n.readings)).sum::<f64>() / nodes.len() as f64;
        files.push(json!({
            "path": path.display().to_string(),
            "day": day.name,
            "nodes": nodes.len(),
            "temperature_c": round(day.temperature_c, 3),
            "humidity_pct": round(day.humidity_pct, 2),
            "speed_of_sound_m_per_s": round(day.speed_of_sound(), 2),
            "ka": round(day.ka(), 3),
            "absorption_db_per_m": round(day.absorption_db_per_m(), 3),
            "noise_offset_db": round(day.noise_offset_db, 3),
            "false_echo_rate_per_s": round(day.false_echo_rate_per_s, 3),
            "mean_kappa": round(mean, 4),
        }));
        out.add(path, data::to_csv(&nodes).into_bytes());
    }
    out.commit()?;
    Ok(json!({ "seed": a.seed, "readings_per_node": a.readings, "files": files }).to_string())
}

fn round(v: f64, digits: i32) -> f64 {
    let p = 10f64.powi(digits);
    (v * p).round() / p
}

/// A command's output files, rendered in memory and written all or nothing.
#[derive(Default)]
struct Outputs {
    files: Vec<(PathBuf, Vec<u8>)>,
}

impl Outputs {
    fn add(&mut self, path: PathBuf, bytes: Vec<u8>) {
        self.files.push((path, bytes));
    }

    /// Writes every file to a temporary file beside it (creating missing
    /// directories), and only when all of them are written renames each into
    /// place. An error before the renames — a directory that cannot be
    /// created, a full disk, a target that is a directory — removes the
    /// temporary files and leaves every target as it was (an empty directory
    /// it created may remain). The renames are the only step that touches a
    /// target; each is atomic on one file system.
    fn commit(self) -> Result<(), CredenceError> {
        let mut staged: Vec<(PathBuf, &Path)> = Vec::new();
        let result = self.files.iter().try_for_each(|(path, bytes)| {
            let tmp = temporary_beside(path);
            stage(path, &tmp, bytes).inspect_err(|_| {
                let _ = std::fs::remove_file(&tmp);
            })?;
            staged.push((tmp, path));
            Ok(())
        });
        if let Err(e) = result {
            for (tmp, _) in &staged {
                let _ = std::fs::remove_file(tmp);
            }
            return Err(e);
        }
        for (i, (tmp, path)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, path) {
                for (tmp, _) in &staged[i..] {
                    let _ = std::fs::remove_file(tmp);
                }
                return Err(CredenceError::io(path, e));
            }
        }
        Ok(())
    }
}

/// `dir/.name.<pid>.tmp` for `dir/name`: the same directory, so the rename
/// stays on one file system.
fn temporary_beside(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

fn stage(path: &Path, tmp: &Path, bytes: &[u8]) -> Result<(), CredenceError> {
    let io = |e| CredenceError::io(path, e);
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| CredenceError::io(dir, e))?;
    }
    if path.is_dir() {
        return Err(io(std::io::Error::other("is a directory; expected a file to write")));
    }
    std::fs::write(tmp, bytes).map_err(io)
}

/// Progress on stderr, at most every two seconds, for long trainings.
struct Reporter {
    start: Instant,
    last: Instant,
}

impl Reporter {
    fn stage<'a>(&'a mut self, stage: &'a str, epochs: u32, restarts: u32) -> impl FnMut(u32, u32, f64) + 'a {
        move |restart, epoch, loss| {
            if self.last.elapsed().as_secs_f64() >= 2.0 || (restart + 1 == restarts && epoch + 1 == epochs) {
                self.last = Instant::now();
                eprintln!(
                    "train: {stage}: restart {}/{restarts}, epoch {}/{epochs}, rmse {:.4} ({:.0} s)",
                    restart + 1,
                    epoch + 1,
                    loss.sqrt(),
                    self.start.elapsed().as_secs_f64()
                );
                let _ = std::io::stderr().flush();
            }
        }
    }
}

/// A band of the (R, θ) grid for the side-lobe comparison.
struct Band {
    name: &'static str,
    theta: (f64, f64),
    r_mm: (u32, u32),
}

/// The side lobes of the Polaroid beam at the grid's angles: the first null is
/// near 12.7°, the first side lobe peaks near 17.2°, the second null is near
/// 23.8°, the second side lobe peaks near 29° (DESIGN §6); "beyond the main
/// lobe" is every node past the first null. The nulls are taken at the grid
/// angles nearest them, where the ranges heard in the side lobes are.
const BANDS: [Band; 5] = [
    Band { name: "beyond_main_lobe", theta: (15.0, 45.0), r_mm: (500, 5500) },
    Band { name: "first_side_lobe", theta: (15.0, 20.0), r_mm: (500, 3000) },
    Band { name: "second_side_lobe", theta: (27.5, 30.0), r_mm: (500, 1500) },
    Band { name: "first_null", theta: (12.5, 12.5), r_mm: (1000, 2500) },
    Band { name: "second_null", theta: (22.5, 22.5), r_mm: (1000, 2500) },
];

fn in_band(b: &Band, s: &Sample) -> bool {
    s.theta_deg >= b.theta.0 && s.theta_deg <= b.theta.1 && (b.r_mm.0..=b.r_mm.1).contains(&s.r_mm)
}

/// Held-out predictions: (sample, net, gaussian).
type Held = Vec<(Sample, f64, f64)>;

fn band_stats(held: &Held) -> Value {
    let mut out = serde_json::Map::new();
    for b in &BANDS {
        let v: Vec<_> = held.iter().filter(|(s, _, _)| in_band(b, s)).collect();
        let n = v.len().max(1) as f64;
        let mean = |f: &dyn Fn(&(Sample, f64, f64)) -> f64| v.iter().map(|x| f(x)).sum::<f64>() / n;
        let rmse = |f: &dyn Fn(&(Sample, f64, f64)) -> f64| (mean(&|x| (f(x) - x.0.kappa).powi(2))).sqrt();
        let range = |f: &dyn Fn(&(Sample, f64, f64)) -> f64| {
            let (lo, hi) =
                v.iter().map(|x| f(x)).fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), k| (l.min(k), h.max(k)));
            json!([round(lo, 4), round(hi, 4)])
        };
        out.insert(
            b.name.into(),
            json!({
                "theta_deg": [b.theta.0, b.theta.1],
                "r_mm": [b.r_mm.0, b.r_mm.1],
                "nodes": v.len(),
                "observed_mean_kappa": round(mean(&|x| x.0.kappa), 4),
                "net_mean_kappa": round(mean(&|x| x.1), 4),
                "gaussian_mean_kappa": round(mean(&|x| x.2), 4),
                "observed_kappa_range": range(&|x| x.0.kappa),
                "net_kappa_range": range(&|x| x.1),
                "gaussian_kappa_range": range(&|x| x.2),
                "net_rmse": round(rmse(&|x| x.1), 4),
                "gaussian_rmse": round(rmse(&|x| x.2), 4),
            }),
        );
    }
    Value::Object(out)
}

/// Runs `train`; returns the JSON report.
pub fn train_cmd(a: &TrainArgs) -> Result<String, CredenceError> {
    let sets = data::read_all(&a.data)?;
    if !a.no_cv && sets.len() < 2 {
        return Err(CredenceError::Usage(format!(
            "leave-one-day-out needs at least two data sets, got {} ({}); pass more files or --no-cv",
            sets.len(),
            sets.iter().map(|s| s.path.display().to_string()).collect::<Vec<_>>().join(", ")
        )));
    }
    let now = Instant::now();
    let mut rep = Reporter { start: now, last: now };
    let mut report = serde_json::Map::new();
    report.insert("days".into(), json!(sets.iter().map(|s| s.name.clone()).collect::<Vec<_>>()));

    if !a.no_cv {
        let mut folds = Vec::new();
        let mut held: Held = Vec::new();
        for (i, test) in sets.iter().enumerate() {
            let train_set = train::pool(sets.iter().enumerate().filter(|(k, _)| *k != i).map(|(_, s)| &s.nodes[..]));
            let test_set = train::pool([&test.nodes[..]]);
            let stage = format!("fold {}/{} (held out {})", i + 1, sets.len(), test.name);
            let (net, _) =
                train::train(&train_set, a.seed, a.epochs, a.restarts, &mut rep.stage(&stage, a.epochs, a.restarts));
            let (gauss, _) = gaussian::fit(&train_set, a.epochs);
            let side: Vec<Sample> = test_set.iter().copied().filter(|s| in_band(&BANDS[0], s)).collect();
            let fold = json!({
                "held_out": test.name,
                "net_rmse": round(train::rmse(&net, &test_set), 4),
                "gaussian_rmse": round(train::rmse(&gauss, &test_set), 4),
                "net_rmse_beyond_main_lobe": round(train::rmse(&net, &side), 4),
                "gaussian_rmse_beyond_main_lobe": round(train::rmse(&gauss, &side), 4),
            });
            eprintln!("train: {stage}: {fold}");
            folds.push(fold);
            for s in test_set {
                let (r, t) = (f64::from(s.r_mm), s.theta_deg);
                held.push((s, net.eval(r, t), gauss.eval(r, t)));
            }
        }
        let mean = |k: &str| folds.iter().map(|f| f[k].as_f64().unwrap_or(f64::NAN)).sum::<f64>() / folds.len() as f64;
        report.insert(
            "leave_one_day_out".into(),
            json!({
                "folds": folds,
                "mean_net_rmse": round(mean("net_rmse"), 4),
                "mean_gaussian_rmse": round(mean("gaussian_rmse"), 4),
                "mean_net_rmse_beyond_main_lobe": round(mean("net_rmse_beyond_main_lobe"), 4),
                "mean_gaussian_rmse_beyond_main_lobe": round(mean("gaussian_rmse_beyond_main_lobe"), 4),
                "bands": band_stats(&held),
            }),
        );
    }

    // The shipped net: every day.
    let all = train::pool(sets.iter().map(|s| &s.nodes[..]));
    let (net, _) =
        train::train(&all, a.seed, a.epochs, a.restarts, &mut rep.stage("final (all days)", a.epochs, a.restarts));
    let (gauss, _) = gaussian::fit(&all, a.epochs);
    let float = net.to_weights();
    let quant = quantise::quantise(&float)?;
    let (max_err, at_r, at_t) = quantise::max_error(&float, &quant);
    let firmware = CredenceNet::new(&quant);
    let fw_model = FirmwareModel(firmware);
    let (g_height, g_width) = gauss.describe();
    let net_rmse = train::rmse(&net, &all);
    report.insert(
        "final".into(),
        json!({
            "net_rmse": round(net_rmse, 4),
            "quantised_net_rmse": round(train::rmse(&fw_model, &all), 4),
            "gaussian_rmse": round(train::rmse(&gauss, &all), 4),
            "gaussian_height_at_3m": round(g_height, 4),
            "gaussian_sigma_deg_at_3m": round(g_width, 3),
            "quantised_max_abs_error": max_err,
            "quantised_max_abs_error_at": { "r_mm": at_r, "theta_deg": at_t },
            "quantised_error_bound": 1.0 / 256.0,
        }),
    );
    if max_err > 1.0 / 256.0 {
        return Err(CredenceError::Quantise(format!(
            "the quantised net is {max_err:.5} from the float net at ({at_r} mm, {at_t}°), over the 1/256 bound"
        )));
    }

    // Weights and figures: rendered first, written all or nothing at the end.
    let mut outputs = Outputs::default();
    if let Some(out) = &a.weights_out {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let prov = quantise::Provenance {
            command: format!("cargo run --release -p echoloc-lab -- {}", args.join(" ")),
            data: sets
                .iter()
                .map(|s| (s.path.display().to_string(), s.nodes.iter().map(|n| u64::from(n.readings)).sum(), s.crc32))
                .collect(),
            seed: a.seed,
            epochs: a.epochs,
            restarts: a.restarts,
            train_rmse: net_rmse,
            max_quant_error: max_err,
        };
        outputs.add(out.clone(), quantise::weights_source(&prov, &float, &quant).into_bytes());
        report.insert("weights_out".into(), json!(out.display().to_string()));
    }

    if let Some(dir) = &a.figures {
        let observed = |r: f64, t: f64| nearest(&all, r, t);
        let netf = |r: f64, t: f64| Some(fw_model.eval(r, t));
        let gaussf = |r: f64, t: f64| Some(gauss.eval(r, t));
        let mut written = Vec::new();
        let days = sets.len();
        let fig = |p: &std::path::Path, bytes: Result<Vec<u8>, String>| {
            bytes.map_err(|e| CredenceError::io(p, std::io::Error::other(e)))
        };
        let (format, ext) = if a.svg { (Format::Svg, "svg") } else { (Format::Png, "png") };
        for (file, title, f) in [
            ("kappa_observed", format!("Observed κ, mean of {days} days"), &observed as plot::Surface<'_>),
            ("kappa_net", "2-10-1 net κ (quantised, firmware)".to_string(), &netf),
            ("kappa_gaussian", "Single-lobe Gaussian κ (fitted)".to_string(), &gaussf),
        ] {
            let p = dir.join(format!("{file}.{ext}"));
            outputs.add(p.clone(), fig(&p, encode(&plot::surface_figure(&title, f), format))?);
            written.push(p.display().to_string());
        }
        let p = dir.join(format!("kappa_profiles.{ext}"));
        let series = [
            plot::Series { label: "observed", colour: [0, 0, 0], kappa: &observed, dots: true },
            plot::Series { label: "net (firmware)", colour: [214, 39, 40], kappa: &netf, dots: false },
            plot::Series { label: "Gaussian", colour: [31, 119, 180], kappa: &gaussf, dots: false },
        ];
        let profiles =
            plot::profile_figure("κ against θ: observed (dots), net, Gaussian", &[1000, 2500, 4000], &series);
        outputs.add(p.clone(), fig(&p, encode(&profiles, format))?);
        written.push(p.display().to_string());
        report.insert("figures".into(), json!(written));
    }
    outputs.commit()?;
    eprintln!("train: done in {:.0} s", now.elapsed().as_secs_f64());
    Ok(Value::Object(report).to_string())
}

/// The firmware's quantised net as a host [`Model`].
struct FirmwareModel<'w>(CredenceNet<'w>);

impl Model for FirmwareModel<'_> {
    fn eval(&self, r_mm: f64, theta_deg: f64) -> f64 {
        self.0.kappa_at(r_mm.round().clamp(0.0, 1e9) as u32, (theta_deg * 1000.0).round() as i32).to_num::<f64>()
    }
}

/// The observed κ of the node nearest (R, θ) in grid units (250 mm, 2.5°).
fn nearest(samples: &[Sample], r_mm: f64, theta_deg: f64) -> Option<f64> {
    samples
        .iter()
        .map(|s| (((f64::from(s.r_mm) - r_mm) / 250.0).powi(2) + ((s.theta_deg - theta_deg) / 2.5).powi(2), s.kappa))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .filter(|(d, _)| *d <= 1.0)
        .map(|(_, k)| k)
}

//! `echoloc-lab scenario`: scenario files (docs/scenario.md) on the host.
//! `replay` runs one through the very filters `simulate` ran (the same
//! records, the same core code), so its figures are the simulate run's.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use echoloc::predict::Mount;
use echoloc::scenario::{Record, Scenario};

use crate::map::LabError;
use crate::predict::load_map_and_blob;
use crate::simulate::{filters, report};

/// `scenario`.
#[derive(Subcommand)]
pub enum ScenarioCmd {
    /// Checks a scenario against its map and runs it through the dead
    /// reckoning, threshold method and EKF: the same JSON as `simulate`,
    /// without the simulator's truth about clutter.
    Replay(ReplayArgs),
}

/// `scenario replay`.
#[derive(Args)]
pub struct ReplayArgs {
    /// The scenario file.
    scenario: PathBuf,
    /// The map it was made on: a blob (.map), a ROS map_server .yaml or a .geojson.
    #[arg(long)]
    map: PathBuf,
    /// C-space buffer for a .yaml or .geojson map, mm (as `simulate` used).
    #[arg(long = "buffer-mm", default_value_t = 100)]
    buffer_mm: u32,
    /// One JSON object (the default prints the same, indented).
    #[arg(long)]
    json: bool,
}

pub fn run(cmd: ScenarioCmd) -> Result<String, LabError> {
    match cmd {
        ScenarioCmd::Replay(a) => replay(&a),
    }
}

fn replay(a: &ReplayArgs) -> Result<String, LabError> {
    let bytes = std::fs::read(&a.scenario).map_err(|e| LabError(format!("{}: {e}", a.scenario.display())))?;
    let s = Scenario::parse(&bytes)
        .map_err(|e| LabError(format!("{}: not a valid scenario: {e}", a.scenario.display())))?;
    let (map, blob) = load_map_and_blob(&a.map, a.buffer_mm)?;
    s.check_map(echoloc::map::crc32(&blob)).map_err(|e| {
        LabError(format!("{}: made on another map than {} (MapMismatch): {e}", a.scenario.display(), a.map.display()))
    })?;
    let mounts: Vec<Mount> = (0..s.transducers()).filter_map(|i| s.mount(i)).collect();
    let records: Vec<Record> = s.records().collect();
    let trace = filters::run(&map, &mounts, s.header(), &records, &mut |_| {})
        .map_err(|e| LabError(format!("{}: {e}", a.scenario.display())))?;
    let r = report(&trace, None);
    Ok(if a.json { r.to_string() } else { serde_json::to_string_pretty(&r).unwrap_or_default() })
}

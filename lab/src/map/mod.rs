//! `echoloc-lab map …`: import polygon maps into the firmware's blob.

mod build;
mod geojson;

use std::fmt;
use std::path::{Path, PathBuf};

use clap::Subcommand;
use echoloc::map::StandardMap;

pub use build::{build_map, MapSummary, Shape};

#[derive(Subcommand)]
pub enum MapCmd {
    /// Import a GeoJSON FeatureCollection (metres) into a map blob.
    Import {
        /// Input map: a `.geojson` file (ROS map_server `.yaml` import comes with the real-maps work).
        input: PathBuf,
        /// Output blob.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
        /// C-space buffer t_b, mm.
        #[arg(long = "buffer-mm", default_value_t = 100)]
        buffer_mm: u32,
        /// Grid cell size, mm; grown automatically until the grid fits the firmware's capacity.
        #[arg(long = "cell-mm", default_value_t = 1000)]
        cell_mm: u32,
    },
    /// Print the summary of a map blob after loading it exactly as the firmware does.
    Info {
        /// The blob.
        map: PathBuf,
    },
}

/// An error that names the file (and, where known, the place in it).
#[derive(Debug)]
pub struct LabError(pub String);

impl fmt::Display for LabError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for LabError {}

pub fn run(cmd: MapCmd) -> Result<String, LabError> {
    match cmd {
        MapCmd::Import { input, out, buffer_mm, cell_mm } => {
            let shapes = read_shapes(&input)?;
            let (blob, summary) =
                build_map(&shapes, buffer_mm, cell_mm).map_err(|e| LabError(format!("{}: {e}", input.display())))?;
            write_atomically(&out, &blob)?;
            Ok(summary.to_json())
        }
        MapCmd::Info { map } => {
            let bytes = std::fs::read(&map).map_err(|e| LabError(format!("{}: {e}", map.display())))?;
            let mut m: Box<StandardMap> = Box::default();
            m.load(&bytes).map_err(|e| LabError(format!("{}: not a valid map blob: {e:?}", map.display())))?;
            Ok(MapSummary::of(&m, m.obstacles().len(), bytes.len()).to_json())
        }
    }
}

/// Reads a map source by its extension.
pub fn read_shapes(input: &Path) -> Result<Vec<Shape>, LabError> {
    let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "geojson" | "json" => {
            let text = std::fs::read_to_string(input).map_err(|e| LabError(format!("{}: {e}", input.display())))?;
            geojson::parse(&text).map_err(|e| LabError(format!("{}: {e}", input.display())))
        }
        "yaml" | "yml" => Err(LabError(format!(
            "{}: ROS map_server import is not built yet (it comes with the real-maps issue); use a .geojson map",
            input.display()
        ))),
        _ => Err(LabError(format!("{}: unknown map format (expected .geojson or .yaml)", input.display()))),
    }
}

/// Writes `bytes` to `path` through a temporary file and a rename, so that a
/// failure never leaves a partial file behind.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), LabError> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, bytes).map_err(|e| LabError(format!("{}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        LabError(format!("{}: {e}", path.display()))
    })
}

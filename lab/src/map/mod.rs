//! `echoloc-lab map …`: import polygon maps (GeoJSON, ROS map_server
//! occupancy grids) into the firmware's blob, inspect, export and preview.
//!
//! A ROS map goes: YAML + PGM/PNG → classified cells ([`ros`]) → contours
//! with holes by marching squares ([`contour`]) → simplification with a
//! guaranteed error bound that keeps every polygon valid ([`simplify`]) →
//! convex pieces (`echoloc::geometry::split_convex_with_holes`) → the
//! firmware's `StandardMap` (buffers, grid) → blob. Nothing is written
//! unless everything succeeded.

pub mod build;
pub mod contour;
pub mod field;
pub mod free_space;
pub mod geojson;
pub mod lines;
pub mod load;
pub mod render;
pub mod ros;
pub mod simplify;
#[cfg(test)]
mod view_identity;

use std::fmt;
use std::path::{Path, PathBuf};

use crate::figure::Format;
use clap::{Subcommand, ValueEnum};
use echoloc::geometry::{Point, COORD_MAX};
use echoloc::map::{MapSource, MapView, StandardMap};

pub use build::{build_map, build_map_with, MapSummary, Shape};
pub use field::FieldOptions;
pub use load::{LoadOptions, LoadedMap, MapKind};
// Where they lived before the lab had a room for each.
pub use crate::error::LabError;
pub use crate::files::write_atomically;

/// Import defaults, shared by `map import` and the other commands that read
/// a map source.
pub const DEFAULT_SIMPLIFY_MM: u32 = 50;

#[derive(Subcommand)]
pub enum MapCmd {
    /// Import a map into a blob: a ROS map_server `.yaml` (with its PGM/PNG
    /// image) or a GeoJSON FeatureCollection in metres.
    Import {
        /// Input map: `.yaml` (ROS map_server) or `.geojson`.
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
        /// Occupancy grids: most distance, mm, between a contour and its simplification (0: none).
        #[arg(long = "simplify-mm", default_value_t = DEFAULT_SIMPLIFY_MM)]
        simplify_mm: u32,
        /// Occupancy grids: what unknown cells count as.
        #[arg(long = "unknown", value_enum, default_value_t = Unknown::Free)]
        unknown: Unknown,
        /// Occupancy grids: contour (round the occupied cells) or lines
        /// (straight walls through them, for real buildings' SLAM maps).
        #[arg(long = "walls", value_enum, default_value_t = Walls::Contour)]
        walls: Walls,
        /// Occupancy grids with --walls lines: most distance, mm, from a
        /// surface cell's centre to its wall (0: one cell).
        #[arg(long = "line-tolerance-mm", default_value_t = 0)]
        line_tolerance_mm: u32,
        /// Also write a PNG preview of the polygon map over the source grid.
        #[arg(long = "preview")]
        preview: Option<PathBuf>,
        /// Localization field: node spacing, mm (docs/localization.md).
        #[arg(long = "field-node-mm", default_value_t = FieldOptions::default().node_mm)]
        field_node_mm: u32,
        /// Localization field: headings per node.
        #[arg(long = "field-dirs", default_value_t = FieldOptions::default().dirs)]
        field_dirs: u32,
        /// Localization field: how far beyond free space a transducer may stand, mm.
        #[arg(long = "field-reach-mm", default_value_t = FieldOptions::default().reach_mm)]
        field_reach_mm: u32,
        /// Localization field: the robot's centre keeps this far from obstacles, mm.
        #[arg(long = "field-clearance-mm", default_value_t = FieldOptions::default().clearance_mm)]
        field_clearance_mm: u32,
        /// Localization field: where the prediction credits no surface, the
        /// first surface a lobe this wide finds is stored, unsure, degrees (0:
        /// none; else above the face lobe and below 90).
        #[arg(long = "field-fallback-deg", default_value_t = FieldOptions::default().fallback_deg)]
        field_fallback_deg: f32,
        /// The map's face lobe: how far off its normal a face still echoes,
        /// degrees; the prediction's δ_max for the field and for the tracker
        /// (default 8 with --walls lines, real buildings; else 15).
        #[arg(long = "face-lobe-deg")]
        face_lobe_deg: Option<f32>,
        /// No localization field (a smaller blob that cannot localize globally).
        #[arg(long = "no-field")]
        no_field: bool,
        /// GeoJSON maps: gaps in the walls up to this wide, mm, count as
        /// closed when finding the building's free space (doorways, an
        /// open entrance; 0: only the walls close; docs/maps.md).
        #[arg(long = "door-mm", default_value_t = free_space::DEFAULT_DOOR_MM,
              value_parser = clap::value_parser!(u32).range(0..=i64::from(free_space::MAX_DOOR_MM)))]
        door_mm: u32,
    },
    /// Compare a compiled map's localization field with the exact prediction
    /// at random poses of the Pioneer ring over its free space.
    FieldCheck {
        /// The blob.
        map: PathBuf,
        /// Robot poses (16 transducers each).
        #[arg(long, default_value_t = 2000)]
        robots: usize,
        /// Seed of the draws.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// A ROS map_server occupancy grid (MAP.yaml and MAP.pgm) from a lidar
    /// run's scans at their poses, by log-odds ray casting: the map a SLAM
    /// user would make of the pass (docs/real-buildings.md).
    FromScans {
        /// The lidar run: a CARMEN log (FLASER, ROBOTLASER1), plain or gzip, or a ROS 2 bag (LaserScan at a pose: docs/lidar-bags.md).
        run: PathBuf,
        /// Output map_server YAML; the PGM is written beside it.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
        /// The part of the run to map, FROM:TO in scan indices (either end may
        /// be left out), or several parts, FROM:TO,FROM:TO.
        #[arg(long, default_value = ":")]
        pass: String,
        /// Cell size, m.
        #[arg(long = "resolution-m", default_value_t = crate::lidar::grid::GridOptions::default().resolution_m)]
        resolution_m: f64,
        /// Beams are used up to this range, m (beyond, they clear cells up to it).
        #[arg(long = "max-range-m", default_value_t = crate::lidar::grid::GridOptions::default().max_range_m)]
        max_range_m: f64,
        /// A ROS 2 bag's topics and frames (a CARMEN log has none).
        #[command(flatten, next_help_heading = "A lidar bag")]
        bag: crate::lidar::bag::LaserBagArgs,
    },
    /// Print the summary of a map blob after loading it exactly as the firmware does.
    Info {
        /// The blob.
        map: PathBuf,
    },
    /// Export a blob's true polygons (convex pieces, metres) as GeoJSON.
    Export {
        /// The blob.
        map: PathBuf,
        /// Output `.geojson`.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
    },
    /// Draw a blob's pieces as a PNG, over the occupancy grid it came from when given.
    Preview {
        /// The blob.
        map: PathBuf,
        /// Output `.png`.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
        /// The ROS map_server `.yaml` to draw underneath.
        #[arg(long = "grid")]
        grid: Option<PathBuf>,
        /// What unknown cells of the grid count as (for the drawing).
        #[arg(long = "unknown", value_enum, default_value_t = Unknown::Free)]
        unknown: Unknown,
    },
}

/// What unknown cells of an occupancy grid count as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Unknown {
    Free,
    Occupied,
}

impl Unknown {
    fn name(self) -> &'static str {
        match self {
            Unknown::Free => "free",
            Unknown::Occupied => "occupied",
        }
    }
}

/// Why a map could not be read, built or written. Each names the file and,
/// where there is one, the field.
#[derive(Debug)]
pub enum ImportError {
    /// Reading or writing a file failed.
    Io { path: PathBuf, source: std::io::Error },
    /// A field of a description file (YAML key, GeoJSON member) is missing or wrong.
    Field { path: PathBuf, field: String, problem: String },
    /// The image a YAML's `image` field names is missing or unusable.
    Image { yaml: PathBuf, image: PathBuf, problem: String },
    /// The content is well-formed but cannot become a map (geometry, capacity).
    Content { path: PathBuf, problem: String },
}

impl fmt::Display for ImportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImportError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            ImportError::Field { path, field, problem } => write!(f, "{}: {field}: {problem}", path.display()),
            ImportError::Image { yaml, image, problem } => {
                write!(f, "{}: image: {}: {problem}", yaml.display(), image.display())
            }
            ImportError::Content { path, problem } => write!(f, "{}: {problem}", path.display()),
        }
    }
}

impl std::error::Error for ImportError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ImportError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl From<ImportError> for LabError {
    fn from(e: ImportError) -> Self {
        LabError(e.to_string())
    }
}

/// How an occupancy grid's obstacles become polygons.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Walls {
    /// Round the occupied cells' free faces, simplified within --simplify-mm.
    Contour,
    /// Straight walls through the surface cells, within --line-tolerance-mm
    /// (`map::lines`; for maps made by SLAM of real buildings).
    Lines,
}

/// How a map source is read and compiled.
#[derive(Clone, Copy, Debug)]
pub struct ImportOptions {
    pub simplify_mm: u32,
    pub unknown: Unknown,
    /// Occupancy grids: contours or straight walls.
    pub walls: Walls,
    /// Occupancy grids with `Walls::Lines`: the deviation bound, mm (0: one cell).
    pub line_tolerance_mm: u32,
    /// The map's face lobe, degrees (`FieldOptions::delta_max_deg`; `None`:
    /// [`field::SMOOTH_FACE_LOBE_DEG`] with `Walls::Lines`, else the field's own).
    pub face_lobe_deg: Option<f32>,
    /// The localization field (`None`: a blob without one, which cannot
    /// localize globally).
    pub field: Option<FieldOptions>,
    /// GeoJSON maps without `free` polygons: gaps in the walls up to this
    /// wide, mm, count as closed when finding what the walls enclose
    /// ([`free_space`]).
    pub door_mm: u32,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            simplify_mm: DEFAULT_SIMPLIFY_MM,
            unknown: Unknown::Free,
            walls: Walls::Contour,
            line_tolerance_mm: 0,
            face_lobe_deg: None,
            field: Some(FieldOptions::default()),
            door_mm: free_space::DEFAULT_DOOR_MM,
        }
    }
}

/// Compiles the shapes of `src` with `opt`'s field: free space from the
/// occupancy grid's known-free cells, or a GeoJSON map's building
/// ([`free_space`]: its `free` polygons, else what its walls enclose, said
/// in the summary as `free_space`).
pub fn compile_source(
    src: &Source,
    buffer_mm: u32,
    cell_mm: u32,
    opt: &ImportOptions,
) -> Result<(Vec<u8>, MapSummary), String> {
    let field = opt.field.map(|f| FieldOptions { delta_max_deg: face_lobe(opt).unwrap_or(f.delta_max_deg), ..f });
    if let Some(free) = &src.free_polygons {
        // Found when the field first asks, after the map was built (and
        // checked against the compiler's capacity).
        let space = std::sync::OnceLock::new();
        let of = || free_space::FreeSpace::of(&src.shapes, free, opt.door_mm);
        let inside = |x: f64, y: f64| space.get_or_init(of).contains(x, y);
        let known: &(dyn Fn(f64, f64) -> bool + Sync) = &inside;
        let (blob, mut summary) =
            build_map_with(&src.shapes, buffer_mm, cell_mm, field.as_ref().map(|f| (f, Some(known))))?;
        if field.is_some() && !src.shapes.is_empty() {
            summary.extra.insert("free_space".into(), space.get_or_init(of).summary());
        }
        return refuse_no_free_node(blob, summary, space.get_or_init(of));
    }
    let known = src.grid.as_ref().map(|g| move |x: f64, y: f64| g.known_free_at(x, y));
    let known_ref = known.as_ref().map(|f| f as &(dyn Fn(f64, f64) -> bool + Sync));
    build_map_with(&src.shapes, buffer_mm, cell_mm, field.as_ref().map(|f| (f, known_ref)))
}

/// A drawing (GeoJSON) compiled with a field that has no free node cannot
/// find itself: refused here, with what its free space was, rather than
/// at a replay's start. (An occupancy grid says itself where it is free:
/// its field is the grid's, as map_server's users expect, and the replay's
/// start says when it has no free node.)
fn refuse_no_free_node(
    blob: Vec<u8>,
    summary: MapSummary,
    space: &free_space::FreeSpace,
) -> Result<(Vec<u8>, MapSummary), String> {
    let Some(field) = summary.extra.get("field") else { return Ok((blob, summary)) };
    // A map with no obstacle has nothing to find itself by: the commands
    // that need them say so (`the map has no obstacles`).
    if field["free_nodes"].as_u64() != Some(0) || summary.convex_pieces == 0 {
        return Ok((blob, summary));
    }
    Err(format!(
        "the localization field has no free node: no node of its free space, {}, is {} mm clear of every \
         obstacle (--field-clearance-mm); give a larger --door-mm or a `free` polygon (GeoJSON), a smaller \
         --field-clearance-mm, or --no-field",
        space.describe(),
        field["clearance_mm"]
    ))
}

/// The face lobe `opt` asks for: given, or a real building's with straight walls.
fn face_lobe(opt: &ImportOptions) -> Option<f32> {
    opt.face_lobe_deg.or((opt.walls == Walls::Lines).then_some(field::SMOOTH_FACE_LOBE_DEG))
}

/// What was read: the shapes, the grid they came from (for ROS maps), and
/// figures for the summary.
pub struct Source {
    pub shapes: Vec<Shape>,
    pub grid: Option<ros::Grid>,
    /// A GeoJSON map's `free` polygons (empty: free space is what its walls
    /// enclose, [`free_space`]); `None` for other sources.
    pub free_polygons: Option<Vec<free_space::Area>>,
    pub extra: serde_json::Map<String, serde_json::Value>,
}

/// Imports a map source (`.yaml` ROS map_server with its image, or
/// `.geojson` in metres) and compiles it into the firmware's map blob
/// (`docs/map-blob.md`): C-space buffer `buffer_mm`, grid cells of
/// `cell_mm` (grown until the grid fits). Returns the blob, the summary
/// `map import` prints, and the source it was read from.
///
/// Splitting a large polygon into convex pieces uses fixed-capacity
/// working sets of a few MB, as on the firmware side; this runs the work on
/// a thread with room for them, so it may be called from any thread (a
/// `build.rs` included).
///
/// ```no_run
/// use echoloc_lab::map::{import, ImportOptions};
/// let (blob, summary, _) = import("maps/warehouse.yaml".as_ref(), 100, 1000, &ImportOptions::default())?;
/// std::fs::write("warehouse.map", &blob)?;
/// println!("{}", summary.to_json());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn import(
    input: &Path,
    buffer_mm: u32,
    cell_mm: u32,
    opt: &ImportOptions,
) -> Result<(Vec<u8>, MapSummary, Source), ImportError> {
    let (input, opt) = (input.to_path_buf(), *opt);
    let path = input.clone();
    let work = move || -> Result<(Vec<u8>, MapSummary, Source), ImportError> {
        let src = read_source(&input, &opt)?;
        let (blob, mut summary) = compile_source(&src, buffer_mm, cell_mm, &opt)
            .map_err(|e| ImportError::Content { path: input, problem: e })?;
        summary.extra.extend(src.extra.clone());
        Ok((blob, summary, src))
    };
    load::on_big_stack(work, |problem| ImportError::Content { path: path.clone(), problem })
}

pub fn run(cmd: MapCmd) -> Result<String, LabError> {
    match cmd {
        MapCmd::Import {
            input,
            out,
            buffer_mm,
            cell_mm,
            simplify_mm,
            unknown,
            walls,
            line_tolerance_mm,
            preview,
            field_node_mm,
            field_dirs,
            field_reach_mm,
            field_clearance_mm,
            field_fallback_deg,
            face_lobe_deg,
            no_field,
            door_mm,
        } => {
            let field = FieldOptions {
                node_mm: field_node_mm,
                dirs: field_dirs,
                reach_mm: field_reach_mm,
                clearance_mm: field_clearance_mm,
                delta_max_deg: FieldOptions::default().delta_max_deg,
                fallback_deg: field_fallback_deg,
            };
            field.validate().map_err(|e| LabError(format!("--{e}")))?;
            let opt = ImportOptions {
                simplify_mm,
                unknown,
                walls,
                line_tolerance_mm,
                face_lobe_deg,
                field: (!no_field).then_some(field),
                door_mm,
            };
            if let Some(d) = face_lobe_deg {
                FieldOptions { delta_max_deg: d, ..field }
                    .validate()
                    .map_err(|e| LabError(format!("--face-lobe-deg: {e}")))?;
            }
            let (blob, summary, src) = import(&input, buffer_mm, cell_mm, &opt)?;
            if let Some(w) = summary.extra.get("free_space").and_then(|f| f.get("warning")).and_then(|w| w.as_str()) {
                eprintln!("echoloc-lab: warning: {}: {w}", input.display());
            }
            // Everything is computed before anything is written.
            let png = match &preview {
                Some(p) => {
                    let aligned = AlignedBytes::new(&blob);
                    let m = MapView::new(aligned.bytes())
                        .map_err(|e| LabError(format!("{}: the new blob does not validate: {e:?}", out.display())))?;
                    // A drawing's free space is the import's own finding: shown; a
                    // grid shows its own.
                    let free = if src.grid.is_none() { render::free_nodes(&m) } else { Vec::new() };
                    Some(render::preview_as(&m, src.grid.as_ref(), unknown, &free, Format::of(p)).map_err(LabError)?)
                }
                None => None,
            };
            write_atomically(&out, &blob)?;
            if let (Some(p), Some(png)) = (&preview, png) {
                if let Err(e) = write_atomically(p, &png) {
                    let _ = std::fs::remove_file(&out);
                    return Err(e);
                }
            }
            Ok(summary.to_json())
        }
        MapCmd::FromScans { run, out, pass, resolution_m, max_range_m, bag } => {
            let passes = crate::lidar::parse_passes(&pass)?;
            let scans = crate::lidar::read_with(&run, &bag.options())?.passes(&passes)?;
            let opt = crate::lidar::grid::GridOptions { resolution_m, max_range_m, ..Default::default() };
            let g = crate::lidar::grid::build(&scans, &opt).map_err(|e| LabError(format!("{}: {e}", run.display())))?;
            let image = crate::lidar::grid::write(&g, &out)?;
            let (free, occupied, unknown) = g.counts();
            Ok(serde_json::json!({
                "run": run.display().to_string(),
                "format": scans.format,
                "pass": passes.iter().map(|p| p.to_string()).collect::<Vec<_>>().join(","),
                "scans": scans.scans.len(),
                "path_m": (scans.path_length_m() * 10.0).round() / 10.0,
                "size_cells": [g.width, g.height],
                "resolution_m": g.resolution,
                "origin": [g.origin.0, g.origin.1],
                "cells": {"free": free, "occupied": occupied, "unknown": unknown},
                "yaml": out.display().to_string(),
                "image": image.display().to_string(),
            })
            .to_string())
        }
        MapCmd::FieldCheck { map, robots, seed } => {
            let a = read_compiled(&map)?;
            let v = view_of(&a, &map)?;
            let c = field::check_field(&v, robots, seed).map_err(|e| LabError(format!("{}: {e}", map.display())))?;
            Ok(c.json().to_string())
        }
        MapCmd::Info { map } => {
            let bytes = std::fs::read(&map).map_err(|e| ImportError::Io { path: map.clone(), source: e })?;
            let aligned = AlignedBytes::new(&bytes);
            match MapView::new(aligned.bytes()) {
                // A compiled map: read in place, as the firmware does, whatever its size.
                Ok(v) => Ok(MapSummary::of_view(&v, bytes.len()).to_json()),
                // Else the older blob, through the host map.
                Err(_) => {
                    let m = blob_to_map(&bytes, &map)?;
                    Ok(MapSummary::of(&m, m.obstacles().len(), bytes.len()).to_json())
                }
            }
        }
        MapCmd::Export { map, out } => {
            let a = read_compiled(&map)?;
            let m = view_of(&a, &map)?;
            let json = render::geojson(&m);
            write_atomically(&out, json.to_string().as_bytes())?;
            Ok(serde_json::json!({
                "features": m.obstacle_count(),
                "convex_pieces": m.piece_count(),
                "out": out.display().to_string(),
            })
            .to_string())
        }
        MapCmd::Preview { map, out, grid, unknown } => {
            let a = read_compiled(&map)?;
            let m = view_of(&a, &map)?;
            let grid = grid.map(|g| ros::load(&g)).transpose()?;
            let png = render::preview_as(&m, grid.as_ref(), unknown, &[], Format::of(&out)).map_err(LabError)?;
            write_atomically(&out, &png)?;
            Ok(serde_json::json!({ "out": out.display().to_string(), "bytes": png.len() }).to_string())
        }
    }
}

/// Reads a map file into aligned bytes, ready for [`view_of`].
pub fn read_compiled(path: &Path) -> Result<AlignedBytes, LabError> {
    let bytes = std::fs::read(path).map_err(|e| ImportError::Io { path: path.to_path_buf(), source: e })?;
    Ok(AlignedBytes::new(&bytes))
}

/// The compiled map in `a` (read from `path`), validated as the firmware does.
pub fn view_of<'a>(a: &'a AlignedBytes, path: &Path) -> Result<MapView<'a>, LabError> {
    MapView::new(a.bytes()).map_err(|e| LabError(format!("{}: not a valid compiled map: {e:?}", path.display())))
}

/// Bytes on an 8-byte boundary, as a compiled map must be read in place.
pub struct AlignedBytes {
    words: Vec<u64>,
    len: usize,
}

impl AlignedBytes {
    pub fn new(bytes: &[u8]) -> Self {
        let mut words = vec![0u64; bytes.len().div_ceil(8)];
        bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..bytes.len()].copy_from_slice(bytes);
        Self { words, len: bytes.len() }
    }

    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice::<u64, u8>(&self.words)[..self.len]
    }
}

/// Loads blob bytes (read from, or made for, `path`) into the host's
/// `StandardMap` (the compiled form is checked in full on the way).
pub fn blob_to_map(bytes: &[u8], path: &Path) -> Result<Box<StandardMap>, LabError> {
    let mut m: Box<StandardMap> = Box::default();
    m.load(AlignedBytes::new(bytes).bytes())
        .map_err(|e| LabError(format!("{}: not a valid map blob: {e:?}", path.display())))?;
    Ok(m)
}

/// Reads a map source by its extension, with the default import options.
pub fn read_shapes(input: &Path) -> Result<Vec<Shape>, LabError> {
    Ok(read_source(input, &ImportOptions::default())?.shapes)
}

/// Reads a map source by its extension.
pub fn read_source(input: &Path, opt: &ImportOptions) -> Result<Source, ImportError> {
    let ext = input.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "geojson" | "json" => {
            let text =
                std::fs::read_to_string(input).map_err(|e| ImportError::Io { path: input.to_path_buf(), source: e })?;
            let m = geojson::parse_map(&text)
                .map_err(|e| ImportError::Content { path: input.to_path_buf(), problem: e })?;
            let mut extra = serde_json::Map::new();
            extra.insert("source".into(), "geojson".into());
            Ok(Source { shapes: m.shapes, grid: None, free_polygons: Some(m.free), extra })
        }
        "yaml" | "yml" => {
            let grid = ros::load(input)?;
            let (shapes, extra) = grid_shapes(input, &grid, opt)?;
            Ok(Source { shapes, grid: Some(grid), free_polygons: None, extra })
        }
        _ => Err(ImportError::Content {
            path: input.to_path_buf(),
            problem: "unknown map format (expected .geojson or .yaml)".into(),
        }),
    }
}

/// The polygons of an occupancy grid, in mm, simplified, with figures for
/// the summary; `path` names the source in errors.
pub fn grid_shapes(
    path: &Path,
    grid: &ros::Grid,
    opt: &ImportOptions,
) -> Result<(Vec<Shape>, serde_json::Map<String, serde_json::Value>), ImportError> {
    let y = &grid.yaml;
    // The map's extent must stay within ±COORD_MAX so every predicate is exact.
    let lim = COORD_MAX as f64;
    for (k, o) in [("origin[0]", y.origin[0]), ("origin[1]", y.origin[1])] {
        if (o * 1000.0).abs() > lim {
            return Err(ImportError::Field {
                path: path.to_path_buf(),
                field: k.into(),
                problem: format!("{o} m is beyond ±{} m (coordinates would overflow)", COORD_MAX / 1000),
            });
        }
    }
    let far_x = y.origin[0] * 1000.0 + grid.width as f64 * y.resolution * 1000.0;
    let far_y = y.origin[1] * 1000.0 + grid.height as f64 * y.resolution * 1000.0;
    if far_x.abs() > lim || far_y.abs() > lim {
        return Err(ImportError::Field {
            path: path.to_path_buf(),
            field: "resolution".into(),
            problem: format!(
                "{} m × {}×{} cells from the origin reaches ({:.0}, {:.0}) m, beyond ±{} m (coordinates would overflow)",
                y.resolution,
                grid.width,
                grid.height,
                far_x / 1000.0,
                far_y / 1000.0,
                COORD_MAX / 1000
            ),
        });
    }
    if opt.walls == Walls::Lines {
        let l = lines::extract(
            grid,
            opt.unknown == Unknown::Occupied,
            &lines::LineOptions { tolerance_m: f64::from(opt.line_tolerance_mm) / 1000.0 },
        );
        let shapes = lines::shapes(&l);
        let mut extra = serde_json::Map::new();
        extra.insert("source".into(), "ros_map_server".into());
        extra.insert("image".into(), y.image.display().to_string().into());
        extra.insert("size_cells".into(), serde_json::json!([grid.width, grid.height]));
        extra.insert("resolution_m".into(), y.resolution.into());
        extra.insert("unknown_as".into(), opt.unknown.name().into());
        extra.insert("walls".into(), "lines".into());
        extra.insert(
            "lines".into(),
            serde_json::json!({
                "surface_cells": l.surface_cells,
                "walls": l.walls.len(),
                "specks": l.specks.len(),
                "tolerance_mm": if opt.line_tolerance_mm > 0 { f64::from(opt.line_tolerance_mm) } else { y.resolution * 1000.0 },
            }),
        );
        return Ok((shapes, extra));
    }
    let occ: Vec<bool> = grid
        .cells
        .iter()
        .map(|&c| c == ros::Cell::Occupied || (c == ros::Cell::Unknown && opt.unknown == Unknown::Occupied))
        .collect();
    let polys = contour::trace(&occ, grid.width, grid.height);
    let half = y.resolution * 500.0;
    let to_mm = |r: &[(i64, i64)]| -> Vec<Point> {
        r.iter()
            .map(|&(u, v)| {
                Point::new(
                    (y.origin[0] * 1000.0 + u as f64 * half).round() as i32,
                    (y.origin[1] * 1000.0 + v as f64 * half).round() as i32,
                )
            })
            .collect()
    };
    let mut shapes = Vec::with_capacity(polys.len());
    let (mut holes_in, mut holes_out, mut verts_in, mut verts_out) = (0, 0, 0, 0);
    for p in &polys {
        let outer = to_mm(&p.outer);
        let holes: Vec<Vec<Point>> = p.holes.iter().map(|h| to_mm(h)).collect();
        holes_in += holes.len();
        verts_in += outer.len() + holes.iter().map(Vec::len).sum::<usize>();
        let (outer, holes) = simplify::simplify(&outer, &holes, opt.simplify_mm);
        holes_out += holes.len();
        verts_out += outer.len() + holes.iter().map(Vec::len).sum::<usize>();
        shapes.push(Shape::Solid { outer, holes });
    }
    let count = |c: ros::Cell| grid.cells.iter().filter(|&&x| x == c).count();
    let mut extra = serde_json::Map::new();
    extra.insert("source".into(), "ros_map_server".into());
    extra.insert("image".into(), y.image.display().to_string().into());
    extra.insert("size_cells".into(), serde_json::json!([grid.width, grid.height]));
    extra.insert("resolution_m".into(), y.resolution.into());
    extra.insert(
        "cells".into(),
        serde_json::json!({
            "occupied": count(ros::Cell::Occupied),
            "free": count(ros::Cell::Free),
            "unknown": count(ros::Cell::Unknown),
        }),
    );
    extra.insert("unknown_as".into(), opt.unknown.name().into());
    extra.insert("simplify_mm".into(), opt.simplify_mm.into());
    extra.insert("contour_vertices".into(), verts_in.into());
    extra.insert("simplified_vertices".into(), verts_out.into());
    extra.insert("holes".into(), holes_out.into());
    extra.insert("holes_dropped".into(), (holes_in - holes_out).into());
    Ok((shapes, extra))
}

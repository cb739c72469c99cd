//! The one map loader every command shares (`predict`, `replay`,
//! `simulate`, `scenario`, `board`, the lab's examples): any map `map
//! import` accepts, as the compiled map read in place ([`MapView`]), the
//! way the firmware reads it from flash. Nothing caps its size but the
//! compiled form's own limits (65 535 pieces): a building of 2 500 convex
//! pieces loads as the depot does.
//!
//! ```no_run
//! use echoloc::map::MapSource;
//! use echoloc_lab::map::load::{load, LoadOptions};
//! let map = load("robot/map.yaml".as_ref(), &LoadOptions::default())?;
//! let view = map.view()?;
//! println!("{} pieces, {}", view.piece_count(), map.kind().describe());
//! # Ok::<(), echoloc_lab::LabError>(())
//! ```

use std::path::{Path, PathBuf};

use echoloc::map::{MapView, StandardMap};

use super::{compile_source, read_source, AlignedBytes, FieldOptions, ImportError, ImportOptions, LabError};

/// What a map file was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// A compiled map (`.map`, `docs/map-blob.md`), read as it is.
    Compiled,
    /// An older blob (`.map` of an earlier version), compiled here.
    OlderBlob,
    /// A ROS map_server `.yaml` with its image, imported here.
    RosMapServer,
    /// A GeoJSON FeatureCollection, imported here.
    GeoJson,
}

impl MapKind {
    /// Words for messages and reports.
    pub fn describe(self) -> &'static str {
        match self {
            MapKind::Compiled => "a compiled map (.map)",
            MapKind::OlderBlob => "an older map blob (.map)",
            MapKind::RosMapServer => "a ROS map_server map (.yaml)",
            MapKind::GeoJson => "a GeoJSON map",
        }
    }

    /// The kind a path names by its extension (`None`: not a map's).
    pub fn of_path(path: &Path) -> Option<MapKind> {
        match path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase().as_str() {
            "map" => Some(MapKind::Compiled),
            "yaml" | "yml" => Some(MapKind::RosMapServer),
            "geojson" | "json" => Some(MapKind::GeoJson),
            _ => None,
        }
    }
}

/// How a map source (`.yaml`, `.geojson`) is compiled; a `.map` carries its own.
#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    /// C-space buffer, mm.
    pub buffer_mm: u32,
    /// Grid cell, mm (grown until the grid fits).
    pub cell_mm: u32,
    /// Simplification, the unknown cells, the localization field.
    pub import: ImportOptions,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { buffer_mm: 100, cell_mm: 1000, import: ImportOptions::default() }
    }
}

impl LoadOptions {
    /// The defaults with buffer `buffer_mm`.
    pub fn buffer(buffer_mm: u32) -> Self {
        Self { buffer_mm, ..Self::default() }
    }

    /// Without a localization field (smaller, faster to build; no global localization).
    pub fn without_field(mut self) -> Self {
        self.import.field = None;
        self
    }

    /// With localization field `f`.
    pub fn with_field(mut self, f: FieldOptions) -> Self {
        self.import.field = Some(f);
        self
    }
}

/// How a `.yaml` map's walls are drawn, for the commands that load one
/// (`simulate`, `replay`, `board`, `predict`): `map import`'s options.
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct GridArgs {
    /// A .yaml map's walls: contour (round the occupied cells) or lines
    /// (straight walls through them, for SLAM maps of real buildings).
    #[arg(long = "walls", value_enum, default_value_t = super::Walls::Contour)]
    pub walls: super::Walls,
    /// With --walls lines: most distance, mm, from a surface cell's centre to its wall (0: one cell).
    #[arg(long = "line-tolerance-mm", default_value_t = 0)]
    pub line_tolerance_mm: u32,
    /// A .yaml map's face lobe, degrees (default 8 with --walls lines, else 15):
    /// `map import --face-lobe-deg`.
    #[arg(long = "face-lobe-deg")]
    pub face_lobe_deg: Option<f32>,
    /// A .geojson map without `free` polygons: gaps in the walls up to this
    /// wide, mm, count as closed when finding its free space: `map import --door-mm`.
    #[arg(long = "door-mm", default_value_t = super::free_space::DEFAULT_DOOR_MM,
          value_parser = clap::value_parser!(u32).range(0..=i64::from(super::free_space::MAX_DOOR_MM)))]
    pub door_mm: u32,
}

impl GridArgs {
    /// The load options with buffer `buffer_mm` and, when `field`, the default localization field.
    pub fn options(&self, buffer_mm: u32, field: bool) -> LoadOptions {
        let mut o = LoadOptions::buffer(buffer_mm);
        o.import.walls = self.walls;
        o.import.line_tolerance_mm = self.line_tolerance_mm;
        o.import.face_lobe_deg = self.face_lobe_deg;
        o.import.door_mm = self.door_mm;
        if !field {
            o.import.field = None;
        }
        o
    }
}

/// A loaded map: the compiled bytes, validated once as the firmware
/// validates them, and where they came from.
pub struct LoadedMap {
    bytes: AlignedBytes,
    path: PathBuf,
    kind: MapKind,
}

impl LoadedMap {
    /// The compiled map read in place. Validated when loaded; validated
    /// again here (cheap next to any use), so nothing is trusted unchecked.
    pub fn view(&self) -> Result<MapView<'_>, LabError> {
        MapView::new(self.bytes.bytes()).map_err(|e| {
            LabError(format!(
                "{}: {} that does not validate as a compiled map: {e:?}",
                self.path.display(),
                self.kind.describe()
            ))
        })
    }

    /// The compiled bytes (what a board's map partition takes).
    pub fn blob(&self) -> &[u8] {
        self.bytes.bytes()
    }

    /// The file it came from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the file was.
    pub fn kind(&self) -> MapKind {
        self.kind
    }

    /// CRC-32 of the compiled bytes (what scenarios name their map by).
    pub fn crc(&self) -> u32 {
        echoloc::map::crc32(self.blob())
    }
}

/// Loads `path` in any form `map import` takes, or a compiled `.map`: the
/// source is imported and compiled with `opt` (a `.map` as it is; an older
/// blob is compiled into the present form). Errors name the file and what
/// it was taken for.
pub fn load(path: &Path, opt: &LoadOptions) -> Result<LoadedMap, LabError> {
    let kind = MapKind::of_path(path).ok_or_else(|| {
        LabError(format!(
            "{}: unknown map format (expected a compiled .map, a ROS map_server .yaml or a .geojson)",
            path.display()
        ))
    })?;
    let (bytes, kind) = match kind {
        MapKind::Compiled | MapKind::OlderBlob => {
            let raw = std::fs::read(path).map_err(|e| ImportError::Io { path: path.to_path_buf(), source: e })?;
            let a = AlignedBytes::new(&raw);
            match MapView::new(a.bytes()) {
                Ok(_) => (a, MapKind::Compiled),
                Err(compiled) => (older_blob(&raw, path, compiled)?, MapKind::OlderBlob),
            }
        }
        MapKind::RosMapServer | MapKind::GeoJson => {
            let (p, o) = (path.to_path_buf(), *opt);
            let blob = on_big_stack(
                move || {
                    let src = read_source(&p, &o.import).map_err(LabError::from)?;
                    compile_source(&src, o.buffer_mm, o.cell_mm, &o.import).map(|(b, _)| b).map_err(|e| {
                        LabError(format!("{}: {} that cannot be compiled: {e}", p.display(), kind.describe()))
                    })
                },
                LabError,
            )?;
            (AlignedBytes::new(&blob), kind)
        }
    };
    let m = LoadedMap { bytes, path: path.to_path_buf(), kind };
    m.view()?;
    Ok(m)
}

/// An older blob (version 1 or 2), through the host's map, compiled into
/// the present form; if it is not one either, the compiled form's error
/// says why (that is what a `.map` is expected to be).
fn older_blob(raw: &[u8], path: &Path, compiled: echoloc::map::BlobError) -> Result<AlignedBytes, LabError> {
    let mut m: Box<StandardMap> = Box::default();
    if m.load(AlignedBytes::new(raw).bytes()).is_err() {
        return Err(LabError(format!("{}: not a valid compiled map: {compiled:?}", path.display())));
    }
    let mut out = vec![0u8; m.compiled_len()];
    let n = m
        .compile(&mut out)
        .map_err(|e| LabError(format!("{}: an older blob that cannot be compiled: {e:?}", path.display())))?;
    out.truncate(n);
    Ok(AlignedBytes::new(&out))
}

/// Runs `f` on a thread with room for the convex splitter's fixed working
/// sets (a few MB, as on the firmware side), so an import may be called
/// from any thread (a `build.rs` included); `fail` words a thread that
/// could not start or panicked.
pub(super) fn on_big_stack<T: Send + 'static, E: Send + 'static>(
    f: impl FnOnce() -> Result<T, E> + Send + 'static,
    fail: impl Fn(String) -> E,
) -> Result<T, E> {
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(f)
        .map_err(|e| fail(format!("cannot start the import: {e}")))?
        .join()
        .unwrap_or_else(|_| Err(fail("internal error: the import panicked".into())))
}

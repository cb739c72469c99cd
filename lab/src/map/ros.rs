//! ROS map_server maps: the YAML description and its PGM or PNG image,
//! classified into free, occupied and unknown cells by map_server's rules.
//!
//! The YAML is read by a YAML 1.2 parser (`saphyr`, which keeps each node's
//! line), so any YAML spelling of map_server's keys reads; every problem names
//! the YAML file, the key and its line. PGM
//! (P5 binary and P2 ASCII, up to 8 bits) is read here; PNG (1–8 bits,
//! grey, grey+alpha, RGB, RGBA, palette) with the `png` crate. 16-bit images
//! are refused (map_server reads 8-bit data).

use std::fs;
use std::path::{Path, PathBuf};

use saphyr::{LoadableYamlNode, MarkedYaml, Scalar, YamlData};

use super::ImportError;

/// map_server's `mode`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Occupied, free, or unknown by the thresholds.
    Trinary,
    /// Like trinary for our purpose (in-between shades are unknown: the map
    /// holds only obstacles), but transparent pixels are unknown.
    Scale,
    /// The pixel value is the occupancy in percent (0–100); anything above
    /// 100 (255 is ROS's −1) is unknown.
    Raw,
}

/// The YAML's contents.
#[derive(Clone, Debug, PartialEq)]
pub struct MapYaml {
    /// The image, resolved against the YAML's directory.
    pub image: PathBuf,
    /// Metres per cell.
    pub resolution: f64,
    /// The lower-left corner of the lower-left cell, metres, and the yaw.
    pub origin: [f64; 3],
    /// Whether white means occupied.
    pub negate: bool,
    /// Occupancy probability above which a cell is occupied.
    pub occupied_thresh: f64,
    /// Occupancy probability below which a cell is free.
    pub free_thresh: f64,
    /// How pixels become occupancy.
    pub mode: Mode,
}

/// A cell's class.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cell {
    Free,
    Occupied,
    Unknown,
}

/// The classified grid. Row 0 is the top of the image (the map's largest y).
#[derive(Clone, Debug)]
pub struct Grid {
    pub width: usize,
    pub height: usize,
    pub cells: Vec<Cell>,
    pub yaml: MapYaml,
}

impl Grid {
    /// The cell in image column `c`, image row `r`.
    pub fn at(&self, c: usize, r: usize) -> Cell {
        self.cells[r * self.width + c]
    }

    /// Whether the cell holding the map point (`x_mm`, `y_mm`) is known to
    /// be free (false outside the image).
    pub fn known_free_at(&self, x_mm: f64, y_mm: f64) -> bool {
        let res = self.yaml.resolution * 1000.0;
        let u = ((x_mm - self.yaml.origin[0] * 1000.0) / res).floor();
        let v = ((y_mm - self.yaml.origin[1] * 1000.0) / res).floor();
        if !(u >= 0.0 && v >= 0.0 && u < self.width as f64 && v < self.height as f64) {
            return false;
        }
        // Image rows run down from the top; v counts up from the bottom.
        self.at(u as usize, self.height - 1 - v as usize) == Cell::Free
    }
}

fn field(path: &Path, field: &str, problem: impl Into<String>) -> ImportError {
    ImportError::Field { path: path.to_path_buf(), field: field.to_string(), problem: problem.into() }
}

/// A value of the YAML and the line it is on (1 is the first).
type Node<'a, 'b> = (&'b MarkedYaml<'a>, usize);

fn scalar_text(n: &MarkedYaml) -> String {
    match &n.data {
        YamlData::Value(Scalar::String(s)) => format!("{s:?}"),
        YamlData::Value(Scalar::Integer(i)) => i.to_string(),
        YamlData::Value(Scalar::FloatingPoint(f)) => f.to_string(),
        YamlData::Value(Scalar::Boolean(b)) => b.to_string(),
        YamlData::Value(Scalar::Null) => "nothing".into(),
        YamlData::Sequence(_) => "a list".into(),
        YamlData::Mapping(_) => "a mapping".into(),
        _ => "something else".into(),
    }
}

/// A YAML number (an integer or a float; map_server reads both as double).
fn as_number(n: &MarkedYaml) -> Option<f64> {
    match &n.data {
        YamlData::Value(Scalar::Integer(i)) => Some(*i as f64),
        YamlData::Value(Scalar::FloatingPoint(f)) => Some(f.into_inner()).filter(|x| x.is_finite()),
        _ => None,
    }
}

/// The parser notices some mistakes only on a later line (a line without
/// `:` is found out at the next key, or at the end): the last line at or
/// before `line` that has more than blanks and a comment.
fn content_line(text: &str, line: usize) -> usize {
    let lines: Vec<&str> = text.lines().collect();
    (1..=line.min(lines.len()))
        .rev()
        .find(|&n| {
            let t = lines[n - 1].trim();
            !t.is_empty() && !t.starts_with('#')
        })
        .unwrap_or(line)
}

/// Parses the YAML text of the map at `path` (used in messages and to
/// resolve `image`) with a YAML 1.2 parser (`saphyr`): any YAML form of
/// map_server's keys (flow lists over several lines, quoted names, block
/// lists, comments). Every problem names the file, the key and its line.
pub fn parse_yaml(path: &Path, text: &str) -> Result<MapYaml, ImportError> {
    let docs = MarkedYaml::load_from_str(text).map_err(|e| {
        let line = content_line(text, e.marker().line());
        field(path, &format!("line {line}"), format!("not YAML: {} (expected `key: value` lines)", e.info()))
    })?;
    let top = docs.first().ok_or_else(|| field(path, "image", "missing: the file is empty"))?;
    let YamlData::Mapping(map) = &top.data else {
        return Err(field(
            path,
            &format!("line {}", top.span.start.line()),
            format!("expected `key: value` lines (map_server's keys), found {}", scalar_text(top)),
        ));
    };
    let mut kv: Vec<(String, &MarkedYaml)> = Vec::new();
    for (k, v) in map {
        match &k.data {
            YamlData::Value(Scalar::String(s)) => kv.push((s.to_string(), v)),
            _ => {
                return Err(field(
                    path,
                    &format!("line {}", k.span.start.line()),
                    format!("a key must be a name, found {}", scalar_text(k)),
                ))
            }
        }
    }
    let get = |k: &str| kv.iter().find(|(q, _)| q == k).map(|(_, v)| (*v, v.span.start.line()));
    let need = |k: &str| get(k).ok_or_else(|| field(path, k, "missing (required by map_server)"));
    let number = |k: &str, (v, line): Node| -> Result<f64, ImportError> {
        as_number(v).ok_or_else(|| field(path, k, format!("expected a number, found {} (line {line})", scalar_text(v))))
    };

    let (img, line) = need("image")?;
    let image = match &img.data {
        YamlData::Value(Scalar::String(s)) if !s.is_empty() => s.to_string(),
        YamlData::Value(Scalar::String(_)) => return Err(field(path, "image", format!("empty (line {line})"))),
        _ => {
            return Err(field(path, "image", format!("expected a file name, found {} (line {line})", scalar_text(img))))
        }
    };
    let image = path.parent().unwrap_or(Path::new(".")).join(image);
    let (res, line) = need("resolution")?;
    let resolution = number("resolution", (res, line))?;
    if resolution < 0.002 {
        return Err(field(
            path,
            "resolution",
            format!("{resolution} m per cell: must be at least 0.002 (2 mm) (line {line})"),
        ));
    }
    let (o, line) = need("origin")?;
    let YamlData::Sequence(parts) = &o.data else {
        return Err(field(path, "origin", format!("expected [x, y, yaw], found {} (line {line})", scalar_text(o))));
    };
    if parts.len() != 3 {
        return Err(field(
            path,
            "origin",
            format!("expected three numbers [x, y, yaw], found {} (line {line})", parts.len()),
        ));
    }
    let mut origin = [0.0; 3];
    for (i, p) in parts.iter().enumerate() {
        origin[i] = number(&format!("origin[{i}]"), (p, p.span.start.line()))?;
    }
    if origin[2] != 0.0 {
        return Err(field(
            path,
            "origin[2]",
            format!(
                "yaw {} rad: rotated maps are not supported (map_server itself mostly ignores yaw) (line {line})",
                origin[2]
            ),
        ));
    }
    // map_server reads negate as an integer, 0 or not; YAML's booleans too.
    let (n, line) = need("negate")?;
    let negate = match &n.data {
        YamlData::Value(Scalar::Integer(0)) | YamlData::Value(Scalar::Boolean(false)) => false,
        YamlData::Value(Scalar::Integer(1)) | YamlData::Value(Scalar::Boolean(true)) => true,
        _ => return Err(field(path, "negate", format!("expected 0 or 1, found {} (line {line})", scalar_text(n)))),
    };
    let occupied = need("occupied_thresh")?;
    let free = need("free_thresh")?;
    let occupied_thresh = number("occupied_thresh", occupied)?;
    let free_thresh = number("free_thresh", free)?;
    for (k, v, line) in [("occupied_thresh", occupied_thresh, occupied.1), ("free_thresh", free_thresh, free.1)] {
        if !(0.0..=1.0).contains(&v) {
            return Err(field(path, k, format!("{v} is outside 0..=1 (line {line})")));
        }
    }
    if free_thresh >= occupied_thresh {
        return Err(field(
            path,
            "free_thresh",
            format!("{free_thresh} must be below occupied_thresh ({occupied_thresh}) (line {})", free.1),
        ));
    }
    let mode = match get("mode") {
        None => Mode::Trinary,
        Some((m, line)) => match &m.data {
            YamlData::Value(Scalar::String(s)) if s == "trinary" => Mode::Trinary,
            YamlData::Value(Scalar::String(s)) if s == "scale" => Mode::Scale,
            YamlData::Value(Scalar::String(s)) if s == "raw" => Mode::Raw,
            _ => {
                return Err(field(
                    path,
                    "mode",
                    format!("expected trinary, scale or raw, found {} (line {line})", scalar_text(m)),
                ))
            }
        },
    };
    Ok(MapYaml { image, resolution, origin, negate, occupied_thresh, free_thresh, mode })
}

#[derive(Debug)]
/// An 8-bit image: the average of the colour channels per pixel, and the
/// alpha channel when there is one.
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub value: Vec<u8>,
    pub alpha: Option<Vec<u8>>,
}

/// Reads the map's image (PGM or PNG, by its content). Errors name the YAML
/// file, the `image` field and the image file.
pub fn read_image(yaml_path: &Path, image: &Path) -> Result<Image, ImportError> {
    let bad =
        |problem: String| ImportError::Image { yaml: yaml_path.to_path_buf(), image: image.to_path_buf(), problem };
    let bytes = fs::read(image).map_err(|e| bad(format!("cannot read: {e}")))?;
    decode_image(&bytes).map_err(bad)
}

/// Decodes a map image held in memory (PGM or PNG, by its content); the
/// error says what is wrong with it.
pub fn decode_image(bytes: &[u8]) -> Result<Image, String> {
    let img = if bytes.starts_with(b"P5") || bytes.starts_with(b"P2") {
        read_pgm(bytes)?
    } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        read_png(bytes)?
    } else {
        return Err("not a PGM (P5/P2) or PNG image".into());
    };
    if img.width == 0 || img.height == 0 {
        return Err(format!("empty image ({}x{})", img.width, img.height));
    }
    Ok(img)
}

fn read_pgm(b: &[u8]) -> Result<Image, String> {
    let ascii = b[1] == b'2';
    let mut pos = 2;
    let mut header = [0usize; 3];
    for (k, name) in ["width", "height", "maxval"].iter().enumerate() {
        header[k] = pgm_token(b, &mut pos).ok_or_else(|| format!("PGM header: missing or bad {name}"))?;
    }
    let [width, height, maxval] = header;
    if maxval == 0 || maxval > 65535 {
        return Err(format!("PGM header: maxval {maxval} is out of range"));
    }
    if maxval > 255 {
        return Err(format!("unsupported image depth: 16-bit PGM (maxval {maxval}); map_server maps are 8-bit"));
    }
    let n = width.checked_mul(height).filter(|&n| n <= MAX_CELLS).ok_or_else(|| too_large("PGM", width, height))?;
    let scale = |v: usize| ((v * 255 + maxval / 2) / maxval) as u8;
    // Reserve no more than the file could hold: a lying header must not make us allocate.
    let mut value = Vec::with_capacity(n.min(b.len()));
    if ascii {
        for i in 0..n {
            let v =
                pgm_token(b, &mut pos).ok_or_else(|| format!("P2 data: pixel {i} of {n} missing or not a number"))?;
            if v > maxval {
                return Err(format!("P2 data: pixel {i} = {v} exceeds maxval {maxval}"));
            }
            value.push(scale(v));
        }
    } else {
        // Exactly one whitespace byte after maxval, then the raster.
        pos += 1;
        let data = b
            .get(pos..pos + n)
            .ok_or_else(|| format!("P5 data: {} bytes, expected {n}", b.len().saturating_sub(pos)))?;
        if let Some(i) = data.iter().position(|&v| v as usize > maxval) {
            return Err(format!("P5 data: pixel {i} = {} exceeds maxval {maxval}", data[i]));
        }
        value.extend(data.iter().map(|&v| scale(v as usize)));
    }
    Ok(Image { width, height, value, alpha: None })
}

/// The next decimal token, skipping whitespace and `#` comments.
fn pgm_token(b: &[u8], pos: &mut usize) -> Option<usize> {
    loop {
        match b.get(*pos)? {
            c if c.is_ascii_whitespace() => *pos += 1,
            b'#' => {
                while *b.get(*pos)? != b'\n' {
                    *pos += 1;
                }
            }
            _ => break,
        }
    }
    let start = *pos;
    while b.get(*pos).is_some_and(u8::is_ascii_digit) {
        *pos += 1;
    }
    std::str::from_utf8(&b[start..*pos]).ok()?.parse().ok()
}

/// The most cells an image may have: 8192 × 8192, far beyond any map the
/// firmware can hold, and a bound on what a lying header can make us
/// allocate (a PNG's decoded size is not limited by its file's).
pub const MAX_CELLS: usize = 1 << 26;

fn too_large(what: &str, width: usize, height: usize) -> String {
    format!("{what} header: {width}x{height} is too large (at most {MAX_CELLS} cells)")
}

fn read_png(b: &[u8]) -> Result<Image, String> {
    let mut dec = png::Decoder::new(b);
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(|e| format!("PNG: {e}"))?;
    // Before the buffer is allocated: the header says what it likes.
    let (w, h) = (reader.info().width as usize, reader.info().height as usize);
    if w.checked_mul(h).is_none_or(|n| n > MAX_CELLS) {
        return Err(too_large("PNG", w, h));
    }
    let depth = reader.info().bit_depth;
    if depth == png::BitDepth::Sixteen {
        return Err("unsupported image depth: 16-bit PNG; map_server maps are 8-bit".into());
    }
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(|e| format!("PNG: {e}"))?;
    let (width, height) = (frame.width as usize, frame.height as usize);
    let (channels, has_alpha) = match frame.color_type {
        png::ColorType::Grayscale => (1, false),
        png::ColorType::GrayscaleAlpha => (2, true),
        png::ColorType::Rgb => (3, false),
        png::ColorType::Rgba => (4, true),
        png::ColorType::Indexed => return Err("PNG: palette not expanded".into()),
    };
    if frame.bit_depth != png::BitDepth::Eight {
        return Err(format!("unsupported image depth: {:?} after expansion", frame.bit_depth));
    }
    let colours = if has_alpha { channels - 1 } else { channels };
    let mut value = Vec::with_capacity(width * height);
    let mut alpha = has_alpha.then(|| Vec::with_capacity(width * height));
    for r in 0..height {
        let row = &buf[r * frame.line_size..][..width * channels];
        for px in row.chunks_exact(channels) {
            let sum: usize = px[..colours].iter().map(|&v| v as usize).sum();
            value.push(((sum + colours / 2) / colours) as u8);
            if let Some(a) = alpha.as_mut() {
                a.push(px[channels - 1]);
            }
        }
    }
    Ok(Image { width, height, value, alpha })
}

/// map_server's classification of one pixel (ROS 1 `map_server`
/// image_loader and Nav2 `map_io`): `occ = (255 − v) / 255` (with `v`
/// first replaced by `255 − v` under `negate`); occupied when `occ >
/// occupied_thresh`, free when `occ < free_thresh`. `raw` reads `v` as a
/// percentage instead. A transparent pixel (alpha < 255) is unknown except
/// in `raw` mode.
pub fn classify(y: &MapYaml, value: u8, alpha: Option<u8>) -> Cell {
    let v = if y.negate { 255 - value } else { value };
    match y.mode {
        Mode::Raw => {
            let p = v as f64;
            if v > 100 {
                Cell::Unknown
            } else if p > y.occupied_thresh * 100.0 {
                Cell::Occupied
            } else if p < y.free_thresh * 100.0 {
                Cell::Free
            } else {
                Cell::Unknown
            }
        }
        Mode::Trinary | Mode::Scale => {
            if alpha.is_some_and(|a| a < 255) {
                return Cell::Unknown;
            }
            let occ = (255.0 - v as f64) / 255.0;
            if occ > y.occupied_thresh {
                Cell::Occupied
            } else if occ < y.free_thresh {
                Cell::Free
            } else {
                Cell::Unknown
            }
        }
    }
}

/// Reads and classifies the map described by the YAML file at `path`.
pub fn load(path: &Path) -> Result<Grid, ImportError> {
    let text = fs::read_to_string(path).map_err(|e| ImportError::Io { path: path.to_path_buf(), source: e })?;
    let yaml = parse_yaml(path, &text)?;
    let img = read_image(path, &yaml.image)?;
    Ok(grid_of(yaml, &img))
}

/// The occupancy grid of a decoded image under its YAML's thresholds.
pub fn grid_of(yaml: MapYaml, img: &Image) -> Grid {
    let cells =
        (0..img.width * img.height).map(|i| classify(&yaml, img.value[i], img.alpha.as_ref().map(|a| a[i]))).collect();
    Grid { width: img.width, height: img.height, cells, yaml }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn yaml(text: &str) -> Result<MapYaml, ImportError> {
        parse_yaml(Path::new("/m/x.yaml"), text)
    }

    const OK: &str = "image: a.pgm\nresolution: 0.05\norigin: [-1.5, 2, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196 # comment\n";

    #[test]
    fn parses_the_flat_format() {
        let y = yaml(OK).unwrap();
        assert_eq!(y.image, Path::new("/m/a.pgm"));
        assert_eq!(y.origin, [-1.5, 2.0, 0.0]);
        assert_eq!(y.mode, Mode::Trinary);
        assert!(!y.negate);
        let y = yaml(&format!("{OK}mode: raw\n")).unwrap();
        assert_eq!(y.mode, Mode::Raw);
    }

    #[test]
    fn field_errors_name_the_field() {
        let cases = [
            (OK.replace("resolution: 0.05\n", ""), "resolution: missing"),
            (OK.replace("0.05", "fast"), "resolution: expected a number"),
            (OK.replace("[-1.5, 2, 0.0]", "[1, 2]"), "origin: expected three numbers"),
            (OK.replace("[-1.5, 2, 0.0]", "[1, 2, 0.3]"), "origin[2]: yaw"),
            (OK.replace("negate: 0", "negate: maybe"), "negate: expected 0 or 1"),
            (OK.replace("0.65", "1.5"), "occupied_thresh: 1.5 is outside"),
            (OK.replace("0.196", "0.7"), "free_thresh: 0.7 must be below"),
            (format!("{OK}mode: fuzzy\n"), "mode: expected trinary"),
            (format!("{OK}image: b.pgm\n"), "line 7: not YAML: duplicated key in mapping"),
        ];
        for (text, want) in cases {
            let e = yaml(&text).unwrap_err().to_string();
            assert!(e.contains("/m/x.yaml") && e.contains(want), "{want}: {e}");
        }
    }

    /// YAML that the old line splitter broke, as map_server (yaml-cpp) reads it.
    #[test]
    fn any_yaml_spelling_of_the_keys() {
        // A flow list over two lines, a quoted image name with spaces,
        // negate as YAML's boolean, mode scale, keys in another order.
        let y = yaml(
            "# my robot's map\nmode: scale\norigin: [-1.5,\n         2.25, 0.0]\nimage: \"my map.pgm\"\n\
             resolution: 0.05\nnegate: true\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
        .unwrap();
        assert_eq!(y.image, Path::new("/m/my map.pgm"));
        assert_eq!(y.origin, [-1.5, 2.25, 0.0]);
        assert_eq!((y.mode, y.negate), (Mode::Scale, true));
        // A block list, single quotes, negate 1, a document marker, integers for doubles.
        let y = yaml("---\nimage: 'a b.png'\nresolution: 1\norigin:\n  - 3\n  - -4\n  - 0\nnegate: 1\noccupied_thresh: 1\nfree_thresh: 0\n").unwrap();
        assert_eq!(y.image, Path::new("/m/a b.png"));
        assert_eq!((y.resolution, y.origin, y.negate), (1.0, [3.0, -4.0, 0.0], true));
        // Errors name the key and its line.
        let e = yaml(&OK.replace("0.05", "fast")).unwrap_err().to_string();
        assert!(e.ends_with("resolution: expected a number, found \"fast\" (line 2)"), "{e}");
        let e = yaml(&OK.replace("[-1.5, 2, 0.0]", "[-1.5,\n  two, 0.0]")).unwrap_err().to_string();
        assert!(e.ends_with("origin[1]: expected a number, found \"two\" (line 4)"), "{e}");
        let e = yaml("image: a.pgm\norigin: [0, 0\n").unwrap_err().to_string();
        assert!(e.contains("/m/x.yaml: line ") && e.contains("not YAML"), "{e}");
        let e = yaml("- image\n").unwrap_err().to_string();
        assert!(e.ends_with("line 1: expected `key: value` lines (map_server's keys), found a list"), "{e}");
        assert!(yaml("").unwrap_err().to_string().contains("image: missing"));
    }

    #[test]
    fn classification_follows_map_server() {
        let y = yaml(OK).unwrap();
        assert_eq!(classify(&y, 0, None), Cell::Occupied);
        assert_eq!(classify(&y, 254, None), Cell::Free);
        assert_eq!(classify(&y, 205, None), Cell::Unknown); // occ 0.19608 > 0.196
        assert_eq!(classify(&y, 206, None), Cell::Free);
        assert_eq!(classify(&y, 254, Some(0)), Cell::Unknown);
        let n = MapYaml { negate: true, ..y.clone() };
        assert_eq!(classify(&n, 255, None), Cell::Occupied);
        let raw = MapYaml { mode: Mode::Raw, ..y };
        assert_eq!(classify(&raw, 100, None), Cell::Occupied);
        assert_eq!(classify(&raw, 0, None), Cell::Free);
        assert_eq!(classify(&raw, 255, None), Cell::Unknown);
        assert_eq!(classify(&raw, 50, None), Cell::Unknown);
    }

    /// Found by the `ros_map` fuzz target: a PNG whose header claims
    /// 7 680 × 1 073 741 888 pixels made the decoder's buffer allocation abort.
    #[test]
    fn a_png_header_claiming_a_huge_image_is_refused_before_allocating() {
        let e = decode_image(include_bytes!("../../tests/data/huge-header.png")).unwrap_err();
        assert!(e.contains("PNG header: 7680x1073741888 is too large"), "{e}");
        let e = read_pgm(b"P5 70000 70000 255\n").unwrap_err();
        assert!(e.contains("PGM header: 70000x70000 is too large"), "{e}");
    }

    #[test]
    fn pgm_p2_and_p5() {
        let p2 = read_pgm(b"P2\n# c\n3 1\n15\n0 15 7\n").unwrap();
        assert_eq!(p2.value, vec![0, 255, 119]);
        let p5 = read_pgm(b"P5 2 1 255\n\x00\xff").unwrap();
        assert_eq!(p5.value, vec![0, 255]);
        assert!(read_pgm(b"P5 2 1 65535\n\x00\x00\x00\x00").unwrap_err().contains("unsupported image depth"));
        assert!(read_pgm(b"P5 2 2 255\n\x00").unwrap_err().contains("P5 data"));
    }
}

//! The credence data files: one CSV per data set ("day"), columns
//! `r_mm,theta_deg,readings,correct`, one row per grid node.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::error::CredenceError;
use super::synth::Node;

/// The header every file starts with.
pub const HEADER: &str = "r_mm,theta_deg,readings,correct";
/// The columns, in order.
pub const COLUMNS: [&str; 4] = ["r_mm", "theta_deg", "readings", "correct"];

/// One data set as read from its file.
#[derive(Clone, Debug)]
pub struct DataSet {
    /// The file's stem (`day1`, …).
    pub name: String,
    /// The file.
    pub path: PathBuf,
    /// CRC-32 of the file's bytes, for provenance in the weights' header.
    pub crc32: u32,
    /// Its nodes, in file order.
    pub nodes: Vec<Node>,
}

/// Formats nodes as the CSV text.
pub fn to_csv(nodes: &[Node]) -> String {
    let mut s = String::with_capacity(24 * (nodes.len() + 1));
    s.push_str(HEADER);
    s.push('\n');
    for n in nodes {
        let _ = writeln!(s, "{},{},{},{}", n.r_mm, n.theta_deg, n.readings, n.correct);
    }
    s
}

/// Parses one CSV file's text; `path` names it in errors.
pub fn parse_csv(path: &Path, text: &str) -> Result<Vec<Node>, CredenceError> {
    let err = |line: usize, field: Option<&'static str>, message: String| CredenceError::Csv {
        path: path.to_path_buf(),
        line,
        field,
        message,
    };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end_matches('\r')));
    let header = lines.by_ref().find(|(_, l)| !l.trim().is_empty());
    let Some((hline, header)) = header else {
        return Err(err(1, None, format!("the file is empty; expected the header `{HEADER}`")));
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    if names != COLUMNS {
        return Err(err(hline, None, format!("header is `{header}`; expected `{HEADER}`")));
    }
    let mut nodes = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (line, text) in lines {
        if text.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        if fields.len() != COLUMNS.len() {
            return Err(err(line, None, format!("{} fields; expected {} ({HEADER})", fields.len(), COLUMNS.len())));
        }
        let int = |i: usize| -> Result<u32, CredenceError> {
            fields[i]
                .parse::<u32>()
                .map_err(|_| err(line, Some(COLUMNS[i]), format!("`{}` is not a non-negative integer", fields[i])))
        };
        let r_mm = int(0)?;
        let theta_deg: f64 = fields[1]
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| err(line, Some("theta_deg"), format!("`{}` is not a number", fields[1])))?;
        let readings = int(2)?;
        let correct = int(3)?;
        if !(500..=5500).contains(&r_mm) {
            return Err(err(line, Some("r_mm"), format!("{r_mm} is outside the net's domain 500..=5500 mm")));
        }
        if !(-45.0..=45.0).contains(&theta_deg) {
            return Err(err(line, Some("theta_deg"), format!("{theta_deg} is outside the net's domain -45..=45°")));
        }
        if readings == 0 {
            return Err(err(line, Some("readings"), "0 readings: κ is undefined".into()));
        }
        if correct > readings {
            return Err(err(line, Some("correct"), format!("{correct} correct of only {readings} readings")));
        }
        if !seen.insert((r_mm, theta_deg.to_bits())) {
            return Err(err(line, None, format!("node ({r_mm} mm, {theta_deg}°) appears twice")));
        }
        nodes.push(Node { r_mm, theta_deg, readings, correct });
    }
    if nodes.is_empty() {
        return Err(err(hline, None, "no data rows after the header".into()));
    }
    Ok(nodes)
}

/// Reads one file.
pub fn read(path: &Path) -> Result<DataSet, CredenceError> {
    let bytes = std::fs::read(path).map_err(|e| CredenceError::io(path, e))?;
    let text = std::str::from_utf8(&bytes).map_err(|e| CredenceError::Csv {
        path: path.to_path_buf(),
        line: 1 + bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count(),
        field: None,
        message: "not UTF-8 text".into(),
    })?;
    let nodes = parse_csv(path, text)?;
    let name = path.file_stem().map_or_else(|| path.display().to_string(), |s| s.to_string_lossy().into_owned());
    Ok(DataSet { name, path: path.to_path_buf(), crc32: crc32fast::hash(&bytes), nodes })
}

/// Reads the data sets named on the command line: files, or directories
/// whose `*.csv` files are taken in name order.
pub fn read_all(inputs: &[PathBuf]) -> Result<Vec<DataSet>, CredenceError> {
    let mut files = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let mut found: Vec<PathBuf> = std::fs::read_dir(input)
                .map_err(|e| CredenceError::io(input, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("csv")))
                .collect();
            if found.is_empty() {
                return Err(CredenceError::Usage(format!("{}: no .csv data sets in this directory", input.display())));
            }
            found.sort();
            files.extend(found);
        } else {
            files.push(input.clone());
        }
    }
    let sets = files.iter().map(|f| read(f)).collect::<Result<Vec<_>, _>>()?;
    let mut names: Vec<&str> = sets.iter().map(|s| s.name.as_str()).collect();
    names.sort_unstable();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        return Err(CredenceError::Usage(format!("two data sets are named `{}`: day names must differ", w[0])));
    }
    Ok(sets)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Node>, String> {
        parse_csv(Path::new("d.csv"), text).map_err(|e| e.to_string())
    }

    #[test]
    fn round_trip() {
        let nodes = vec![
            Node { r_mm: 500, theta_deg: 0.0, readings: 100, correct: 97 },
            Node { r_mm: 750, theta_deg: 2.5, readings: 100, correct: 3 },
        ];
        assert_eq!(parse(&to_csv(&nodes)).unwrap(), nodes);
    }

    #[test]
    fn errors_name_file_line_and_field() {
        let e = parse("r_mm,theta_deg,readings,correct\n500,0,100,97\n750,x,100,3\n").unwrap_err();
        assert_eq!(e, "d.csv:3: field `theta_deg`: `x` is not a number");
        let e = parse("r_mm,theta_deg,readings,correct\n500,0,10,11\n").unwrap_err();
        assert_eq!(e, "d.csv:2: field `correct`: 11 correct of only 10 readings");
        let e = parse("r,theta\n").unwrap_err();
        assert!(e.starts_with("d.csv:1: header is `r,theta`"), "{e}");
        assert!(parse("").unwrap_err().contains("empty"));
        assert!(parse(HEADER).unwrap_err().contains("no data rows"));
        assert!(parse("r_mm,theta_deg,readings,correct\n500,0,1\n").unwrap_err().contains("3 fields"));
        assert!(parse("r_mm,theta_deg,readings,correct\n500,0,-1,0\n").unwrap_err().contains("field `readings`"));
        assert!(parse("r_mm,theta_deg,readings,correct\n9000,0,1,0\n").unwrap_err().contains("outside"));
        assert!(parse("r_mm,theta_deg,readings,correct\n500,0,1,0\n500,0,1,1\n").unwrap_err().contains("twice"));
    }
}

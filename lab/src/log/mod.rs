//! The plain log a robot's own logger can write (`docs/log.md`): CSV with a
//! header, one row per reading.
//!
//! | column | unit | |
//! |---|---|---|
//! | `time_s` | s | when the transducer fired; never decreasing; rows of a whole-ring reading share one time |
//! | `transducer` | index | into the ring's order (the `--ring` file, or `pioneer16`) |
//! | `range_mm` | mm | the echo's range; empty for no echo |
//! | `odom_x_m`, `odom_y_m`, `odom_theta_rad` | m, m, rad | the odometry pose at the reading, cumulative, as robots log it |
//! | `ref_x_m`, `ref_y_m`, `ref_theta_rad` | m, m, rad | optional: a reference pose (laser, motion capture); the columns may be absent, or a row's three cells empty |
//!
//! Columns may come in any order; lines starting with `#` are comments.
//! [`read`] checks every row and refuses the whole log at the first bad
//! one with a [`LogError`] naming its line; [`write()`] writes the format.
//!
//! ```
//! use echoloc_lab::log::{read, write};
//! let text = "\
//! time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad
//! 0.00,0,1520,0,0,0
//! 0.04,1,,0.001,0,0.0001
//! ";
//! let log = read(text, 16).unwrap();
//! assert_eq!(log.rows[0].range_mm, Some(1520));
//! assert_eq!(log.rows[1].range_mm, None);
//! assert_eq!(read(&write(&log.rows, false), 16).unwrap().rows, log.rows);
//!
//! let bad = "time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad\n0,16,1000,0,0,0\n";
//! assert_eq!(read(bad, 16).unwrap_err().to_string(), "line 2: transducer 16: the ring has 16 (0 to 15)");
//! ```

use std::fmt;

/// The columns every log has.
pub const COLUMNS: [&str; 6] = ["time_s", "transducer", "range_mm", "odom_x_m", "odom_y_m", "odom_theta_rad"];
/// The reference pose's columns, all three or none.
pub const REFERENCE_COLUMNS: [&str; 3] = ["ref_x_m", "ref_y_m", "ref_theta_rad"];
/// Fastest the odometry's heading may turn between two rows, rad/s: a full
/// turn a second, beyond any wheeled robot (a Pioneer turns at most 300°/s,
/// a TurtleBot 3 160°/s). See [`turn_too_fast`].
pub const MAX_TURN_RATE_RAD_S: f64 = std::f64::consts::TAU;
/// The least time a turn is measured over, s: rows of one whole-ring
/// reading share a time, and may still carry odometry a few firings apart.
pub const TURN_RATE_MIN_DT_S: f64 = 0.1;
/// Largest range a row may give, mm (100 m: beyond any sonar).
pub const MAX_RANGE_MM: f64 = 100_000.0;

/// One reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// Firing time, s.
    pub time_s: f64,
    /// Transducer index into the ring.
    pub transducer: u8,
    /// Range, mm, rounded; `None`: no echo.
    pub range_mm: Option<u32>,
    /// Cumulative odometry pose: x m, y m, θ rad.
    pub odometry: [f64; 3],
    /// Reference pose, when the row has one.
    pub reference: Option<[f64; 3]>,
    /// The row's line in the file (1 is the header), for messages.
    pub line: u64,
}

/// A log, every row checked.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Log {
    /// The rows, in file order.
    pub rows: Vec<Row>,
}

impl Log {
    /// Whether any row has a reference pose.
    pub fn has_reference(&self) -> bool {
        self.rows.iter().any(|r| r.reference.is_some())
    }
}

/// Why a log was refused: the line and what is wrong there.
#[derive(Clone, Debug, PartialEq)]
pub struct LogError {
    /// The line (1 is the header; 0: the file as a whole).
    pub line: u64,
    /// What is wrong.
    pub problem: Problem,
}

/// What is wrong with a log.
#[derive(Clone, Debug, PartialEq)]
pub enum Problem {
    /// The file could not be read as CSV.
    Csv(String),
    /// No header line.
    NoHeader,
    /// A required column is not in the header.
    MissingColumn(&'static str),
    /// A header cell is not a column of the format.
    UnknownColumn(String),
    /// A column named twice.
    DuplicateColumn(String),
    /// Only some of the reference columns are in the header.
    PartialReferenceColumns,
    /// A row with another number of cells than the header.
    CellCount {
        /// Cells the header has.
        expected: usize,
        /// Cells the row has.
        found: usize,
    },
    /// A required cell is empty.
    Empty(&'static str),
    /// A cell is not a number.
    NotANumber {
        /// The column.
        column: &'static str,
        /// Its text.
        text: String,
    },
    /// A number is infinite or NaN.
    NotFinite(&'static str),
    /// A transducer index is not an integer.
    BadTransducer(String),
    /// A transducer index beyond the ring.
    UnknownTransducer {
        /// The index.
        index: u64,
        /// Transducers the ring has.
        ring: usize,
    },
    /// A range zero, negative or beyond [`MAX_RANGE_MM`].
    BadRange(f64),
    /// A negative time.
    NegativeTime(f64),
    /// A row earlier than the one before it.
    OutOfOrder {
        /// This row's time, s.
        time_s: f64,
        /// The previous row's, s.
        previous_s: f64,
    },
    /// The odometry heading turns faster than [`MAX_TURN_RATE_RAD_S`] since the previous row.
    HeadingJump {
        /// The previous row's θ, rad.
        from: f64,
        /// This row's θ, rad.
        to: f64,
        /// Time between the two rows, s.
        dt_s: f64,
        /// The turn, rad (wrapped, or as logged in a cumulative log: [`heading_step`]).
        turn: f64,
    },
    /// One or two of a row's three reference cells are empty.
    PartialReference,
    /// No rows.
    NoRows,
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "line {}: ", self.line)?;
        }
        match &self.problem {
            Problem::Csv(e) => write!(f, "not CSV: {e}"),
            Problem::NoHeader => write!(f, "no header line (expected {})", COLUMNS.join(",")),
            Problem::MissingColumn(c) => write!(f, "the header has no column {c} (needed: {})", COLUMNS.join(",")),
            Problem::UnknownColumn(c) => {
                write!(f, "column {c:?} is not one of {}, {}", COLUMNS.join(","), REFERENCE_COLUMNS.join(","))
            }
            Problem::DuplicateColumn(c) => write!(f, "column {c} appears twice"),
            Problem::PartialReferenceColumns => {
                write!(f, "the reference pose needs all three columns {} or none", REFERENCE_COLUMNS.join(","))
            }
            Problem::CellCount { expected, found } => {
                write!(f, "{found} cells where the header has {expected} (a missing or extra column)")
            }
            Problem::Empty(c) => write!(f, "{c} is empty"),
            Problem::NotANumber { column, text } => write!(f, "{column} {text:?} is not a number"),
            Problem::NotFinite(c) => write!(f, "{c} is not finite"),
            Problem::BadTransducer(t) => write!(f, "transducer {t:?} is not an index 0, 1, 2, …"),
            Problem::UnknownTransducer { index, ring } => {
                write!(f, "transducer {index}: the ring has {ring} (0 to {})", ring.saturating_sub(1))
            }
            Problem::BadRange(r) => write!(
                f,
                "range_mm {r}: a range must be above 0 and at most {MAX_RANGE_MM} mm (leave the cell empty for no echo)"
            ),
            Problem::NegativeTime(t) => write!(f, "time_s {t} is negative"),
            Problem::OutOfOrder { time_s, previous_s } => {
                write!(
                    f,
                    "time_s {time_s} is earlier than the row before it ({previous_s}): rows must be in time order"
                )
            }
            Problem::HeadingJump { from, to, dt_s, turn } => write!(
                f,
                "odom_theta_rad goes from {from} to {to}, a turn of {:.3} rad in {dt_s} s, faster than any robot turns \
                 (a full turn a second): that is not odometry (a reset, or degrees logged as radians?)",
                turn.abs()
            ),
            Problem::PartialReference => {
                write!(f, "the reference pose needs all three cells {} or none", REFERENCE_COLUMNS.join(","))
            }
            Problem::NoRows => write!(f, "the log has no rows"),
        }
    }
}

impl std::error::Error for LogError {}

/// An angle wrapped into (−π, π].
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    let w = a.rem_euclid(t);
    if w > std::f64::consts::PI {
        w - t
    } else {
        w
    }
}

/// Where each column is in the header.
struct Layout {
    index: [usize; 6],
    reference: Option<[usize; 3]>,
    cells: usize,
}

fn layout(header: &csv::StringRecord) -> Result<Layout, LogError> {
    let err = |problem| LogError { line: 1, problem };
    let names: Vec<&str> = header.iter().collect();
    if names.iter().all(|n| n.is_empty()) {
        return Err(err(Problem::NoHeader));
    }
    for (i, n) in names.iter().enumerate() {
        if !COLUMNS.contains(n) && !REFERENCE_COLUMNS.contains(n) {
            return Err(err(Problem::UnknownColumn(n.to_string())));
        }
        if names[..i].contains(n) {
            return Err(err(Problem::DuplicateColumn(n.to_string())));
        }
    }
    let find = |c: &str| names.iter().position(|n| *n == c);
    let mut index = [0; 6];
    for (slot, c) in index.iter_mut().zip(COLUMNS) {
        *slot = find(c).ok_or(err(Problem::MissingColumn(c)))?;
    }
    let refs = REFERENCE_COLUMNS.map(find);
    let reference = match refs {
        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
        [None, None, None] => None,
        _ => return Err(err(Problem::PartialReferenceColumns)),
    };
    Ok(Layout { index, reference, cells: names.len() })
}

fn number(cell: &str, column: &'static str) -> Result<Option<f64>, Problem> {
    if cell.is_empty() {
        return Ok(None);
    }
    let v: f64 = cell.parse().map_err(|_| Problem::NotANumber { column, text: cell.to_string() })?;
    if !v.is_finite() {
        return Err(Problem::NotFinite(column));
    }
    Ok(Some(v))
}

fn required(cell: &str, column: &'static str) -> Result<f64, Problem> {
    number(cell, column)?.ok_or(Problem::Empty(column))
}

fn row(rec: &csv::StringRecord, l: &Layout, ring: usize, line: u64) -> Result<Row, Problem> {
    if rec.len() != l.cells {
        return Err(Problem::CellCount { expected: l.cells, found: rec.len() });
    }
    let cell = |i: usize| rec.get(i).unwrap_or("");
    let time_s = required(cell(l.index[0]), COLUMNS[0])?;
    if time_s < 0.0 {
        return Err(Problem::NegativeTime(time_s));
    }
    let t = cell(l.index[1]);
    if t.is_empty() {
        return Err(Problem::Empty(COLUMNS[1]));
    }
    let index: u64 = t.parse().map_err(|_| Problem::BadTransducer(t.to_string()))?;
    let transducer = u8::try_from(index)
        .ok()
        .filter(|&i| usize::from(i) < ring)
        .ok_or(Problem::UnknownTransducer { index, ring })?;
    let range_mm = match number(cell(l.index[2]), COLUMNS[2])? {
        None => None,
        Some(r) if r > 0.0 && r <= MAX_RANGE_MM && r.round() >= 1.0 => Some(r.round() as u32),
        Some(r) => return Err(Problem::BadRange(r)),
    };
    let odometry = [3, 4, 5].map(|k| required(cell(l.index[k]), COLUMNS[k]));
    let odometry = [odometry[0].clone()?, odometry[1].clone()?, odometry[2].clone()?];
    let reference = match l.reference {
        None => None,
        Some(ix) => {
            let v = [0, 1, 2].map(|k| number(cell(ix[k]), REFERENCE_COLUMNS[k]));
            match [v[0].clone()?, v[1].clone()?, v[2].clone()?] {
                [Some(x), Some(y), Some(th)] => Some([x, y, th]),
                [None, None, None] => None,
                _ => return Err(Problem::PartialReference),
            }
        }
    };
    Ok(Row { time_s, transducer, range_mm, odometry, reference, line })
}

/// Reads a log for a ring of `ring` transducers. Every row is checked; the
/// first bad one refuses the whole log.
pub fn read(text: &str, ring: usize) -> Result<Log, LogError> {
    let mut r = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let header = r.headers().map_err(|e| LogError { line: 1, problem: Problem::Csv(e.to_string()) })?.clone();
    let header_line = header.position().map_or(1, |p| p.line());
    let l = layout(&header).map_err(|e| LogError { line: header_line, ..e })?;
    let mut rows: Vec<Row> = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| LogError {
            line: e.position().map_or(0, |p| p.line()),
            problem: Problem::Csv(e.to_string()),
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        let err = |problem| LogError { line, problem };
        let row = row(&rec, &l, ring, line).map_err(err)?;
        if let Some(prev) = rows.last() {
            if row.time_s < prev.time_s {
                return Err(err(Problem::OutOfOrder { time_s: row.time_s, previous_s: prev.time_s }));
            }
        }
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(LogError { line: 0, problem: Problem::NoRows });
    }
    let wrapped = headings_wrapped(rows.iter().map(|r| r.odometry[2]));
    for w in rows.windows(2) {
        let (from, to, dt_s) = (w[0].odometry[2], w[1].odometry[2], w[1].time_s - w[0].time_s);
        let turn = heading_step(from, to, wrapped);
        if turn_too_fast(turn, dt_s) {
            return Err(LogError { line: w[1].line, problem: Problem::HeadingJump { from, to, dt_s, turn } });
        }
    }
    Ok(Log { rows })
}

/// Whether a log's headings are wrapped: every one within one turn,
/// [−π, π] or [0, 2π] (a hair of rounding allowed). A log whose heading
/// leaves that range is cumulative, and its steps are read as logged.
pub fn headings_wrapped(thetas: impl IntoIterator<Item = f64>) -> bool {
    const EPS: f64 = 1e-3;
    thetas.into_iter().all(|t| (-std::f64::consts::PI - EPS..=std::f64::consts::TAU + EPS).contains(&t))
}

/// The turn from heading `from` to `to`, rad: through the short way in a
/// wrapped log, as logged in a cumulative one ([`headings_wrapped`]).
pub fn heading_step(from: f64, to: f64, wrapped: bool) -> f64 {
    if wrapped {
        wrap(to - from)
    } else {
        to - from
    }
}

/// The rule real odometry cannot break: a turn of `turn` rad in `dt_s`
/// seconds (at least [`TURN_RATE_MIN_DT_S`]) is faster than
/// [`MAX_TURN_RATE_RAD_S`]. No robot turns that fast, whatever its logging
/// rate: a log with a whole-ring row a metre apart, turning 80° between
/// them, passes. Degrees logged as radians break it as soon as the robot
/// turns faster than 6.3°/s (57 times as fast in "radians"), or when the
/// heading crosses ±180 (a cumulative "turn" of 360 rad); logged at 10 Hz,
/// any turn of more than 36° in a step (a reset) breaks it too. What it
/// cannot see: a degrees log whose heading never leaves ±3.14° reads as a
/// wrapped radian log.
///
/// ```
/// use echoloc_lab::log::turn_too_fast;
/// assert!(!turn_too_fast(80f64.to_radians(), 2.5)); // a real log, a ring a metre
/// assert!(turn_too_fast(80.0, 2.5)); // the same turn, degrees logged as radians
/// ```
pub fn turn_too_fast(turn: f64, dt_s: f64) -> bool {
    turn.abs() > MAX_TURN_RATE_RAD_S * dt_s.max(TURN_RATE_MIN_DT_S)
}

/// The log's rows split into ring cycles: a cycle ends before a transducer
/// fires a second time. A ring that fires one transducer at a time and
/// whole-ring rows sharing one time both give one cycle per round.
pub fn cycles(rows: &[Row]) -> Vec<&[Row]> {
    let mut out = Vec::new();
    let (mut start, mut seen) = (0, [false; 256]);
    for (i, r) in rows.iter().enumerate() {
        if seen[usize::from(r.transducer)] {
            out.push(&rows[start..i]);
            start = i;
            seen = [false; 256];
        }
        seen[usize::from(r.transducer)] = true;
    }
    if start < rows.len() {
        out.push(&rows[start..]);
    }
    out
}

/// A log's last ring cycle, cut short: what [`drop_partial_last_ring`] dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartialRing {
    /// Its readings.
    pub readings: usize,
    /// The line of its first.
    pub line: u64,
}

impl PartialRing {
    /// For a command's summary.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({"readings": self.readings, "line": self.line})
    }

    /// The note a command prints to standard error.
    pub fn note(&self, ring: usize) -> String {
        format!(
            "the log ends mid-ring: its last ring cycle (line {}) has {} of the {ring} readings, dropped (the \
             driver fires every transducer once a cycle)",
            self.line, self.readings
        )
    }
}

/// Drops the log's last ring cycle ([`cycles`]) when it has fewer than
/// `ring` readings and a whole cycle comes before it: a recording stopped
/// by hand ends mid-ring more often than not. A partial cycle anywhere
/// else is left for the caller to refuse (a logger that lost readings),
/// and so is a log that is one partial cycle.
///
/// ```
/// use echoloc_lab::log::{drop_partial_last_ring, read, PartialRing};
/// let mut text = String::from("time_s,transducer,range_mm,odom_x_m,odom_y_m,odom_theta_rad\n");
/// for (i, t) in [0, 1, 2, 0].iter().enumerate() {
///     text += &format!("{i},{t},1000,0,0,0\n");
/// }
/// let mut log = read(&text, 3).unwrap();
/// assert_eq!(drop_partial_last_ring(&mut log, 3), Some(PartialRing { readings: 1, line: 5 }));
/// assert_eq!(log.rows.len(), 3);
/// assert_eq!(drop_partial_last_ring(&mut log, 3), None);
/// ```
pub fn drop_partial_last_ring(log: &mut Log, ring: usize) -> Option<PartialRing> {
    let c = cycles(&log.rows);
    let last = c.last()?;
    if c.len() < 2 || last.len() >= ring || c[c.len() - 2].len() != ring {
        return None;
    }
    let dropped = PartialRing { readings: last.len(), line: last[0].line };
    log.rows.truncate(log.rows.len() - dropped.readings);
    Some(dropped)
}

/// Reads a log file for a ring of `ring` transducers; errors name the file and the line.
pub fn read_file(path: &std::path::Path, ring: usize) -> Result<Log, crate::LabError> {
    let text = std::fs::read_to_string(path).map_err(|e| crate::LabError(format!("{}: {e}", path.display())))?;
    read(&text, ring).map_err(|e| crate::LabError(format!("{}: {e}", path.display())))
}

/// Writes `rows` in the format, with the reference columns when
/// `with_reference`. Numbers are written in Rust's shortest form that reads
/// back to the same `f64`, so [`read`] gives the very same rows.
pub fn write(rows: &[Row], with_reference: bool) -> String {
    let mut out = COLUMNS.join(",");
    if with_reference {
        out.push(',');
        out.push_str(&REFERENCE_COLUMNS.join(","));
    }
    out.push('\n');
    for r in rows {
        let range = r.range_mm.map(|v| v.to_string()).unwrap_or_default();
        let [x, y, th] = r.odometry;
        out.push_str(&format!("{},{},{range},{x},{y},{th}", r.time_s, r.transducer));
        if with_reference {
            match r.reference {
                Some([a, b, c]) => out.push_str(&format!(",{a},{b},{c}")),
                None => out.push_str(",,,"),
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests;

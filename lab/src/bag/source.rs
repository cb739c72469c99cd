//! Opening a bag: a rosbag2 directory (its `metadata.yaml` naming the
//! storage files, in order) or a bare `.mcap` or `.db3` file, and every
//! message of the types echoloc reads, grouped by topic. Two storages:
//! MCAP (here) and sqlite3 (`super::sqlite`), each file read by what it is
//! (a `.db3` name or SQLite's magic bytes), both giving the same
//! [`Messages`].

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::msgs::types;
use super::{sqlite, BagError};

pub use super::stored::{Messages, Stored, Topic};

/// `metadata.yaml`, as far as echoloc reads it.
#[derive(Deserialize)]
struct Metadata {
    rosbag2_bagfile_information: Info,
}

#[derive(Deserialize)]
struct Info {
    storage_identifier: String,
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_mode: String,
    #[serde(default)]
    compression_format: String,
}

/// The storage files (MCAP or sqlite3) of the bag at `path`: a
/// directory's `metadata.yaml` names them; a file is one.
pub fn files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if !path.is_dir() {
        if !path.exists() {
            return Err(BagError::Io { path: path.into(), problem: "no such file or directory".into() });
        }
        return Ok(vec![path.into()]);
    }
    let meta = path.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta).map_err(|e| BagError::Io {
        path: meta.clone(),
        problem: format!("{e} (a rosbag2 directory has a metadata.yaml; or give the .mcap or .db3 file itself)"),
    })?;
    let m: Metadata =
        serde_norway::from_str(&text).map_err(|e| BagError::Metadata { path: meta.clone(), problem: e.to_string() })?;
    let info = m.rosbag2_bagfile_information;
    if !matches!(info.storage_identifier.as_str(), "mcap" | "sqlite3") {
        return Err(BagError::Metadata {
            path: meta,
            problem: format!(
                "storage_identifier {:?}: echoloc reads rosbag2's mcap (the default since Iron) and sqlite3 \
                 (Humble's) storages",
                info.storage_identifier
            ),
        });
    }
    if !info.compression_mode.is_empty() && info.compression_mode != "NONE" {
        return Err(BagError::Metadata {
            path: meta,
            problem: format!(
                "compression_mode {} ({}): rosbag2's own file or message compression is not read \
                 (MCAP's chunk compression is; re-record with a storage preset, or `ros2 bag convert`)",
                info.compression_mode, info.compression_format
            ),
        });
    }
    if info.relative_file_paths.is_empty() {
        return Err(BagError::Metadata { path: meta, problem: "relative_file_paths is empty".into() });
    }
    Ok(info.relative_file_paths.iter().map(|f| path.join(f)).collect())
}

/// The types a sonar bag's messages are read from.
pub const SONAR_TYPES: &[&str] = &[types::RANGE, types::POINT_CLOUD, types::ODOMETRY, types::POSE_COV, types::TF];

/// Reads every message of `files` of the types a sonar bag is read from
/// ([`SONAR_TYPES`]), checking each MCAP chunk's CRC.
pub fn read(files: &[PathBuf]) -> Result<Messages, BagError> {
    read_types(files, SONAR_TYPES)
}

/// Reads every message of `files` whose type is one of `wanted` (the other
/// topics are only counted: a laser's scans are large, and a sonar replay
/// has no use for them), checking each MCAP chunk's CRC. A file named
/// `.db3`, or one that starts with SQLite's magic bytes, is read as
/// rosbag2's sqlite3 storage; any other as MCAP.
pub fn read_types(files: &[PathBuf], wanted: &[&str]) -> Result<Messages, BagError> {
    let mut out = Messages::default();
    for f in files {
        if sqlite::is_db3(f) {
            sqlite::read_file(f, wanted, &mut out)?;
            continue;
        }
        let bytes = std::fs::read(f).map_err(|e| BagError::Io { path: f.clone(), problem: e.to_string() })?;
        if bytes.starts_with(sqlite::MAGIC) {
            sqlite::read_file(f, wanted, &mut out)?;
        } else {
            read_bytes_of(&bytes, f, wanted, &mut out)?;
        }
    }
    Ok(out)
}

/// Checks the framing of an MCAP file's records before the `mcap` crate
/// streams it: every top-level record within the file, and every record of
/// an uncompressed chunk within its chunk. (`mcap` 0.26's linear reader
/// subtracts an inner record's length from what its chunk has left without
/// checking: found by the `bag` fuzz target, a record running past its chunk
/// underflows there, a panic with overflow checks, a misread without.)
pub fn check_framing(bytes: &[u8]) -> Result<(), String> {
    const MAGIC: &[u8] = b"\x89MCAP0\r\n";
    if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
        return Err("not an MCAP file (no magic bytes)".into());
    }
    let mut at = MAGIC.len();
    // Records until the footer (0x02) or the end; the trailing magic after the footer.
    while at + 9 <= bytes.len() {
        let op = bytes[at];
        let len = u64_at(bytes, at + 1).unwrap_or(u64::MAX);
        let body = at + 9;
        let end = usize::try_from(len).ok().and_then(|l| body.checked_add(l)).filter(|&e| e <= bytes.len());
        let Some(end) = end else {
            return Err(format!(
                "the {} record at byte {at} claims {len} bytes, past the file's end (a truncated file?)",
                record_name(op)
            ));
        };
        if op == 0x02 {
            return Ok(());
        }
        check_fields(op, &bytes[body..end]).map_err(|e| format!("the {} record at byte {at}: {e}", record_name(op)))?;
        if op == 0x06 {
            let chunk = &bytes[body..end];
            let clen = u32_at(chunk, 28).map(|v| v as usize);
            let records_at = clen.and_then(|c| c.checked_add(32));
            let rlen = records_at.and_then(|r| u64_at(chunk, r)).and_then(|v| usize::try_from(v).ok());
            let (Some(clen), Some(records_at), Some(rlen)) = (clen, records_at, rlen) else {
                return Err(format!("chunk at byte {at}: its header runs past its end"));
            };
            let start = records_at + 8;
            if start.checked_add(rlen).is_none_or(|e| e > chunk.len()) {
                return Err(format!("chunk at byte {at}: its records claim {rlen} bytes, past its end"));
            }
            if clen == 0 {
                let records = &chunk[start..start + rlen];
                let mut r = 0usize;
                while r < records.len() {
                    let inner = u64_at(records, r + 1).and_then(|v| usize::try_from(v).ok());
                    let next = inner.and_then(|l| (r + 9).checked_add(l)).filter(|&n| n <= records.len());
                    let Some(next) = next else {
                        return Err(format!(
                            "chunk at byte {at}: the record at byte {} runs past the chunk's end",
                            body + start + r
                        ));
                    };
                    let inner_op = records[r];
                    check_fields(inner_op, &records[r + 9..next]).map_err(|e| {
                        let name = record_name(inner_op);
                        format!("chunk at byte {at}: the {name} record at byte {}: {e}", body + start + r)
                    })?;
                    r = next;
                }
            }
        }
        at = end;
    }
    if at < bytes.len() {
        return Err(format!("the file ends inside the record at byte {at}"));
    }
    Ok(())
}

/// The little-endian `u64` at `at` in `b`, if `b` holds it.
fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    b.get(at..at.checked_add(8)?).map(|s| u64::from_le_bytes(s.try_into().unwrap_or([0; 8])))
}

/// The little-endian `u32` at `at` in `b`, if `b` holds it.
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    b.get(at..at.checked_add(4)?).map(|s| u32::from_le_bytes(s.try_into().unwrap_or([0; 4])))
}

/// A field of an MCAP record's body, as the specification lays it out.
#[derive(Clone, Copy)]
enum Field {
    /// So many bytes.
    Fixed(usize),
    /// A `u32` length and that many bytes (a string, or bytes).
    Prefixed32,
    /// A `u64` length and that many bytes.
    Prefixed64,
    /// A `u32` length and that many bytes of string pairs.
    StringMap,
    /// The rest of the body.
    Rest,
}

/// Checks that every length-prefixed field of an MCAP record's body
/// (`op`'s layout in the specification) lies within the body. (`mcap`
/// 0.26 allocates a string or a map by its stated length before reading
/// it: found by the `bag` fuzz target, a Header whose profile claimed
/// 4 GiB in a 26-byte record made it ask for 4 GiB.) Unknown opcodes and
/// a chunk's records (checked by the caller) are left alone.
fn check_fields(op: u8, body: &[u8]) -> Result<(), String> {
    use Field::{Fixed, Prefixed32, Prefixed64, Rest, StringMap};
    let layout: &[Field] = match op {
        0x01 => &[Prefixed32, Prefixed32],
        0x03 => &[Fixed(2), Prefixed32, Prefixed32, Prefixed32],
        0x04 => &[Fixed(4), Prefixed32, Prefixed32, StringMap],
        0x06 => &[Fixed(28), Prefixed32, Prefixed64],
        0x07 => &[Fixed(2), Prefixed32],
        0x08 => &[Fixed(32), Prefixed32, Fixed(8), Prefixed32, Fixed(16)],
        0x09 => &[Fixed(16), Prefixed32, Prefixed32, Prefixed64, Fixed(4)],
        0x0A => &[Fixed(40), Prefixed32, Prefixed32],
        0x0B => &[Fixed(42), Prefixed32],
        0x0C => &[Prefixed32, StringMap],
        0x0D => &[Fixed(16), Prefixed32],
        _ => &[Rest],
    };
    let mut at = 0usize;
    for (i, f) in layout.iter().enumerate() {
        let (width, len) = match f {
            Fixed(n) => (0, Some(*n as u64)),
            Prefixed32 | StringMap => (4, u32_at(body, at).map(u64::from)),
            Prefixed64 => (8, u64_at(body, at)),
            Rest => return Ok(()),
        };
        let end = len
            .and_then(|l| usize::try_from(l).ok())
            .and_then(|l| (at + width).checked_add(l))
            .filter(|&e| e <= body.len());
        let Some(end) = end else {
            return Err(format!("its field {} claims {} bytes, past the record's end", i + 1, len.unwrap_or(u64::MAX)));
        };
        if matches!(f, StringMap) {
            // Pairs of strings, each within the map.
            let map = &body[at + 4..end];
            let mut m = 0usize;
            while m < map.len() {
                let n = u32_at(map, m).map(|n| n as usize);
                let Some(next) = n.and_then(|n| (m + 4).checked_add(n)).filter(|&e| e <= map.len()) else {
                    return Err(format!("a string of its field {} runs past the field's end", i + 1));
                };
                m = next;
            }
        }
        at = end;
    }
    Ok(())
}

/// The MCAP record type of `op`.
fn record_name(op: u8) -> &'static str {
    match op {
        0x01 => "header",
        0x02 => "footer",
        0x03 => "schema",
        0x04 => "channel",
        0x05 => "message",
        0x06 => "chunk",
        0x07 => "message index",
        0x08 => "chunk index",
        0x09 => "attachment",
        0x0A => "attachment index",
        0x0B => "statistics",
        0x0C => "metadata",
        0x0D => "metadata index",
        0x0E => "summary offset",
        0x0F => "data end",
        _ => "unknown",
    }
}

/// Adds the messages of one MCAP file's bytes of [`SONAR_TYPES`] to `out`;
/// `path` names it in errors.
pub fn read_bytes(bytes: &[u8], path: &Path, out: &mut Messages) -> Result<(), BagError> {
    read_bytes_of(bytes, path, SONAR_TYPES, out)
}

/// Adds the messages of one MCAP file's bytes whose type is one of `wanted`
/// to `out`; `path` names it in errors.
pub fn read_bytes_of(bytes: &[u8], path: &Path, wanted: &[&str], out: &mut Messages) -> Result<(), BagError> {
    check_framing(bytes).map_err(|problem| BagError::Unreadable { path: path.into(), problem })?;
    let unreadable = |e: mcap::McapError| BagError::Unreadable { path: path.into(), problem: e.to_string() };
    let stream = mcap::MessageStream::new_with_options(bytes, mcap::read::Options::ValidateChunkCrcs.into())
        .map_err(unreadable)?;
    for m in stream {
        let m = m.map_err(unreadable)?;
        let ch = &m.channel;
        let ty = ch.schema.as_ref().map_or(String::new(), |s| s.name.clone());
        let topic = out.topics.entry(ch.topic.clone()).or_insert_with(|| Topic {
            name: ch.topic.clone(),
            ty: ty.clone(),
            count: 0,
        });
        if topic.ty != ty {
            return Err(BagError::Unreadable {
                path: path.into(),
                problem: format!("topic {} carries two types, {} and {ty}", ch.topic, topic.ty),
            });
        }
        topic.count += 1;
        if !wanted.contains(&ty.as_str()) {
            continue;
        }
        let schema_encoding = ch.schema.as_ref().map_or("", |s| s.encoding.as_str());
        if ch.message_encoding != "cdr" || !matches!(schema_encoding, "ros2msg" | "ros2idl") {
            return Err(BagError::Encoding {
                topic: ch.topic.clone(),
                problem: format!(
                    "message encoding {:?}, schema encoding {schema_encoding:?}: a ROS 2 bag's are \"cdr\" \
                     and \"ros2msg\"",
                    ch.message_encoding
                ),
            });
        }
        out.by_topic
            .entry(ch.topic.clone())
            .or_default()
            .push(Stored { log_time: m.log_time, data: m.data.into_owned() });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An MCAP written by the `mcap` crate without compression, one message.
    fn small() -> Vec<u8> {
        let mut w = mcap::WriteOptions::new().compression(None).create(std::io::Cursor::new(Vec::new())).unwrap();
        let s = w.add_schema("nav_msgs/msg/Odometry", "ros2msg", b"").unwrap();
        let c = w.add_channel(s, "/odom", "cdr", &Default::default()).unwrap();
        let h = mcap::records::MessageHeader { channel_id: c, sequence: 1, log_time: 5, publish_time: 5 };
        w.write_to_known_channel(&h, &[0, 1, 0, 0, 1, 2, 3, 4]).unwrap();
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    /// The `bag` fuzz target's find: a record inside an uncompressed chunk
    /// that runs past the chunk is refused before `mcap` reads it.
    #[test]
    fn a_record_running_past_its_chunk_is_refused() {
        let good = small();
        let mut m = Messages::default();
        read_bytes(&good, Path::new("good.mcap"), &mut m).unwrap();
        assert_eq!(m.topics["/odom"].count, 1);
        // Find the chunk (opcode 0x06) and lengthen its first record by 64 bytes.
        let mut at = 8;
        let mut bad = good.clone();
        loop {
            let len = u64::from_le_bytes(good[at + 1..at + 9].try_into().unwrap()) as usize;
            if good[at] == 0x06 {
                let clen = u32::from_le_bytes(good[at + 9 + 28..at + 9 + 32].try_into().unwrap()) as usize;
                let first = at + 9 + 32 + clen + 8;
                let inner = u64::from_le_bytes(good[first + 1..first + 9].try_into().unwrap());
                bad[first + 1..first + 9].copy_from_slice(&(inner + 64).to_le_bytes());
                break;
            }
            at += 9 + len;
        }
        let e = read_bytes(&bad, Path::new("bad.mcap"), &mut Messages::default()).unwrap_err().to_string();
        assert!(
            e.starts_with("bad.mcap: unreadable MCAP: chunk at byte") && e.contains("runs past the chunk's end"),
            "{e}"
        );
        assert!(check_framing(b"not mcap").unwrap_err().contains("no magic"));
        assert!(check_framing(&good).is_ok());
        assert!(check_framing(&good[..good.len() - 30]).is_err(), "a file cut in its summary");
    }

    /// The `bag` fuzz target's second find: a Header (the first record)
    /// whose profile string claims 4 GiB is refused before `mcap` allocates
    /// it; so is every record's string that runs past its record.
    #[test]
    fn a_string_longer_than_its_record_is_refused() {
        let good = small();
        assert_eq!(good[8], 0x01, "the first record is the Header");
        let mut bad = good.clone();
        bad[17..21].copy_from_slice(&0xFFFF_0004u32.to_le_bytes());
        let e = read_bytes(&bad, Path::new("bad.mcap"), &mut Messages::default()).unwrap_err().to_string();
        assert!(e.contains("the header record at byte 8: its field 1 claims 4294901764 bytes"), "{e}");
        // Every record of a good file passes, and one byte more in any
        // record's first length-prefixed field is refused.
        let mut at = 8;
        let mut seen = 0;
        while good[at] != 0x02 {
            let len = u64::from_le_bytes(good[at + 1..at + 9].try_into().unwrap()) as usize;
            let body = &good[at + 9..at + 9 + len];
            assert!(check_fields(good[at], body).is_ok(), "record {:#x} at {at}", good[at]);
            let first = match good[at] {
                0x01 | 0x0C => Some(0),
                0x03 | 0x07 => Some(2),
                0x04 => Some(4),
                0x0D => Some(16),
                _ => None,
            };
            if let Some(f) = first {
                let mut b = body.to_vec();
                let n = u32::from_le_bytes(b[f..f + 4].try_into().unwrap());
                let past = (len - f - 4) as u32 + 1;
                b[f..f + 4].copy_from_slice(&past.max(n + 1).to_le_bytes());
                assert!(check_fields(good[at], &b).is_err(), "record {:#x} at {at}", good[at]);
                seen += 1;
            }
            at += 9 + len;
        }
        assert!(seen >= 2, "{seen}");
    }
}

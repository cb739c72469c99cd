//! Opening a bag: a rosbag2 directory (its `metadata.yaml` naming the MCAP
//! files, in order) or a bare `.mcap` file, and every message of the types
//! echoloc reads, grouped by topic.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::msgs::types;
use super::BagError;

/// One message as stored: its topic's index in [`Messages::topics`], and
/// its CDR bytes.
#[derive(Clone, Debug)]
pub struct Stored {
    /// rosbag2's receive time, ns.
    pub log_time: u64,
    /// The CDR bytes.
    pub data: Vec<u8>,
}

/// A topic of the bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Topic {
    /// The topic's name.
    pub name: String,
    /// Its type (`sensor_msgs/msg/Range`), from the channel's schema.
    pub ty: String,
    /// Messages on it.
    pub count: usize,
}

/// Every topic of the bag, and the messages of the topics whose type echoloc reads.
#[derive(Debug, Default)]
pub struct Messages {
    /// All topics, by name.
    pub topics: BTreeMap<String, Topic>,
    /// The messages of the topics echoloc can read, by topic, in file order.
    pub by_topic: BTreeMap<String, Vec<Stored>>,
}

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

/// The MCAP files of the bag at `path`: a directory's `metadata.yaml`
/// names them; a file is one.
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
        problem: format!("{e} (a rosbag2 directory has a metadata.yaml; or give the .mcap file itself)"),
    })?;
    let m: Metadata =
        serde_norway::from_str(&text).map_err(|e| BagError::Metadata { path: meta.clone(), problem: e.to_string() })?;
    let info = m.rosbag2_bagfile_information;
    if info.storage_identifier != "mcap" {
        return Err(BagError::Metadata {
            path: meta,
            problem: format!(
                "storage_identifier {:?}: echoloc reads MCAP, rosbag2's default since Iron \
                 (convert with `ros2 bag convert` to storage mcap)",
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

/// Whether echoloc reads messages of type `ty`.
fn wanted(ty: &str) -> bool {
    [types::RANGE, types::POINT_CLOUD, types::ODOMETRY, types::POSE_COV, types::TF].contains(&ty)
}

/// Reads every message of `files`, checking each chunk's CRC.
pub fn read(files: &[PathBuf]) -> Result<Messages, BagError> {
    let mut out = Messages::default();
    for f in files {
        let bytes = std::fs::read(f).map_err(|e| BagError::Io { path: f.clone(), problem: e.to_string() })?;
        read_bytes(&bytes, f, &mut out)?;
    }
    Ok(out)
}

/// Adds the messages of one MCAP file's bytes to `out`; `path` names it in errors.
pub fn read_bytes(bytes: &[u8], path: &Path, out: &mut Messages) -> Result<(), BagError> {
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
        if !wanted(&ty) {
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

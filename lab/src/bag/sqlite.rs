//! rosbag2's sqlite3 storage (`.db3`, ROS 2 Humble's default): the same
//! [`Messages`] as an MCAP file gives, so every check downstream is the same.
//!
//! rosbag2 keeps a bag's topics and messages in two tables (Foxy to Jazzy;
//! Iron added `type_description_hash` to `topics`, Jazzy a
//! `message_definitions` table, Humble a `schema` and a `metadata` table):
//!
//! ```sql
//! CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
//!   serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
//! CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
//!   timestamp INTEGER NOT NULL, data BLOB NOT NULL);
//! ```
//!
//! Only `topics(id, name, type, serialization_format)` and
//! `messages(id, topic_id, timestamp, data)` are read, so every layout
//! since Foxy reads alike. Messages are taken in the order they were
//! recorded (`id`, the order rosbag2's writer inserted them in, as the MCAP
//! path takes a file's order), and `data` is the message's CDR bytes as
//! MCAP stores them. The file is opened read-only and never written.

use std::collections::BTreeMap;
use std::path::Path;

use rusqlite::types::ValueRef;
use rusqlite::{Connection, ErrorCode, OpenFlags};

use super::stored::{Messages, Stored, Topic};
use super::BagError;

/// The first 16 bytes of every SQLite 3 database file.
pub const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// Whether `path` names a rosbag2 sqlite3 storage file by its extension
/// (`.db3`, as rosbag2 names them).
pub fn is_db3(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("db3"))
}

/// A rosbag2 topic as its `topics` row has it.
struct TopicRow {
    name: String,
    ty: String,
    format: String,
}

/// What SQLite's error says, in a reader's words for the two a wrong file
/// gives.
fn problem(e: &rusqlite::Error) -> String {
    match e.sqlite_error_code() {
        Some(ErrorCode::NotADatabase) => format!("not a SQLite database ({e}): a rosbag2 .db3 file is one"),
        Some(ErrorCode::DatabaseCorrupt) => format!("a damaged SQLite database ({e}): a truncated file?"),
        _ => e.to_string(),
    }
}

/// What an SQLite value is, in words.
fn kind(v: ValueRef<'_>) -> &'static str {
    match v {
        ValueRef::Null => "NULL",
        ValueRef::Integer(_) => "an integer",
        ValueRef::Real(_) => "a real",
        ValueRef::Text(_) => "text",
        ValueRef::Blob(_) => "a blob",
    }
}

/// Adds the messages of the sqlite3 storage file at `path` whose type is
/// one of `wanted` to `out` (the other topics only counted), as
/// [`super::source::read_bytes_of`] does for an MCAP file.
pub fn read_file(path: &Path, wanted: &[&str], out: &mut Messages) -> Result<(), BagError> {
    let err = |problem: String| BagError::Sqlite { path: path.into(), problem };
    let sql = |e: rusqlite::Error| err(problem(&e));
    if !path.is_file() {
        return Err(BagError::Io { path: path.into(), problem: "no such file".into() });
    }
    // Read-only: a bag is never written, and a missing file is not created.
    let db = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX)
        .map_err(sql)?;
    let tables: Vec<String> = db
        .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
        .and_then(|mut s| s.query_map([], |r| r.get(0))?.collect())
        .map_err(sql)?;
    for t in ["topics", "messages"] {
        if !tables.iter().any(|x| x == t) {
            let have = if tables.is_empty() { "none".to_string() } else { tables.join(", ") };
            return Err(err(format!(
                "no table \"{t}\" (rosbag2's sqlite3 storage keeps its topics and messages in tables \"topics\" \
                 and \"messages\"; tables: {have})"
            )));
        }
    }
    let mut topics: BTreeMap<i64, TopicRow> = BTreeMap::new();
    {
        let mut s = db.prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id").map_err(sql)?;
        let mut rows = s.query([]).map_err(sql)?;
        while let Some(r) = rows.next().map_err(sql)? {
            let id: i64 = r.get(0).map_err(sql)?;
            let text = |i: usize| -> Result<String, BagError> {
                r.get::<_, String>(i).map_err(|e| err(format!("topics row id {id}: {}", problem(&e))))
            };
            let row = TopicRow { name: text(1)?, ty: text(2)?, format: text(3)? };
            if topics.insert(id, row).is_some() {
                return Err(err(format!("two topics rows have id {id}")));
            }
        }
    }
    let mut s = db.prepare("SELECT id, topic_id, timestamp, data FROM messages ORDER BY id").map_err(sql)?;
    let mut rows = s.query([]).map_err(sql)?;
    while let Some(r) = rows.next().map_err(sql)? {
        let id: i64 = r.get(0).map_err(sql)?;
        let topic_id =
            r.get::<_, i64>(1).map_err(|e| err(format!("messages row id {id}: topic_id: {}", problem(&e))))?;
        let Some(t) = topics.get(&topic_id) else {
            return Err(err(format!(
                "messages row id {id}: topic_id {topic_id} is not in the topics table (ids: {})",
                topics.keys().map(i64::to_string).collect::<Vec<_>>().join(", ")
            )));
        };
        let topic = out.topics.entry(t.name.clone()).or_insert_with(|| Topic {
            name: t.name.clone(),
            ty: t.ty.clone(),
            count: 0,
        });
        if topic.ty != t.ty {
            return Err(err(format!("topic {} carries two types, {} and {}", t.name, topic.ty, t.ty)));
        }
        // The message's index on its topic, as every later error names it.
        let index = topic.count;
        topic.count += 1;
        if !wanted.contains(&t.ty.as_str()) {
            continue;
        }
        if t.format != "cdr" {
            return Err(BagError::Encoding {
                topic: t.name.clone(),
                problem: format!("serialization_format {:?}: a ROS 2 bag's is \"cdr\"", t.format),
            });
        }
        let at = |what: String| err(format!("topic {}, message {index} (messages row id {id}): {what}", t.name));
        let log_time = match r.get_ref(2).map_err(sql)? {
            ValueRef::Integer(v) => u64::try_from(v).map_err(|_| at(format!("timestamp {v} is negative")))?,
            v => return Err(at(format!("timestamp is {}, not an integer", kind(v)))),
        };
        let data = match r.get_ref(3).map_err(sql)? {
            ValueRef::Blob(b) => b.to_vec(),
            v => return Err(at(format!("data is {}, not a blob of CDR bytes", kind(v)))),
        };
        out.by_topic.entry(t.name.clone()).or_default().push(Stored { log_time, data });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bag::msgs::types;
    use crate::bag::source::SONAR_TYPES;

    /// A fresh scratch directory for one test.
    fn scratch(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("echoloc-sqlite-unit-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A bag in ROS 2 Humble's layout (rosbag2's schema version 3: no
    /// `type_description_hash`, no `message_definitions`), written here
    /// with SQL, independent of any rosbag2 writer: an Odometry topic, a
    /// Range topic, a String topic echoloc does not read, messages inserted
    /// out of topic order.
    fn humble(path: &Path) -> Connection {
        let db = Connection::open(path).unwrap();
        db.execute_batch(
            "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
             INSERT INTO schema VALUES (3, 'humble');
             CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
             CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
               serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL,
               data BLOB NOT NULL);
             CREATE INDEX timestamp_idx ON messages (timestamp ASC);
             INSERT INTO topics VALUES (1, '/odom', 'nav_msgs/msg/Odometry', 'cdr', '');
             INSERT INTO topics VALUES (2, '/sonar/0', 'sensor_msgs/msg/Range', 'cdr', '');
             INSERT INTO topics VALUES (7, '/chatter', 'std_msgs/msg/String', 'cdr', '');
             INSERT INTO messages VALUES (1, 1, 100, X'0001000001');
             INSERT INTO messages VALUES (2, 2, 150, X'0001000002');
             INSERT INTO messages VALUES (3, 7, 160, X'00010000');
             INSERT INTO messages VALUES (4, 1, 200, X'0001000003');
             INSERT INTO messages VALUES (5, 1, 190, X'0001000004');",
        )
        .unwrap();
        db
    }

    #[test]
    fn a_humble_layout_reads_as_messages_in_recorded_order() {
        let d = scratch("humble");
        let f = d.join("run_0.db3");
        drop(humble(&f));
        let before = std::fs::read(&f).unwrap();
        let mut m = Messages::default();
        read_file(&f, SONAR_TYPES, &mut m).unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), before, "the file is read, never written");
        assert_eq!(m.topics.len(), 3);
        assert_eq!(m.topics["/odom"], Topic { name: "/odom".into(), ty: types::ODOMETRY.into(), count: 3 });
        assert_eq!(m.topics["/chatter"].count, 1, "a topic echoloc does not read is counted");
        assert!(!m.by_topic.contains_key("/chatter"), "and not kept");
        // Row order (the recorder's), not timestamp order: 200 before 190.
        let odom: Vec<(u64, Vec<u8>)> = m.by_topic["/odom"].iter().map(|s| (s.log_time, s.data.clone())).collect();
        assert_eq!(odom, [(100, vec![0, 1, 0, 0, 1]), (200, vec![0, 1, 0, 0, 3]), (190, vec![0, 1, 0, 0, 4])]);
        assert_eq!(m.by_topic["/sonar/0"].len(), 1);
        // Two files of one bag add up, each with its own topic ids.
        read_file(&f, SONAR_TYPES, &mut m).unwrap();
        assert_eq!(m.topics["/odom"].count, 6);
        assert_eq!(m.by_topic["/odom"].len(), 6);
    }

    /// The refusals, each naming what is wrong.
    #[test]
    fn malformed_files_are_refused_by_name() {
        let d = scratch("bad");
        let refuse = |name: &str, change: &str| -> String {
            let f = d.join(format!("{name}.db3"));
            let db = humble(&f);
            db.execute_batch(change).unwrap();
            drop(db);
            read_file(&f, SONAR_TYPES, &mut Messages::default()).unwrap_err().to_string()
        };
        let e = refuse("no-messages", "DROP TABLE messages;");
        assert!(e.ends_with("no-messages.db3: unreadable sqlite3 bag: no table \"messages\" (rosbag2's sqlite3 storage keeps its topics and messages in tables \"topics\" and \"messages\"; tables: metadata, schema, topics)"), "{e}");
        let e = refuse("no-topics", "DROP TABLE topics;");
        assert!(e.contains("no table \"topics\""), "{e}");
        let e = refuse("no-column", "ALTER TABLE topics DROP COLUMN serialization_format;");
        assert!(e.contains("unreadable sqlite3 bag: no such column: serialization_format"), "{e}");
        let e = refuse("orphan", "UPDATE messages SET topic_id = 99 WHERE id = 4;");
        assert!(e.ends_with("messages row id 4: topic_id 99 is not in the topics table (ids: 1, 2, 7)"), "{e}");
        let e = refuse("json", "UPDATE topics SET serialization_format = 'json' WHERE id = 2;");
        assert_eq!(e, "topic /sonar/0: serialization_format \"json\": a ROS 2 bag's is \"cdr\"");
        // Only the topics echoloc reads must be CDR.
        let f = d.join("other.db3");
        let db = humble(&f);
        db.execute_batch("UPDATE topics SET serialization_format = 'json' WHERE id = 7;").unwrap();
        drop(db);
        read_file(&f, SONAR_TYPES, &mut Messages::default()).unwrap();
        let e = refuse("text", "UPDATE messages SET data = 'text' WHERE id = 4;");
        assert!(
            e.ends_with("topic /odom, message 1 (messages row id 4): data is text, not a blob of CDR bytes"),
            "{e}"
        );
        let e = refuse("negative", "UPDATE messages SET timestamp = -5 WHERE id = 5;");
        assert!(e.ends_with("topic /odom, message 2 (messages row id 5): timestamp -5 is negative"), "{e}");
        let e = refuse("two-types", "UPDATE topics SET name = '/odom' WHERE id = 2;");
        assert!(e.ends_with("topic /odom carries two types, nav_msgs/msg/Odometry and sensor_msgs/msg/Range"), "{e}");
    }

    /// Files that are not SQLite, or a SQLite file cut short: a typed
    /// error, never a panic, and nothing created.
    #[test]
    fn not_sqlite_and_truncated_files() {
        let d = scratch("notdb");
        let text = d.join("notes.db3");
        std::fs::write(&text, "these are notes, not a database, and long enough to have a header of a hundred bytes, which SQLite reads first").unwrap();
        let e = read_file(&text, SONAR_TYPES, &mut Messages::default()).unwrap_err().to_string();
        assert!(e.contains("notes.db3: unreadable sqlite3 bag: not a SQLite database"), "{e}");
        let missing = d.join("missing.db3");
        let e = read_file(&missing, SONAR_TYPES, &mut Messages::default()).unwrap_err().to_string();
        assert!(e.ends_with("missing.db3: no such file"), "{e}");
        assert!(!missing.exists(), "opened read-only: nothing created");
        // A bag with enough rows to span pages, cut at each of several lengths.
        let f = d.join("big.db3");
        let db = humble(&f);
        db.execute_batch(
            "WITH RECURSIVE k(i) AS (SELECT 10 UNION ALL SELECT i + 1 FROM k WHERE i < 2000)
             INSERT INTO messages SELECT i, 1, i * 10, randomblob(300) FROM k;",
        )
        .unwrap();
        drop(db);
        let whole = std::fs::read(&f).unwrap();
        assert!(whole.len() > 100_000 && whole.starts_with(MAGIC));
        let mut all = Messages::default();
        read_file(&f, SONAR_TYPES, &mut all).unwrap();
        assert_eq!(all.by_topic["/odom"].len(), 1994);
        let mut refused = Vec::new();
        for cut in [50, 100, 4096, 5000, whole.len() / 3, whole.len() / 2, whole.len() - 4096] {
            let g = d.join(format!("cut-{cut}.db3"));
            std::fs::write(&g, &whole[..cut]).unwrap();
            let mut m = Messages::default();
            match read_file(&g, SONAR_TYPES, &mut m) {
                Err(e) => {
                    assert!(matches!(e, BagError::Sqlite { .. }), "{e}");
                    refused.push(cut);
                }
                // Read whole or not at all: a cut that leaves every message
                // (the index's last page gone) may read, one losing some may not.
                Ok(()) => assert_eq!(m.by_topic.get("/odom").map(Vec::len), Some(1994), "cut at {cut}"),
            }
        }
        assert!(refused.len() >= 5, "a cut file is refused (only at {refused:?})");
        assert!(is_db3(&f) && is_db3(Path::new("a/B.DB3")) && !is_db3(Path::new("a.mcap")));
    }
}

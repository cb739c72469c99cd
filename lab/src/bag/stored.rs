//! A bag's messages as a storage gives them (MCAP in [`super::source`],
//! sqlite3 in `sqlite`), for the readers of each message type.

use std::collections::BTreeMap;

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

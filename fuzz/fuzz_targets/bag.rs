//! ROS 2 bags (lab/src/bag/): the input as a whole MCAP file, then as the
//! CDR messages of a bag with every topic type echoloc reads (Range per
//! transducer and by frame, a RosAria PointCloud, Odometry, /tf, /tf_static,
//! /amcl_pose, a ground truth), through the whole reader: decoding, REP 117,
//! the ring from /tf_static, interpolation. Must return Ok or a BagError,
//! never panic.
#![no_main]

use std::path::Path;

use echoloc_lab::bag::msgs::types;
use echoloc_lab::bag::source::{read_bytes, Messages, Stored, Topic};
use echoloc_lab::bag::{from_messages, Options};
use libfuzzer_sys::fuzz_target;

const TOPICS: [(&str, &str); 8] = [
    ("/sonar/0", types::RANGE),
    ("/sonar/1", types::RANGE),
    ("/sonar", types::POINT_CLOUD),
    ("/odom", types::ODOMETRY),
    ("/tf", types::TF),
    ("/tf_static", types::TF),
    ("/amcl_pose", types::POSE_COV),
    ("/ground_truth", types::ODOMETRY),
];

fuzz_target!(|data: &[u8]| {
    let mut m = Messages::default();
    if let Ok(()) = read_bytes(data, Path::new("fuzz.mcap"), &mut m) {
        let _ = from_messages(&m, &Options::default());
    }
    // The bytes as messages: a selector byte, a length byte, that many bytes.
    let mut m = Messages::default();
    let mut rest = data;
    while let [sel, len, tail @ ..] = rest {
        let n = usize::from(*len).min(tail.len());
        let (name, ty) = TOPICS[usize::from(*sel) % TOPICS.len()];
        let mut msg = vec![0, 1, 0, 0];
        msg.extend_from_slice(&tail[..n]);
        let t = m.topics.entry(name.into()).or_insert_with(|| Topic { name: name.into(), ty: ty.into(), count: 0 });
        t.count += 1;
        m.by_topic.entry(name.into()).or_default().push(Stored { log_time: 0, data: msg });
        rest = &tail[n..];
    }
    for ranges in [vec![], vec!["/sonar".to_string()]] {
        let _ = from_messages(&m, &Options { ranges, ..Options::default() });
    }
});

//! Foxglove out (`docs/foxglove.md`): a run (`simulate`, `replay`) or what a
//! controller sent (`link`) as an MCAP recording a person opens in Foxglove
//! and scrubs, and the same channels served live over Foxglove's WebSocket
//! protocol while it runs (`--live`). Written through Foxglove's own SDK
//! (the `foxglove` crate): its well-known schemas as protobuf, zstd chunks,
//! its WebSocket server. Every message is stamped with the run's own time.
//!
//! | topic | schema | one message |
//! |---|---|---|
//! | `/map` | `foxglove.SceneUpdate` | at the start: the true outlines (blue), the C-space buffers (green), unmapped objects (magenta, simulator only) |
//! | `/tf` | `foxglove.FrameTransforms` | per reading: `map` → `ekf`, `dead_reckoning`, `threshold`, and `truth` where known |
//! | `/pose/ekf`, `/pose/dead_reckoning`, `/pose/threshold`, `/pose/truth` | `foxglove.PoseInFrame` | per reading (truth: per reading that has one) |
//! | `/ekf/covariance` | `foxglove.SceneUpdate` | per reading: the 2σ position ellipse around the estimate |
//! | `/sonar` | `foxglove.SceneUpdate` | per reading: the transducer's sensor window (entity `sonar/N`, replacing its last), the predicted and observed ranges as arcs, coloured by verdict |
//! | `/localization/mode` | `foxglove.Log` | at the start and at each change: searching, tracking or lost, with the reason |
//! | `/particles` | `foxglove.PointCloud` | as drawn at the start (searching from no pose), then per ring cycle while searching or lost, at most 4 a second: x, y, heading, weight |
//! | `/hypotheses` | `foxglove.SceneUpdate` | per ring cycle while searching: with the place test its living places (2σ ellipse, evidence over the null, smallest lead, cycles lived; the best green); the heaviest cluster (2σ ellipse, weight) and the best place found elsewhere (its lead) |
//!
//! [`run::record`] writes a run; [`Recording`] writes any well-known
//! message on a channel:
//!
//! ```
//! use echoloc_lab::foxglove::{scene, Recording};
//! use foxglove::messages::Log;
//!
//! let mut rec = Recording::new()?;
//! let t = 1_500_000_000; // ns
//! rec.write("/localization/mode", t, &Log { timestamp: Some(scene::stamp(t)), level: 2,
//!     message: "tracking".into(), ..Default::default() });
//! let bytes = rec.finish()?;
//! // Read back with Foxglove's own reader.
//! let m = mcap::MessageStream::new(&bytes)?.next().unwrap()?;
//! assert_eq!(m.channel.schema.as_ref().unwrap().name, "foxglove.Log");
//! assert_eq!((m.channel.message_encoding.as_str(), m.log_time), ("protobuf", t));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod controller;
pub mod live;
pub mod run;
pub mod scene;

use std::collections::BTreeMap;
use std::io::Cursor;
use std::sync::Arc;

use foxglove::messages::{FrameTransforms, Log, PointCloud, PoseInFrame, SceneUpdate};
use foxglove::{Channel, Context, McapCompression, McapWriteOptions, McapWriterHandle};

pub use controller::record_link;
pub use run::record;

/// Why a recording could not be written, or the live view not served.
#[derive(Debug)]
pub enum RecordingError {
    /// The SDK refused (the MCAP writer, or the WebSocket server's address).
    Foxglove(foxglove::FoxgloveError),
    /// `--live`'s address does not parse.
    Address(String),
}

impl std::fmt::Display for RecordingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Foxglove(e) => write!(f, "Foxglove SDK: {e}"),
            Self::Address(a) => write!(f, "not a HOST:PORT address: {a:?}"),
        }
    }
}

impl std::error::Error for RecordingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Foxglove(e) => Some(e),
            Self::Address(_) => None,
        }
    }
}

impl From<foxglove::FoxgloveError> for RecordingError {
    fn from(e: foxglove::FoxgloveError) -> Self {
        Self::Foxglove(e)
    }
}

/// The channels of one recording, by topic, one map per schema.
#[derive(Default)]
pub struct Channels {
    scenes: BTreeMap<String, Channel<SceneUpdate>>,
    transforms: BTreeMap<String, Channel<FrameTransforms>>,
    poses: BTreeMap<String, Channel<PoseInFrame>>,
    logs: BTreeMap<String, Channel<Log>>,
    clouds: BTreeMap<String, Channel<PointCloud>>,
}

impl Channels {
    /// The channel of `topic` in `ctx`, made on first use.
    fn get<T: Message>(&mut self, ctx: &Arc<Context>, topic: &str) -> &Channel<T> {
        T::channels(self).entry(topic.to_string()).or_insert_with(|| ctx.channel_builder(topic).build::<T>())
    }
}

/// A well-known Foxglove message this module writes.
pub trait Message: foxglove::Encode + Sized {
    /// Its channels.
    fn channels(c: &mut Channels) -> &mut BTreeMap<String, Channel<Self>>;
}

macro_rules! message {
    ($t:ty, $field:ident) => {
        impl Message for $t {
            fn channels(c: &mut Channels) -> &mut BTreeMap<String, Channel<Self>> {
                &mut c.$field
            }
        }
    };
}
message!(SceneUpdate, scenes);
message!(FrameTransforms, transforms);
message!(PoseInFrame, poses);
message!(Log, logs);
message!(PointCloud, clouds);

/// An MCAP recording being written in memory (written to disk by the caller
/// with the run's other outputs, all or nothing), and optionally served
/// live ([`Recording::serve`]). Its own SDK context: recordings made side by
/// side (tests) never share a channel.
pub struct Recording {
    ctx: Arc<Context>,
    mcap: Option<McapWriterHandle<Cursor<Vec<u8>>>>,
    live: Option<live::Live>,
    channels: Channels,
    counts: BTreeMap<String, u64>,
}

impl Recording {
    /// An empty recording (zstd chunks).
    pub fn new() -> Result<Self, RecordingError> {
        let ctx = Context::new();
        let options = McapWriteOptions::new().compression(Some(McapCompression::Zstd));
        let mcap = ctx.mcap_writer_with_options(options).create(Cursor::new(Vec::new()))?;
        Ok(Self { ctx, mcap: Some(mcap), live: None, channels: Channels::default(), counts: BTreeMap::new() })
    }

    /// Serves every channel live on `addr` (`HOST:PORT`; port 0 picks one)
    /// from the next message on, at `pace` ([`live`]); returns the address
    /// bound.
    pub fn serve(&mut self, addr: &str, pace: live::Pace) -> Result<std::net::SocketAddr, RecordingError> {
        let l = live::Live::start(addr, pace)?;
        let a = l.addr();
        self.live = Some(l);
        Ok(a)
    }

    /// With a live view: advertises `topic` to the viewers before its first
    /// message (the recording is untouched).
    pub fn advertise<T: Message>(&mut self, topic: &str) {
        if let Some(l) = &mut self.live {
            l.advertise::<T>(topic);
        }
    }

    /// With a live view: waits up to `wait` for a viewer to subscribe
    /// ([`live::Live::wait_for_viewer`]); whether one did.
    pub fn wait_for_viewer(&self, wait: std::time::Duration) -> bool {
        self.live.as_ref().is_some_and(|l| l.wait_for_viewer(wait))
    }

    /// Writes `msg` on `topic` (created on first use) at `t_ns`, and sends
    /// it to the live view's viewers.
    pub fn write<T: Message>(&mut self, topic: &str, t_ns: u64, msg: &T) {
        if let Some(l) = &mut self.live {
            l.send(topic, t_ns, msg);
        }
        self.channels.get::<T>(&self.ctx, topic).log_with_time(msg, t_ns);
        *self.counts.entry(topic.to_string()).or_insert(0) += 1;
    }

    /// Writes the map on `/map`, kept for viewers that connect later.
    pub fn write_map(&mut self, t_ns: u64, map: &SceneUpdate) {
        if let Some(l) = &mut self.live {
            l.keep_map(t_ns, map);
        }
        self.write("/map", t_ns, map);
    }

    /// Messages written per topic.
    pub fn counts(&self) -> &BTreeMap<String, u64> {
        &self.counts
    }

    /// Viewers connected now (0 without a live view).
    pub fn viewers(&self) -> usize {
        self.live.as_ref().map_or(0, live::Live::viewers)
    }

    /// Stops the live view (after serving until its viewers have gone, for
    /// at most `hold`) and returns the file's bytes.
    pub fn finish_holding(mut self, hold: std::time::Duration) -> Result<Vec<u8>, RecordingError> {
        if let Some(l) = self.live.take() {
            l.stop(hold);
        }
        let Some(mcap) = self.mcap.take() else { return Ok(Vec::new()) };
        Ok(mcap.close()?.into_inner())
    }

    /// The file's bytes (a live view stops at once).
    pub fn finish(self) -> Result<Vec<u8>, RecordingError> {
        self.finish_holding(std::time::Duration::ZERO)
    }
}

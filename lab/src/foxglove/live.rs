//! The live view (`--live [HOST:PORT]`): the recording's channels served
//! over Foxglove's WebSocket protocol by the SDK's server while the run goes
//! on, so a person opens Foxglove, connects to `ws://HOST:8765` and watches.
//!
//! The viewers have their own SDK context, apart from the recording's: the
//! recording is the same whoever watches. Each viewer has a bounded queue
//! ([`BACKLOG`] messages) that drops its oldest when the viewer is slow, so
//! a slow or gone viewer never stalls the run. A viewer that subscribes to
//! `/map` after it was sent gets the map again (it is sent once per run).

use std::net::{SocketAddr, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{Context, WebSocketServerHandle};

use super::{Channels, Message, RecordingError};

/// Messages queued for one viewer before its oldest are dropped.
pub const BACKLOG: usize = 16_384;

/// The default address, Foxglove's (and `foxglove_bridge`'s) port.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8765";

/// `--live [ADDR]` and `--live-hold-s`, shared by `link` and `replay`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct LiveArgs {
    /// Serves the run live over Foxglove's WebSocket protocol while it runs
    /// (docs/foxglove.md): open Foxglove and connect to ws://ADDR. ADDR defaults
    /// to 127.0.0.1:8765; port 0 picks a free one. The address is printed on
    /// stderr as `live: ws://…`.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = DEFAULT_ADDR)]
    pub live: Option<String>,
    /// After the run, keep serving --live until the viewers have gone, for at most this many seconds.
    #[arg(long = "live-hold-s", default_value_t = 0.0)]
    pub live_hold_s: f64,
    /// Before the run, wait up to this many seconds for a viewer to subscribe
    /// (so that it sees the run from its first message).
    #[arg(long = "live-wait-s", default_value_t = 0.0)]
    pub live_wait_s: f64,
}

impl LiveArgs {
    /// The hold after the run and the wait before it, checked.
    pub fn hold_and_wait(&self) -> Result<(Duration, Duration), String> {
        let d = |v: f64, name: &str| {
            if v.is_finite() && (0.0..=86_400.0).contains(&v) {
                Ok(Duration::from_secs_f64(v))
            } else {
                Err(format!("{name} {v} is not a duration of 0 s to a day"))
            }
        };
        Ok((d(self.live_hold_s, "--live-hold-s")?, d(self.live_wait_s, "--live-wait-s")?))
    }

    /// Serves `rec` if `--live` asks, printing the address on stderr.
    pub fn serve(&self, rec: &mut super::Recording, pace: Pace) -> Result<(), String> {
        if let Some(addr) = &self.live {
            let bound = rec.serve(addr, pace).map_err(|e| format!("--live {addr}: {e}"))?;
            eprintln!("live: ws://{bound}");
        }
        Ok(())
    }
}

/// When a message goes to the viewers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pace {
    /// As soon as it is written (`link`: the controller's own pace).
    AsWritten,
    /// When the wall clock since the first message reaches the run's time
    /// since it, divided by this speed (`replay --live --speed`).
    Speed(f64),
}

/// Counts subscriptions, and asks for the map again when a viewer
/// subscribes to it.
struct Subscriptions {
    map_wanted: Arc<AtomicBool>,
    count: Arc<AtomicUsize>,
}

impl ServerListener for Subscriptions {
    fn on_subscribe(&self, _client: Client, channel: ChannelView) {
        self.count.fetch_add(1, Ordering::AcqRel);
        if channel.topic() == "/map" {
            self.map_wanted.store(true, Ordering::Release);
        }
    }
}

/// A running live view.
pub struct Live {
    ctx: Arc<Context>,
    server: WebSocketServerHandle,
    addr: SocketAddr,
    channels: Channels,
    pace: Pace,
    /// (wall clock, run time ns) of the first message.
    origin: Option<(Instant, u64)>,
    map_wanted: Arc<AtomicBool>,
    /// Subscriptions made so far.
    subscriptions: Arc<AtomicUsize>,
    /// The last `/map` and its time.
    map: Option<(u64, foxglove::messages::SceneUpdate)>,
}

impl Live {
    /// Serves on `addr` (`HOST:PORT`).
    pub fn start(addr: &str, pace: Pace) -> Result<Self, RecordingError> {
        let a = addr
            .to_socket_addrs()
            .ok()
            .and_then(|mut i| i.next())
            .ok_or_else(|| RecordingError::Address(addr.to_string()))?;
        if let Pace::Speed(s) = pace {
            if !(s.is_finite() && s > 0.0) {
                return Err(RecordingError::Address(format!("speed {s} is not a positive number")));
            }
        }
        let ctx = Context::new();
        let map_wanted = Arc::new(AtomicBool::new(false));
        let subscriptions = Arc::new(AtomicUsize::new(0));
        let server = ctx
            .websocket_server()
            .name("echoloc-lab")
            .bind(a.ip().to_string(), a.port())
            .message_backlog_size(BACKLOG)
            .listener(Arc::new(Subscriptions { map_wanted: map_wanted.clone(), count: subscriptions.clone() }))
            .start_blocking()?;
        let addr = SocketAddr::new(a.ip(), server.port());
        Ok(Self {
            ctx,
            server,
            addr,
            channels: Channels::default(),
            pace,
            origin: None,
            map_wanted,
            subscriptions,
            map: None,
        })
    }

    /// The address bound.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Viewers connected now.
    pub fn viewers(&self) -> usize {
        self.server.client_count()
    }

    /// Advertises `topic` before its first message, so that a viewer can
    /// subscribe before the run starts.
    pub fn advertise<T: Message>(&mut self, topic: &str) {
        self.channels.get::<T>(&self.ctx, topic);
    }

    /// Waits up to `wait` for a viewer to subscribe, then until its
    /// subscriptions have settled (no new one for 200 ms); whether one did.
    pub fn wait_for_viewer(&self, wait: Duration) -> bool {
        let end = Instant::now() + wait;
        while self.subscriptions.load(Ordering::Acquire) == 0 {
            if Instant::now() >= end {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let mut seen = self.subscriptions.load(Ordering::Acquire);
        loop {
            std::thread::sleep(Duration::from_millis(200));
            let now = self.subscriptions.load(Ordering::Acquire);
            if now == seen {
                return true;
            }
            seen = now;
        }
    }

    /// Sends `msg` on `topic` to the viewers subscribed to it, once the
    /// run's clock reaches `t_ns` ([`Pace`]).
    pub fn send<T: Message>(&mut self, topic: &str, t_ns: u64, msg: &T) {
        self.wait_until(t_ns);
        if topic == "/map" {
            // Whoever asked for the map before it was sent gets it now.
            self.map_wanted.store(false, Ordering::Release);
        }
        self.channels.get::<T>(&self.ctx, topic).log_with_time(msg, t_ns);
        self.resend_map();
    }

    /// Keeps the map for viewers that subscribe later.
    pub fn keep_map(&mut self, t_ns: u64, map: &foxglove::messages::SceneUpdate) {
        self.map = Some((t_ns, map.clone()));
    }

    fn resend_map(&mut self) {
        if self.map_wanted.swap(false, Ordering::AcqRel) {
            if let (Some((t, m)), Some(c)) = (&self.map, self.channels.scenes.get("/map")) {
                c.log_with_time(m, *t);
            }
        }
    }

    fn wait_until(&mut self, t_ns: u64) {
        let Pace::Speed(speed) = self.pace else { return };
        let (wall, t0) = *self.origin.get_or_insert((Instant::now(), t_ns));
        let due = t_ns.saturating_sub(t0) as f64 / 1e9 / speed;
        let due = wall + Duration::from_secs_f64(due.min(1e9));
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
    }

    /// After the run: keeps serving (the map to late viewers too) until
    /// every viewer has gone or `hold` has passed, then stops.
    pub fn stop(mut self, hold: Duration) {
        let end = Instant::now() + hold;
        while Instant::now() < end && self.viewers() > 0 {
            self.resend_map();
            std::thread::sleep(Duration::from_millis(20));
        }
        self.server.stop().wait_blocking();
    }
}

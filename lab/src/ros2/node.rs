//! The DDS side of `link --ros2`: a ROS 2 node (ros2-client on RustDDS, no
//! ROS installed) that publishes what [`super::bridge`] makes and takes
//! amcl's inputs: `/initialpose` and the `reinitialize_global_localization`
//! service, turned into link commands for the controller, and with
//! `--ros2-odom` the robot's `/odom`, turned into the link's odometry.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use echoloc::link::{FromController, ToController};
use echoloc::predict::Mount;
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, Message, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, QosProfile, ServiceMapping,
    ServiceTypeName,
};
use rustdds::DomainParticipantBuilder;

use super::bridge::{initial_pose_command, Bridge, Out, Sample};
use super::msgs::{DiagnosticArray, Empty, PoseArray, PoseWithCovarianceStamped, RangeOut};
use super::odom::{Anchor, OdomClock, OdomCounts};
use super::{Ros2Args, ServiceMappingArg};
use crate::bag::msgs::{OdometryMsg, TfMessage};
use crate::map::LabError;

impl Message for PoseWithCovarianceStamped {}
impl Message for Empty {}
impl Message for OdometryMsg {}

/// What the node did, for the link's summary.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Ros2Counts {
    pub poses: u32,
    pub tf: u32,
    pub ranges: u32,
    pub diagnostics: u32,
    pub particle_clouds: u32,
    pub initial_poses: u32,
    pub initial_poses_refused: u32,
    pub global_localizations: u32,
    pub publish_errors: u32,
    /// `/odom` taken and refused (`--ros2-odom`).
    pub odometry: Option<OdomCounts>,
}

/// The node, its publishers, and the thread that takes its inputs.
pub struct Ros2Node {
    // Dropped last: the publishers need it.
    node: Node,
    pose: Publisher<PoseWithCovarianceStamped>,
    tf: Publisher<TfMessage>,
    _tf_static: Publisher<TfMessage>,
    ranges: Vec<Publisher<RangeOut>>,
    diagnostics: Publisher<DiagnosticArray>,
    particles: Publisher<PoseArray>,
    bridge: Bridge,
    counts: Arc<Mutex<Ros2Counts>>,
    stop: Arc<AtomicBool>,
    inputs: Option<JoinHandle<()>>,
    linger: Duration,
    pose_topic: String,
    /// The clocks' anchor, for the `/odom` taker.
    anchor: Arc<Mutex<Option<Anchor>>>,
    /// The `/odom` samples sent on, for `map → odom` (`--ros2-odom`).
    odometry_sent: Option<Receiver<Sample>>,
    /// The same samples for the link to send, until it takes them.
    odometry_feed: Option<Receiver<Sample>>,
}

/// Transducer `k`'s Range topic, `/sonar_<k>`, named as its frame: a ROS 2
/// name's token cannot start with a digit, so not the bags' `/sonar/<k>`.
pub fn range_topic(k: usize) -> String {
    format!("/sonar_{k}")
}

/// The host's clock, ns since the epoch.
pub fn now_ns() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

fn err(what: &str) -> impl Fn(ros2_client::CreateError) -> LabError + '_ {
    move |e| LabError(format!("--ros2: {what}: {e:?}"))
}

/// The domain id from `ROS_DOMAIN_ID` (0 when unset), as ROS 2 takes it.
pub fn domain_id() -> Result<u16, LabError> {
    match std::env::var("ROS_DOMAIN_ID") {
        Err(_) => Ok(0),
        Ok(s) if s.trim().is_empty() => Ok(0),
        Ok(s) => s
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|&d| d <= 232)
            .ok_or_else(|| LabError(format!("ROS_DOMAIN_ID={s:?}: not a domain id (0..=232)"))),
    }
}

impl Ros2Node {
    /// Joins the ROS 2 graph as `args` says, for a controller with ring
    /// `mounts` fed `odometry`; commands from ROS go to `commands`.
    pub fn start(
        args: &Ros2Args,
        mounts: &[Mount],
        odometry: &[Sample],
        commands: Sender<ToController>,
    ) -> Result<Self, LabError> {
        let mut b = DomainParticipantBuilder::new(domain_id()?);
        if args.ros2_localhost {
            b = b.with_only_networks([std::net::Ipv4Addr::LOCALHOST]);
        }
        let participant = b.build().map_err(|e| LabError(format!("--ros2: the DDS participant: {e:?}")))?;
        let context = Context::from_domain_participant(participant).map_err(err("the context"))?;
        let name = NodeName::new(&args.ros2_namespace, &args.ros2_node_name)
            .map_err(|e| LabError(format!("--ros2-node-name/--ros2-namespace: {e:?}")))?;
        let mut node = context
            .new_node(name, NodeOptions::new().start_parameter_services(false))
            .map_err(|e| LabError(format!("--ros2: the node: {e:?}")))?;

        // QoS as amcl and tf2 use them.
        let latched = QosProfile::publisher_default()
            .reliability_reliable(WhenFull::DEFAULT)
            .durability(Durability::TransientLocal)
            .history(History::KeepLast { depth: 1 });
        let stream = |depth| {
            QosProfile::publisher_default()
                .reliability_reliable(WhenFull::DEFAULT)
                .durability(Durability::Volatile)
                .history(History::KeepLast { depth })
        };
        let topic = |node: &mut Node, n: &str, pkg: &str, ty: &str, q: &QosProfile| {
            let name = Name::parse(n).map_err(|e| LabError(format!("--ros2: topic {n}: {e:?}")))?;
            node.create_topic(&name, MessageTypeName::new(pkg, ty), q).map_err(err(n))
        };
        let t = topic(&mut node, &args.ros2_pose_topic, "geometry_msgs", "PoseWithCovarianceStamped", &latched)?;
        let pose = node.create_publisher(&t, None).map_err(err("/amcl_pose"))?;
        let tfq = stream(100);
        let t = topic(&mut node, "/tf", "tf2_msgs", "TFMessage", &tfq)?;
        let tf = node.create_publisher(&t, None).map_err(err("/tf"))?;
        let t = topic(&mut node, "/tf_static", "tf2_msgs", "TFMessage", &latched)?;
        let tf_static: Publisher<TfMessage> = node.create_publisher(&t, None).map_err(err("/tf_static"))?;
        let mut ranges = Vec::new();
        for k in 0..mounts.len() {
            let t = topic(&mut node, &range_topic(k), "sensor_msgs", "Range", &stream(10))?;
            ranges.push(node.create_publisher(&t, None).map_err(err("a Range topic"))?);
        }
        let t = topic(&mut node, "/diagnostics", "diagnostic_msgs", "DiagnosticArray", &stream(10))?;
        let diagnostics = node.create_publisher(&t, None).map_err(err("/diagnostics"))?;
        let t = topic(&mut node, "/particlecloud", "geometry_msgs", "PoseArray", &stream(5))?;
        let particles = node.create_publisher(&t, None).map_err(err("/particlecloud"))?;

        let t = topic(&mut node, "/initialpose", "geometry_msgs", "PoseWithCovarianceStamped", &stream(10))?;
        let initial = node.create_subscription::<PoseWithCovarianceStamped>(&t, None).map_err(err("/initialpose"))?;
        let mapping = match args.ros2_service_mapping {
            ServiceMappingArg::Enhanced => ServiceMapping::Enhanced,
            ServiceMappingArg::Cyclone => ServiceMapping::Cyclone,
            ServiceMappingArg::Basic => ServiceMapping::Basic,
        };
        let service = Name::parse("/reinitialize_global_localization").map_err(|e| LabError(format!("{e:?}")))?;
        let server = node
            .create_server::<Empty, Empty>(
                mapping,
                &service,
                &ServiceTypeName::new("std_srvs", "Empty"),
                stream(10),
                stream(10),
            )
            .map_err(err("the global localization service"))?;

        // /odom as the robot's odometry nodes publish it (diff_drive_controller,
        // Gazebo: reliable); deep, so that a burst is not lost between polls.
        let odom = if args.ros2_odom {
            let t = topic(&mut node, &args.ros2_odom_topic, "nav_msgs", "Odometry", &stream(1000))?;
            Some(node.create_subscription::<OdometryMsg>(&t, None).map_err(err("/odom"))?)
        } else {
            None
        };
        let bridge = Bridge::new(args.ros_distro, mounts, odometry).with_base_frame(&args.ros2_base_frame);
        if let Err(e) = tf_static.publish(bridge.static_tf(now_ns())) {
            return Err(LabError(format!("--ros2: /tf_static: {e:?}")));
        }
        let counts = Arc::new(Mutex::new(Ros2Counts::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let anchor = Arc::new(Mutex::new(None));
        let (sent_tx, sent_rx) = std::sync::mpsc::channel();
        let (feed_tx, feed_rx) = std::sync::mpsc::channel();
        let mut clock = odom.as_ref().map(|_| OdomClock::new(&args.ros2_base_frame));
        let (c, s, wide, a) = (counts.clone(), stop.clone(), args.wide(), anchor.clone());
        let inputs = std::thread::spawn(move || {
            let mut tied = None;
            // Polled: a few ms late is nothing beside a ring cycle.
            while !s.load(Ordering::Relaxed) {
                if let (Some(odom), Some(clock)) = (&odom, clock.as_mut()) {
                    let mut refusals = Vec::new();
                    while let Ok(Some((m, _))) = odom.take() {
                        if let Err(why) = clock.push(&m) {
                            refusals.push(why);
                        }
                    }
                    let anchor = *a.lock().unwrap_or_else(|p| p.into_inner());
                    if tied.is_some() && anchor != tied {
                        // A new Hello: the controller's clock began again.
                        clock.restart();
                    }
                    tied = anchor;
                    for r in clock.drain(anchor) {
                        match r {
                            // The bridge first: the controller's reading at this time comes after.
                            Ok(sample) => {
                                let _ = sent_tx.send(sample);
                                let _ = feed_tx.send(sample);
                            }
                            Err(why) => refusals.push(why),
                        }
                    }
                    let n = clock.counts.refused as usize;
                    for (k, why) in refusals.iter().enumerate() {
                        let k = n - refusals.len() + k + 1;
                        if k <= 10 || k.is_multiple_of(1000) {
                            eprintln!("ros2: /odom refused ({k} so far): {why}");
                        }
                    }
                    c.lock().unwrap_or_else(|p| p.into_inner()).odometry = Some(clock.counts.clone());
                }
                while let Ok(Some((m, _))) = initial.take() {
                    let mut c = c.lock().unwrap_or_else(|p| p.into_inner());
                    match initial_pose_command(&m, wide) {
                        Ok(cmd) => {
                            eprintln!("ros2: /initialpose taken: {cmd:?}");
                            c.initial_poses += 1;
                            let _ = commands.send(cmd);
                        }
                        Err(why) => {
                            eprintln!("ros2: /initialpose refused: {why}");
                            c.initial_poses_refused += 1;
                        }
                    }
                }
                while let Ok(Some((id, _))) = server.receive_request() {
                    eprintln!("ros2: reinitialize_global_localization: searching all free space");
                    c.lock().unwrap_or_else(|p| p.into_inner()).global_localizations += 1;
                    let _ = commands.send(ToController::Search { around: None });
                    let _ = server.send_response(id, Empty::default());
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        Ok(Self {
            node,
            pose,
            tf,
            _tf_static: tf_static,
            ranges,
            diagnostics,
            particles,
            bridge,
            counts,
            stop,
            inputs: Some(inputs),
            linger: Duration::from_secs_f64(args.ros2_linger_s.max(0.0)),
            pose_topic: args.ros2_pose_topic.clone(),
            anchor,
            odometry_sent: args.ros2_odom.then_some(sent_rx),
            odometry_feed: args.ros2_odom.then_some(feed_rx),
        })
    }

    /// With `--ros2-odom`: the odometry to send the controller, on its clock, as it comes.
    pub fn take_odometry_feed(&mut self) -> Option<Receiver<Sample>> {
        self.odometry_feed.take()
    }

    /// Waits up to `timeout` until every topic the node publishes per
    /// reading or cycle has a subscriber discovered (and a moment for the
    /// match to settle), so that a test's reader misses nothing; `false`
    /// when one has none by then. A robot does not wait (`--ros2-wait-s 0`).
    pub fn wait_for_subscribers(&self, timeout: Duration) -> bool {
        let deadline = std::time::Instant::now() + timeout;
        let mut topics = vec![self.pose_topic.clone(), "/tf".to_string(), "/diagnostics".to_string()];
        topics.extend((0..self.ranges.len()).map(range_topic));
        loop {
            if topics.iter().all(|t| self.node.subscription_count(t) > 0) {
                std::thread::sleep(Duration::from_millis(300));
                return true;
            }
            if std::time::Instant::now() > deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Publishes what one message from the controller says.
    pub fn push(&mut self, m: &FromController) {
        if let Some(rx) = &self.odometry_sent {
            for s in rx.try_iter() {
                self.bridge.add_odometry(s);
            }
        }
        let out = self.bridge.push(m, now_ns());
        *self.anchor.lock().unwrap_or_else(|p| p.into_inner()) = self.bridge.anchor();
        for o in out {
            self.publish(o);
        }
    }

    /// Publishes one message on its topic.
    pub fn publish(&self, o: Out) {
        let mut c = self.counts.lock().unwrap_or_else(|p| p.into_inner());
        let ok = match o {
            Out::Pose(p) => {
                c.poses += 1;
                self.pose.publish(*p).is_ok()
            }
            Out::Tf(t) => {
                c.tf += 1;
                self.tf.publish(t).is_ok()
            }
            Out::Range(k, r) => {
                c.ranges += 1;
                self.ranges.get(k).is_some_and(|p| p.publish(r).is_ok())
            }
            Out::Diagnostics(d) => {
                c.diagnostics += 1;
                self.diagnostics.publish(d).is_ok()
            }
            Out::Particles(p) => {
                c.particle_clouds += 1;
                self.particles.publish(p).is_ok()
            }
        };
        if !ok {
            c.publish_errors += 1;
        }
    }

    /// Stops taking inputs, keeps the node up `--ros2-linger-s` so reliable
    /// readers get the last samples, and says what it did.
    pub fn finish(mut self) -> Ros2Counts {
        std::thread::sleep(self.linger);
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.inputs.take() {
            let _ = h.join();
        }
        let c = self.counts.lock().unwrap_or_else(|p| p.into_inner()).clone();
        c
    }
}

//! `echoloc-lab link`: the robot computer's end of the host link
//! (`docs/link.md`). Streams odometry to a controller — cumulative poses
//! composed from a scenario's increments, JSON lines from stdin, or with
//! `--ros2 --ros2-odom` the robot's `/odom` as it comes — and
//! prints every message the controller sends back as a JSON line. With
//! `--qemu ELF` it first starts the QEMU firmware (the board's `link`
//! binary) with UART0 on a Unix socket and the scenario in the board's
//! scenario partition; with `--socket PATH` it connects to a controller
//! already listening there. The framing is the core's own
//! (`echoloc::link::frame`), so both ends share one implementation.

use std::io::{BufRead, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use clap::Args;
use echoloc::link::frame::{encode, max_frame_len, Decoder};
use echoloc::link::{FromController, ToController};
use echoloc::scenario::Scenario;
use serde_json::json;

use crate::map::LabError;

/// The board's scenario partition (`boards/qemu-mps2-an386/src/replay.rs`).
const SCENARIO_PARTITION: &str = "0x00300000";

/// `link`.
#[derive(Args)]
pub struct LinkArgs {
    /// A scenario: its odometry is streamed (and, with --qemu, the firmware replays its echoes).
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Read the odometry from stdin instead: one JSON object per line, {"time_us":…, "x":…, "y":…, "theta":…}
    /// (cumulative pose in m and rad, time on the controller's clock).
    #[arg(long = "odometry-stdin")]
    odometry_stdin: bool,
    /// Start this QEMU firmware (the board's `link` binary) and talk to it.
    #[arg(long)]
    qemu: Option<PathBuf>,
    /// Or talk to a controller listening on this Unix socket.
    #[arg(long)]
    socket: Option<PathBuf>,
    /// Damage every Nth odometry frame (one bit flipped) and send a garbage frame after it (never the last frame).
    #[arg(long = "corrupt-every")]
    corrupt_every: Option<u32>,
    /// Writes what the controller sent as a Foxglove recording (MCAP,
    /// docs/foxglove.md): its poses, covariance, sensor windows and verdicts.
    #[arg(long)]
    mcap: Option<PathBuf>,
    #[command(flatten)]
    live: crate::foxglove::live::LiveArgs,
    /// The controller's ring, for the sensor windows of --mcap and --live: pioneer16 or a JSON ring file.
    #[arg(long, default_value = "pioneer16")]
    ring: String,
    /// Give up after this many seconds.
    #[arg(long = "timeout-s", default_value_t = 120)]
    timeout_s: u64,
    #[command(flatten)]
    ros2: crate::ros2::Ros2Args,
}

/// Odometry samples as the link sends them: (time µs, x m, y m, θ rad).
type Sample = crate::ros2::bridge::Sample;

/// Where the odometry comes from: all known before the run (a scenario,
/// stdin), or as it comes (`/odom`).
enum Feed {
    Fixed(Vec<Sample>),
    Stream(std::sync::mpsc::Receiver<Sample>),
}

/// How far ahead of the controller's last reading the odometry runs when
/// commands can come mid-run (`--ros2`), µs: enough that the controller
/// never waits for a sample, little enough that a command sent now is
/// taken within a few ring cycles (the socket would hold the whole run).
const PACED_LEAD_US: u32 = 2_000_000;

/// Commands to send between odometry frames, and the controller's progress
/// that paces the odometry so that they come in time.
struct Commands {
    rx: std::sync::mpsc::Receiver<ToController>,
    /// The last reading's time on the controller's clock, µs, once one came.
    progress: std::sync::Arc<std::sync::Mutex<Option<u32>>>,
    /// Set when the reader is done.
    done: std::sync::Arc<std::sync::atomic::AtomicBool>,
    sent: u32,
}

/// Cumulative odometry from a scenario's increments, composed in `f64`
/// from the origin, stamped with each firing's time relative to the first
/// (the controller's clock when it replays the scenario).
pub fn scenario_odometry(s: &Scenario<'_>) -> Vec<Sample> {
    let t0 = s.records().next().map_or(0, |r| r.time_us);
    let mut x = [0.0f64; 3];
    s.records()
        .map(|r| {
            let u = r.odometry.map(f64::from);
            let (sn, cs) = x[2].sin_cos();
            x = [x[0] + cs * u[0] - sn * u[1], x[1] + sn * u[0] + cs * u[1], x[2] + u[2]];
            let theta = (x[2] + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
            (r.time_us.wrapping_sub(t0), x[0] as f32, x[1] as f32, theta as f32)
        })
        .collect()
}

fn stdin_odometry() -> Result<Vec<Sample>, LabError> {
    let mut out = Vec::new();
    for (i, line) in std::io::stdin().lock().lines().enumerate() {
        let line = line.map_err(|e| LabError(format!("stdin: {e}")))?;
        if line.trim().is_empty() {
            continue;
        }
        let v: serde_json::Value =
            serde_json::from_str(&line).map_err(|e| LabError(format!("stdin line {}: {e}", i + 1)))?;
        let f = |k: &str| {
            v[k].as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| LabError(format!("stdin line {}: no finite \"{k}\"", i + 1)))
        };
        let t = v["time_us"].as_u64().filter(|&t| t <= u64::from(u32::MAX));
        let t = t.ok_or_else(|| LabError(format!("stdin line {}: \"time_us\" must be an integer 0..2^32", i + 1)))?;
        out.push((t as u32, f("x")? as f32, f("y")? as f32, f("theta")? as f32));
    }
    Ok(out)
}

/// QEMU with UART0 on `sock` and `scenario` in the partition.
fn start_qemu(elf: &Path, scenario: &Path, sock: &Path) -> Result<Child, LabError> {
    Command::new("qemu-system-arm")
        .args(["-cpu", "cortex-m4", "-machine", "mps2-an386", "-nographic", "-monitor", "none"])
        .args(["-icount", "shift=0", "-semihosting-config", "enable=on,target=native"])
        .arg("-chardev")
        .arg(format!("socket,id=link,path={},server=on,wait=on", sock.display()))
        .args(["-serial", "chardev:link"])
        .arg("-device")
        .arg(format!("loader,file={},addr={SCENARIO_PARTITION}", scenario.display()))
        .arg("-kernel")
        .arg(elf)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| LabError(format!("cannot start qemu-system-arm: {e} (scripts/setup.sh installs it)")))
}

fn connect(sock: &Path, qemu: &mut Option<Child>, deadline: Instant) -> Result<UnixStream, LabError> {
    loop {
        match UnixStream::connect(sock) {
            Ok(s) => return Ok(s),
            Err(e) => {
                if let Some(q) = qemu.as_mut() {
                    if let Ok(Some(status)) = q.try_wait() {
                        return Err(LabError(format!("QEMU exited ({status}) before the link opened")));
                    }
                }
                if Instant::now() > deadline {
                    return Err(LabError(format!("{}: cannot connect: {e}", sock.display())));
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
}

/// What the writer sent.
#[derive(Default)]
struct Sent {
    odometry: u32,
    corrupted: u32,
    garbage: u32,
    /// Commands from ROS 2 (`SetPose`, `Search`).
    commands: u32,
}

/// Sends every sample, then `End` (a stream has none: it ends when the
/// reader is done); stops at the first write error (a controller that
/// closed the line), returning what went out.
fn send_all(w: UnixStream, feed: Feed, corrupt_every: Option<u32>, commands: Option<Commands>) -> Sent {
    let mut sent = Sent::default();
    let mut commands = commands;
    let _ = send_frames(w, feed, corrupt_every, &mut sent, commands.as_mut());
    sent.commands = commands.map_or(0, |c| c.sent);
    sent
}

/// Sends the commands that came; `false` once the reader is done.
fn send_commands(w: &mut UnixStream, c: &mut Commands, buf: &mut [u8]) -> std::io::Result<bool> {
    while let Ok(cmd) = c.rx.try_recv() {
        let n = encode::<_, 64>(&cmd, buf).map_err(|e| std::io::Error::other(format!("{e:?}")))?;
        w.write_all(&buf[..n])?;
        c.sent += 1;
    }
    Ok(!c.done.load(std::sync::atomic::Ordering::Relaxed))
}

/// With commands: waits until `time_us` is within [`PACED_LEAD_US`] of the
/// controller's last reading (of the first sample, before any reading),
/// sending the commands that come meanwhile. `false` once the reader is done.
fn pace(w: &mut UnixStream, c: &mut Commands, time_us: u32, first: u32, buf: &mut [u8]) -> std::io::Result<bool> {
    loop {
        if !send_commands(w, c, buf)? {
            return Ok(false);
        }
        let last = c.progress.lock().unwrap_or_else(|p| p.into_inner()).unwrap_or(first);
        // Wrapping: the controller's clock wraps at 2³² µs.
        if (time_us.wrapping_sub(last) as i32) <= PACED_LEAD_US as i32 {
            return Ok(true);
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn send_frames(
    mut w: UnixStream,
    feed: Feed,
    corrupt_every: Option<u32>,
    sent: &mut Sent,
    mut commands: Option<&mut Commands>,
) -> std::io::Result<()> {
    let mut buf = [0u8; max_frame_len(64)];
    let (n_samples, mut fixed, stream) = match feed {
        Feed::Fixed(v) => (Some(v.len()), Some(v.into_iter()), None),
        Feed::Stream(rx) => (None, None, Some(rx)),
    };
    let mut first = None;
    for k in 0.. {
        let (time_us, x, y, theta) = match (fixed.as_mut(), &stream) {
            (Some(it), _) => match it.next() {
                Some(s) => s,
                None => break,
            },
            (None, Some(rx)) => match rx.recv_timeout(Duration::from_millis(20)) {
                Ok(s) => s,
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                    // Commands wait for no sample; the reader's end stops the stream.
                    let more = match commands.as_deref_mut() {
                        Some(c) => send_commands(&mut w, c, &mut buf)?,
                        None => false,
                    };
                    if more {
                        continue;
                    }
                    return Ok(());
                }
                Err(_) => return Ok(()),
            },
            (None, None) => break,
        };
        let first = *first.get_or_insert(time_us);
        if let Some(c) = commands.as_deref_mut() {
            if !pace(&mut w, c, time_us, first, &mut buf)? {
                return Ok(());
            }
        }
        let n = encode::<_, 64>(&ToController::Odometry { time_us, x, y, theta }, &mut buf)
            .map_err(|e| std::io::Error::other(format!("{e:?}")))?;
        let frame = &mut buf[..n];
        let damage = corrupt_every.is_some_and(|c| c > 0 && (k as u32 + 1).is_multiple_of(c))
            && n_samples.is_none_or(|n| k + 1 < n);
        if damage {
            // One bit inside the frame, never making a delimiter: one bad frame.
            let i = n / 2;
            frame[i] ^= if frame[i] ^ 0x10 != 0 { 0x10 } else { 0x20 };
            sent.corrupted += 1;
        }
        w.write_all(frame)?;
        sent.odometry += 1;
        if damage {
            w.write_all(&[0x00, 0x55, 0x21, 0x7e, 0x00])?;
            sent.garbage += 1;
        }
    }
    if stream.is_some() {
        return Ok(());
    }
    let n = encode::<_, 64>(&ToController::End, &mut buf).map_err(|e| std::io::Error::other(format!("{e:?}")))?;
    w.write_all(&buf[..n])?;
    w.flush()
}

pub fn link_cmd(a: &LinkArgs) -> Result<String, LabError> {
    let deadline = Instant::now() + Duration::from_secs(a.timeout_s);
    if let Some(p) = &a.mcap {
        crate::simulate::check_writable(p)?;
    }
    let mounts = crate::predict::ring_mounts(&a.ring)?;
    let scenario_bytes = match &a.scenario {
        Some(p) => Some(std::fs::read(p).map_err(|e| LabError(format!("{}: {e}", p.display())))?),
        None => None,
    };
    let samples = match (&scenario_bytes, a.odometry_stdin, a.ros2.ros2_odom) {
        (_, true, true) => {
            return Err(LabError("--odometry-stdin and --ros2-odom are two odometries: give one".into()))
        }
        (_, false, true) => Vec::new(),
        (_, true, false) => stdin_odometry()?,
        (Some(b), false, false) => {
            let s = Scenario::parse(b).map_err(|e| LabError(format!("not a valid scenario: {e}")))?;
            scenario_odometry(&s)
        }
        (None, false, false) => {
            return Err(LabError("give --scenario FILE, --odometry-stdin or --ros2 --ros2-odom".into()))
        }
    };
    let sock_path;
    let mut qemu = None;
    match (&a.qemu, &a.socket) {
        (Some(elf), None) => {
            let Some(scn) = &a.scenario else {
                return Err(LabError("--qemu needs --scenario (the firmware replays its echoes)".into()));
            };
            sock_path = std::env::temp_dir().join(format!("echoloc-link-{}.sock", std::process::id()));
            let _ = std::fs::remove_file(&sock_path);
            qemu = Some(start_qemu(elf, scn, &sock_path)?);
        }
        (None, Some(s)) => sock_path = s.clone(),
        _ => return Err(LabError("give exactly one of --qemu ELF and --socket PATH".into())),
    }
    // The firmware's console, kept for the summary and echoed to stderr.
    let console = qemu.as_mut().and_then(|q| q.stdout.take()).map(|out| {
        std::thread::spawn(move || {
            let mut lines = Vec::new();
            for line in std::io::BufReader::new(out).lines().map_while(Result::ok) {
                eprintln!("firmware: {line}");
                lines.push(line);
            }
            lines
        })
    });
    let (hold, wait) = a.live.hold_and_wait().map_err(LabError)?;
    // The recording is made as the messages come, and served from there.
    let mut rec = match (&a.mcap, &a.live.live) {
        (None, None) => None,
        _ => Some(crate::foxglove::Recording::new().map_err(|e| LabError(format!("--mcap: {e}")))?),
    };
    if let Some(r) = rec.as_mut() {
        a.live.serve(r, crate::foxglove::live::Pace::AsWritten).map_err(LabError)?;
        crate::foxglove::controller::LinkRecorder::advertise(r);
        if !wait.is_zero() && !r.wait_for_viewer(wait) {
            eprintln!("live: no viewer within --live-wait-s; running without");
        }
    }
    let mut recorder = crate::foxglove::controller::LinkRecorder::new(&mounts);
    let mut stream = None;
    let (mut ros, commands) = if a.ros2.ros2 {
        let (tx, rx) = std::sync::mpsc::channel();
        let mut node = crate::ros2::node::Ros2Node::start(&a.ros2, &mounts, &samples, tx)?;
        stream = node.take_odometry_feed().map(Feed::Stream);
        let wait = Duration::from_secs_f64(a.ros2.ros2_wait_s.clamp(0.0, 3600.0));
        if !wait.is_zero() && !node.wait_for_subscribers(wait) {
            eprintln!("ros2: not every topic had a subscriber within --ros2-wait-s; running without");
        }
        let c = Commands { rx, progress: Default::default(), done: Default::default(), sent: 0 };
        (Some(node), Some(c))
    } else {
        (None, None)
    };
    let progress = commands.as_ref().map(|c| (c.progress.clone(), c.done.clone()));
    let mut on_message = |m: &FromController| {
        if let Some(r) = rec.as_mut() {
            recorder.push(r, m);
        }
        if let Some(n) = ros.as_mut() {
            n.push(m);
        }
        if let (Some((p, _)), FromController::Reading(r)) = (&progress, m) {
            *p.lock().unwrap_or_else(|p| p.into_inner()) = Some(r.time_us);
        }
    };
    let feed = stream.unwrap_or(Feed::Fixed(samples));
    let result = talk(&sock_path, &mut qemu, deadline, feed, a.corrupt_every, commands, &mut on_message);
    let ros2 = ros.take().map(|n| n.finish());
    let firmware_exit = qemu.as_mut().map(|q| wait_or_kill(q, deadline));
    if a.qemu.is_some() {
        let _ = std::fs::remove_file(&sock_path);
    }
    let console = console.and_then(|h| h.join().ok()).unwrap_or_default();
    let (sent, received, dropped) = result?;
    if let Some(r) = rec {
        let bytes = r.finish_holding(hold).map_err(|e| LabError(format!("--mcap: {e}")))?;
        if let Some(p) = &a.mcap {
            crate::map::write_atomically(p, &bytes)?;
        }
    }
    let summary = json!({"host": {
        "odometry_sent": sent.odometry, "corrupted": sent.corrupted, "garbage": sent.garbage,
        "commands_sent": sent.commands, "ros2": ros2,
        "messages_received": received, "frames_dropped": dropped,
        "firmware_exit": firmware_exit.flatten(),
        "firmware_console": console.iter().filter(|l| l.starts_with("link:") || l.starts_with("pose error") || l.starts_with("FAIL")).collect::<Vec<_>>(),
    }});
    match firmware_exit {
        Some(Some(0)) | None => Ok(summary.to_string()),
        Some(code) => Err(LabError(format!("the firmware exited with {code:?}: {summary}"))),
    }
}

fn wait_or_kill(q: &mut Child, deadline: Instant) -> Option<i32> {
    let end = deadline.max(Instant::now() + Duration::from_secs(10));
    while Instant::now() < end {
        if let Ok(Some(s)) = q.try_wait() {
            return s.code();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = q.kill();
    q.wait().ok().and_then(|s| s.code())
}

fn talk(
    sock: &Path,
    qemu: &mut Option<Child>,
    deadline: Instant,
    feed: Feed,
    corrupt_every: Option<u32>,
    commands: Option<Commands>,
    on_message: &mut dyn FnMut(&FromController),
) -> Result<(Sent, u32, u32), LabError> {
    let stream = connect(sock, qemu, deadline)?;
    let writer = stream.try_clone().map_err(|e| LabError(format!("socket: {e}")))?;
    let done = commands.as_ref().map(|c| c.done.clone());
    let sender = std::thread::spawn(move || send_all(writer, feed, corrupt_every, commands));
    let mut reader = stream;
    reader.set_read_timeout(Some(Duration::from_millis(200))).map_err(|e| LabError(format!("socket: {e}")))?;
    let mut rx = Decoder::<256>::new();
    let mut received = 0u32;
    let stdout = std::io::stdout();
    let mut buf = [0u8; 4096];
    'read: loop {
        if Instant::now() > deadline {
            return Err(LabError("timed out waiting for the controller".into()));
        }
        let n = match reader.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                if qemu.as_mut().is_some_and(|q| matches!(q.try_wait(), Ok(Some(_)))) {
                    break;
                }
                continue;
            }
            Err(e) => return Err(LabError(format!("socket: {e}"))),
        };
        for &b in &buf[..n] {
            if let Some(Ok(m)) = rx.push::<FromController>(b) {
                received += 1;
                on_message(&m);
                let line = serde_json::to_string(&m).map_err(|e| LabError(e.to_string()))?;
                let mut out = stdout.lock();
                let _ = writeln!(out, "{line}");
                let _ = out.flush();
                if matches!(m, FromController::Status { .. }) {
                    break 'read;
                }
            }
        }
    }
    // The writer may still be blocked on a controller that stopped reading,
    // or pacing itself on one that is done.
    if let Some(d) = &done {
        d.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    let _ = reader.shutdown(std::net::Shutdown::Both);
    let sent = sender.join().map_err(|_| LabError("the sender panicked".into()))?;
    Ok((sent, received, rx.counts().dropped()))
}

//! A bag's range readings, before they become rows: which topics carry
//! them, each message's readings (a Range's one, a RosAria PointCloud's
//! whole ring) checked and stamped, and the ring they index.

use std::collections::BTreeMap;

use echoloc::predict::Mount;

use super::msgs::{self, types};
use super::source::Messages;
use super::{
    chain, decoded, leaf, named, of_type, static_transforms, stored, strip, topics_of, wrap, BagError, MessageProblem,
    NoEcho, Options, Transducer, Used,
};
use crate::log::MAX_RANGE_MM;

/// A reading before the ring is known.
pub(super) struct Raw {
    /// When it was taken, ns.
    pub(super) stamp: i64,
    /// Which transducer: its frame, or its point of a cloud.
    pub(super) transducer: Key,
    pub(super) range_mm: Option<u32>,
}

#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) enum Key {
    Frame(String),
    Point(usize),
}

/// Sort key of a frame name: its trailing number, then the name
/// (`sonar_2` before `sonar_10`).
pub(super) fn frame_order(f: &str) -> (u64, String) {
    let digits: String =
        f.chars().rev().take_while(char::is_ascii_digit).collect::<Vec<_>>().into_iter().rev().collect();
    (digits.parse().unwrap_or(u64::MAX), f.to_string())
}

/// The range topics (named, else every Range topic, else the PointCloud,
/// `/sonar` of several), and whether they are a PointCloud.
pub(super) fn topics<'a>(m: &'a Messages, o: &Options) -> Result<(Vec<&'a str>, bool), BagError> {
    let range_topics: Vec<&str> = if o.ranges.is_empty() {
        let r = of_type(m, types::RANGE);
        if !r.is_empty() {
            r
        } else {
            match of_type(m, types::POINT_CLOUD)[..] {
                [] => return Err(BagError::NoRangeTopic { topics: topics_of(m) }),
                [one] => vec![one],
                ref several => match several.iter().find(|t| leaf(t) == "sonar") {
                    Some(t) => vec![*t],
                    None => {
                        return Err(BagError::Ambiguous {
                            what: "PointCloud",
                            option: "--ranges",
                            candidates: several.iter().map(|s| s.to_string()).collect(),
                        })
                    }
                },
            }
        }
    } else {
        o.ranges
            .iter()
            .map(|t| named(m, "--ranges", t, &[types::RANGE, types::POINT_CLOUD]))
            .collect::<Result<_, _>>()?
    };
    let cloud = m.topics[range_topics[0]].ty == types::POINT_CLOUD;
    if range_topics.iter().any(|t| (m.topics[*t].ty == types::POINT_CLOUD) != cloud)
        || (cloud && range_topics.len() > 1)
    {
        return Err(BagError::MixedRanges);
    }
    Ok((range_topics, cloud))
}

/// Every reading of the range topics.
pub(super) struct Readings {
    pub(super) raws: Vec<Raw>,
    pub(super) no_echo: NoEcho,
    /// Each Range frame, and the topic (its index) it was first seen on.
    pub(super) frames_of: BTreeMap<String, usize>,
}

/// Reads every message of `topics`: a PointCloud's points on `cloud_ring`,
/// stamped as [`Options::cloud_timing`] says, or each Range's reading.
/// Refuses a message no sonar could send, naming the topic and message,
/// and a topic whose time runs backwards.
pub(super) fn readings(
    m: &Messages,
    o: &Options,
    topics: &[&str],
    cloud_ring: Option<&[Mount]>,
) -> Result<Readings, BagError> {
    let mut out = Readings { raws: Vec::new(), no_echo: NoEcho::default(), frames_of: BTreeMap::new() };
    for (ti, topic) in topics.iter().enumerate() {
        let mut last: Option<i64> = None;
        for (index, s) in stored(m, topic).iter().enumerate() {
            let (stamp, readings) = match cloud_ring {
                Some(ring) => {
                    let c: msgs::PointCloud = decoded(topic, index, types::POINT_CLOUD, s)?;
                    (c.header.stamp, cloud_points(&c, ring, o, &mut out.no_echo))
                }
                None => {
                    let r: msgs::Range = decoded(topic, index, types::RANGE, s)?;
                    (r.header.stamp, range_frame(&r, &mut out.no_echo))
                }
            };
            let readings = readings.map_err(|problem| BagError::Message {
                topic: topic.to_string(),
                index,
                stamp_s: stamp.seconds(),
                problem,
            })?;
            for (k, ..) in &readings {
                if let Key::Frame(f) = k {
                    out.frames_of.entry(f.clone()).or_insert(ti);
                }
            }
            let t = stamp.seconds().map(|_| stamp.nanos()).ok_or(BagError::Message {
                topic: topic.to_string(),
                index,
                stamp_s: None,
                problem: MessageProblem::BadStamp,
            })?;
            if let Some(prev) = last {
                if t < prev {
                    return Err(BagError::TimeBackwards {
                        topic: topic.to_string(),
                        index,
                        stamp_s: t as f64 / 1e9,
                        previous_s: prev as f64 / 1e9,
                    });
                }
            }
            last = Some(t);
            for (transducer, range_mm, offset_ns) in readings {
                out.raws.push(Raw { stamp: t + offset_ns, transducer, range_mm });
            }
        }
    }
    Ok(out)
}

/// A RosAria cloud's points as readings on `ring` (point k is transducer
/// k, its range the point's distance from the transducer, a point at the
/// maximum no echo), each with its firing time from the stamp, ns.
fn cloud_points(
    c: &msgs::PointCloud,
    ring: &[Mount],
    o: &Options,
    no_echo: &mut NoEcho,
) -> Result<Vec<(Key, Option<u32>, i64)>, MessageProblem> {
    if strip(&c.header.frame_id) != o.base_frame {
        return Err(MessageProblem::CloudFrame { frame: c.header.frame_id.clone(), base: o.base_frame.clone() });
    }
    if c.points.len() != ring.len() {
        return Err(MessageProblem::PointCount { found: c.points.len(), ring: ring.len() });
    }
    let mut rs = Vec::with_capacity(ring.len());
    for (k, (p, mount)) in c.points.iter().zip(ring).enumerate() {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return Err(MessageProblem::BadPoint { point: k });
        }
        let (dx, dy) =
            (f64::from(p.x) - f64::from(mount.x_mm) / 1000.0, f64::from(p.y) - f64::from(mount.y_mm) / 1000.0);
        let r = dx.hypot(dy);
        let axis = f64::from(mount.heading_mdeg).to_radians() / 1000.0;
        if r > 0.05 {
            let off = wrap(dy.atan2(dx) - axis).abs().to_degrees();
            if off > 5.0 {
                return Err(MessageProblem::OffAxis { point: k, degrees: off });
            }
        }
        let reading = if r >= o.cloud_max_m - 0.0005 {
            no_echo.beyond_max += 1;
            None
        } else if r * 1000.0 > MAX_RANGE_MM {
            return Err(MessageProblem::BeyondAnySonar { value: r });
        } else if (r * 1000.0).round() < 1.0 {
            return Err(MessageProblem::ZeroRange);
        } else {
            Some((r * 1000.0).round() as u32)
        };
        rs.push((Key::Point(k), reading, o.cloud_timing.offset_ns(k)));
    }
    Ok(rs)
}

/// A Range's reading at its frame, the transducer's.
fn range_frame(r: &msgs::Range, no_echo: &mut NoEcho) -> Result<Vec<(Key, Option<u32>, i64)>, MessageProblem> {
    let frame = strip(&r.header.frame_id).to_string();
    if frame.is_empty() {
        return Err(MessageProblem::NoFrame);
    }
    Ok(vec![(Key::Frame(frame), range_reading(r, no_echo)?, 0)])
}

/// A Range's reading under REP 117: `+Inf` no return, `-Inf` too close,
/// outside `[min_range, max_range]` no echo; NaN, negative, zero and
/// limits no sonar has refused.
fn range_reading(r: &msgs::Range, no_echo: &mut NoEcho) -> Result<Option<u32>, MessageProblem> {
    let (lo, hi) = (r.min_range, r.max_range);
    if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && lo < hi) {
        return Err(MessageProblem::BadLimits { min: lo, max: hi });
    }
    if f64::from(hi) * 1000.0 > MAX_RANGE_MM {
        return Err(MessageProblem::BeyondAnySonar { value: f64::from(hi) });
    }
    let v = r.range;
    Ok(if v.is_nan() {
        return Err(MessageProblem::NanRange);
    } else if v == f32::INFINITY {
        no_echo.infinite += 1;
        None
    } else if v == f32::NEG_INFINITY {
        no_echo.too_close += 1;
        None
    } else if v < 0.0 {
        return Err(MessageProblem::NegativeRange(v));
    } else if v == 0.0 {
        return Err(MessageProblem::ZeroRange);
    } else if v > hi {
        no_echo.beyond_max += 1;
        None
    } else if v < lo {
        no_echo.below_min += 1;
        None
    } else {
        let mm = (f64::from(v) * 1000.0).round();
        if mm < 1.0 {
            return Err(MessageProblem::ZeroRange);
        }
        Some(mm as u32)
    })
}

/// The ring the readings index.
pub(super) struct Ring {
    pub(super) mounts: Vec<Mount>,
    pub(super) transducers: Vec<Transducer>,
    pub(super) index_of: BTreeMap<Key, u8>,
}

/// The ring: a cloud's points in order on `cloud_ring`; Range frames in
/// frame order, their mounts from `--ring` or `/tf_static`.
pub(super) fn ring(
    m: &Messages,
    o: &Options,
    topics: &[&str],
    frames_of: &BTreeMap<String, usize>,
    cloud_ring: Option<Vec<Mount>>,
    used: &mut Used,
) -> Result<Ring, BagError> {
    if let Some(ring) = cloud_ring {
        used.ring = if o.ring.is_some() {
            "--ring".into()
        } else {
            "pioneer16 (RosAria's Pioneer ring; --ring to change)".into()
        };
        let transducers = ring
            .iter()
            .enumerate()
            .map(|(i, &mount)| Transducer { index: i as u8, frame: format!("point {i}"), mount })
            .collect();
        let index_of = (0..ring.len()).map(|i| (Key::Point(i), i as u8)).collect();
        return Ok(Ring { mounts: ring, transducers, index_of });
    }
    let mut frames: Vec<&String> = frames_of.keys().collect();
    frames.sort_by_key(|f| frame_order(f));
    if frames.len() > 255 {
        return Err(BagError::TooManyTransducers(frames.len()));
    }
    let mounts: Vec<Mount> = match &o.ring {
        Some(ring) => {
            if ring.len() != frames.len() {
                return Err(BagError::RingSize {
                    frames: frames.iter().map(|s| s.to_string()).collect(),
                    ring: ring.len(),
                });
            }
            used.ring = "--ring".into();
            ring.clone()
        }
        None => {
            used.ring = "/tf_static".into();
            let statics = static_transforms(m)?;
            frames
                .iter()
                .map(|f| {
                    let p = chain(&statics, &o.base_frame, f).ok_or_else(|| BagError::NoTransform {
                        topic: topics[frames_of[*f]].to_string(),
                        frame: f.to_string(),
                        base: o.base_frame.clone(),
                    })?;
                    Ok(Mount {
                        x_mm: (p[0] * 1000.0).round() as i32,
                        y_mm: (p[1] * 1000.0).round() as i32,
                        heading_mdeg: (wrap(p[2]).to_degrees() * 1000.0).round() as i32,
                    })
                })
                .collect::<Result<_, BagError>>()?
        }
    };
    let transducers = frames
        .iter()
        .zip(&mounts)
        .enumerate()
        .map(|(i, (f, &mount))| Transducer { index: i as u8, frame: f.to_string(), mount })
        .collect();
    let index_of = frames.iter().enumerate().map(|(i, f)| (Key::Frame(f.to_string()), i as u8)).collect();
    Ok(Ring { mounts, transducers, index_of })
}

//! # echoloc
//!
//! `no_std` firmware library for the microcontroller that drives a mobile
//! robot's sonar ring. It predicts what every transducer should read from the
//! robot's pose and a polygon map, rates each prediction, compares it with the
//! real echo, and corrects the pose, following the paper *Autonomous Mobile Robot
//! Self-Referencing with Sensor Windows and Neural Networks*.
//!
//! Its modules:
//!
//! | module | what it does |
//! |---|---|
//! | [`geometry`] | integer-millimetre points, exact `i64` predicates, convex pieces, convex splitting |
//! | [`tvector`] | the paper's t-vectors: edge-side bit masks, front surfaces, segment–piece collision |
//! | [`credence`] | credence κ(R, θ): the model trait and fixed-point κ |
//! | [`buffer`] | C-space buffers: a piece grown conservatively by `t_b` |
//! | [`driver`] | the sonar ring driver over embedded-hal 1.0: Polaroid 6500-class modules, multiplexer, firing schedule, EERUF, faults |
//! | [`window`] | sensor windows: parameters, pseudo-paths, placement, exact sector tests, beacon collection |
//! | [`predict`] | range prediction: the four signature tests, Cases I–III, subsurface search, occlusion; rings of transducers |
//! | [`map`] | the fixed-capacity obstacle map, its uniform grid index and its binary blob |
//! | [`referencing`] | self-referencing: verdicts, the EKF over (x, y, φ), the paper's threshold method |
//! | [`localize`] | finding itself: Monte Carlo localization in fixed memory, and the localizer's modes (searching, tracking, lost) |
//! | [`f32math`] | sin, cos and √ in single precision (the M4F has no double-precision FPU) |
//! | [`scenario`] | scenario files: a recorded run, versioned and CRC-checked, read in place; a replay bench that feeds one through the real driver |
//! | [`link`] | the host link: versioned messages, postcard, COBS and CRC-32 frames over `embedded-io` |
//! | [`controller`] | the controller's loop: ring readings and the robot's odometry through prediction, verdicts and the EKF |
//!
//! Every geometric *decision* is exact integer arithmetic; there is no
//! allocator and no float on these paths (the pose filter in [`referencing`]
//! is `f32`, as DESIGN §3 allows). `unsafe` is denied but for one measured
//! exception: the FPU's square root on hard-float ARM ([`f32math::sqrt`]).
//!
//! ```
//! use echoloc::geometry::{Point, Segment};
//! use echoloc::map::{Map, ObstacleKind};
//!
//! // A 1 m square box and a wall, grown by a 100 mm C-space buffer.
//! let mut map: Map<64, 1024, 256, 1024> = Map::new();
//! let square = [Point::new(0, 0), Point::new(1000, 0), Point::new(1000, 1000), Point::new(0, 1000)];
//! map.add_obstacle(ObstacleKind::Solid, &[&square[..]]).unwrap();
//! map.add_obstacle(ObstacleKind::Wall, &[&[Point::new(2000, 0), Point::new(2000, 3000)][..]]).unwrap();
//! map.finish(100, 500).unwrap();
//!
//! let ray = Segment::new(Point::new(-500, 500), Point::new(3000, 500));
//! let first = map.first_hit(ray).unwrap().expect("the ray meets the box");
//! assert_eq!(first.obstacle, 0); // the box is hit before the wall
//! ```
#![no_std]
#![deny(unsafe_code)]
#![warn(missing_docs)]
// No panic paths (issue #14, docs/robustness.md): none of these outside
// tests. Indexing is denied where hostile bytes arrive (the host link, the
// scenario reader, the compiled-map validator); elsewhere the panic-never
// link check (`scripts/panic-never.sh`) proves what indexing remains is
// bounds-checked away.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::todo,
        clippy::unimplemented,
        clippy::unreachable
    )
)]

pub mod buffer;
pub mod controller;
pub mod credence;
pub mod driver;
pub mod f32math;
pub mod geometry;
#[cfg_attr(not(test), deny(clippy::indexing_slicing))]
pub mod link;
pub mod localize;
pub mod map;
pub mod predict;
pub mod referencing;
#[cfg_attr(not(test), deny(clippy::indexing_slicing))]
pub mod scenario;
pub mod tvector;
pub mod window;

//! The host link: the controller and the robot's computer exchange framed
//! messages over a serial line (`docs/link.md`).
//!
//! | file | what it holds |
//! |---|---|
//! | [`message`] | the versioned messages: odometry in; per reading the outcome, prediction, κ, verdict, pose, covariance and the localizer's mode out; cycle (with the mode and particles) and link status |
//! | [`frame`] | framing: `postcard` encoding, a version byte and a CRC-32, COBS between `0x00` delimiters; a decoder that drops and counts every bad frame |
//! | [`port`] | [`Link`]: the framing over any `embedded-io` serial port, non-blocking on receive |
//!
//! ```
//! use echoloc::link::frame::{encode, Decoder, FrameError};
//! use echoloc::link::ToController;
//!
//! let msg = ToController::Odometry { time_us: 1_000, x: 1.5, y: -0.25, theta: 0.1 };
//! let mut frame = [0u8; 64];
//! let n = encode::<_, 32>(&msg, &mut frame).unwrap();
//! let mut rx = Decoder::<64>::new();
//! // Garbage on the line, then the frame: the garbage is dropped, the frame decoded.
//! let mut got = Vec::new();
//! for &b in [0x17u8, 0x42, 0x00].iter().chain(&frame[..n]) {
//!     if let Some(r) = rx.push::<ToController>(b) {
//!         got.push(r);
//!     }
//! }
//! assert_eq!(got, [Err(FrameError::Cobs), Ok(msg)]);
//! assert_eq!((rx.counts().ok, rx.counts().dropped()), (1, 1));
//! ```

pub mod frame;
pub mod message;
pub mod port;

pub use message::{
    CycleReport, FromController, ReadingReport, RxCounts, ToController, WireMode, WireOutcome, WireUpdate, WireVerdict,
    PROTOCOL_VERSION,
};
pub use port::{Link, LinkError};

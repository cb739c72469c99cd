//! The host link's framing under a damaged line: bit flips, truncated
//! frames and garbage between frames. Every frame that arrives whole is
//! decoded to the message sent; every damaged one is dropped and counted;
//! nothing is ever misread. COBS is checked against the `cobs` crate's
//! reference behaviour only through round trips; the CRC against
//! `crc32fast`.

use echoloc::link::frame::{encode, max_frame_len, Decoder, FrameError};
use echoloc::link::{
    CycleReport, FromController, ReadingReport, RxCounts, ToController, WireMode, WireOutcome, WireUpdate, WireVerdict,
    PROTOCOL_VERSION,
};
use proptest::prelude::*;

const RAW: usize = 96;

fn frame<T: serde::Serialize>(m: &T) -> Vec<u8> {
    let mut out = [0u8; max_frame_len(RAW)];
    let n = encode::<_, RAW>(m, &mut out).unwrap();
    out[..n].to_vec()
}

fn odometry(i: u32) -> ToController {
    let f = i as f32;
    ToController::Odometry { time_us: i * 37_501, x: f * 0.013, y: -f * 0.007, theta: (f * 0.01).sin() }
}

fn reading(i: u32) -> FromController {
    FromController::Reading(ReadingReport {
        time_us: i * 40_000,
        cycle: i / 16,
        transducer: (i % 16) as u8,
        outcome: if i.is_multiple_of(3) { WireOutcome::NoEcho } else { WireOutcome::Unconfirmed(400 + i) },
        predicted_mm: (!i.is_multiple_of(5)).then_some(500 + 2 * i),
        kappa: 0.75,
        verdict: WireVerdict::Confirmed,
        update: WireUpdate::Accepted,
        pose: [i as f32, 2.0, -0.5],
        covariance: [1e-4, 0.0, 1e-6, 1e-4, 0.0, 1e-5],
        mode: [WireMode::Tracking, WireMode::Searching, WireMode::Lost][(i % 3) as usize],
    })
}

/// xorshift64*: a fixed stream, so a failure names its seed.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn every_message_kind_round_trips() {
    let mut rx = Decoder::<128>::new();
    let from = [
        FromController::Hello { protocol: PROTOCOL_VERSION, transducers: 16, map_crc: 0x45f2_7bc7, time_us: 0 },
        reading(3),
        FromController::Cycle(CycleReport {
            cycle: 9,
            verdicts: [1, 2, 3, 4, 5, 6],
            gate: [7, 8],
            mode: WireMode::Searching,
            particles: 1024,
            handoff: false,
            hypotheses: 5,
            lead: 37.25,
            behind: 0.5,
        }),
        FromController::Status {
            rx: RxCounts { ok: 5, crc: 1, ..RxCounts::default() },
            odometry_refused: 2,
            readings: 99,
            stale: 1,
        },
    ];
    for m in from {
        let got: Vec<_> = frame(&m).into_iter().filter_map(|b| rx.push::<FromController>(b)).collect();
        assert_eq!(got, [Ok(m)]);
    }
    for m in [
        odometry(12),
        ToController::Search { around: None },
        ToController::Search { around: Some(([1.0, 2.0, 0.5], [0.5, 0.5, 0.2])) },
        ToController::End,
    ] {
        let got: Vec<_> = frame(&m).into_iter().filter_map(|b| rx.push::<ToController>(b)).collect();
        assert_eq!(got, [Ok(m)]);
    }
    assert_eq!(rx.counts().ok, 8);
    assert_eq!(rx.counts().dropped(), 0);
}

/// The largest a cycle's report can be (every count at its widest varint)
/// fits the controller's send buffer (`link::port::TX_RAW`), with the
/// largest reading's worst case beside it: a `send` never fails for size.
#[test]
fn the_widest_cycle_and_reading_fit_the_controllers_send_buffer() {
    use echoloc::link::port::TX_RAW;
    let cycle = FromController::Cycle(CycleReport {
        cycle: u32::MAX,
        verdicts: [u16::MAX; 6],
        gate: [u16::MAX; 2],
        mode: WireMode::Searching,
        particles: u16::MAX,
        handoff: true,
        hypotheses: u8::MAX,
        lead: f32::MAX,
        behind: f32::MIN,
    });
    let reading = FromController::Reading(ReadingReport {
        time_us: u32::MAX,
        cycle: u32::MAX,
        transducer: u8::MAX,
        outcome: WireOutcome::Unconfirmed(u32::MAX),
        predicted_mm: Some(u32::MAX),
        kappa: 1.0,
        verdict: WireVerdict::Confirmed,
        update: WireUpdate::Accepted,
        pose: [f32::MAX; 3],
        covariance: [f32::MAX; 6],
        mode: WireMode::Lost,
    });
    for m in [cycle, reading] {
        let mut out = [0u8; max_frame_len(TX_RAW)];
        let n = encode::<_, TX_RAW>(&m, &mut out).unwrap_or_else(|e| panic!("{m:?}: {e:?}"));
        assert!(n <= max_frame_len(TX_RAW));
    }
}

#[test]
fn the_crc_is_crc32_iso_hdlc_over_version_and_message() {
    let f = frame(&odometry(5));
    let inner = &f[1..f.len() - 1];
    let mut raw = vec![0u8; inner.len()];
    let n = cobs::decode(inner, &mut raw).unwrap().frame_size();
    let (body, crc) = raw[..n].split_at(n - 4);
    assert_eq!(body[0], PROTOCOL_VERSION);
    assert_eq!(u32::from_le_bytes(crc.try_into().unwrap()), crc32fast::hash(body));
    assert!(!inner.contains(&0), "COBS leaves no zero inside a frame");
}

#[test]
fn damaged_line_drops_and_counts_every_bad_frame_and_decodes_every_good_one() {
    for seed in 1..=20u64 {
        let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let mut line = Vec::new();
        let mut intact = Vec::new();
        let mut damaged = 0u32;
        for i in 0..500u32 {
            let m = odometry(i);
            let mut f = frame(&m);
            match rng.below(6) {
                // A bit flipped anywhere in the frame, delimiters included.
                0 => {
                    let k = rng.below(f.len());
                    f[k] ^= 1 << rng.below(8);
                    damaged += 1;
                }
                // Truncated: the frame's tail lost (at least one byte of body kept).
                1 => {
                    let keep = 2 + rng.below(f.len() - 3);
                    f.truncate(keep);
                    damaged += 1;
                }
                // Garbage before the frame (zeros included): the frame itself is whole.
                2 => {
                    let g: Vec<u8> = (0..1 + rng.below(40)).map(|_| rng.next() as u8).collect();
                    line.extend_from_slice(&g);
                    intact.push(m);
                }
                _ => intact.push(m),
            }
            line.extend_from_slice(&f);
        }
        let mut rx = Decoder::<64>::new();
        let mut got = Vec::new();
        let mut errors = 0u32;
        for &b in &line {
            match rx.push::<ToController>(b) {
                Some(Ok(m)) => got.push(m),
                Some(Err(_)) => errors += 1,
                None => {}
            }
        }
        // Nothing misread, nothing whole lost: exactly the intact frames, in order.
        assert_eq!(got, intact, "seed {seed}");
        let c = rx.counts();
        assert_eq!(c.ok as usize, intact.len(), "seed {seed}");
        assert_eq!(c.dropped(), errors, "seed {seed}: every drop counted once");
        // Each damaged frame is at least one drop (a flip that makes a zero splits it in two).
        assert!(c.dropped() >= damaged, "seed {seed}: {c:?}, {damaged} damaged");
    }
}

#[test]
fn an_oversized_frame_is_dropped_and_the_next_one_decoded() {
    let mut rx = Decoder::<16>::new();
    let mut got = Vec::new();
    let long = frame(&reading(1)); // longer than 16 bytes
    let short = frame(&ToController::End);
    for &b in long.iter().chain(&short) {
        if let Some(r) = rx.push::<ToController>(b) {
            got.push(r);
        }
    }
    assert_eq!(got, [Err(FrameError::Overflow), Ok(ToController::End)]);
}

#[test]
fn another_version_or_message_type_is_refused() {
    // A sound frame of protocol version 1 (before the localizer's mode).
    let mut raw = vec![1u8];
    raw.extend_from_slice(&postcard::to_allocvec(&ToController::End).unwrap());
    raw.extend_from_slice(&crc32fast::hash(&raw).to_le_bytes());
    let mut f = vec![0u8];
    f.extend_from_slice(&cobs::encode_vec(&raw));
    f.push(0);
    let mut rx = Decoder::<64>::new();
    let got: Vec<_> = f.iter().filter_map(|&b| rx.push::<ToController>(b)).collect();
    assert_eq!(got, [Err(FrameError::Version(1))]);
    // A controller's message read as a host's: version and CRC sound, payload not a message.
    let got: Vec<_> = frame(&reading(2)).into_iter().filter_map(|b| rx.push::<ToController>(b)).collect();
    assert_eq!(got, [Err(FrameError::Decode)]);
    assert_eq!((rx.counts().version, rx.counts().decode), (1, 1));
}

proptest! {
    /// Arbitrary bytes never panic the decoder, and whatever it accepts
    /// re-encodes to a frame that carries the same message.
    #[test]
    fn arbitrary_bytes_are_safe(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut rx = Decoder::<64>::new();
        for b in bytes {
            if let Some(Ok(m)) = rx.push::<ToController>(b) {
                let mut again = Decoder::<64>::new();
                let got: Vec<_> = frame(&m).into_iter().filter_map(|b| again.push::<ToController>(b)).collect();
                prop_assert_eq!(got, vec![Ok(m)]);
            }
        }
    }
}

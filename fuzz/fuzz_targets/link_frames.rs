//! The host link's decoder on arbitrary bytes, for both directions'
//! messages: no panic, and every message it accepts re-encodes to a frame
//! that decodes to the same message.
#![no_main]

use echoloc::link::frame::{encode, max_frame_len, Decoder};
use echoloc::link::{FromController, ToController};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut to = Decoder::<64>::new();
    let mut from = Decoder::<256>::new();
    for &b in data {
        if let Some(Ok(m)) = to.push::<ToController>(b) {
            let mut f = [0u8; max_frame_len(64)];
            let n = encode::<_, 64>(&m, &mut f).expect("a decoded message fits its own frame");
            let mut again = Decoder::<64>::new();
            let back: Vec<_> = f[..n].iter().filter_map(|&b| again.push::<ToController>(b)).collect();
            // Compared as frames, so that a NaN (which never equals itself) round-trips too.
            let [Ok(x)] = back.as_slice() else { panic!("a re-encoded message did not decode: {back:?}") };
            let mut g = [0u8; max_frame_len(64)];
            let k = encode::<_, 64>(x, &mut g).expect("fits");
            assert_eq!(&f[..n], &g[..k], "round trip");
        }
        if let Some(Ok(m)) = from.push::<FromController>(b) {
            let mut f = [0u8; max_frame_len(160)];
            let n = encode::<_, 160>(&m, &mut f).expect("a decoded message fits its own frame");
            let mut again = Decoder::<256>::new();
            assert_eq!(f[..n].iter().filter_map(|&b| again.push::<FromController>(b)).count(), 1);
        }
    }
    let c = to.counts();
    assert!(c.ok as usize + c.dropped() as usize <= data.len());
});

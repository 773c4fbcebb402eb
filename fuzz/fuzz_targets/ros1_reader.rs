//! The ROS 1 bag reader: a bag built from the input (chunks uncompressed, bz2 or lz4; indexed
//! or not, as a recording that did not close), so every execution reaches the reader's chunks,
//! time order and message decoding; or the input itself as the `.bag` file.
//!
//! Layout: one byte of read options; one byte of layout (bits 0–1: the raw file, or a bag of
//! chunks uncompressed, bz2, lz4; bit 2: no index; bits 3–5: messages per chunk − 1); then, for
//! a built bag, each message a topic byte (of `/joint_states` JointState, `/scalar` Float64,
//! `/other` String), an 8-byte little-endian record time and a payload (a 2-byte length and that
//! many bytes).
#![no_main]

use calib_fuzz::{Ros1Compression, check_sample, options, ros1_bag, scratch};
use calib_io::LogReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [flags, layout, rest @ ..] = data else {
        return;
    };
    let mut rest: &[u8] = rest;
    let file = match layout & 3 {
        0 => rest.to_vec(),
        mode => {
            let mut messages = Vec::new();
            while let [topic, t0, t1, t2, t3, t4, t5, t6, t7, lo, hi, tail @ ..] = rest {
                let n = usize::from(u16::from_le_bytes([*lo, *hi])).min(tail.len());
                let (payload, tail) = tail.split_at(n);
                rest = tail;
                let time = u64::from_le_bytes([*t0, *t1, *t2, *t3, *t4, *t5, *t6, *t7]);
                messages.push((usize::from(*topic), time, payload));
            }
            let compression = match mode {
                1 => Ros1Compression::None,
                2 => Ros1Compression::Bz2,
                _ => Ros1Compression::Lz4,
            };
            let per_chunk = usize::from((layout >> 3) & 7) + 1;
            ros1_bag(&messages, per_chunk, compression, layout & 4 == 0)
        }
    };
    let path = scratch("bag", &file);
    let Ok(reader) = LogReader::open(&path, &options(*flags)) else {
        return;
    };
    let channels = reader.channels().len();
    let unordered = options(*flags).allow_unordered_time;
    let mut last = f64::NEG_INFINITY;
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
        // The clock's stamps increase unless told to pass them on (issue 33).
        assert!(
            unordered || sample.t > last,
            "stamp {} after {last}",
            sample.t
        );
        last = sample.t;
    }
});

//! JointState CDR and JSON message decoding, through the MCAP reader: the input's payloads are
//! wrapped into a well-formed MCAP file, so every execution reaches the decoders.
//!
//! Layout: one byte of read options, one byte of [`Layout`], then messages, each a 2-byte
//! little-endian length and that many bytes (the last one takes what is left).
#![no_main]

use calib_fuzz::{Layout, check_sample, options, payloads, scratch, wrap_messages};
use calib_io::mcap_log::McapReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [flags, layout, rest @ ..] = data else {
        return;
    };
    let file = wrap_messages(&Layout::from_byte(*layout), &payloads(rest));
    let path = scratch("mcap", &file);
    let Ok(reader) = McapReader::open(&path, &options(*flags)) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
    }
});

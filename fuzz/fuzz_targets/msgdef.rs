//! Fields read by path (`TOPIC.field.path`) through a message definition the file carries: the
//! input's definition text and payloads are wrapped into a well-formed MCAP file, so every
//! execution reaches the `ros2msg` parser and the CDR walk.
//!
//! Layout: one byte of read options; the definition text up to the first NUL byte; the field
//! path up to the next; then messages, each a 2-byte little-endian length and that many bytes.
#![no_main]

use calib_fuzz::{PROBE_TOPIC, check_sample, options, payloads, scratch, wrap_with_definition};
use calib_io::mcap_log::McapReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [flags, rest @ ..] = data else {
        return;
    };
    let mut parts = rest.splitn(3, |b| *b == 0);
    let (Some(definition), Some(path), Some(messages)) = (parts.next(), parts.next(), parts.next())
    else {
        return;
    };
    let Ok(path) = std::str::from_utf8(path) else {
        return;
    };
    let file = wrap_with_definition(definition, &payloads(messages));
    let file = scratch("mcap", &file);
    let mut opts = options(*flags);
    opts.fields = vec![format!("{PROBE_TOPIC}.{path}")];
    let Ok(reader) = McapReader::open(&file, &opts) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
    }
});

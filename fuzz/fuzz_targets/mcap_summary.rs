//! The MCAP summary and the message definitions read from it: a well-formed file of a topic read
//! by field path (`/probe.a`, `/probe.b`), whose summary section is replaced by the input (the
//! footer pointing at it, its CRC zeroed or kept as the input chooses), so every execution
//! reaches the summary reader, the statistics and chunk index checks, and the choice between
//! the summary's and the data section's definitions.
//!
//! Layout: one byte of read options; one byte of flags (bit 0: keep the footer's CRC, which
//! then no longer matches); the rest: the summary section.
#![no_main]

use calib_fuzz::{PROBE_TOPIC, check_sample, options, scratch, wrap_with_definition};
use calib_io::mcap_log::McapReader;
use libfuzzer_sys::fuzz_target;

const DEFINITION: &[u8] = b"float64 a\nfloat64 b\n";

fuzz_target!(|data: &[u8]| {
    let [flags, keep_crc, summary @ ..] = data else {
        return;
    };
    let payloads: Vec<Vec<u8>> = (0..4u32)
        .map(|i| {
            let mut p = vec![0, 1, 0, 0];
            p.extend(f64::from(i).to_le_bytes());
            p.extend((1000.0 + f64::from(i)).to_le_bytes());
            p
        })
        .collect();
    let refs: Vec<&[u8]> = payloads.iter().map(Vec::as_slice).collect();
    let file = wrap_with_definition(DEFINITION, &refs);
    // Footer: opcode, length, summary start, summary offset start, CRC; then the magic.
    let footer = file.len() - 8 - 29;
    let start = u64::from_le_bytes(file[footer + 9..footer + 17].try_into().unwrap()) as usize;
    if start == 0 {
        return;
    }
    let mut out = file[..start].to_vec();
    out.extend_from_slice(summary);
    let mut tail = file[footer..].to_vec();
    tail[17..25].copy_from_slice(&0u64.to_le_bytes());
    if keep_crc & 1 == 0 {
        tail[25..29].copy_from_slice(&0u32.to_le_bytes());
    }
    out.extend_from_slice(&tail);
    let path = scratch("mcap", &out);
    let mut opts = options(*flags);
    opts.fields = vec![format!("{PROBE_TOPIC}.a"), format!("{PROBE_TOPIC}.b")];
    let Ok(reader) = McapReader::open(&path, &opts) else {
        return;
    };
    let channels = reader.channels().len();
    let a = reader
        .names()
        .iter()
        .position(|n| n.display == format!("{PROBE_TOPIC}.a"));
    let b = reader
        .names()
        .iter()
        .position(|n| n.display == format!("{PROBE_TOPIC}.b"));
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
        // Whatever the summary says, the fields are those the messages were written with.
        if let (Some(a), Some(b)) = (a, b) {
            assert!(sample.values[a] < sample.values[b], "a and b swapped: {sample:?}");
        }
    }
});

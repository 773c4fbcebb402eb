//! The MCAP log reader on arbitrary files: the first byte chooses the read options, the rest is
//! the file.
#![no_main]

use calib_fuzz::{check_sample, options, scratch};
use calib_io::mcap_log::McapReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, file)) = data.split_first() else {
        return;
    };
    let path = scratch("mcap", file);
    let Ok(reader) = McapReader::open(&path, &options(flags)) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
    }
});

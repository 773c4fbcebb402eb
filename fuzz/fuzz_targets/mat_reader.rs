//! The MATLAB reader on arbitrary files (byte 0: read options; the rest: the file), through
//! `LogReader` as `calib` opens a `.mat` file: v4 matrices, v5 data elements, compressed
//! variables and structs, then the columns turned into samples.
#![no_main]

use calib_fuzz::{check_sample, options, scratch};
use calib_io::LogReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, file)) = data.split_first() else {
        return;
    };
    let opts = options(flags);
    let path = scratch("mat", file);
    let Ok(reader) = LogReader::open(&path, &opts) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
    }
});

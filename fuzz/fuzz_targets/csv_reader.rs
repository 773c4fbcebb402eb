//! The CSV log reader: the first byte chooses the read options, the rest is the file.
#![no_main]

use calib_fuzz::{check_sample, check_sparse_row, options, scratch};
use calib_io::csv_log::CsvReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, file)) = data.split_first() else {
        return;
    };
    let opts = options(flags);
    let path = scratch("csv", file);
    let Ok(reader) = CsvReader::open(&path, &opts) else {
        return;
    };
    let channels = reader.channels().len();
    // A sparse file's rows hold NaN where a channel has no sample (aligned by `LogReader`).
    let sparse = reader.is_sparse();
    let mut prev_t = f64::NEG_INFINITY;
    for sample in reader {
        let Ok(sample) = sample else { break };
        if sparse {
            check_sparse_row(&sample, channels);
        } else {
            check_sample(&sample, channels);
        }
        if !opts.allow_unordered_time {
            assert!(sample.t > prev_t, "time stamps increase");
        }
        prev_t = sample.t;
    }
});

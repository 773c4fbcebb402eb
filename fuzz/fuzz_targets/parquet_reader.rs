//! The Parquet reader, through `LogReader` as `calib` runs it: the first byte chooses the read
//! options, the rest is the `.parquet` file. Seeds: the fixtures in `testdata/parquet/`
//! (`-max_len=81920`).
#![no_main]

use calib_fuzz::{check_sparse_row, options, scratch};
use calib_io::LogReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&flags, file)) = data.split_first() else {
        return;
    };
    let path = scratch("parquet", file);
    let Ok(reader) = LogReader::open(&path, &options(flags)) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        // A null in a column is a NaN: no reading of that channel at that row.
        check_sparse_row(&sample, channels);
    }
});

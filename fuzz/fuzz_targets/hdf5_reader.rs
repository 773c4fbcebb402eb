//! The HDF5 and MATLAB v7.3 reader, through `LogReader` as `calib` runs it: the first byte
//! chooses the read options, the second the file's form (bit 0: a `.mat` file, the input after a
//! 512-byte MATLAB v7.3 header; else a `.h5` file of the input), the rest is the file. Seeds: the
//! fixtures in `testdata/hdf5/` (`-max_len=65536`).
#![no_main]

use calib_fuzz::{check_sparse_row, options, scratch};
use calib_io::LogReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [flags, form, file @ ..] = data else {
        return;
    };
    let path = if form & 1 == 1 {
        let mut mat = vec![b' '; 512];
        mat[..19].copy_from_slice(b"MATLAB 7.3 MAT-file");
        mat[124..128].copy_from_slice(&[0x00, 0x02, b'I', b'M']);
        mat.extend_from_slice(file);
        scratch("mat", &mat)
    } else {
        scratch("h5", file)
    };
    let Ok(reader) = LogReader::open(&path, &options(*flags)) else {
        return;
    };
    let channels = reader.channels().len();
    for sample in reader {
        let Ok(sample) = sample else { break };
        // Channels of unequal lengths leave NaN where one has no value.
        check_sparse_row(&sample, channels);
    }
});

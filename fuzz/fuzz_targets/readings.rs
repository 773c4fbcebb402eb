//! The shift-angle readings parser: the first byte is the polygon's number of faces (0: not
//! given), the rest is the CSV.
#![no_main]

use calib_io::readings::parse_readings;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Some((&faces, file)) = data.split_first() else {
        return;
    };
    let faces = (faces != 0).then_some(usize::from(faces));
    let _ = parse_readings(file, Path::new("readings.csv"), faces);
});

//! The correction table reader.
#![no_main]

use calib_fuzz::scratch;
use calib_io::table::read_table;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = scratch("csv", data);
    let Ok(table) = read_table(&path) else {
        return;
    };
    for v in table.map.values().iter().chain(table.u.iter().flatten()) {
        assert!(v.is_finite(), "table value {v} is not finite");
    }
});

//! The uncertainty budget TOML parser.
#![no_main]

use calib_io::budget::parse_budget;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // `read_budget` refuses files that are not UTF-8 before parsing.
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_budget(text, Path::new("budget.toml"));
});

//! A long run, for the tests that stop calib while it writes.
//!
//! Declared by the tests that use it: `#[path = "common/long.rs"] mod long;`.

use crate::common::{quick_with, write};
use std::path::{Path, PathBuf};

/// The quick scenario, 15 times as long and 5 times as dense: 150 000 samples, long enough to
/// signal or kill calib while the log is written. Written to `dir/long.toml`.
pub fn long_scenario(dir: &Path) -> PathBuf {
    let text = quick_with(&[
        ("revolutions = 2.0", "revolutions = 30.0"),
        ("rate_hz = 200.0", "rate_hz = 1000.0"),
    ]);
    write(dir, "long.toml", &text)
}

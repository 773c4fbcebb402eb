//! The air-bearing coast of `testdata/scenarios/spindown.toml` and `calib tdr` on it.
//!
//! Declared by the tests that use it: `#[path = "common/coast.rs"] mod coast;`.

use crate::common::{calib, s, simulate, testdata};
use std::path::{Path, PathBuf};
use std::process::Output;

/// The simulated coast in `dir`: encoder `enc` and reference `ref` on one shaft.
pub fn coast_log(dir: &Path) -> PathBuf {
    simulate(&testdata("scenarios/spindown.toml"), dir, "coast.mcap")
}

/// Runs `calib tdr LOG --channel enc --ref ref -o OUT`.
pub fn tdr_with_reference(log: &Path, out: &Path) -> Output {
    calib(&[
        "tdr",
        s(log),
        "--channel",
        "enc",
        "--ref",
        "ref",
        "-o",
        s(out),
    ])
}

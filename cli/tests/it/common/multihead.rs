//! The SelfA run of `testdata/scenarios/multihead.toml` and `calib multihead` on it.
//!
//! Declared by the tests that use it: `#[path = "common/multihead.rs"] mod multihead;`.

use crate::common::{calib, s, simulate, testdata};
use std::path::{Path, PathBuf};
use std::process::Output;

/// The SelfA heads of `testdata/scenarios/multihead.toml`, numbered as in the paper.
pub const HEADS: &str = "h1@0,h2@360/7,h3@90,h4@720/7,h5@120,h6@1080/7,h7@180,h8@1440/7,h9@240,\
                         h10@1800/7,h11@270,h12@2160/7";

/// The simulated SelfA log in `dir` (8801 samples of 12 heads).
pub fn selfa_log(dir: &Path) -> PathBuf {
    simulate(&testdata("scenarios/multihead.toml"), dir, "selfa.mcap")
}

/// Runs `calib multihead LOG --heads HEADS -o OUT EXTRA…`.
pub fn multihead(log: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["multihead", s(log), "--heads", HEADS, "-o", s(out)];
    args.extend_from_slice(extra);
    calib(&args)
}

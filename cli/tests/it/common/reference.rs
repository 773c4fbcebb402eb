//! `calib reference` runs: one sensor against a reference encoder on the same shaft.
//!
//! Declared by the tests that run it: `#[path = "common/reference.rs"] mod reference;`.

use crate::common::{calib, s};
use std::path::Path;
use std::process::Output;

/// Runs `calib reference LOG --dut DUT --ref REFERENCE -o OUT EXTRA…`.
pub fn reference(log: &Path, dut: &str, reference: &str, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "reference",
        s(log),
        "--dut",
        dut,
        "--ref",
        reference,
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    calib(&args)
}

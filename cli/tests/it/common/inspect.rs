//! `calib inspect` runs that must succeed, for the tests of what it finds in a log.
//!
//! Declared by the tests that use it: `#[path = "common/inspect.rs"] mod inspect;`.

use crate::common::{calib, expect_exit, s, stdout};
use serde_json::Value;
use std::path::Path;

/// Runs `calib inspect LOG EXTRA…`, which must succeed; what it printed.
#[track_caller]
pub fn inspect(log: &Path, extra: &[&str]) -> String {
    let mut args = vec!["inspect", s(log)];
    args.extend_from_slice(extra);
    let o = calib(&args);
    expect_exit(&o, 0);
    stdout(&o)
}

/// Runs `calib inspect LOG --json EXTRA…`, which must succeed; the JSON it printed.
#[track_caller]
pub fn inspect_json(log: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["inspect", s(log), "--json"];
    args.extend_from_slice(extra);
    let o = calib(&args);
    expect_exit(&o, 0);
    serde_json::from_str(&stdout(&o)).unwrap_or_else(|e| panic!("{e}:\n{}", stdout(&o)))
}

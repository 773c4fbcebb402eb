//! The JSON files calib writes (report.json, summary.json), read back.
//!
//! Declared by the tests that read them: `#[path = "common/json.rs"] mod json;`.

use serde_json::Value;
use std::path::Path;

/// The JSON file at `path`; panics naming the file if it cannot be read.
pub fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

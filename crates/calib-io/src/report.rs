//! JSON outputs (`report.json`), written atomically with stable formatting.

use crate::Error;
use crate::atomic::write_atomic;
use std::path::Path;

/// The pretty-printed JSON of `value` with a trailing newline: what [`write_json`] writes.
pub fn render_json<T: serde::Serialize>(value: &T) -> Result<String, serde_json::Error> {
    let mut s = serde_json::to_string_pretty(value)?;
    s.push('\n');
    Ok(s)
}

/// Writes `value` as pretty-printed JSON to `path`; the file appears only when complete.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), Error> {
    let text = render_json(value).map_err(|e| Error::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(path, text.as_bytes())
}

//! JSON outputs (`report.json`) with stable formatting; the CLI writes them with its other
//! outputs, all atomically.

/// The pretty-printed JSON of `value` with a trailing newline, as report.json is written.
pub fn render_json<T: serde::Serialize>(value: &T) -> Result<String, serde_json::Error> {
    let mut s = serde_json::to_string_pretty(value)?;
    s.push('\n');
    Ok(s)
}

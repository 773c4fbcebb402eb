//! Exit statuses: `0` success, `1` bad or insufficient data, `2` bad usage, `3` a gate failed.

/// Bad or insufficient data.
pub const DATA: u8 = 1;
/// Bad usage: an option or argument that cannot work whatever the data.
pub const USAGE: u8 = 2;
/// A gate failed (`--max-pp`, `--max-residual`, `--fail-on-warning`, En > 1 in `calib compare`):
/// the outputs were written, but the result is not good enough.
pub const GATE: u8 = 3;

/// An error in how calib was called (as opposed to what the data holds).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Usage(pub String);

/// A run that wrote its outputs and has a summary to print, but must exit with `code`: a gate
/// failed, or some of several logs could not be calibrated.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct Failed {
    /// What goes to standard output, as for a successful run.
    pub stdout: String,
    /// The exit status.
    pub code: u8,
    /// The one-line reason, for standard error.
    pub message: String,
}

/// An OS error's reason without the `(os error N)` suffix, for a message that names the path
/// and what to do itself.
pub fn os_reason(e: &std::io::Error) -> String {
    let s = e.to_string();
    match s.find(" (os error") {
        Some(i) => s[..i].to_string(),
        None => s,
    }
}

/// The message of an error chain, as `calib: error: …` prints it: each cause once (a cause whose
/// text an outer one already quotes is left out, so an OS error is not printed twice), the
/// system's `(os error N)` dropped, what to do added for the common OS errors, and control
/// characters escaped.
pub fn render(err: &anyhow::Error) -> String {
    let mut message = String::new();
    let mut hint = None;
    for cause in err.chain() {
        let text = cause.to_string();
        if let Some(io) = cause.downcast_ref::<std::io::Error>() {
            hint = hint.or_else(|| io_hint(io));
        }
        if message.contains(&text) {
            continue;
        }
        if !message.is_empty() {
            message.push_str(": ");
        }
        message.push_str(&text);
    }
    let mut message = crate::flags::in_cli_words(&strip_os_error(&message));
    if let Some(hint) = hint {
        message.push_str("; ");
        message.push_str(hint);
    }
    crate::ui::escape_controls(&message)
}

/// `text` without the ` (os error N)` the system appends.
fn strip_os_error(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(" (os error ") {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        match rest.find(')') {
            Some(j) => rest = &rest[j + 1..],
            None => break,
        }
    }
    out.push_str(rest);
    out
}

/// What to do about an OS error, for the kinds a user can act on.
fn io_hint(e: &std::io::Error) -> Option<&'static str> {
    use std::io::ErrorKind as K;
    Some(match e.kind() {
        K::PermissionDenied => "check its permissions, or choose a path you can read or write",
        K::StorageFull => "free some space on that disk, or write the outputs elsewhere",
        K::ReadOnlyFilesystem => "that file system is read-only: write the outputs elsewhere",
        K::IsADirectory => "that is a folder: name a file",
        K::NotADirectory => "a part of the path is a file, not a folder: check the path",
        K::AlreadyExists => "something is in the way at that path: remove it or choose another",
        _ => return None,
    })
}

/// The exit status for an error: a [`Failed`] run's own code; [`USAGE`] if any error in its
/// chain is a [`Usage`] error or an unknown unit or channel name; else [`DATA`].
pub fn code_of(err: &anyhow::Error) -> u8 {
    if let Some(f) = err.downcast_ref::<Failed>() {
        return f.code;
    }
    let usage = err.chain().any(|e| {
        e.is::<Usage>()
            || e.is::<calib_core::angle::UnknownUnit>()
            || e.is::<calib_core::UnknownChannel>()
            || e.is::<calib_io::ChannelLookup>()
    });
    if usage { USAGE } else { DATA }
}

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

/// The exit status for an error: a [`Failed`] run's own code; [`USAGE`] if any error in its
/// chain is a [`Usage`] error or an unknown unit or channel name; else [`DATA`].
pub fn code_of(err: &anyhow::Error) -> u8 {
    if let Some(f) = err.downcast_ref::<Failed>() {
        return f.code;
    }
    let usage = err.chain().any(|e| {
        e.is::<Usage>()
            || e.is::<calib_core::angle::UnknownUnit>()
            || e.is::<calib_core::sample::UnknownChannel>()
            || e.is::<calib_io::naming::ChannelLookup>()
    });
    if usage { USAGE } else { DATA }
}

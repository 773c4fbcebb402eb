//! Exit statuses: `0` success, `1` bad or insufficient data, `2` bad usage.

/// Bad or insufficient data.
pub const DATA: u8 = 1;
/// Bad usage: an option or argument that cannot work whatever the data.
pub const USAGE: u8 = 2;

/// An error in how calib was called (as opposed to what the data holds).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Usage(pub String);

/// The exit status for an error: [`USAGE`] if any error in its chain is a [`Usage`] error or an
/// unknown unit or channel name, else [`DATA`].
pub fn code_of(err: &anyhow::Error) -> u8 {
    let usage = err.chain().any(|e| {
        e.is::<Usage>()
            || e.is::<calib_core::angle::UnknownUnit>()
            || e.is::<calib_core::sample::UnknownChannel>()
    });
    if usage { USAGE } else { DATA }
}

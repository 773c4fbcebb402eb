//! `calib csrr`.

/// Arguments of `calib csrr`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The log to read (.csv or .mcap).
    pub log: std::path::PathBuf,
}

/// Runs `calib csrr`.
pub fn run(_args: &Args) -> anyhow::Result<String> {
    anyhow::bail!("not implemented yet")
}

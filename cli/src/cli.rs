//! Command-line arguments (clap derive). Doc comments here are the `--help` text.

use crate::commands;
use clap::{Parser, Subcommand};

/// Calibrate angular encoders and angle sensors from recorded runs.
///
/// calib reads a log of synchronized sensor samples (CSV, or MCAP with ROS 2 JointState or JSON
/// messages) and writes each sensor's error map as a correction table, plus a report.
///
/// Start with `calib inspect LOG` to see what a log holds, then run a method, e.g.
/// `calib csrr run.mcap -o out/`. Exit status: 0 success, 1 bad or insufficient data, 2 bad usage.
#[derive(Debug, Parser, PartialEq)]
#[command(name = "calib", version, about, long_about)]
pub struct Cli {
    /// Options of every command.
    #[command(flatten)]
    pub global: crate::ui::Global,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand, PartialEq)]
pub enum Command {
    /// Show what a log holds: channels, rates, gaps, segments and CSRR sessions.
    Inspect(commands::inspect::Args),
    /// Write a simulated run with a known truth, from a scenario file.
    Simulate(commands::simulate::Args),
    /// Self-calibrate two coaxial sensors by the CSRR method.
    Csrr(commands::csrr::Args),
    // Help from its `Args` doc.
    Multihead(commands::multihead::Args),
    // The next three take their help from their `Args` docs (a doc comment here would replace it).
    ShiftAngle(commands::shift_angle::Args),
    Uncertainty(commands::uncertainty::Args),
    Compare(commands::compare::Args),
    // Help from its `Args` doc too.
    Reference(commands::reference::Args),
    Export(commands::export::Args),
    // Help from its `Args` doc too.
    Tdr(commands::tdr::Args),
    Apply(commands::apply::Args),
}

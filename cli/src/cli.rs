//! Command-line arguments (clap derive). Doc comments here are the `--help` text.

use crate::commands;
use clap::{Parser, Subcommand};

/// Calibrate angular encoders and angle sensors from recorded runs.
///
/// calib reads a log of synchronized sensor samples (CSV, MCAP with ROS 2 JointState or JSON
/// messages, or a ROS 2 bag: its directory or a .db3 file) and writes each sensor's error map as a
/// correction table, plus a report.
///
/// Start with `calib inspect LOG` to see what a log holds, then run a method, e.g.
/// `calib csrr run.mcap -o out/`. Exit status: 0 success, 1 bad or insufficient data, 2 bad usage,
/// 3 a gate failed (--max-pp, --max-residual, --fail-on-warning, En > 1 in compare; the outputs
/// are written all the same).
#[derive(Debug, Parser, PartialEq)]
#[command(name = "calib", version, about, long_about, after_help = calib_io::limits::help_text())]
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
    // The rest take their help from their `Args` docs (a doc comment here would replace it).
    Simulate(commands::simulate::Args),
    Csrr(commands::csrr::Args),
    Multihead(commands::multihead::Args),
    Tdr(commands::tdr::Args),
    ShiftAngle(commands::shift_angle::Args),
    Reference(commands::reference::Args),
    MoteusDump(commands::moteus_dump::Args),
    Uncertainty(commands::uncertainty::Args),
    Compare(commands::compare::Args),
    Apply(commands::apply::Args),
    Compose(commands::compose::Args),
    Export(commands::export::Args),
    Import(commands::import::Args),
    Plan(commands::plan::Args),
}

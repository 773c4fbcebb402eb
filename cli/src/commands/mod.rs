//! One module per subcommand: each loads its inputs, computes with `calib-core`, and renders.

pub mod apply;
pub mod compare;
pub mod compose;
pub mod csrr;
pub mod export;
pub mod inspect;
pub mod multihead;
pub mod plan;
pub mod reference;
pub mod shift_angle;
pub mod simulate;
pub mod tdr;
pub mod uncertainty;

use crate::cli::{Cli, Command};

/// Runs a command; returns what to print on standard output.
pub fn run(cli: Cli) -> anyhow::Result<String> {
    crate::ui::set(cli.global);
    match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::Csrr(args) => csrr::run(&args),
        Command::Multihead(args) => multihead::run(&args),
        Command::ShiftAngle(args) => shift_angle::run(&args),
        Command::Uncertainty(args) => uncertainty::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Reference(args) => reference::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Tdr(args) => tdr::run(&args),
        Command::Apply(args) => apply::run(&args),
        Command::Compose(args) => compose::run(&args),
        Command::Plan(args) => plan::run(&args),
    }
}

//! One module per subcommand: each loads its inputs, computes with `calib-core`, and renders.

pub mod apply;
pub mod compare;
pub mod compose;
pub mod csrr;
pub mod export;
pub mod import;
pub mod inspect;
pub mod moteus_dump;
pub mod multihead;
pub mod plan;
pub mod reference;
pub mod shift_angle;
pub mod simulate;
pub mod tdr;
pub mod uncertainty;

use crate::cli::{Cli, Command};
use crate::overwrite::Inputs;
use std::path::{Path, PathBuf};

/// Runs a command; returns what to print on standard output.
pub fn run(cli: Cli) -> anyhow::Result<String> {
    crate::ui::set(cli.global);
    crate::overwrite::protect(inputs(&cli.command));
    match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::Csrr(args) => csrr::run(&args),
        Command::Multihead(args) => multihead::run(&args),
        Command::ShiftAngle(args) => shift_angle::run(&args),
        Command::Uncertainty(args) => uncertainty::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Reference(args) => reference::run(&args),
        Command::MoteusDump(args) => moteus_dump::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Import(args) => import::run(&args),
        Command::Tdr(args) => tdr::run(&args),
        Command::Apply(args) => apply::run(&args),
        Command::Compose(args) => compose::run(&args),
        Command::Plan(args) => plan::run(&args),
    }
}

/// Every path a command reads, with what it is: none of them may be written
/// ([`crate::overwrite`]). A new command or input option is listed here.
fn inputs(command: &Command) -> Inputs {
    fn logs(logs: &[PathBuf]) -> Vec<(&Path, &'static str)> {
        logs.iter().map(|l| (l.as_path(), "log")).collect()
    }
    let paths: Vec<(&Path, &'static str)> = match command {
        Command::Inspect(a) => vec![(&a.log, "log")],
        Command::Simulate(a) => a
            .scenario
            .iter()
            .map(|s| (s.as_path(), "scenario"))
            .collect(),
        Command::Csrr(a) => {
            let mut p = logs(&a.common.logs);
            p.extend(a.truth.as_deref().map(|t| (t, "truth")));
            p.extend(a.ref_table.as_deref().map(|t| (t, "table")));
            p
        }
        Command::Multihead(a) => logs(&a.common.logs),
        Command::Tdr(a) => logs(&a.common.logs),
        Command::Reference(a) => {
            let mut p = logs(&a.common.logs);
            p.extend(a.ref_table.as_deref().map(|t| (t, "table")));
            p.extend(a.ref_file.as_deref().map(|f| (f, "reference file")));
            p
        }
        Command::ShiftAngle(a) => {
            let mut p: Vec<_> = a
                .readings
                .iter()
                .map(|r| (r.as_path(), "readings"))
                .collect();
            p.extend(a.budget.as_deref().map(|b| (b, "budget")));
            p
        }
        Command::Uncertainty(a) => vec![(&a.budget, "budget")],
        Command::Compare(a) => vec![(&a.map1, "table"), (&a.map2, "table")],
        Command::Apply(a) => vec![(&a.table, "table"), (&a.log, "log")],
        Command::Compose(a) => vec![(&a.first, "table"), (&a.residual, "table")],
        Command::Export(a) => vec![(&a.table, "table")],
        Command::Import(a) => vec![(&a.file, "table")],
        Command::MoteusDump(a) => vec![(&a.dump, "dump")],
        // A plan reads no file: it is computed from its options.
        Command::Plan(_) => Vec::new(),
    };
    Inputs::new(paths)
}

//! Command-line arguments (clap derive). Doc comments here are the `--help` text.

use crate::overwrite::Inputs;
use crate::{commands, method};
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::path::{Path, PathBuf};

/// The limits calib-io checks before any work ([`calib_io::limits`]), as `--help` lists them.
fn limits_help() -> String {
    use calib_io::limits::*;
    format!(
        "Limits (checked before any work): --points at most {MAX_TABLE_POINTS} for every table; \
         calib simulate writes at most {MAX_SIMULATED_SAMPLES} samples unless --force; CSV lines \
         at most {MAX_CSV_LINE_BYTES} bytes and {MAX_CSV_COLUMNS} columns; readings within \
         ±{MAX_READING_REV:e} revolutions and time stamps within ±{MAX_TIME_S:e} s; MCAP files and \
         bags at most {MAX_TOPICS} topics, {MAX_JOINTS} joints per JointState message, \
         {MAX_JSON_FIELDS} fields per JSON message and {MAX_MESSAGE_TYPES} types per message \
         definition; MCAP records inside chunks at most {MAX_MCAP_RECORD_BYTES} bytes (or the \
         file's length); bag payloads at most {MAX_PAYLOAD_BYTES} bytes decompressed, bag splits \
         at most {MAX_DECOMPRESSION_RATIO}× their compressed size."
    )
}

/// Calibrate angular encoders and angle sensors from recorded runs.
///
/// calib reads a log of synchronized sensor samples (CSV, MCAP with ROS 2 JointState or JSON
/// messages, a ROS 2 bag: its directory or a .db3 file, or a ROS 1 .bag file) and writes each
/// sensor's error map as a correction table, plus a report.
///
/// Start with `calib inspect LOG` to see what a log holds, then run a method, e.g.
/// `calib csrr run.mcap -o out/`. Exit status: 0 success, 1 bad or insufficient data, 2 bad usage,
/// 3 a gate failed (--max-pp, --max-residual, --fail-on-warning, En > 1 in compare; the outputs
/// are written all the same).
#[derive(Debug, Parser, PartialEq)]
#[command(name = "calib", version, after_help = limits_help())]
pub struct Cli {
    /// Options of every command.
    #[command(flatten)]
    pub global: crate::ui::Global,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

impl Cli {
    /// The arguments of this process, parsed by [`command`] (exits with clap's message and
    /// status 2 on bad usage, and after printing `--help` or `--version`).
    pub fn from_env() -> Self {
        let matches = command().get_matches();
        Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
    }
}

/// The command line as clap parses and prints it: the derived one, with every command's short
/// help (`-h`, the command list) set to the first paragraph of its long help (`--help`), so the
/// two start with the same sentence (clap derive drops the short one's final period).
pub fn command() -> clap::Command {
    same_first_sentence(Cli::command())
}

/// `cmd` and its subcommands, each with its short help set to its long help's first paragraph.
fn same_first_sentence(cmd: clap::Command) -> clap::Command {
    let long = cmd
        .get_long_about()
        .or(cmd.get_about())
        .map(|text| first_paragraph(&text.to_string()));
    let cmd = match long {
        Some(about) => cmd.about(about),
        None => cmd,
    };
    let names: Vec<String> = cmd
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    names.into_iter().fold(cmd, |cmd, name| {
        cmd.mut_subcommand(name, same_first_sentence)
    })
}

/// The first paragraph of a help text on one line, ending with a period.
fn first_paragraph(text: &str) -> String {
    let paragraph = text.trim_start().split("\n\n").next().unwrap_or("");
    let line = paragraph.split_whitespace().collect::<Vec<_>>().join(" ");
    match line.ends_with(['.', ':', '?']) {
        true => line,
        false => format!("{line}."),
    }
}

/// The subcommands.
#[derive(Debug, Subcommand, PartialEq)]
pub enum Command {
    /// Show what a log holds: channels, rates, gaps, segments and CSRR sessions.
    Inspect(commands::inspect::Args),
    // The rest take their help from their `Args` docs (a doc comment here would replace it).
    Simulate(commands::simulate::Args),
    Csrr(method::csrr::Args),
    Multihead(method::multihead::Args),
    Tdr(method::tdr::Args),
    ShiftAngle(method::shift_angle::Args),
    Reference(method::reference::Args),
    MoteusDump(commands::moteus_dump::Args),
    Uncertainty(commands::uncertainty::Args),
    Compare(commands::compare::Args),
    Apply(commands::apply::Args),
    Compose(commands::compose::Args),
    Export(commands::export::Args),
    Import(commands::import::Args),
    Plan(commands::plan::Args),
}

impl Command {
    /// The command's `--jobs`, where it has one (see [`crate::threads`]).
    pub fn jobs(&self) -> Option<u16> {
        match self {
            Command::Inspect(a) => a.jobs,
            Command::Csrr(a) => a.common.batch.jobs,
            Command::Multihead(a) => a.common.batch.jobs,
            Command::Tdr(a) => a.common.batch.jobs,
            Command::Reference(a) => a.common.batch.jobs,
            Command::ShiftAngle(a) => a.batch.jobs,
            Command::Apply(a) => a.jobs,
            _ => None,
        }
    }

    /// The command's `--force`, where it has one: replace files calib did not write
    /// ([`crate::output::check_replaces_only_calibs`]).
    pub fn force(&self) -> bool {
        match self {
            Command::Inspect(_) | Command::Uncertainty(_) => false,
            Command::Simulate(a) => a.force,
            Command::Csrr(a) => a.common.batch.force,
            Command::Multihead(a) => a.common.batch.force,
            Command::Tdr(a) => a.common.batch.force,
            Command::Reference(a) => a.common.batch.force,
            Command::ShiftAngle(a) => a.batch.force,
            Command::MoteusDump(a) => a.force,
            Command::Compare(a) => a.force,
            Command::Apply(a) => a.force,
            Command::Compose(a) => a.force,
            Command::Export(a) => a.force,
            Command::Import(a) => a.force,
            Command::Plan(a) => a.force,
        }
    }

    /// Every path the command reads, with what it is: none of them may be written
    /// ([`crate::overwrite`]). A new command or input option is listed here.
    pub fn inputs(&self) -> Inputs {
        fn logs(logs: &[PathBuf]) -> Vec<(&Path, &'static str)> {
            logs.iter().map(|l| (l.as_path(), "log")).collect()
        }
        let paths: Vec<(&Path, &'static str)> = match self {
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
            Command::Compare(a) => {
                // With --against, MAP1 is the new run's folder.
                let what = if a.against.is_some() { "run" } else { "table" };
                let mut p = vec![(a.map1.as_path(), what)];
                p.extend(a.map2.as_deref().map(|m| (m, "table")));
                p.extend(a.against.as_deref().map(|r| (r, "run")));
                p
            }
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
}

#[cfg(test)]
mod tests {
    /// `calib CMD -h` and `calib CMD --help` start with the same sentence, for every command
    /// and the tool itself (issue 31), and the command list shows that sentence.
    #[test]
    fn short_and_long_help_start_alike() {
        fn check(cmd: &mut clap::Command, path: &str) {
            let path = format!("{path} {}", cmd.get_name()).trim().to_string();
            let short = cmd.render_help().to_string();
            let long = cmd.render_long_help().to_string();
            let first = |help: &str| help.lines().next().unwrap_or("").to_string();
            let (s, l) = (first(&short), first(&long));
            assert!(s.ends_with('.'), "{path} -h: {s}");
            assert!(
                l.starts_with(s.trim_end_matches('.')) || s.starts_with(&l),
                "{path}: -h starts {s:?}, --help {l:?}"
            );
            let names: Vec<String> = cmd
                .get_subcommands()
                .map(|c| c.get_name().to_string())
                .collect();
            for name in names {
                if name != "help" {
                    check(cmd.find_subcommand_mut(&name).unwrap(), &path);
                }
            }
        }
        check(&mut super::command(), "");
        let list = super::command().render_help().to_string();
        assert!(
            list.contains("inspect      Show what a log holds: channels, rates, gaps, segments and CSRR sessions."),
            "{list}"
        );
    }

    /// The channel-naming paragraph is written once and shown by every command that reads a log.
    #[test]
    fn every_log_command_explains_channel_names_once() {
        let mut cli = super::command();
        let names = crate::input::channel_names();
        for name in ["inspect", "csrr", "multihead", "tdr", "reference"] {
            let help = cli
                .find_subcommand_mut(name)
                .unwrap()
                .render_long_help()
                .to_string();
            assert_eq!(help.matches(names.as_str()).count(), 1, "{name}: {help}");
        }
    }
}

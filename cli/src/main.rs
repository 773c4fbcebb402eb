//! `calib`: calibrate angular encoders and angle sensors from recorded runs.

// Doc comments on the argument structs are clap's `--help` text, written for a terminal (TOML
// tables such as `[[component]]`, placeholders such as `<a>.csv`), not rustdoc markup.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

mod batch;
mod cli;
mod commands;
mod document;
mod exit;
mod flags;
mod input;
mod json;
mod method;
mod output;
mod overwrite;
mod reference_table;
#[cfg(test)]
mod schema;
mod summary;
mod threads;
mod ui;
mod units;

use std::io::Write;
use std::process::ExitCode;

fn main() -> ExitCode {
    clean_up_on_signals();
    let cli = cli::Cli::from_env();
    let (output, code) = match run(cli) {
        Ok(output) => (output, 0),
        // Outputs written and a summary to print, but a non-zero status (a gate, failed logs).
        Err(err) if err.is::<exit::Failed>() => {
            let failed = err.downcast::<exit::Failed>().expect("checked by is()");
            eprintln!("calib: {}", failed.message);
            (failed.stdout, failed.code)
        }
        Err(err) => {
            eprintln!("calib: error: {}", exit::render(&err));
            return ExitCode::from(exit::code_of(&err));
        }
    };
    let mut stdout = std::io::stdout().lock();
    match stdout
        .write_all(output.as_bytes())
        .and_then(|()| stdout.flush())
    {
        // A closed pipe (`calib … | head`) is not a failure of calib.
        Ok(()) => ExitCode::from(code),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::from(code),
        Err(e) => {
            eprintln!("calib: cannot write to standard output: {e}");
            ExitCode::from(exit::DATA)
        }
    }
}

/// Runs a command; returns what to print on standard output.
fn run(cli: cli::Cli) -> anyhow::Result<String> {
    use cli::Command;
    ui::set(cli.global);
    threads::declare(cli.command.jobs())?;
    overwrite::protect(cli.command.inputs());
    output::allow_replacing(cli.command.force());
    match cli.command {
        Command::Inspect(args) => commands::inspect::run(&args),
        Command::Simulate(args) => commands::simulate::run(&args),
        Command::Csrr(args) => method::run(&args),
        Command::Multihead(args) => method::run(&args),
        Command::Tdr(args) => method::run(&args),
        Command::Reference(args) => method::run(&args),
        Command::ShiftAngle(args) => method::run(&args),
        Command::Uncertainty(args) => commands::uncertainty::run(&args),
        Command::Compare(args) => commands::compare::run(&args),
        Command::MoteusDump(args) => commands::moteus_dump::run(&args),
        Command::Export(args) => commands::export::run(&args),
        Command::Import(args) => commands::import::run(&args),
        Command::Apply(args) => commands::apply::run(&args),
        Command::Compose(args) => commands::compose::run(&args),
        Command::Plan(args) => commands::plan::run(&args),
    }
}

/// On SIGINT or SIGTERM, removes this run's temporary files and folders and exits with
/// 128 + the signal's number, as a shell reports a process killed by it. Outputs already renamed
/// into place stay: each is complete.
fn clean_up_on_signals() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            eprintln!("calib: interrupted; removing this run's temporary files");
            calib_io::atomic::remove_live_and_exit(128 + signal);
        }
    });
}

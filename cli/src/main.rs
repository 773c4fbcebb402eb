//! `calib`: calibrate angular encoders and angle sensors from recorded runs.

// Doc comments on the argument structs are clap's `--help` text, written for a terminal (TOML
// tables such as `[[component]]`, placeholders such as `<a>.csv`), not rustdoc markup.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

mod cli;
mod commands;
mod document;
mod exit;
mod input;
mod output;
mod summary;
mod ui;

use clap::Parser;
use std::io::Write;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match commands::run(cli) {
        Ok(output) => {
            let mut stdout = std::io::stdout().lock();
            match stdout
                .write_all(output.as_bytes())
                .and_then(|()| stdout.flush())
            {
                // A closed pipe (`calib … | head`) is not a failure of calib.
                Ok(()) => ExitCode::SUCCESS,
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("calib: cannot write to standard output: {e}");
                    ExitCode::from(exit::DATA)
                }
            }
        }
        Err(err) => {
            eprintln!("calib: error: {err:#}");
            ExitCode::from(exit::code_of(&err))
        }
    }
}

//! What every method command (csrr, multihead, tdr, reference) shares: the arguments that name
//! its logs, output, unit and output form ([`MethodArgs`], flattened into each command's
//! `Args`), and the loop that reads a log's channels ([`for_each_sample`]). A new method needs
//! its core module, an `Args` struct flattening [`MethodArgs`], and a render function.

use crate::batch::{self, BatchArgs, Outcome};
use crate::input::{LogArgs, open_selected, parse_unit};
use crate::units::UnitCheck;
use anyhow::Context;
use calib_core::{AngleUnit, Sample};
use calib_io::LogReader;
use calib_io::prefetch::Prefetch;
use std::path::{Path, PathBuf};

/// The arguments of every method command.
#[derive(Debug, clap::Args, PartialEq)]
pub struct MethodArgs {
    /// The logs (.csv, .mcap, or a rosbag2 bag: its directory or a .db3 file), calibrated
    /// independently and in parallel.
    #[arg(required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long = "output", default_value = "calib-out")]
    pub output: PathBuf,
    /// Unit of CSV, JSON and std_msgs readings: deg (the default), rad, arcsec, rev, counts:N.
    /// JointState positions are radians. Without it, readings that fit radians or counts and
    /// not degrees (a whole turn within [0, 2π), whole numbers beyond 1024) are refused, naming
    /// the likely unit.
    #[arg(long, value_parser = parse_unit)]
    pub unit: Option<AngleUnit>,
    /// Print report.json on standard output instead of the summary (summary.json with several
    /// logs).
    #[arg(long)]
    pub json: bool,
    /// Pipelines and gates.
    #[command(flatten)]
    pub batch: BatchArgs,
    /// How the log is timed (CSV time column, MCAP stamps) and its channels aligned.
    #[command(flatten)]
    pub input: LogArgs,
}

impl MethodArgs {
    /// Calibrates every log with `calibrate(log, folder)` as the method `method`
    /// ([`batch::run`]): the folders, gates, summary.json and exit status of every method.
    pub fn run<F>(&self, method: &str, calibrate: F) -> anyhow::Result<String>
    where
        F: Fn(&Path, &Path) -> anyhow::Result<Outcome> + Sync,
    {
        crate::units::declare(self.unit);
        batch::run(
            method,
            &self.logs,
            &self.output,
            &self.batch,
            self.json,
            calibrate,
        )
    }

    /// Opens `log` reading the channels `names` only, in this order, the first setting the
    /// clock ([`open_selected`]): sample value `k` is channel `names[k]`.
    pub fn open(&self, log: &Path, names: &[&str]) -> anyhow::Result<LogReader> {
        open_selected(log, self.unit, &self.input, names)
    }
}

/// Reads every sample of `reader` (opened on `log` by [`MethodArgs::open`]) and calls `push`
/// with it. Decoding runs ahead on a second thread ([`Prefetch`]) while this one pushes; a
/// progress bar shows on a terminal; a sample that cannot be read stops the loop with an error
/// naming the log; readings that fit another unit than the default they were read in are a
/// usage error once all are read ([`UnitCheck`]). Returns the reader, for its warnings and
/// alignment.
pub fn for_each_sample(
    log: &Path,
    reader: LogReader,
    mut push: impl FnMut(&Sample),
) -> anyhow::Result<LogReader> {
    let bar = crate::ui::reading(log);
    let mut units = UnitCheck::new(&reader);
    let mut samples = Prefetch::new(reader);
    for (n, sample) in samples.by_ref().enumerate() {
        let s = sample.with_context(|| format!("cannot read {}", log.display()))?;
        if n as u64 % crate::ui::TICK == 0 {
            bar.inc(crate::ui::TICK);
        }
        units.push(&s.values);
        push(&s);
    }
    bar.finish_and_clear();
    units.finish(log)?;
    Ok(samples.finish())
}

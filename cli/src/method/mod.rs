//! What every method command (csrr, multihead, tdr, reference, shift-angle) shares: the
//! arguments that name its logs, output, unit and output form ([`MethodArgs`], flattened into
//! each command's `Args`), the loop that reads a log's channels ([`for_each_sample`]), the context
//! a failed run's error gets from its log ([`in_log`]), and the tail of every run ([`finish_log`],
//! [`finish`]): its report, report.json, the tables, report.html and the summary, written and
//! rendered the same way for every method. `CONTRIBUTING.md` lists the files a new method touches.

pub mod csrr;
pub mod multihead;
pub mod reference;
pub mod shift_angle;
pub mod tdr;

use crate::batch::{self, BatchArgs, ChannelFigures, Outcome};
use crate::input::{
    LogArgs, alignment_detail, alignment_text, command_line, open_selected, parse_unit,
};
use crate::units::UnitCheck;
use anyhow::Context;
use calib_core::report::ReportSection;
use calib_core::{AngleUnit, Report, SampleRef};
use calib_io::LogReader;
use calib_report::Document;
use std::path::{Path, PathBuf};

/// The arguments of every method command.
#[derive(Debug, clap::Args, PartialEq)]
#[command(next_help_heading = "Logs and outputs")]
pub struct MethodArgs {
    /// The logs (.csv, .mcap, a rosbag2 bag: its directory or a .db3 file, or a ROS 1 .bag),
    /// calibrated independently and in parallel. A log may be a URL — s3://BUCKET/KEY,
    /// gs://BUCKET/KEY, az://CONTAINER/KEY, http(s)://HOST/PATH — read where it is, with the
    /// credentials the cloud's own tools take from the environment (docs/recordings.md); the
    /// outputs stay local.
    #[arg(required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Output folder (created if missing): the tables, report.json and report.html.
    #[arg(
        short,
        long = "output",
        value_name = "DIR",
        default_value = "calib-out"
    )]
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
    /// How each run's outputs are presented.
    pub fn presentation(&self) -> Presentation<'_> {
        Presentation {
            json: self.json,
            plots: self.batch.plots.as_deref(),
        }
    }

    /// Where the runs of a method over these logs go.
    pub fn runs(&self) -> Runs<'_> {
        Runs {
            inputs: &self.logs,
            output: &self.output,
            batch: &self.batch,
            json: self.json,
            unit: self.unit,
        }
    }

    /// Opens `log` reading the channels `names` only, in this order, the first setting the
    /// clock ([`open_selected`]): sample value `k` is channel `names[k]`.
    pub fn open(&self, log: &Path, names: &[&str]) -> anyhow::Result<LogReader> {
        open_selected(log, self.unit, &self.input, names)
    }
}

/// A calibration method: its arguments check themselves and prepare what every input's run
/// shares before any input is read, then calibrate one input into one folder (load with
/// calib-io, compute with calib-core, and [`finish_log`] or [`finish`]); [`run`] does the rest.
/// A new method is a folder here (`mod.rs`: its `Args` and this trait; `summary.rs`;
/// `document.rs`), a variant of [`crate::cli::Command`] and a line of `main.rs`'s dispatch.
pub trait Method: Sync {
    /// The method's name in report.json and summary.json.
    const NAME: &'static str;
    /// What every input's run shares: parsed options, a reference's table.
    type Prepared: Sync;
    /// The inputs, the output folder and how the runs are gated.
    fn runs(&self) -> Runs<'_>;
    /// Checks the arguments (a usage error, exit 2, before any input is read) and prepares what
    /// every run shares.
    fn prepare(&self) -> anyhow::Result<Self::Prepared>;
    /// Calibrates `input` into the folder `out`.
    fn calibrate(
        &self,
        prepared: &Self::Prepared,
        input: &Path,
        out: &Path,
    ) -> anyhow::Result<Outcome>;
}

/// Where a method's runs go.
pub struct Runs<'a> {
    /// The inputs, each calibrated independently (in parallel with several).
    pub inputs: &'a [PathBuf],
    /// The output folder (one subfolder per input with several).
    pub output: &'a Path,
    /// Pipelines and gates.
    pub batch: &'a BatchArgs,
    /// report.json (summary.json) on standard output instead of the summary.
    pub json: bool,
    /// The unit readings are declared in, for the unit check.
    pub unit: Option<AngleUnit>,
}

/// Runs the method `m` over its inputs ([`batch::run`]): the folders, gates, summary.json and
/// exit status of every method.
pub fn run<M: Method>(m: &M) -> anyhow::Result<String> {
    let prepared = m.prepare()?;
    let runs = m.runs();
    if runs.json {
        crate::ui::json_output();
    }
    crate::units::declare(runs.unit);
    batch::run(
        M::NAME,
        runs.inputs,
        runs.output,
        runs.batch,
        runs.json,
        |input, out| m.calibrate(&prepared, input, out),
    )
}

/// Reads every sample of `reader` (opened on `log` by [`MethodArgs::open`]) and calls `push`
/// with it. Decoding runs ahead on a second thread ([`crate::threads::prefetch`]) while this
/// one pushes; a progress line with the bytes read of the log's size and the time left shows on
/// a terminal (not with `--quiet` or `--json`); a sample that cannot be read stops the loop with
/// an error
/// naming the log; readings that fit another unit than the one they were read in are a
/// data error once all are read ([`UnitCheck`]). Returns the reader, for its warnings and
/// alignment.
pub fn for_each_sample(
    log: &Path,
    reader: LogReader,
    mut push: impl FnMut(SampleRef),
) -> anyhow::Result<LogReader> {
    let progress = reader.progress();
    let bar = crate::ui::reading(log, &progress);
    let mut units = UnitCheck::new(&reader);
    let mut samples = crate::threads::prefetch(reader);
    while let Some(batch) = samples.next_batch() {
        let batch = batch.with_context(|| format!("cannot read {}", log.display()))?;
        crate::ui::advance(&bar, &progress);
        for s in batch.iter() {
            units.push(s.values);
            push(s);
        }
    }
    bar.finish_and_clear();
    units.finish(log)?;
    let reader = samples.finish();
    if let Some(note) = reader.remote_note() {
        crate::ui::note(&note);
    }
    Ok(reader)
}

/// A method's error, with what the CSV time column's step and the readings' speed say where
/// they fit another unit better: a column in milliseconds read as seconds makes every speed 1000×
/// too slow, one in seconds read as milliseconds 1000× too fast. `still`: the error says the run
/// moved slower than this speed, rad/s (a channel that "never moves"), so a smaller unit that
/// would make it fast enough is named too.
pub fn with_time_hint<E>(err: E, reader: &LogReader, still: Option<f64>) -> anyhow::Error
where
    E: std::error::Error + Send + Sync + 'static,
{
    let hint = match still {
        Some(min_speed) => reader.time_unit_hint_when_still(min_speed),
        None => reader.time_unit_hint(),
    };
    match hint {
        Some(hint) => anyhow::anyhow!("{err}; {hint}"),
        None => anyhow::Error::new(err),
    }
}

/// The context a failed run's error gets from its log: a log cut short says so, whatever the
/// method then lacks (a missing session, a short coast) — the cut is the likelier cause.
pub fn in_log(err: anyhow::Error, reader: &LogReader, log: &Path) -> anyhow::Error {
    match &reader.diagnostics().truncated {
        Some(t) => err.context(format!(
            "{} is cut short at byte {} (only the {} messages before it were read)",
            crate::ui::shown(log),
            t.byte_offset,
            t.messages_read
        )),
        None => err,
    }
}

/// How a run's outputs are presented: what the command prints, and the plots beside.
#[derive(Debug, Clone, Copy)]
pub struct Presentation<'a> {
    /// report.json on standard output instead of the summary (`--json`).
    pub json: bool,
    /// Every plot of report.html also written as SVG and PNG into this folder (`--plots`).
    pub plots: Option<&'a Path>,
}

/// What a method's run gives the shared tail ([`finish_log`], [`finish`]).
pub struct Results<'r> {
    /// The method's report section.
    pub section: ReportSection,
    /// The files written beside report.json, `(name, contents)`: the tables.
    pub tables: Vec<(String, Vec<u8>)>,
    /// The channels the gates judge, in the summary's order.
    pub channels: Vec<String>,
    /// RMS of the fit's residuals, arcsec, for methods that fit.
    pub residual_rms_arcsec: Option<f64>,
    /// The method's report.html, from the finished report.
    pub document: Box<dyn FnOnce(&Report) -> Document + 'r>,
    /// The method's summary, from the finished report.
    pub summary: Box<dyn FnOnce(&Report) -> String + 'r>,
}

/// The tail of a run over `log` read by `reader`: [`finish`] with the log as the input, the
/// reader's warnings first, and how its channels were aligned in the report and before the
/// summary.
pub fn finish_log(
    reader: &LogReader,
    log: &Path,
    out: &Path,
    shown: Presentation,
    mut results: Results,
) -> anyhow::Result<Outcome> {
    results.section = results
        .section
        .with_alignment(alignment_detail(reader))
        .with_reading(reader.reading())
        .with_time_origin(reader.time_origin_s());
    finish(
        out,
        shown,
        vec![log.display().to_string()],
        reader.warnings(log),
        &alignment_text(reader.alignment().as_ref()),
        results,
    )
}

/// The tail of every run: the report of `results` (calibrated from `inputs`, `warnings` before
/// the method's own), report.json, the tables and report.html written together into `out`
/// ([`crate::output::write_outputs`], the plots too with `--plots`), and what the command prints
/// — the summary after `before`, or report.json with `--json`.
pub fn finish(
    out: &Path,
    shown: Presentation,
    inputs: Vec<String>,
    warnings: Vec<String>,
    before: &str,
    mut results: Results,
) -> anyhow::Result<Outcome> {
    for w in &mut results.section.warnings {
        *w = crate::flags::in_cli_words(w);
    }
    let warnings = warnings
        .iter()
        .map(|w| crate::flags::in_cli_words(w))
        .collect();
    let report = Report::new(results.section, inputs, Some(command_line()), warnings);
    let report_json = calib_io::report::render_json(&report)?;
    let document = (results.document)(&report);
    let mut files = results.tables;
    files.push(("report.json".to_string(), report_json.as_bytes().to_vec()));
    let files = crate::output::write_outputs(out, &files, &document, shown.plots)?;
    let text = if shown.json {
        report_json
    } else {
        before.to_string() + &(results.summary)(&report)
    };
    Ok(Outcome {
        text,
        channels: results
            .channels
            .iter()
            .map(|name| ChannelFigures::of(name, &report.channels[name]))
            .collect(),
        residual_rms_arcsec: results.residual_rms_arcsec,
        warnings: report.warnings,
        files,
    })
}

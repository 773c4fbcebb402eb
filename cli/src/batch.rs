//! Running a method over several logs, for CI pipelines: one output folder per log, calibrated in
//! parallel, gates on the results, `summary.json` and a JUnit XML file.
//!
//! A method command plugs in by flattening [`BatchArgs`] into its arguments and handing
//! [`run`] a closure that calibrates one log into one folder and returns an [`Outcome`].
//!
//! Layout: with one log (and no `--per-log`) the output folder holds that log's files directly,
//! as it always did; with several, `DIR/<log stem>/` holds each log's files (`-2`, `-3`, … added
//! to stems that repeat, in input order) and `DIR/summary.json` the verdict of every log.
//!
//! Exit status over all logs: `2` if a log was bad usage (a missing file, an unknown channel),
//! else `1` if a log could not be calibrated, else `3` if a log failed a gate, else `0`. Every
//! log is processed whatever happens to the others, and every output is written.

use crate::exit::{self, Failed};
use crate::input::file_stem;
use anyhow::Context;
use calib_core::ChannelReport;
use rayon::prelude::*;
use schemars::JsonSchema;
use serde::Serialize;
use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Options every method command shares: plots, pipelines over many logs, and gates.
#[derive(Debug, Clone, clap::Args, PartialEq)]
#[command(next_help_heading = "Plots, several logs and gates")]
pub struct BatchArgs {
    /// Also write every plot of report.html as a standalone SVG and PNG into DIR (one log).
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Threads to compute on (default: the CALIB_JOBS environment variable, else the number of
    /// cores). 1: the log is read and calibrated on one thread. More: a log is read ahead on a
    /// second thread (MCAP chunks decompressed on up to two more) while the solver splits its
    /// work over N threads, and several logs are calibrated N at a time. Results are the same
    /// whatever N.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
    /// Write a JUnit XML file: one test case per log, a <failure> where a gate failed, an
    /// <error> where the log could not be calibrated.
    #[arg(long, value_name = "FILE")]
    pub junit: Option<PathBuf>,
    /// Gate: exit 3 when a calibrated channel's peak-to-peak error exceeds ARCSEC (see
    /// --gate-on). The outputs are written all the same.
    #[arg(long, value_name = "ARCSEC", value_parser = positive_arcsec, allow_hyphen_values = true)]
    pub max_pp: Option<f64>,
    /// What --max-pp judges. before: the calibrated map's peak-to-peak (the sensor's error
    /// without correction). after: what is left after applying the correction, where the
    /// method can measure it: csrr with --truth or --ref (the peak-to-peak of calibrated map −
    /// the true error, or the error the reference sees), tdr with --ref (the same against the
    /// reference), reference (the peak-to-peak of each direction's mean deviation − the map:
    /// the hysteresis the correction cannot remove). Elsewhere the gate fails, naming the
    /// channel.
    #[arg(long, value_enum, value_name = "WHEN", requires = "max_pp")]
    pub gate_on: Option<GateOn>,
    /// Gate: exit 3 when the fit's residual RMS exceeds ARCSEC (csrr joint, multihead joint and
    /// tdr: per sample; shift-angle: per reading). Methods without a fit fail this gate.
    #[arg(long, value_name = "ARCSEC", value_parser = positive_arcsec, allow_hyphen_values = true)]
    pub max_residual: Option<f64>,
    /// Gate: exit 3 when the report of a log has any warning.
    #[arg(long)]
    pub fail_on_warning: bool,
    /// Use the layout for several logs (DIR/<log stem>/, DIR/summary.json) even for one log:
    /// for scripts whose wildcard may match a single file.
    #[arg(long)]
    pub per_log: bool,
    /// Replace an output folder that holds the results of another command or of other logs,
    /// and files in it (or in --plots DIR) that calib did not write, such as your own
    /// report.json beside the logs with -o . (without it either is refused, exit 2, naming the
    /// run or the files, before anything is written: rerunning the same command on the same logs
    /// replaces its results without asking, and calib's own earlier outputs, listed in the
    /// folder's hidden .calib-manifest, are always replaced).
    #[arg(long)]
    pub force: bool,
}

/// What `--max-pp` judges.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, Serialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum GateOn {
    /// The calibrated map's peak-to-peak: the sensor's error without correction.
    Before,
    /// The peak-to-peak left after correction, where the method can measure it.
    After,
}

/// clap value parser for gate thresholds: a positive, finite number of arcseconds.
fn positive_arcsec(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}`: give a positive number of arcseconds")),
    }
}

/// The figures of one calibrated channel that the gates judge.
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
pub struct ChannelFigures {
    /// The channel's name, as in the report.
    pub channel: String,
    /// Peak-to-peak of its calibrated map (its error without correction), arcsec.
    pub peak_to_peak_before_arcsec: f64,
    /// Peak-to-peak left after correction, arcsec, where the method measures it.
    pub peak_to_peak_after_arcsec: Option<f64>,
}

impl ChannelFigures {
    /// The figures of channel `name` from its entry in the report.
    pub fn of(name: &str, ch: &ChannelReport) -> Self {
        ChannelFigures {
            channel: name.to_string(),
            peak_to_peak_before_arcsec: ch.peak_to_peak_arcsec,
            peak_to_peak_after_arcsec: ch.after_correction.as_ref().map(|a| a.peak_to_peak_arcsec),
        }
    }
}

/// What calibrating one log into one folder gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// What the command prints for this log alone: its summary, or report.json with `--json`.
    pub text: String,
    /// Every calibrated channel, in report order.
    pub channels: Vec<ChannelFigures>,
    /// RMS of the fit's residuals, arcsec, for methods that fit.
    pub residual_rms_arcsec: Option<f64>,
    /// The report's warnings.
    pub warnings: Vec<String>,
    /// The files written, relative to the log's output folder.
    pub files: Vec<String>,
}

/// The verdict on one log.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
enum Status {
    Pass,
    Fail,
    Error,
}

/// One log's line in `summary.json`.
#[derive(Debug, Serialize, JsonSchema)]
struct LogResult {
    /// The log, as given.
    log: String,
    /// The log's output folder, relative to the output folder (`.` with one log).
    output: String,
    /// `pass`, `fail` (a gate failed) or `error` (not calibrated).
    status: Status,
    /// Every calibrated channel, in report order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    channels: Vec<ChannelFigures>,
    /// RMS of the fit's residuals, arcsec, for methods that fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    residual_rms_arcsec: Option<f64>,
    /// The report's warnings.
    warnings: Vec<String>,
    /// The gates that failed, one line each.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    gate_failures: Vec<String>,
    /// Why the log could not be calibrated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    error: Option<String>,
    /// The files written, relative to `output`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    files: Vec<String>,
    #[serde(skip)]
    exit_code: u8,
    #[serde(skip)]
    text: String,
}

/// The gates as they were set, for `summary.json`.
#[derive(Debug, Serialize, JsonSchema)]
struct Gates {
    /// `--max-pp`, arcsec.
    max_pp_arcsec: Option<f64>,
    /// What `--max-pp` judges: `before` or `after` correction.
    gate_on: GateOn,
    /// `--max-residual`, arcsec.
    max_residual_arcsec: Option<f64>,
    /// `--fail-on-warning`.
    fail_on_warning: bool,
}

/// `summary.json`: the verdict on every log of a run.
#[derive(Debug, Serialize, JsonSchema)]
pub(crate) struct Summary<'a> {
    /// The version of this file's shape (`calib_core::report::SCHEMA_VERSION`, shared with
    /// report.json).
    schema_version: u32,
    /// Version of calib that wrote it.
    calib_version: &'static str,
    /// The method.
    method: &'a str,
    /// The gates as they were set.
    gates: Gates,
    /// Logs calibrated that passed the gates.
    passed: usize,
    /// Logs calibrated that failed a gate.
    failed: usize,
    /// Logs that could not be calibrated.
    errors: usize,
    /// Every log, in input order.
    logs: &'a [LogResult],
}

/// Calibrates every log of `logs` with `calibrate(log, folder)`, judges each against the gates,
/// and writes `summary.json` (several logs) and the JUnit file. Returns what to print; a run
/// with a failed gate or a failed log returns [`Failed`] with the exit status described in the
/// module's documentation. With one log (and no `--per-log`) the log's own error is returned as
/// it is, so a single calibration behaves exactly as a plain command.
pub fn run<F>(
    method: &str,
    logs: &[PathBuf],
    output: &Path,
    opts: &BatchArgs,
    json: bool,
    calibrate: F,
) -> anyhow::Result<String>
where
    F: Fn(&Path, &Path) -> anyhow::Result<Outcome> + Sync,
{
    crate::output::prepare_folder(output, "-o")?;
    // Held until the run returns: a second run into the folder refuses at once.
    let _lock = crate::output::lock_folder(output, "-o")?;
    if !opts.force {
        crate::output::check_replacing(output, method, logs)?;
    }
    if logs.len() == 1 && !opts.per_log {
        // The reports every method writes, checked now rather than after the calibration (the
        // tables' names, known only then, are checked before anything is written).
        crate::output::check_replaces_only_calibs(
            output,
            ["report.json", "report.html"],
            &format!("-o {}", crate::ui::shown(output)),
        )?;
    }
    if let Some(plots) = &opts.plots {
        check_plots_folder(plots, output)?;
    }
    let _plots_lock = match &opts.plots {
        Some(plots) => {
            crate::output::prepare_folder(plots, "--plots")?;
            Some(crate::output::lock_folder(plots, "--plots")?)
        }
        None => None,
    };
    if let Some(path) = &opts.junit {
        crate::overwrite::check(path, &format!("--junit {}", crate::ui::shown(path)))?;
        crate::output::check_file_replaceable(path, "--junit")?;
    }
    if logs.len() == 1 && !opts.per_log {
        let result = calibrate(&logs[0], output);
        let judged = judge(&logs[0], ".", result.as_ref(), opts);
        if let Some(path) = &opts.junit {
            write_junit(path, method, std::slice::from_ref(&judged))?;
        }
        let outcome = result?;
        if judged.status == Status::Fail {
            return Err(Failed {
                stdout: outcome.text,
                code: exit::GATE,
                message: format!("gate failed: {}", judged.gate_failures.join("; ")),
            }
            .into());
        }
        return Ok(outcome.text);
    }

    if opts.plots.is_some() {
        return Err(exit::Usage(
            "--plots takes one log: with several, each log's report.html holds its plots".into(),
        )
        .into());
    }
    let folders = folder_names(logs);
    let summary_path = output.join("summary.json");
    crate::overwrite::check(&summary_path, &format!("-o {}", crate::ui::shown(output)))?;
    crate::output::check_replaces_only_calibs(
        output,
        ["summary.json"],
        &format!("-o {}", crate::ui::shown(output)),
    )?;
    std::fs::create_dir_all(output)
        .with_context(|| format!("cannot create the output folder {}", output.display()))?;
    // On rayon's threads, as many as `--jobs` (crate::threads); `collect` keeps the input order
    // whatever order the logs finish in.
    let results: Vec<LogResult> = logs
        .par_iter()
        .zip(&folders)
        .map(|(log, folder)| {
            let result = calibrate(log, &output.join(folder));
            judge(log, folder, result.as_ref(), opts)
        })
        .collect();

    let count = |s: Status| results.iter().filter(|r| r.status == s).count();
    let (passed, failed, errors) = (
        count(Status::Pass),
        count(Status::Fail),
        count(Status::Error),
    );
    let summary = Summary {
        schema_version: calib_core::report::SCHEMA_VERSION,
        calib_version: env!("CARGO_PKG_VERSION"),
        method,
        gates: Gates {
            max_pp_arcsec: opts.max_pp,
            gate_on: opts.gate_on.unwrap_or(GateOn::Before),
            max_residual_arcsec: opts.max_residual,
            fail_on_warning: opts.fail_on_warning,
        },
        passed,
        failed,
        errors,
        logs: &results,
    };
    let summary_json = calib_io::report::render_json(&summary)?;
    calib_io::atomic::write_atomic(&summary_path, summary_json.as_bytes())?;
    crate::output::record_written([&summary_path]);
    if let Some(path) = &opts.junit {
        write_junit(path, method, &results)?;
    }

    let stdout = if json {
        summary_json
    } else {
        render_text(&results, output, &summary_path)
    };
    let code = [exit::USAGE, exit::DATA, exit::GATE]
        .into_iter()
        .find(|c| results.iter().any(|r| r.exit_code == *c));
    match code {
        None => Ok(stdout),
        Some(code) => Err(Failed {
            stdout,
            code,
            message: format!(
                "{failed} of {} logs failed a gate, {errors} could not be calibrated; see {}",
                results.len(),
                summary_path.display()
            ),
        }
        .into()),
    }
}

/// Refuses a `--plots` path that names a file of the `-o` folder (`-o out --plots
/// out/report.html`): the plots' folder would be made where a table or report goes.
fn check_plots_folder(plots: &Path, output: &Path) -> anyhow::Result<()> {
    let in_output = plots
        .parent()
        .is_some_and(|parent| crate::output::same_path(parent, output));
    let file_like = plots.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        ["html", "json", "csv", "svg", "png"].contains(&e.to_ascii_lowercase().as_str())
    });
    if in_output && file_like {
        return Err(exit::Usage(format!(
            "--plots {}: this names a file in the -o folder {}, where the tables and reports \
             go; --plots takes a folder for the plot files (SVG and PNG), e.g. --plots {}",
            plots.display(),
            output.display(),
            output.join("plots").display()
        ))
        .into());
    }
    Ok(())
}

/// The output folder of each log: its file stem made safe as a file name, with `-2`, `-3`, …
/// appended where an earlier log already took the name.
fn folder_names(logs: &[PathBuf]) -> Vec<String> {
    let mut taken = BTreeSet::new();
    logs.iter()
        .map(|log| {
            let stem = file_stem(&log.file_stem().unwrap_or_default().to_string_lossy());
            let name = (1..)
                .map(|k| {
                    if k == 1 {
                        stem.clone()
                    } else {
                        format!("{stem}-{k}")
                    }
                })
                .find(|n| !taken.contains(n))
                .expect("an unbounded range has a free name");
            taken.insert(name.clone());
            name
        })
        .collect()
}

/// Judges one log's outcome against the gates.
fn judge(
    log: &Path,
    folder: &str,
    result: Result<&Outcome, &anyhow::Error>,
    opts: &BatchArgs,
) -> LogResult {
    let mut r = LogResult {
        log: log.display().to_string(),
        output: folder.to_string(),
        status: Status::Pass,
        channels: Vec::new(),
        residual_rms_arcsec: None,
        warnings: Vec::new(),
        gate_failures: Vec::new(),
        error: None,
        files: Vec::new(),
        exit_code: 0,
        text: String::new(),
    };
    let o = match result {
        Ok(o) => o,
        Err(e) => {
            r.status = Status::Error;
            r.error = Some(format!("{e:#}"));
            r.exit_code = exit::code_of(e);
            return r;
        }
    };
    if let Some(max) = opts.max_pp {
        let after = opts.gate_on == Some(GateOn::After);
        for c in &o.channels {
            let (value, what) = if after {
                (c.peak_to_peak_after_arcsec, "after correction")
            } else {
                (Some(c.peak_to_peak_before_arcsec), "before correction")
            };
            match value {
                Some(v) if exceeds(v, max) => r.gate_failures.push(format!(
                    "`{}`: peak-to-peak {what} {v:.3}″ > {max}″ (--max-pp)",
                    c.channel
                )),
                Some(_) => {}
                None => r.gate_failures.push(format!(
                    "`{}`: this method and its options give no peak-to-peak after correction (--gate-on after; see --help)",
                    c.channel
                )),
            }
        }
    }
    if let Some(max) = opts.max_residual {
        match o.residual_rms_arcsec {
            Some(v) if exceeds(v, max) => r.gate_failures.push(format!(
                "fit residual RMS {v:.4}″ > {max}″ (--max-residual)"
            )),
            Some(_) => {}
            None => r.gate_failures.push(
                "this method and its options fit no residuals (--max-residual; see --help)".into(),
            ),
        }
    }
    if opts.fail_on_warning {
        for w in &o.warnings {
            r.gate_failures
                .push(format!("warning (--fail-on-warning): {w}"));
        }
    }
    if !r.gate_failures.is_empty() {
        r.status = Status::Fail;
        r.exit_code = exit::GATE;
    }
    r.channels = o.channels.clone();
    r.residual_rms_arcsec = o.residual_rms_arcsec;
    r.warnings = o.warnings.clone();
    r.files = o.files.clone();
    r.text = o.text.clone();
    r
}

/// Whether `value` fails a gate of `max`: above it, or not a number at all.
fn exceeds(value: f64, max: f64) -> bool {
    value > max || value.is_nan()
}

/// Standard output for several logs: each log's summary in input order, then the verdicts.
fn render_text(results: &[LogResult], output: &Path, summary_path: &Path) -> String {
    let mut s = String::new();
    for r in results {
        let _ = writeln!(s, "=== {} → {}", r.log, output.join(&r.output).display());
        match &r.error {
            Some(e) => {
                let _ = writeln!(s, "error: {e}");
            }
            None => s.push_str(&r.text),
        }
        s.push('\n');
    }
    let width = results
        .iter()
        .map(|r| r.log.chars().count())
        .max()
        .unwrap_or(0);
    let _ = writeln!(s, "summary");
    for r in results {
        let (status, why) = match r.status {
            Status::Pass => ("pass", String::new()),
            Status::Fail => ("FAIL", r.gate_failures.join("; ")),
            Status::Error => ("ERROR", r.error.clone().unwrap_or_default()),
        };
        let first_line = why.lines().next().unwrap_or_default();
        let line = format!("  {status:<5}  {:<width$}  {first_line}", r.log);
        let _ = writeln!(s, "{}", line.trim_end());
    }
    let count = |st: Status| results.iter().filter(|r| r.status == st).count();
    let _ = writeln!(
        s,
        "{} logs: {} passed, {} failed a gate, {} could not be calibrated\nwrote {}",
        results.len(),
        count(Status::Pass),
        count(Status::Fail),
        count(Status::Error),
        summary_path.display()
    );
    s
}

/// Writes the JUnit XML file: one `<testcase>` per log.
fn write_junit(path: &Path, method: &str, results: &[LogResult]) -> anyhow::Result<()> {
    calib_io::atomic::write_atomic(path, render_junit(method, results).as_bytes())
        .with_context(|| format!("cannot write the JUnit file {}", path.display()))?;
    crate::output::record_written([path]);
    Ok(())
}

/// The JUnit XML of `results`: no times or host names, so equal runs give equal files.
fn render_junit(method: &str, results: &[LogResult]) -> String {
    let count = |st: Status| results.iter().filter(|r| r.status == st).count();
    let (n, failures, errors) = (results.len(), count(Status::Fail), count(Status::Error));
    let suite = xml_attr(&format!("calib {method}"));
    let mut s = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(
        s,
        "<testsuites name=\"{suite}\" tests=\"{n}\" failures=\"{failures}\" errors=\"{errors}\">"
    );
    let _ = writeln!(
        s,
        "  <testsuite name=\"{suite}\" tests=\"{n}\" failures=\"{failures}\" errors=\"{errors}\" skipped=\"0\">"
    );
    for r in results {
        let _ = writeln!(
            s,
            "    <testcase name=\"{}\" classname=\"{}\">",
            xml_attr(&r.log),
            xml_attr(&format!("calib.{method}"))
        );
        match r.status {
            Status::Pass => {}
            Status::Fail => {
                let _ = writeln!(
                    s,
                    "      <failure type=\"gate\" message=\"{}\">{}</failure>",
                    xml_attr(&r.gate_failures[0]),
                    xml_text(&r.gate_failures.join("\n"))
                );
            }
            Status::Error => {
                let e = r.error.as_deref().unwrap_or_default();
                let kind = if r.exit_code == exit::USAGE {
                    "usage"
                } else {
                    "data"
                };
                let _ = writeln!(
                    s,
                    "      <error type=\"{kind}\" message=\"{}\">{}</error>",
                    xml_attr(e.lines().next().unwrap_or_default()),
                    xml_text(e)
                );
            }
        }
        if !r.text.is_empty() {
            let _ = writeln!(s, "      <system-out>{}</system-out>", xml_text(&r.text));
        }
        let _ = writeln!(s, "    </testcase>");
    }
    s.push_str("  </testsuite>\n</testsuites>\n");
    s
}

/// `text` escaped for an XML 1.0 attribute value: as [`xml_text`], and line breaks and tabs as
/// character references (a parser would turn them into spaces).
fn xml_attr(text: &str) -> String {
    xml_text(text).replace('\n', "&#10;").replace('\t', "&#9;")
}

/// `text` escaped for XML 1.0 character data: markup characters as entities, carriage returns
/// as a character reference (a parser would drop them), and the control characters XML 1.0
/// cannot carry as U+FFFD.
fn xml_text(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\'' => s.push_str("&apos;"),
            '\r' => s.push_str("&#13;"),
            '\n' | '\t' => s.push(c),
            c if (c as u32) < 0x20 || c == '\u{FFFE}' || c == '\u{FFFF}' => s.push('\u{FFFD}'),
            c => s.push(c),
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeated_stems_get_numbered_folders_in_input_order() {
        let logs: Vec<PathBuf> = ["x/run.mcap", "y/run.csv", "run-2.mcap", "z/a b.csv"]
            .iter()
            .map(PathBuf::from)
            .collect();
        assert_eq!(folder_names(&logs), ["run", "run-2", "run-2-2", "a_b"]);
    }

    #[test]
    fn escaping_covers_markup_line_breaks_and_forbidden_controls() {
        let raw = "a<b & \"c\" 'd'>\n\t\r\u{1}é";
        let text = "a&lt;b &amp; &quot;c&quot; &apos;d&apos;&gt;\n\t&#13;\u{FFFD}é";
        assert_eq!(xml_text(raw), text);
        assert_eq!(
            xml_attr(raw),
            text.replace('\n', "&#10;").replace('\t', "&#9;")
        );
    }

    #[test]
    fn gate_thresholds_must_be_positive_numbers() {
        assert_eq!(positive_arcsec("2.5"), Ok(2.5));
        for bad in ["0", "-1", "nan", "inf", "abc", ""] {
            assert!(positive_arcsec(bad).is_err(), "{bad}");
        }
    }
}

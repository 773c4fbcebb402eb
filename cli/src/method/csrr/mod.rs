//! `calib csrr`: self-calibration of two coaxial sensors.

mod document;
mod summary;

use crate::batch::Outcome;
use crate::exit::Usage;
use crate::method::{MethodArgs, Results, finish_log, for_each_sample, in_log, with_time_hint};
use crate::output::{table_name, turn_table};
use crate::reference_table::ReferenceTable;
use anyhow::Context;
use calib_core::ErrorMap;
use calib_core::angle::{ARCSEC_PER_RAD, Unwrapper};
use calib_core::csrr::{Csrr, CsrrError, CsrrOptions, Method};
use calib_core::reference_cal::Latency;
use calib_core::segment::SegmentOptions;
use calib_report::trace::Trace;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};
use summary::render_summary;

/// The solver, as chosen on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// Joint least squares of both maps and every relative rotation (needs a handful of sessions;
    /// exact for large errors; unaffected by speed variation).
    Joint,
    /// The seed paper's method as published (one map point per session; needs many sessions
    /// densely covering 0–360°; sensitive to sampling non-uniformity).
    Paper,
}

/// Self-calibrate two coaxial sensors by the CSRR method (coaxial sensors relative rotation).
///
/// Record the two sensors turning together for whole revolutions (a session), stop, turn one
/// rotor against the other, and repeat: 5 sessions of 3 revolutions at well-spread relative
/// rotations (e.g. 0°, 76°, 87°, 141°, 179°) are plenty for the default joint method. Sessions
/// are found in the log from the motion — both sensors turning the same way while their
/// difference `a − b` repeats from one revolution to the next, whatever the size of their errors,
/// forwards or backwards, at any speed, of at least one revolution — or taken from a CSV
/// `session` column.
///
/// Writes DIR/<a>.csv and DIR/<b>.csv (correction tables: angle_deg, error_arcsec,
/// correction_arcsec; error = reading − true angle, correction = −error, as a function of the
/// sensor's own reading, zero mean), DIR/report.json and DIR/report.html (error maps, spectrum,
/// session timeline), and prints a summary. With several logs, each log's files go to
/// DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// Channels on separate topics are aligned on A's stamps (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
#[command(after_long_help = crate::input::channel_names())]
pub struct Args {
    /// Channel of sensor A (the rotor turned between sessions).
    #[arg(long, default_value = "a")]
    pub a: String,
    /// Channel of sensor B.
    #[arg(long, default_value = "b")]
    pub b: String,
    /// Channel of a reference encoder on B's shaft, to check the result against: what
    /// correction leaves of the error it sees ("after, vs reference") holds the reference's own
    /// error too.
    #[arg(long = "ref")]
    pub reference: Option<String>,
    /// The reference's own calibrated or simulated error table (a whole turn): B's error left
    /// after correction against the reference is split into the part the reference's own error
    /// explains and the rest.
    #[arg(long, value_name = "FILE", requires = "reference")]
    pub ref_table: Option<PathBuf>,
    /// A folder of true error tables `<a>.csv`, `<b>.csv` (as `calib simulate` writes beside a
    /// simulated log) to compare the maps with in report.html.
    #[arg(long, value_name = "DIR")]
    pub truth: Option<PathBuf>,
    /// The solver.
    #[arg(long, value_enum, default_value_t = MethodArg::Joint)]
    pub method: MethodArg,
    /// Highest harmonic order tested (default: 40 % of the samples per revolution of the densest
    /// session, at most 2000). Only orders whose amplitude stands above the noise are kept
    /// (chi-square of A's or B's pair of coefficients above 2·ln(2M/0.01) for M orders tested:
    /// for noise alone a 1 % chance that any passes), so a high value costs time, not accuracy;
    /// orders above it that the residual still holds are warned about (joint method).
    #[arg(long)]
    pub max_order: Option<usize>,
    /// Points of the output tables (default: enough for linear interpolation to 0.01″, ≥ 3600).
    #[arg(long)]
    pub points: Option<usize>,
    /// Largest departure, degrees, of the relative angle `a − b` from its value one revolution
    /// earlier within a session (it is periodic in the shaft's angle whatever the sensors'
    /// errors; a relative turn or a slip is a drift that is not). Default: from each session's
    /// own scatter (10× the RMS departure of its first blocks, at least 0.01°), reported.
    #[arg(long)]
    pub session_tol: Option<f64>,
    /// Speed below which a sensor counts as stopped, degrees per second.
    #[arg(long, default_value_t = 1.0)]
    pub min_speed: f64,
    /// Detect sessions from the motion even when the log has a `session` column.
    #[arg(long)]
    pub detect_sessions: bool,
    /// B's lag behind A, removed by moving B's readings to A's instants (interpolated in
    /// time): two interfaces rarely sample at the same instant (an SSI/BiSS master, a CAN
    /// encoder, a resolver terminal: 1–50 ms), and a lag τ makes `a − b` change by τ × the
    /// change of speed, which no pair of maps can hold (2 ms at 60 r/min: 2592″ between rest
    /// and speed). `auto` measures it from how each session's `a − b` departs from one
    /// revolution earlier as the speed changes (free of the maps) and, where significant, reads
    /// the log again with it removed (up to 4 readings); SECONDS removes this lag (positive: B's
    /// sample is older than its stamp, i.e. than A's); `0` removes none and warns where the
    /// sessions show one. report.json: details.latency_s and details.latency.
    #[arg(long, default_value = "auto", value_parser = crate::input::parse_latency, value_name = "SECONDS|auto")]
    pub latency: Latency,
    /// Orders whose observability (0 blind … 1 ideal) is below this are left out of the maps.
    #[arg(long, default_value_t = 0.01)]
    pub min_observability: f64,
    /// Benchmark readings of A and B for `--method paper`, degrees.
    #[arg(long, num_args = 2, value_names = ["A_DEG", "B_DEG"], default_values_t = [0.0, 0.0])]
    pub benchmarks: Vec<f64>,
    /// Logs, output, unit, output form, gates, timing.
    #[command(flatten)]
    pub common: MethodArgs,
}

/// Runs `calib csrr`.
impl super::Method for Args {
    const NAME: &'static str = "csrr";
    type Prepared = ();

    fn runs(&self) -> super::Runs<'_> {
        self.common.runs()
    }

    fn prepare(&self) -> anyhow::Result<()> {
        prepare(self)
    }

    fn calibrate(&self, (): &(), log: &Path, out: &Path) -> anyhow::Result<Outcome> {
        calibrate(self, log, out)
    }
}

/// Checks the arguments before any log is read.
fn prepare(args: &Args) -> anyhow::Result<()> {
    if args.a == args.b {
        return Err(Usage(format!(
            "--a and --b both name `{}`: name the two sensors' channels",
            args.a
        ))
        .into());
    }
    if let Some(r) = args
        .reference
        .as_ref()
        .filter(|r| **r == args.a || **r == args.b)
    {
        return Err(Usage(format!(
            "--ref `{r}` is also a calibrated sensor's channel; the reference must be a third \
             encoder on B's shaft (or leave --ref out)"
        ))
        .into());
    }
    if let Some(tol) = args.session_tol {
        crate::input::check_range("--session-tol", tol, 0.0, 180.0, "degrees")?;
    }
    crate::input::check_range(
        "--min-speed",
        args.min_speed,
        0.0,
        360_000.0,
        "degrees per second",
    )?;
    crate::input::check_fraction("--min-observability", args.min_observability)?;
    crate::input::check_points(args.points)?;
    if let Some(h) = args.max_order {
        crate::input::check_count("--max-order", h, 1, None)?;
    }
    if args.truth.is_some() && args.common.logs.len() > 1 {
        return Err(
            Usage("--truth DIR holds the truth of one log: give one log with it".into()).into(),
        );
    }
    Ok(())
}

/// Calibrates one log into the folder `out`.
fn calibrate(args: &Args, log: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let mut names = vec![args.a.as_str(), args.b.as_str()];
    names.extend(args.reference.as_deref());
    let reader = args.common.open(log, &names)?;
    let opts = CsrrOptions {
        method: match args.method {
            MethodArg::Joint => Method::Joint,
            MethodArg::Paper => Method::Paper,
        },
        max_order: args.max_order,
        segments: SegmentOptions {
            min_speed: args.min_speed.to_radians(),
            relative_tol: args.session_tol.map(f64::to_radians),
            use_marks: reader.has_session_marks() && !args.detect_sessions,
            ..SegmentOptions::default()
        },
        points: args.points,
        benchmarks: (
            args.benchmarks[0].to_radians(),
            args.benchmarks[1].to_radians(),
        ),
        reference: args.reference.is_some(),
        min_observability: args.min_observability,
        ..CsrrOptions::default()
    };
    let truth = args
        .truth
        .as_deref()
        .map(|dir| read_truth(dir, args))
        .transpose()?;
    let reference_table = args
        .ref_table
        .as_deref()
        .map(ReferenceTable::read)
        .transpose()?;
    let mut trace = TraceRecorder::new(&args.a, &args.b);
    let (mut first, mut last) = (Some(reader), None);
    let mut solving: Option<indicatif::ProgressBar> = None;
    // One reading of the log per pass: `auto` reads it again with the lag it found removed.
    let cal = calib_core::csrr::latency::calibrate(&opts, args.latency, |csrr: &mut Csrr| {
        if let Some(bar) = solving.take() {
            bar.finish_and_clear();
        }
        let reader = match first.take() {
            Some(reader) => reader,
            None => args.common.open(log, &names)?,
        };
        trace = TraceRecorder::new(&args.a, &args.b);
        // The sample's values are the channels in the order opened: A, B, then the reference.
        last = Some(for_each_sample(log, reader, |s| {
            let (a, b) = (s.values[0], s.values[1]);
            trace.push(s.t, a, b);
            match s.values.get(2) {
                Some(&r) => csrr.push_with_reference(s.t, a, b, r, s.session),
                None => csrr.push(s.t, a, b, s.session),
            }
        })?);
        solving = Some(crate::ui::working("solving"));
        anyhow::Ok(())
    })?;
    if let Some(bar) = solving {
        bar.finish_and_clear();
    }
    let reader = last.expect("the log is read at least once");
    let cal = cal.map_err(|e| {
        if let CsrrError::NoWholeTurn {
            sensor,
            turn,
            cause,
        } = e
        {
            let name = if sensor == 'A' { &args.a } else { &args.b };
            let who = format!("{}: channel `{name}`", log.display());
            return crate::input::no_whole_turn(*cause, &who, &turn);
        }
        let pair = format!("{}: channels `{}` and `{}`", log.display(), args.a, args.b);
        let (e, context) = match &e {
            CsrrError::NeverMoves { sensor } => {
                let name = if *sensor == 'A' { &args.a } else { &args.b };
                (
                    with_time_hint(e, &reader, Some(args.min_speed.to_radians())),
                    format!("{pair}: channel `{name}`"),
                )
            }
            _ => (with_time_hint(e, &reader, None), pair),
        };
        in_log(e.context(context), &reader, log)
    })?;
    let truth = truth.as_ref().map(|(a, b)| (a, b));
    let mut section = cal.report_section((&args.a, &args.b), args.reference.as_deref(), truth);
    if let Some(table) = &reference_table
        && let Some(after) = section
            .channels
            .get_mut(&args.b)
            .and_then(|ch| ch.after_correction.as_mut())
            .filter(|a| a.against == "reference")
    {
        after.reference_split = cal.reference_split(&table.map);
    }
    let tables = vec![
        turn_table(
            &args.a,
            &cal.a,
            cal.uncertainty.as_ref().map(|(u, _)| u.u.as_slice()),
        )?,
        turn_table(
            &args.b,
            &cal.b,
            cal.uncertainty.as_ref().map(|(_, u)| u.u.as_slice()),
        )?,
    ];
    let results = Results {
        section,
        tables,
        channels: vec![args.a.clone(), args.b.clone()],
        residual_rms_arcsec: cal.residual_rms.map(|r| r * ARCSEC_PER_RAD),
        document: Box::new(|report| {
            document::document((&args.a, &args.b), &cal, report, &trace.trace, truth)
        }),
        summary: Box::new(|report| render_summary(args, out, &cal, report)),
    };
    finish_log(&reader, log, out, args.common.presentation(), results)
}

/// The true maps of A and B from `--truth DIR`.
fn read_truth(dir: &Path, args: &Args) -> anyhow::Result<(ErrorMap, ErrorMap)> {
    let read = |name: &str| {
        let path = dir.join(table_name(name));
        calib_io::table::read_turn_table(&path)
            .map(|t| t.map)
            .with_context(|| format!("--truth: cannot read the truth of `{name}`"))
    };
    Ok((read(&args.a)?, read(&args.b)?))
}

/// Collects the decimated timeline of the log: both rotations unwrapped (revolutions) and
/// their relative angle (degrees), in a fixed number of buckets whatever the log's length.
struct TraceRecorder {
    trace: Trace,
    ua: Unwrapper,
    ub: Unwrapper,
}

impl TraceRecorder {
    fn new(a: &str, b: &str) -> Self {
        TraceRecorder {
            trace: Trace::new(&[a, b, &format!("{a} − {b}")], 1000),
            ua: Unwrapper::new(),
            ub: Unwrapper::new(),
        }
    }
    fn push(&mut self, t: f64, a: f64, b: f64) {
        let (a, b) = (self.ua.unwrap(a), self.ub.unwrap(b));
        self.trace
            .push(t, &[a / TAU, b / TAU, (a - b).to_degrees()]);
    }
}

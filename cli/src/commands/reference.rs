//! `calib reference`: cross-calibration of an encoder against a better reference encoder.

use crate::batch::{self, BatchArgs, ChannelFigures, Outcome};
use crate::exit::Usage;
use crate::input::{LogArgs, alignment_detail, alignment_text, open_selected, parse_unit};
use crate::output::{table_name, write_tables_and_report};
use crate::summary::{TextTable, ending, key_values};
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{ReferenceCal, ReferenceCalibration, ReferenceOptions};
use calib_core::{AngleUnit, ChannelReport, Report};
use serde_json::json;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Largest `--points` accepted (a 0.0001° grid; beyond it the tables are only memory).
const MAX_POINTS: usize = 3_600_000;

/// Calibrate an encoder (the DUT) against a better reference encoder on the same shaft.
///
/// Record both encoders turning together: whole revolutions, ideally 5 or more in each direction
/// (ISO 230-2). The DUT's error map is DUT reading − reference reading (mean removed) as a
/// function of the DUT's reading, the mean of both directions; the report holds the ISO 230-2
/// figures (systematic deviation E, reversal value B, repeatability R, accuracy A). The
/// reference's own error is part of the map: use a reference much better than the DUT.
///
/// Writes DIR/<dut>.csv (angle_deg, error_arcsec, correction_arcsec, u_arcsec; correction =
/// −error, applied as reading + correction(reading)), DIR/report.json and DIR/report.html (the
/// map with its uncertainty band, the ISO 230-2 figures), and prints a summary. With several
/// logs, each log's files go to DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// Channels are named by their CSV column; in MCAP by the joint name (JointState) or field
/// (JSON) where no other topic carries that name, and always accepted as TOPIC/NAME
/// (/sensor_a/joint_states/encoder; `calib inspect LOG` lists them). A qualified channel's table
/// is named without the leading `/` and with `/` as `_`. Channels on separate topics are aligned
/// on the stamps of the DUT (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The logs (.csv or .mcap), calibrated independently and in parallel.
    #[arg(required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Channel of the encoder to calibrate (device under test).
    #[arg(long)]
    pub dut: String,
    /// Channel of the reference encoder.
    #[arg(long = "ref")]
    pub reference: String,
    /// The reference's stated standard uncertainty, arcseconds (combined into u_arcsec).
    #[arg(long, default_value_t = 0.0)]
    pub ref_u: f64,
    /// Output folder.
    #[arg(short, long = "output", default_value = "calib-out")]
    pub output: PathBuf,
    /// Points of the output table.
    #[arg(long, default_value_t = 3600)]
    pub points: usize,
    /// Unit of CSV and JSON readings: deg, rad, arcsec, rev, counts:N.
    #[arg(long, value_parser = parse_unit)]
    pub unit: Option<AngleUnit>,
    /// Speed below which the DUT counts as stopped, degrees per second.
    #[arg(long, default_value_t = 1.0)]
    pub min_speed: f64,
    /// Largest change of the difference between the two readings while moving, degrees; beyond
    /// it the reference is taken not to be on the DUT's shaft.
    #[arg(long, default_value_t = 5.0)]
    pub follow_tol: f64,
    /// Travel after each reversal of direction whose data are not used, degrees (the ISO 230-2
    /// approach: backlash settles).
    #[arg(long, default_value_t = 1.0)]
    pub approach: f64,
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

/// Runs `calib reference`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if args.dut == args.reference {
        return Err(Usage(format!(
            "--dut and --ref both name `{}`: name the encoder to calibrate and the reference",
            args.dut
        ))
        .into());
    }
    if !(2..=MAX_POINTS).contains(&args.points) {
        return Err(Usage(format!("--points must be between 2 and {MAX_POINTS}")).into());
    }
    let finite_nonneg = |v: f64| v.is_finite() && v >= 0.0;
    if !(finite_nonneg(args.ref_u)
        && finite_nonneg(args.approach)
        && args.min_speed.is_finite()
        && args.min_speed > 0.0
        && args.follow_tol.is_finite()
        && args.follow_tol > 0.0)
    {
        return Err(Usage(
            "--min-speed and --follow-tol must be positive, --ref-u and --approach at least 0"
                .into(),
        )
        .into());
    }
    batch::run(
        "reference",
        &args.logs,
        &args.output,
        &args.batch,
        args.json,
        |log, out| calibrate(args, log, out),
    )
}

/// Calibrates one log into the folder `out`.
fn calibrate(args: &Args, log: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let names = [args.dut.as_str(), args.reference.as_str()];
    let mut reader = open_selected(log, args.unit, &args.input, &names)?;
    let (id, ir) = (0, 1);
    let bar = crate::ui::reading(log);
    let mut cal = ReferenceCal::new(ReferenceOptions {
        points: args.points,
        min_speed: args.min_speed.to_radians(),
        reference_u: args.ref_u / ARCSEC_PER_RAD,
        follow_tol: args.follow_tol.to_radians(),
        approach: args.approach.to_radians(),
    });
    for (n, sample) in reader.by_ref().enumerate() {
        let s = sample.with_context(|| format!("cannot read {}", log.display()))?;
        if n as u64 % crate::ui::TICK == 0 {
            bar.inc(crate::ui::TICK);
        }
        cal.push(s.t, s.values[id], s.values[ir]);
    }
    bar.finish_and_clear();
    let cal = cal.finish().with_context(|| {
        format!(
            "{}: DUT `{}`, reference `{}`",
            log.display(),
            args.dut,
            args.reference
        )
    })?;
    let mut warnings = reader.warnings(log);
    warnings.extend(cal.warnings.iter().cloned());

    let mut report = build_report(args, log, &cal, warnings);
    if let Some(a) = alignment_detail(&reader) {
        report.details.insert("alignment".to_string(), a);
    }
    let json = calib_io::report::render_json(&report)?;
    let doc = crate::document::reference::document(&args.dut, &args.reference, &cal, &report);
    let files = write_tables_and_report(out, &[(&args.dut, &cal.map, Some(&cal.u))], &json, &doc)?;
    let text = if args.json {
        json
    } else {
        alignment_text(reader.alignment().as_ref()) + &render_summary(args, out, &cal, &report)
    };
    Ok(Outcome {
        text,
        channels: vec![ChannelFigures {
            channel: args.dut.clone(),
            peak_to_peak_before_arcsec: report.channels[&args.dut].peak_to_peak_arcsec,
            peak_to_peak_after_arcsec: peak_to_peak_after(&cal),
        }],
        residual_rms_arcsec: None,
        warnings: report.warnings,
        files,
    })
}

/// What the correction leaves of the DUT's error, arcsec: the peak-to-peak, over the grid points
/// and both directions, of each direction's mean deviation minus the map (the map is the mean of
/// the two directions, so this is the hysteresis a single table cannot correct).
fn peak_to_peak_after(cal: &ReferenceCalibration) -> Option<f64> {
    let residuals =
        cal.up
            .iter()
            .zip(&cal.down)
            .zip(cal.map.values())
            .flat_map(|((up, down), map)| {
                [up, down]
                    .into_iter()
                    .filter(|p| p.n > 0)
                    .map(move |p| p.mean - map)
            });
    let (lo, hi) = residuals.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    (hi >= lo).then_some((hi - lo) * ARCSEC_PER_RAD)
}

fn build_report(
    args: &Args,
    log: &Path,
    cal: &ReferenceCalibration,
    warnings: Vec<String>,
) -> Report {
    let mut channels = BTreeMap::new();
    channels.insert(
        args.dut.clone(),
        ChannelReport::of_map(&table_name(&args.dut), &cal.map, 10),
    );
    let iso: serde_json::Map<String, serde_json::Value> = cal
        .iso
        .arcsec()
        .into_iter()
        .map(|(k, v)| (format!("{k}_arcsec"), json!(v)))
        .collect();
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    let mut details = BTreeMap::new();
    details.insert("reference".to_string(), json!(args.reference));
    details.insert("reference_u_arcsec".to_string(), json!(args.ref_u));
    details.insert("revolutions".to_string(), json!(cal.revolutions));
    details.insert(
        "min_passes".to_string(),
        json!({"increasing": cal.min_passes.0, "decreasing": cal.min_passes.1}),
    );
    details.insert("max_u_arcsec".to_string(), json!(u_max));
    details.insert("iso230_2".to_string(), serde_json::Value::Object(iso));
    Report {
        calib_version: env!("CARGO_PKG_VERSION").to_string(),
        method: "reference".to_string(),
        inputs: vec![log.display().to_string()],
        command_line: Some(crate::input::command_line()),
        channels,
        sessions: Vec::new(),
        warnings,
        details,
    }
}

fn render_summary(args: &Args, out: &Path, cal: &ReferenceCalibration, report: &Report) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Reference calibration of `{}` against `{}`\n",
        args.dut, args.reference
    );
    let iso: std::collections::BTreeMap<_, _> = cal.iso.arcsec().into_iter().collect();
    let fmt = |k: &str| {
        iso.get(k)
            .copied()
            .flatten()
            .map_or("—".to_string(), |v| format!("{v:.3}″"))
    };
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    o += &key_values(&[
        (
            "run",
            format!(
                "{:.2} revolutions, at least {} pass(es) increasing, {} decreasing",
                cal.revolutions, cal.min_passes.0, cal.min_passes.1
            ),
        ),
        (
            "ISO 230-2",
            format!(
                "systematic E {}, reversal B {}, repeatability R {}, accuracy A {}",
                fmt("systematic"),
                fmt("reversal"),
                fmt("repeatability"),
                fmt("accuracy")
            ),
        ),
    ]);
    let ch = &report.channels[&args.dut];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(3)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    let mut t = TextTable::new(&["channel", "p-p before", "rms", "max u", "largest orders"]);
    t.row(vec![
        args.dut.clone(),
        format!("{:.3}″", ch.peak_to_peak_arcsec),
        format!("{:.3}″", ch.rms_arcsec),
        format!("{u_max:.3}″"),
        top.join(", "),
    ]);
    let _ = writeln!(o, "\n{}", t.render().trim_end());
    let _ = writeln!(
        o,
        "  (error = {} − {}, zero mean; every ISO 230-2 figure is in report.json and report.html)",
        args.dut, args.reference
    );
    o += &ending(
        &report.warnings,
        out,
        &[ch.table.clone(), "report.json".to_string()],
        "error map with its uncertainty band, each direction, spectrum",
    );
    o
}

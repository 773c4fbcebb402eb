//! `calib reference`: cross-calibration of an encoder against a better reference encoder.

use crate::batch::{self, BatchArgs, ChannelFigures, Outcome};
use crate::exit::Usage;
use crate::input::{LogArgs, alignment_detail, alignment_text, open_selected, parse_unit};
use crate::output::{table_name, write_outputs};
use crate::summary::{TextTable, ending, key_values};
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{
    ReferenceCal, ReferenceCalibration, ReferenceOptions, TableMap, Targets,
};
use calib_core::{AngleUnit, ChannelReport, Report};
use calib_io::prefetch::Prefetch;
use serde_json::json;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Calibrate an encoder (the DUT) against a better reference encoder on the same shaft.
///
/// Record both encoders turning together: whole revolutions, ideally 5 or more in each direction
/// (ISO 230-2), or for a joint that never turns a whole revolution, its travel swept back and
/// forth. The DUT's error map is DUT reading − reference reading (mean removed) as a function of
/// the DUT's reading, the mean of both directions; the report holds the ISO 230-2 figures
/// (systematic deviation E, reversal value B, repeatability R, accuracy A) at the target
/// positions (--targets). The reference's own error is part of the map: use a reference much
/// better than the DUT.
///
/// A run that does not cover a whole turn gives a range table over the readings it crossed
/// (a `# range_deg: LO to HI` first line, then the same columns); a whole turn but for a gap of at
/// most --bridge-gap degrees gives a whole-turn table with the gap bridged by interpolation, and a
/// warning naming it. Large DUT errors (degrees) are measured: the reference is refused only if
/// the difference of the readings at the same DUT reading differs from pass to pass by more than
/// --follow-tol.
///
/// Writes DIR/<dut>.csv (angle_deg, error_arcsec, correction_arcsec, u_arcsec; correction =
/// −error, applied as reading + correction(reading)), DIR/report.json and DIR/report.html (the
/// map with its uncertainty band, the ISO 230-2 figures), and prints a summary. With several
/// logs, each log's files go to DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// Channels are named by their CSV column; in MCAP and rosbag2 bags by the joint name
/// (JointState, DynamicJointState) or field (JSON) where no other topic carries that name, by the
/// topic for std_msgs scalars, as TOPIC.field.path for a numeric field of another message whose
/// MCAP file carries its definition (/motor/state.position), and always accepted as TOPIC/NAME
/// (/sensor_a/joint_states/encoder; `calib inspect LOG` lists them). A qualified channel's table is
/// named without the leading `/` and with `/` as `_`. Channels on separate topics are aligned on
/// the stamps of the DUT (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The logs (.csv, .mcap, or a rosbag2 bag: its directory or a .db3 file), calibrated
    /// independently and in parallel.
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
    /// Largest spread, degrees, of the difference between the two readings at one DUT reading
    /// from pass to pass; beyond it the reference is taken not to be on the DUT's shaft (a run
    /// that crosses no reading twice: largest change of the difference over the run).
    #[arg(long, default_value_t = 5.0)]
    pub follow_tol: f64,
    /// Largest gap of never-reached readings, degrees, bridged by interpolation in a whole-turn
    /// table (with a warning); a wider gap gives a range table.
    #[arg(long, default_value_t = 5.0)]
    pub bridge_gap: f64,
    /// ISO 230-2 target positions: a count K (one in the middle of each of K equal parts of the
    /// map's range) or a list of readings in degrees (`--targets 20,40,60`); each moved to the
    /// nearest grid point.
    #[arg(long, default_value = "20", value_parser = parse_targets)]
    pub targets: Targets,
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

/// `--targets`: a count (`20`) or a comma-separated list of degrees (`15,30.5,45`).
fn parse_targets(text: &str) -> Result<Targets, String> {
    let text = text.trim();
    if !text.contains(',') {
        return match text.parse::<usize>() {
            Ok(k) if k >= 1 => Ok(Targets::Count(k)),
            _ => Err(format!(
                "`{text}`: give a count of targets (≥ 1) or a list of readings in degrees such as 15,30,45"
            )),
        };
    }
    text.split(',')
        .map(|a| match a.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v.to_radians()),
            _ => Err(format!(
                "`{}` is not an angle in degrees; give the targets as 15,30,45",
                a.trim()
            )),
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Targets::Angles)
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
    crate::input::check_points(Some(args.points))?;
    crate::input::check_non_negative("--ref-u", args.ref_u, "arcseconds")?;
    crate::input::check_non_negative("--approach", args.approach, "degrees")?;
    crate::input::check_range(
        "--min-speed",
        args.min_speed,
        0.0,
        360_000.0,
        "degrees per second",
    )?;
    crate::input::check_range("--follow-tol", args.follow_tol, 0.0, 180.0, "degrees")?;
    if !(args.bridge_gap.is_finite() && (0.0..360.0).contains(&args.bridge_gap)) {
        return Err(Usage(format!(
            "--bridge-gap {} is outside its range: at least 0 and below 360 degrees",
            calib_io::limits::readable(args.bridge_gap)
        ))
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
    let reader = open_selected(log, args.unit, &args.input, &names)?;
    let (id, ir) = (0, 1);
    let bar = crate::ui::reading(log);
    let mut cal = ReferenceCal::new(ReferenceOptions {
        points: args.points,
        min_speed: args.min_speed.to_radians(),
        reference_u: args.ref_u / ARCSEC_PER_RAD,
        follow_tol: args.follow_tol.to_radians(),
        approach: args.approach.to_radians(),
        max_gap: args.bridge_gap.to_radians(),
        targets: args.targets.clone(),
    });
    // Decoding runs ahead on a second thread.
    let mut samples = Prefetch::new(reader);
    for (n, sample) in samples.by_ref().enumerate() {
        let s = sample.with_context(|| format!("cannot read {}", log.display()))?;
        if n as u64 % crate::ui::TICK == 0 {
            bar.inc(crate::ui::TICK);
        }
        cal.push(s.t, s.values[id], s.values[ir]);
    }
    let reader = samples.finish();
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
    let table = match &cal.map {
        TableMap::Turn(m) => calib_io::table::render_table(m, Some(&cal.u)),
        TableMap::Range(m) => calib_io::table::render_range_table(m, Some(&cal.u)),
    }
    .with_context(|| format!("the table of channel `{}`", args.dut))?;
    let files = write_outputs(
        out,
        &[
            (table_name(&args.dut), table.into_bytes()),
            ("report.json".to_string(), json.as_bytes().to_vec()),
        ],
        &doc,
    )?;
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
        match &cal.map {
            TableMap::Turn(m) => ChannelReport::of_map(&table_name(&args.dut), m, 10),
            // A range has no Fourier series: harmonics need a whole turn.
            TableMap::Range(m) => ChannelReport {
                table: table_name(&args.dut),
                points: m.len(),
                peak_to_peak_arcsec: m.peak_to_peak() * ARCSEC_PER_RAD,
                rms_arcsec: m.rms() * ARCSEC_PER_RAD,
                harmonics: Vec::new(),
            },
        },
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
    details.insert(
        "range".to_string(),
        cal.map.range().map_or(serde_json::Value::Null, |(lo, hi)| {
            json!({"start_deg": lo.to_degrees(), "end_deg": hi.to_degrees(), "span_deg": (hi - lo).to_degrees()})
        }),
    );
    details.insert(
        "gap".to_string(),
        cal.gap.map_or(serde_json::Value::Null, |g| {
            json!({
                "from_deg": g.from.to_degrees(),
                "to_deg": g.to.to_degrees(),
                "size_deg": g.size.to_degrees(),
                "points": g.points,
                "bridged": "linear interpolation",
            })
        }),
    );
    details.insert(
        "repeat_spread_deg".to_string(),
        json!(cal.repeat_spread.map(f64::to_degrees)),
    );
    details.insert("iso230_2_targets".to_string(), target_table(cal));
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

/// The per-target statistics of ISO 230-2, arcsec (`null` where a direction has no data).
fn target_table(cal: &ReferenceCalibration) -> serde_json::Value {
    let a = |v: f64| v * ARCSEC_PER_RAD;
    let side = |p: &calib_core::reference_cal::PointStats| {
        json!({
            "passes": p.n,
            "mean_arcsec": (p.n > 0).then(|| a(p.mean)),
            "s_arcsec": p.s.map(a),
            "repeatability_arcsec": p.s.map(|s| a(4.0 * s)),
        })
    };
    cal.targets
        .iter()
        .map(|t| {
            let both = t.up.n > 0 && t.down.n > 0;
            json!({
                "target_deg": t.angle.to_degrees(),
                "increasing": side(&t.up),
                "decreasing": side(&t.down),
                "mean_bidirectional_arcsec": match (t.up.n, t.down.n) {
                    (0, 0) => None,
                    (0, _) => Some(a(t.down.mean)),
                    (_, 0) => Some(a(t.up.mean)),
                    _ => Some(a(0.5 * (t.up.mean + t.down.mean))),
                },
                "reversal_arcsec": both.then(|| a(t.up.mean - t.down.mean)),
            })
        })
        .collect()
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
    let coverage = match (cal.map.range(), cal.gap) {
        (Some((lo, hi)), _) => format!(
            "range table from {:.3}° to {:.3}° ({:.3}° of the DUT's reading; no whole turn)",
            lo.to_degrees(),
            hi.to_degrees(),
            (hi - lo).to_degrees()
        ),
        (None, Some(g)) => format!(
            "whole turn, {:.3}° never reached between {:.3}° and {:.3}° (bridged)",
            g.size.to_degrees(),
            g.from.to_degrees(),
            calib_core::angle::wrap_2pi(g.to).to_degrees()
        ),
        (None, None) => "whole turn".to_string(),
    };
    o += &key_values(&[
        (
            "run",
            format!(
                "{:.2} revolutions, at least {} pass(es) increasing, {} decreasing",
                cal.revolutions, cal.min_passes.0, cal.min_passes.1
            ),
        ),
        ("map", coverage),
        (
            "ISO 230-2",
            format!(
                "{} targets: systematic E {}, reversal B {}, repeatability R {}, accuracy A {}",
                cal.targets.len(),
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
        if top.is_empty() {
            "— (a range has no harmonics)".to_string()
        } else {
            top.join(", ")
        },
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
        if cal.map.range().is_some() {
            "error map over the range with its uncertainty band, each direction"
        } else {
            "error map with its uncertainty band, each direction, spectrum"
        },
    );
    o
}

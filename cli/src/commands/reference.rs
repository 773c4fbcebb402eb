//! `calib reference`: cross-calibration of an encoder against a better reference encoder.

use crate::batch::{ChannelFigures, Outcome};
use crate::exit::Usage;
use crate::input::{alignment_detail, alignment_text};
use crate::method::{MethodArgs, for_each_sample};
use crate::output::{table_name, write_outputs};
use crate::reference_table::ReferenceTable;
use crate::summary::{TextTable, ending, key_values};
use anyhow::Context;
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{
    ReferenceCal, ReferenceCalibration, ReferenceOptions, TableMap, Targets,
};
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
    /// Channel of the encoder to calibrate (device under test).
    #[arg(long)]
    pub dut: String,
    /// Channel of the reference encoder.
    #[arg(long = "ref")]
    pub reference: String,
    /// The reference's stated standard uncertainty, arcseconds, combined into every u_arcsec.
    /// Without it (or --ref-table) the reference's uncertainty is not known: u excludes the
    /// reference, which the summary, the report and a warning say (--fail-on-warning fails).
    #[arg(long, value_name = "ARCSEC", conflicts_with = "ref_table")]
    pub ref_u: Option<f64>,
    /// The reference's own calibrated table (angle_deg, error_arcsec, correction_arcsec,
    /// u_arcsec; a whole turn, e.g. from an earlier `calib reference` or `calib csrr` of it):
    /// its readings are corrected by it, and its largest u is combined into every u_arcsec.
    #[arg(long, value_name = "FILE")]
    pub ref_table: Option<PathBuf>,
    /// Points of the output table.
    #[arg(long, default_value_t = 3600)]
    pub points: usize,
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
    /// Logs, output, unit, output form, gates, timing.
    #[command(flatten)]
    pub common: MethodArgs,
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
    if let Some(u) = args.ref_u {
        crate::input::check_non_negative("--ref-u", u, "arcseconds")?;
    }
    let reference = args
        .ref_table
        .as_deref()
        .map(ReferenceTable::read)
        .transpose()?;
    if let (Some(path), Some(ReferenceTable { u_max: None, .. })) = (&args.ref_table, &reference) {
        return Err(Usage(format!(
            "--ref-table {}: the table has no u_arcsec column, so the reference's uncertainty is \
             still not known; give a table with u_arcsec, or the reference's stated uncertainty \
             with --ref-u",
            path.display()
        ))
        .into());
    }
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
    args.common.run("reference", |log, out| {
        calibrate(args, reference.as_ref(), log, out)
    })
}

/// Calibrates one log into the folder `out`, the reference's readings corrected by its table
/// where given.
fn calibrate(
    args: &Args,
    reference: Option<&ReferenceTable>,
    log: &Path,
    out: &Path,
) -> anyhow::Result<Outcome> {
    let names = [args.dut.as_str(), args.reference.as_str()];
    let reference_u = match reference {
        Some(r) => r.u_max,
        None => args.ref_u.map(|u| u / ARCSEC_PER_RAD),
    };
    let reader = args.common.open(log, &names)?;
    let (id, ir) = (0, 1);
    let mut cal = ReferenceCal::new(ReferenceOptions {
        points: args.points,
        min_speed: args.min_speed.to_radians(),
        reference_u: reference_u.unwrap_or(0.0),
        follow_tol: args.follow_tol.to_radians(),
        approach: args.approach.to_radians(),
        max_gap: args.bridge_gap.to_radians(),
        targets: args.targets.clone(),
    });
    // A calibrated reference reads r − error(r) (its table's correction applied).
    let corrected = |r: f64| reference.map_or(r, |t| r - t.map.eval_linear(r));
    let reader = for_each_sample(log, reader, |s| {
        cal.push(s.t, s.values[id], corrected(s.values[ir]));
    })?;
    let cal = cal.finish().with_context(|| {
        format!(
            "{}: DUT `{}`, reference `{}`",
            log.display(),
            args.dut,
            args.reference
        )
    })?;
    let report = Report::new(
        cal.report_section(
            &args.dut,
            &args.reference,
            reference_u.map(|u| u * ARCSEC_PER_RAD),
        )
        .with_alignment(alignment_detail(&reader)),
        vec![log.display().to_string()],
        Some(crate::input::command_line()),
        reader.warnings(log),
    );
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
    let text = if args.common.json {
        json
    } else {
        alignment_text(reader.alignment().as_ref()) + &render_summary(args, out, &cal, &report)
    };
    Ok(Outcome {
        text,
        channels: vec![ChannelFigures::of(&args.dut, &report.channels[&args.dut])],
        residual_rms_arcsec: None,
        warnings: report.warnings,
        files,
    })
}

/// Whether the report's u leaves the reference out (its uncertainty not given).
pub fn excludes_reference(report: &Report) -> bool {
    matches!(&report.details, calib_core::report::Details::Reference(d) if d.u_excludes_reference)
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
    let excludes = excludes_reference(report);
    let u_label = if excludes {
        "max u (excludes the reference)"
    } else {
        "max u"
    };
    let mut t = TextTable::new(&["channel", "p-p before", "rms", u_label, "largest orders"]);
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

//! `calib reference`: cross-calibration of an encoder against a better reference encoder.

use crate::exit::Usage;
use crate::input::{channel, open_log, parse_unit};
use crate::output::{table_name, write_tables_and_report};
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{ReferenceCal, ReferenceCalibration, ReferenceOptions};
use calib_core::{AngleUnit, ChannelReport, Report};
use serde_json::json;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::PathBuf;

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
/// −error, applied as reading + correction(reading)) and DIR/report.json, and prints a summary.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The log (.csv or .mcap).
    pub log: PathBuf,
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
    /// Print report.json on standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
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
    let mut reader = open_log(&args.log, args.unit)?;
    let id = channel(&reader, &args.log, &args.dut)?;
    let ir = channel(&reader, &args.log, &args.reference)?;
    let mut cal = ReferenceCal::new(ReferenceOptions {
        points: args.points,
        min_speed: args.min_speed.to_radians(),
        reference_u: args.ref_u / ARCSEC_PER_RAD,
        follow_tol: args.follow_tol.to_radians(),
        approach: args.approach.to_radians(),
    });
    for sample in reader.by_ref() {
        let s = sample.with_context(|| format!("cannot read {}", args.log.display()))?;
        cal.push(s.t, s.values[id], s.values[ir]);
    }
    let cal = cal.finish().with_context(|| {
        format!(
            "{}: DUT `{}`, reference `{}`",
            args.log.display(),
            args.dut,
            args.reference
        )
    })?;
    let mut warnings = reader.warnings(&args.log);
    warnings.extend(cal.warnings.iter().cloned());

    let report = build_report(args, &cal, warnings);
    let json = calib_io::report::render_json(&report)?;
    write_tables_and_report(&args.output, &[(&args.dut, &cal.map, Some(&cal.u))], &json)?;
    if args.json {
        return Ok(json);
    }
    Ok(render_summary(args, &cal, &report))
}

fn build_report(args: &Args, cal: &ReferenceCalibration, warnings: Vec<String>) -> Report {
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
        inputs: vec![args.log.display().to_string()],
        command_line: None,
        channels,
        sessions: Vec::new(),
        warnings,
        details,
    }
}

fn render_summary(args: &Args, cal: &ReferenceCalibration, report: &Report) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Reference calibration of `{}` against `{}` — {:.2} revolutions, at least {} pass(es) increasing, {} decreasing",
        args.dut, args.reference, cal.revolutions, cal.min_passes.0, cal.min_passes.1
    );
    let ch = &report.channels[&args.dut];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(4)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    let _ = writeln!(
        o,
        "\nmap (error = DUT − reference, zero mean): p-p {:.3}″  rms {:.3}″  largest orders {}  max u {:.3}″  → {}",
        cal.map.peak_to_peak() * ARCSEC_PER_RAD,
        ch.rms_arcsec,
        top.join(", "),
        u_max,
        args.output.join(&ch.table).display()
    );
    let _ = writeln!(o, "\nISO 230-2 (arcsec; — where the data cannot give it)");
    for (name, v) in cal.iso.arcsec() {
        let v = v.map_or("—".to_string(), |v| format!("{v:.3}"));
        let _ = writeln!(o, "  {name:<20} {v:>10}");
    }
    for w in &report.warnings {
        let _ = writeln!(o, "\nwarning: {w}");
    }
    let _ = writeln!(o, "\nwrote {}", args.output.join("report.json").display());
    o
}

//! `calib tdr`: self-calibration of one encoder from a free spin-down (coast-down) log.

use crate::batch::{self, BatchArgs, ChannelFigures, Outcome};
use crate::exit::Usage;
use crate::input::{
    LogArgs, alignment_detail, alignment_text, command_line, open_selected, parse_unit,
};
use crate::output::{table_name, write_tables_and_report};
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::tdr::{
    FALSE_ORDER_PROBABILITY, Tdr, TdrCalibration, TdrOptions, significance_threshold,
};
use calib_core::{AngleUnit, ChannelReport, Report};
use calib_io::prefetch::Prefetch;
use serde_json::json;
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Largest `--max-order` accepted: the fit is dense in the orders (cost ∝ samples·orders²).
const MAX_ORDER: usize = 1000;
/// Largest `--max-drag-order` accepted: a drag's imprint falls as 1/h², and each order costs
/// two columns of the dense fit.
const MAX_DRAG_ORDER: usize = 100;
/// Largest `--motion-degree` accepted (Chebyshev series of higher degree can follow the error).
const MAX_DEGREE: usize = 60;

/// Self-calibrate one encoder from a spin-down: the shaft coasting freely (TDR, Lu & Trumper).
///
/// Spin the shaft up, release the drive (or cut the motor current) and log the encoder while the
/// shaft coasts down: 10 revolutions at the least, a few hundred is better, with the speed
/// falling noticeably (≥ 2 %). A free shaft's angle is a smooth function of time, so the part of
/// the reading that is periodic in angle is the encoder's error: the motion (a Chebyshev series
/// in time) and the map (a Fourier series of the reading) are fitted together by least squares.
/// A driven plateau before the release and the slow end of the coast are left out.
///
/// The orders come from the data: every order the coast resolves is tested (by default up to
/// 0.4 × the samples per revolution at its slowest end) and those standing above the noise are
/// kept; periodic structure left in the residual above the highest order is warned about.
///
/// An angle-dependent drag (rolling bearings, motor cogging, unbalance) shakes the shaft by
/// a_h/(h·ω)² at order h. Its imprint grows as 1/ω² while the encoder's error does not change
/// with speed, so over a coast whose speed falls enough (1/ω² varying by ≥ 10 % RMS) the drag is
/// fitted jointly and separated from the map, and reported. Over a narrower coast it cannot be,
/// and the warnings say how far the shaft must coast down. With --ref, the map is also checked
/// against a reference encoder on the same shaft.
///
/// Writes DIR/<channel>.csv (angle_deg, error_arcsec, correction_arcsec; error = reading − true
/// angle, correction = −error, a function of the encoder's own reading, zero mean) and
/// DIR/report.json and DIR/report.html, and prints a summary. With several logs, each log's files
/// go to DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// Channels are named by their CSV column; in MCAP and rosbag2 bags by the joint name
/// (JointState, DynamicJointState) or field (JSON) where no other topic carries that name, by the
/// topic for std_msgs scalars, as TOPIC.field.path for a numeric field of another message whose
/// MCAP file carries its definition (/motor/state.position), and always accepted as TOPIC/NAME
/// (/sensor_a/joint_states/encoder; `calib inspect LOG` lists them). A qualified channel's table is
/// named without the leading `/` and with `/` as `_`. Channels on separate topics are aligned on
/// the stamps of --channel (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The logs (.csv, .mcap, or a rosbag2 bag: its directory or a .db3 file), calibrated
    /// independently and in parallel.
    #[arg(required = true, value_name = "LOG")]
    pub logs: Vec<PathBuf>,
    /// Channel of the encoder to calibrate.
    #[arg(long)]
    pub channel: String,
    /// Channel of a reference encoder on the same shaft, to check the map against.
    #[arg(long = "ref")]
    pub reference: Option<String>,
    /// Output folder.
    #[arg(short, long = "output", default_value = "calib-out")]
    pub output: PathBuf,
    /// Highest harmonic order tested. Default: 0.4 × the samples per revolution where the coast
    /// is slowest (at most 500). Only orders that stand above the noise are kept in the map.
    #[arg(long)]
    pub max_order: Option<usize>,
    /// Highest order of angle-dependent drag fitted and separated from the map (0: none).
    #[arg(long, default_value_t = 16)]
    pub max_drag_order: usize,
    /// Degree of the motion's polynomial (Chebyshev series in time); default: chosen by the
    /// Bayesian information criterion, at most 30 and at most half the revolutions.
    #[arg(long)]
    pub motion_degree: Option<usize>,
    /// Fewest revolutions of coast accepted.
    #[arg(long, default_value_t = 10.0)]
    pub min_revolutions: f64,
    /// Points of the output table.
    #[arg(long, default_value_t = 3600)]
    pub points: usize,
    /// Unit of CSV and JSON readings: deg, rad, arcsec, rev, counts:N.
    #[arg(long, value_parser = parse_unit)]
    pub unit: Option<AngleUnit>,
    /// Print report.json on standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Pipelines and gates.
    #[command(flatten)]
    pub batch: BatchArgs,
    /// How the log is timed (CSV time column, MCAP stamps) and its channels aligned.
    #[command(flatten)]
    pub input: LogArgs,
}

/// Runs `calib tdr`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if args.reference.as_ref() == Some(&args.channel) {
        return Err(Usage(format!(
            "--channel and --ref both name `{}`: name the encoder to calibrate and a different reference",
            args.channel
        ))
        .into());
    }
    crate::input::check_points(Some(args.points))?;
    if let Some(h) = args.max_order.filter(|h| !(1..=MAX_ORDER).contains(h)) {
        return Err(Usage(format!(
            "--max-order {h} is outside its range, 1 to {MAX_ORDER}"
        ))
        .into());
    }
    if args.max_drag_order > MAX_DRAG_ORDER {
        return Err(Usage(format!(
            "--max-drag-order {} is outside its range, 0 to {MAX_DRAG_ORDER}",
            args.max_drag_order
        ))
        .into());
    }
    if let Some(p) = args.motion_degree.filter(|p| !(1..=MAX_DEGREE).contains(p)) {
        return Err(Usage(format!(
            "--motion-degree {p} is outside its range, 1 to {MAX_DEGREE}"
        ))
        .into());
    }
    if !(args.min_revolutions.is_finite() && args.min_revolutions >= 1.0) {
        return Err(Usage(format!(
            "--min-revolutions {} is outside its range, 1 or more",
            calib_io::limits::readable(args.min_revolutions)
        ))
        .into());
    }
    batch::run(
        "tdr",
        &args.logs,
        &args.output,
        &args.batch,
        args.json,
        |log, out| calibrate(args, log, out),
    )
}

/// Calibrates one log into the folder `out`.
fn calibrate(args: &Args, log: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let mut names = vec![args.channel.as_str()];
    names.extend(args.reference.as_deref());
    let reader = open_selected(log, args.unit, &args.input, &names)?;
    let ic = 0;
    let ir = args.reference.as_ref().map(|_| 1);
    let mut tdr = Tdr::new(TdrOptions {
        max_order: args.max_order,
        max_drag_order: args.max_drag_order,
        motion_degree: args.motion_degree,
        points: args.points,
        min_revolutions: args.min_revolutions,
        ..TdrOptions::default()
    });
    let mut travel = crate::input::Travel::default();
    // Decoding runs ahead on a second thread.
    let mut samples = Prefetch::new(reader);
    for sample in samples.by_ref() {
        let s = sample.with_context(|| format!("cannot read {}", log.display()))?;
        travel.push(s.values[ic]);
        match ir {
            Some(ir) => tdr.push_with_reference(s.t, s.values[ic], s.values[ir]),
            None => tdr.push(s.t, s.values[ic]),
        }
    }
    let reader = samples.finish();
    let cal = tdr.finish().map_err(|e| {
        let hint = travel.no_whole_turn(
            log,
            &args.channel,
            "TDR needs a free coast of at least one whole turn (better many) to tell the encoder's error, periodic in \
             angle, from the motion; a coast over part of a turn cannot separate them",
        );
        match hint {
            Some(hint) => anyhow::Error::new(e).context(hint),
            None => anyhow::Error::new(e),
        }
    });
    let cal = cal.with_context(|| format!("{}: channel `{}`", log.display(), args.channel))?;
    let mut warnings = reader.warnings(log);
    warnings.extend(cal.warnings.iter().cloned());

    let mut report = build_report(args, log, &cal, warnings);
    if let Some(a) = alignment_detail(&reader) {
        report.details.insert("alignment".to_string(), a);
    }
    let json = calib_io::report::render_json(&report)?;
    let files = write_tables_and_report(
        out,
        &[(&args.channel, &cal.map, Some(&cal.uncertainty.u))],
        &json,
        &crate::document::tdr::document(&args.channel, args.reference.as_deref(), &cal, &report),
    )?;
    let text = if args.json {
        json
    } else {
        alignment_text(reader.alignment().as_ref()) + &render_summary(args, out, &cal, &report)
    };
    // After correction: what the reference still sees of the corrected encoder.
    let after = cal
        .reference
        .as_ref()
        .map(|r| cal.map.minus(&r.map).peak_to_peak() * ARCSEC_PER_RAD);
    Ok(Outcome {
        text,
        channels: vec![ChannelFigures {
            channel: args.channel.clone(),
            peak_to_peak_before_arcsec: report.channels[&args.channel].peak_to_peak_arcsec,
            peak_to_peak_after_arcsec: after,
        }],
        residual_rms_arcsec: Some(cal.residual_rms * ARCSEC_PER_RAD),
        warnings: report.warnings,
        files,
    })
}

fn rpm(rad_s: f64) -> f64 {
    rad_s * 60.0 / std::f64::consts::TAU
}

fn build_report(args: &Args, log: &Path, cal: &TdrCalibration, warnings: Vec<String>) -> Report {
    let mut channels = BTreeMap::new();
    channels.insert(
        args.channel.clone(),
        ChannelReport::of_map(&table_name(&args.channel), &cal.map, 10),
    );
    let m = &cal.motion;
    let (_, _, decel_start) = m.eval(m.t_start);
    let (_, _, decel_end) = m.eval(m.t_end);
    let mut details = BTreeMap::new();
    details.insert(
        "motion".to_string(),
        json!({
            "model": "Chebyshev series of time",
            "degree": m.degree,
            "start_s": m.t_start,
            "end_s": m.t_end,
            "speed_start_rpm": rpm(cal.speed_start),
            "speed_end_rpm": rpm(cal.speed_end),
            "acceleration_start_rad_s2": decel_start * cal.direction,
            "acceleration_end_rad_s2": decel_end * cal.direction,
            "direction": if cal.direction > 0.0 { "increasing" } else { "decreasing" },
        }),
    );
    details.insert("revolutions".to_string(), json!(cal.revolutions));
    details.insert("samples_used".to_string(), json!(cal.samples_used));
    details.insert("max_order".to_string(), json!(cal.max_order));
    details.insert(
        "orders".to_string(),
        json!({
            "max_order_tested": cal.max_order,
            "samples_per_revolution_densest": cal.samples_per_revolution_densest,
            "kept": cal.orders,
            "rule": format!(
                "an order is kept when its coefficients' chi-square against their covariance exceeds 2·ln(M/α) = {:.2} (M = {} orders tested, α = {})",
                significance_threshold(cal.max_order),
                cal.max_order,
                FALSE_ORDER_PROBABILITY
            ),
            "residual_structure": cal.unresolved.iter().map(|h| {
                let h = h.to_report();
                json!({"order": h.order, "amplitude_arcsec": h.amplitude_arcsec, "phase_deg": h.phase_deg})
            }).collect::<Vec<_>>(),
        }),
    );
    details.insert(
        "uncertainty".to_string(),
        json!({ args.channel.clone(): crate::document::uncertainty_json(&cal.uncertainty) }),
    );
    details.insert(
        "residual_rms_arcsec".to_string(),
        json!(cal.residual_rms * ARCSEC_PER_RAD),
    );
    let dependence: Vec<_> = cal
        .speed_dependence
        .iter()
        .map(|s| {
            let h = s.harmonic.to_report();
            json!({
                "order": h.order,
                "amplitude_arcsec": h.amplitude_arcsec,
                "phase_deg": h.phase_deg,
                "u_arcsec": s.u * ARCSEC_PER_RAD,
            })
        })
        .collect();
    let separated: Vec<_> = cal
        .drag
        .iter()
        .map(|d| {
            let h = d.deceleration.to_report();
            json!({
                "order": h.order,
                "deceleration_rad_s2": d.deceleration.amplitude,
                "phase_deg": h.phase_deg,
                "imprint_arcsec": d.imprint * ARCSEC_PER_RAD,
                "u_imprint_arcsec": d.u_imprint * ARCSEC_PER_RAD,
            })
        })
        .collect();
    let sep = &cal.drag_separation;
    details.insert(
        "drag".to_string(),
        json!({
            "ambiguity": cal.ambiguity,
            "separated": sep.separated,
            "inverse_square_speed_variation": sep.variation,
            "separation_noise_gain": sep.noise_gain,
            "max_drag_order": args.max_drag_order,
            "terms": separated,
            "mean_inverse_square_speed_s2": cal.drag_gain,
            "map_shift_arcsec_per_rad_s2_over_order_squared": cal.drag_gain * ARCSEC_PER_RAD,
            "speed_dependent_orders": dependence,
        }),
    );
    if let (Some(name), Some(r)) = (&args.reference, &cal.reference) {
        details.insert(
            "reference".to_string(),
            json!({
                "channel": name,
                "max_difference_arcsec": r.max_abs_diff_arcsec,
                "rms_difference_arcsec": r.rms_diff_arcsec,
            }),
        );
    }
    Report {
        calib_version: env!("CARGO_PKG_VERSION").to_string(),
        method: "tdr".to_string(),
        inputs: vec![log.display().to_string()],
        command_line: Some(command_line()),
        channels,
        sessions: Vec::new(),
        warnings,
        details,
    }
}

fn render_summary(args: &Args, out: &Path, cal: &TdrCalibration, report: &Report) -> String {
    let mut o = String::new();
    let m = &cal.motion;
    let _ = writeln!(
        o,
        "Spin-down (TDR) self-calibration of `{}` — coast {:.3}–{:.3} s, {:.1} revolutions, {:.1} → {:.1} r/min",
        args.channel,
        m.t_start,
        m.t_end,
        cal.revolutions,
        rpm(cal.speed_start),
        rpm(cal.speed_end)
    );
    let _ = writeln!(
        o,
        "motion: Chebyshev series of degree {} in time; residual rms {:.4}″ over {} samples",
        m.degree,
        cal.residual_rms * ARCSEC_PER_RAD,
        cal.samples_used
    );
    let ch = &report.channels[&args.channel];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(4)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    let _ = writeln!(
        o,
        "\nmap (error = reading − true angle, zero mean): p-p {:.3}″  rms {:.3}″  largest orders {}  → {}",
        cal.map.peak_to_peak() * ARCSEC_PER_RAD,
        ch.rms_arcsec,
        top.join(", "),
        out.join(&ch.table).display()
    );
    let _ = writeln!(
        o,
        "standard uncertainty u of the table: max {:.4}″, rms {:.4}″ (budget in report.json)",
        cal.uncertainty.max() * ARCSEC_PER_RAD,
        cal.uncertainty.rms() * ARCSEC_PER_RAD
    );
    if let (Some(name), Some(r)) = (&args.reference, &cal.reference) {
        let _ = writeln!(
            o,
            "check against `{name}`: max |map − reference map| {:.3}″, rms {:.3}″",
            r.max_abs_diff_arcsec, r.rms_diff_arcsec
        );
    }
    let _ = writeln!(
        o,
        "orders: {} kept of 1–{} tested (those above the noise){}",
        cal.orders.len(),
        cal.max_order,
        if cal.unresolved.is_empty() {
            String::new()
        } else {
            format!(
                "; residual structure above them at {} orders",
                cal.unresolved.len()
            )
        }
    );
    let sep = &cal.drag_separation;
    if sep.separated && !cal.drag.is_empty() {
        let list: Vec<String> = cal
            .drag
            .iter()
            .map(|d| {
                format!(
                    "order {}: {:.4} rad/s² ({:.3}″ ± {:.3}″ at the mean 1/ω²)",
                    d.deceleration.order,
                    d.deceleration.amplitude,
                    d.imprint * ARCSEC_PER_RAD,
                    d.u_imprint * ARCSEC_PER_RAD
                )
            })
            .collect();
        let _ = writeln!(
            o,
            "\ndrag separated from the map (1/ω² varies by {:.0} % over the coast): {}",
            100.0 * sep.variation,
            list.join(", ")
        );
    } else if sep.separated {
        let _ = writeln!(
            o,
            "\ndrag: none found above the noise (1/ω² varies by {:.0} % over the coast, enough to separate it)",
            100.0 * sep.variation
        );
    } else {
        let _ = writeln!(
            o,
            "\ndrag: not separable on this coast; a deceleration of 1 rad/s² at order h would add {:.3}″/h² to the map's order h (⟨ω⁻²⟩ = {:.3e} s²)",
            cal.drag_gain * ARCSEC_PER_RAD,
            cal.drag_gain
        );
    }
    o += &crate::summary::ending(
        &report.warnings,
        out,
        &[
            report.channels[&args.channel].table.clone(),
            "report.json".to_string(),
        ],
        "the map, its spectrum with the drag orders marked, the drag, the coast",
    );
    o
}

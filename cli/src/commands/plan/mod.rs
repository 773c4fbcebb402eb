//! `calib plan`: the set-up that lets a method see the orders asked for, and the `u` it will
//! give, before a sample is recorded.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::plan::MAX_PLANNED_ANGLES;
use calib_core::plan::csrr::{CsrrPlan, CsrrPlanOptions, CsrrRig};
use calib_core::plan::multihead::MultiheadPlan;
use serde_json::json;
use std::fmt::Write;
use std::path::{Path, PathBuf};

mod reference;
mod shift_angle;
mod tdr;

pub use reference::ReferenceArgs;
pub use shift_angle::ShiftAngleArgs;
pub use tdr::TdrArgs;

/// Plan a calibration run before recording it: which set-up lets the method see every order up
/// to N, and the uncertainty it will give.
///
/// Each planner evaluates a set-up with the same formulas the method uses for its observability
/// and its u (see docs/plan.md). Write the planned run as a simulator scenario, simulate it and
/// calibrate the simulation to see the result before recording:
///
///   calib plan csrr --max-order 90 --procedure run.md
///   calib simulate run.toml -o sim.mcap
///   calib csrr sim.mcap -o out/
///
/// The planners: csrr (relative rotations), multihead (head positions), tdr (how far and how
/// long to coast, at which rate), shift-angle (shifts, readings and the Table 3 budget),
/// reference (ISO 230-2 targets, passes and the approach for a backlash).
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The method to plan for.
    #[command(subcommand)]
    pub method: Method,
    /// Replace --procedure's files even if calib did not write them (without it, a file there
    /// that no calib manifest of its folder lists is refused, exit 2, and left as it is).
    #[arg(long, global = true)]
    pub force: bool,
}

/// The planners.
#[derive(Debug, clap::Subcommand, PartialEq)]
pub enum Method {
    /// CSRR: the relative rotations Δ that make every order up to N observable.
    ///
    /// Proposes the relative rotations (the first 0°, or those given with --fixed; multiples of
    /// the mechanism's --step if given) that maximize, over orders 1..N, the worst of the
    /// method's observability q_h = 1 − |Σ_k e^{ihΔ_k}|/K and of 1.2 × the phase spread
    /// p_h = mean_k sin²(hΔ_k/2). With --deltas it evaluates the given rotations instead and
    /// names their blind orders. Prints the rotations, the worst orders, and per order the noise
    /// gain and the u it adds to either map for the given noise and samples per session.
    Csrr(CsrrArgs),
    /// Multi-head: where to place K heads on one scale so that every order up to N is seen.
    ///
    /// Proposes head angles (the first at 0°; multiples of --step if given) that maximize, over
    /// orders 1..N, the worst observability of the joint multi-head method,
    /// o_h = Σ_j |e^{ihψ_j} − 1|²/(2K). With --positions it evaluates the given placement
    /// instead and names its blind orders (SelfA's 3/4/7-head sets: the multiples of 84). Prints
    /// the placement, the worst orders, and the map's u for the given noise and revolutions.
    Multihead(MultiheadArgs),
    /// TDR (spin-down): how far the shaft must coast down, for how long, at which sample rate.
    ///
    /// The coast must sweep 1/ω² by at least 10 % RMS for calib tdr to separate an
    /// angle-dependent drag from the encoder's error (its rule, ≈ 16 % of the speed lost); the
    /// plan proposes coasting on to where the separation costs 1.5× the noise at the drag's
    /// orders (or to --end-rpm), and a sample rate that gives N/0.4 samples per revolution at
    /// the release speed. It prints the coast's duration and revolutions and the map's u from
    /// the method's own fit on the planned samples.
    Tdr(TdrArgs),
    /// Shift-angle (polygon and autocollimator): the shifts and readings that give every angle
    /// a point, the blind orders and the GUM budget of the paper's Table 3.
    ///
    /// Shifts S = 0, d, 2d, … below the pitch 360°/F give a point every d degrees (--spacing);
    /// the readings follow the paper: the full F × F matrix at S = 0, start face 1 at the other
    /// shifts. Orders F, 2F, … are blind whatever the shifts (the closure of eq. 2). Prints the
    /// u of every point from the joint fit and Table 3's budget for F faces, evaluated as
    /// `calib shift-angle --budget` evaluates one (no simulator scenario exists for
    /// shift-angle readings: --procedure writes the readings sheet and the budget file).
    ShiftAngle(ShiftAngleArgs),
    /// Reference (ISO 230-2): targets, passes per direction, the approach after each reversal
    /// for a backlash, the sweep that gives them, and the u of the map.
    ///
    /// Targets (j + ½)·360°/k, k from calib reference's 20 upwards until every expected order
    /// of the DUT (--orders) is seen at 8 phases or more (at a divisor of an order, every target
    /// sees the same value and the ISO figures miss it). The approach is twice the backlash, at
    /// least the method's 1°. u is the method's: the spread of a crossing over the passes,
    /// halved for the two directions, with the reference's u.
    Reference(ReferenceArgs),
}

/// `calib plan multihead`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct MultiheadArgs {
    /// Heads in all (the first at 0°).
    #[arg(long, value_name = "K", required_unless_present = "positions")]
    pub heads: Option<usize>,
    /// The highest order the map must hold.
    #[arg(long, value_name = "N")]
    pub max_order: usize,
    /// The step of the mounting holes, degrees: every proposed angle is a multiple of it.
    #[arg(long, value_name = "DEG", conflicts_with = "positions")]
    pub step: Option<f64>,
    /// Evaluate these head angles (degrees, the first the reference) instead of proposing some.
    #[arg(long, value_delimiter = ',', value_name = "DEG,...")]
    pub positions: Vec<f64>,
    /// Sample rate of the recording, Hz.
    #[arg(long, default_value_t = 400.0, value_name = "HZ")]
    pub rate: f64,
    /// Speed of the scale, r/min.
    #[arg(long, default_value_t = 10.0, value_name = "RPM")]
    pub rpm: f64,
    /// Constant-speed revolutions recorded.
    #[arg(long, default_value_t = 3.0, value_name = "REVS")]
    pub revolutions: f64,
    /// Each head's reading noise, arcsec.
    #[arg(long, default_value_t = 0.01, value_name = "ARCSEC")]
    pub noise: f64,
    /// Each head's resolution, arcsec.
    #[arg(long, default_value_t = 0.01, value_name = "ARCSEC")]
    pub resolution: f64,
    /// Print the plan as JSON (positions_deg, blind_orders, every order's observability and u).
    #[arg(long)]
    pub json: bool,
}

/// `calib plan csrr`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct CsrrArgs {
    /// The highest order the maps must hold (e.g. 3 × the sensors' pole pairs).
    #[arg(long, value_name = "N")]
    pub max_order: usize,
    /// Sessions (relative rotations) in all.
    #[arg(long, default_value_t = 5, value_name = "K")]
    pub sessions: usize,
    /// Relative rotations to keep, degrees (default 0): the others are planned around them.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "DEG,...",
        conflicts_with = "deltas"
    )]
    pub fixed: Vec<f64>,
    /// The step of the mechanism that sets the relative rotation, degrees: every proposed
    /// rotation is a multiple of it.
    #[arg(long, value_name = "DEG", conflicts_with = "deltas")]
    pub step: Option<f64>,
    /// Evaluate these relative rotations (degrees) instead of proposing some.
    #[arg(long, value_delimiter = ',', value_name = "DEG,...")]
    pub deltas: Vec<f64>,
    /// Sample rate of the recording, Hz.
    #[arg(long, default_value_t = 400.0, value_name = "HZ")]
    pub rate: f64,
    /// Speed of the shaft during a session, r/min.
    #[arg(long, default_value_t = 10.0, value_name = "RPM")]
    pub rpm: f64,
    /// Constant-speed revolutions per session.
    #[arg(long, default_value_t = 3.0, value_name = "REVS")]
    pub revolutions: f64,
    /// Each sensor's reading noise, arcsec (standard deviation per sample).
    #[arg(long, default_value_t = 0.05, value_name = "ARCSEC")]
    pub noise: f64,
    /// Each sensor's resolution, arcsec (adds resolution²/12 to the noise's variance).
    #[arg(long, default_value_t = 0.09, value_name = "ARCSEC")]
    pub resolution: f64,
    /// The orders you expect the errors to hold (e.g. 72,144,216): the map's u is for these.
    /// Default: every order up to N, an upper bound.
    #[arg(long, value_delimiter = ',', value_name = "H,...")]
    pub orders: Vec<usize>,
    /// Write the procedure (the sessions in order: turn, revolutions, speed) to FILE and a
    /// matching simulator scenario beside it (FILE with the extension .toml).
    #[arg(long, value_name = "FILE")]
    pub procedure: Option<PathBuf>,
    /// Print the plan as JSON (deltas_deg, blind_orders, every order's observability and u).
    #[arg(long)]
    pub json: bool,
}

/// Ramps, pauses and relative turns of the written procedure and scenario, seconds.
const RAMP_S: f64 = 1.0;
const PAUSE_S: f64 = 1.0;
const TURN_S: f64 = 2.0;

/// Runs `calib plan`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    match &args.method {
        Method::Csrr(a) => csrr(a),
        Method::Multihead(a) => multihead(a),
        Method::Tdr(a) => tdr::run(a),
        Method::ShiftAngle(a) => shift_angle::run(a),
        Method::Reference(a) => reference::run(a),
    }
}

/// Writes the procedure `text` to `path` and each `(extension, what, text)` beside it (the
/// path with that extension); refuses a procedure path that one of them would overwrite.
/// Returns the paths written.
fn write_procedure(
    path: &Path,
    text: &str,
    beside: &[(&str, &str, String)],
) -> anyhow::Result<Vec<PathBuf>> {
    let others: Vec<PathBuf> = beside
        .iter()
        .map(|(ext, _, _)| path.with_extension(ext))
        .collect();
    if others.iter().any(|o| o == path) {
        let exts: Vec<String> = beside.iter().map(|b| format!(".{}", b.0)).collect();
        return Err(anyhow::Error::new(Usage(format!(
            "--procedure {}: the files written beside the procedure end in {}; give the \
             procedure another extension (e.g. {})",
            path.display(),
            exts.join(", "),
            path.with_extension("md").display()
        ))));
    }
    for file in std::iter::once(path).chain(others.iter().map(PathBuf::as_path)) {
        crate::output::check_file_replaceable(file, "--procedure")?;
    }
    calib_io::atomic::write_atomic(path, text.as_bytes())
        .with_context(|| format!("cannot write the procedure {}", path.display()))?;
    let mut written = vec![path.to_path_buf()];
    for (other, (_, what, text)) in others.into_iter().zip(beside) {
        calib_io::atomic::write_atomic(&other, text.as_bytes())
            .with_context(|| format!("cannot write the {what} {}", other.display()))?;
        written.push(other);
    }
    crate::output::record_written(&written);
    Ok(written)
}

/// `--name` must be a positive number.
fn positive(name: &str, v: f64) -> anyhow::Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(anyhow::Error::new(Usage(format!(
            "{name} must be a positive number, not {}",
            calib_io::limits::readable(v)
        ))))
    }
}

/// `--name` must be a number ≥ 0 of `unit`.
fn non_negative(name: &str, v: f64, unit: &str) -> anyhow::Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(anyhow::Error::new(Usage(format!(
            "{name} must be ≥ 0 {unit}, not {}",
            calib_io::limits::readable(v)
        ))))
    }
}

/// Refuses more than [`MAX_PLANNED_ANGLES`] of `what` given with `option`.
fn angles_within(option: &str, count: usize, what: &str) -> anyhow::Result<()> {
    if count > MAX_PLANNED_ANGLES {
        return Err(anyhow::Error::new(Usage(format!(
            "{option}: {count} {what}, more than the {MAX_PLANNED_ANGLES} calib plans (far more \
             than a rig mounts); give at most {MAX_PLANNED_ANGLES}"
        ))));
    }
    Ok(())
}

/// A number as typed: at most six decimals, no trailing zeros (30, 0.05, 111.9).
fn num(x: f64) -> String {
    let s = format!("{x:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// Noise per sample from a reading noise and a resolution (arcsec), rad: `√(σ² + q²/12)`.
fn sample_sigma(noise: f64, resolution: f64) -> f64 {
    (noise * noise + resolution * resolution / 12.0).sqrt() / ARCSEC_PER_RAD
}

fn csrr(args: &CsrrArgs) -> anyhow::Result<String> {
    let usage = |m: String| anyhow::Error::new(Usage(m));
    let positive = [
        ("--rate", args.rate),
        ("--rpm", args.rpm),
        ("--revolutions", args.revolutions),
    ];
    for (name, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return Err(usage(format!("{name} must be a positive number, not {v}")));
        }
    }
    for (name, v) in [("--noise", args.noise), ("--resolution", args.resolution)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(usage(format!("{name} must be ≥ 0 arcsec, not {v}")));
        }
    }
    if let Some(h) = args.orders.iter().find(|&&h| h == 0 || h > args.max_order) {
        return Err(usage(format!(
            "--orders: order {h} is outside 1..{} (--max-order)",
            args.max_order
        )));
    }
    if args.deltas.len() == 1 {
        return Err(usage(
            "--deltas needs at least two relative rotations (CSRR compares sessions)".into(),
        ));
    }
    if args.deltas.iter().any(|d| !d.is_finite()) {
        return Err(usage(
            "--deltas: every rotation must be a number of degrees".into(),
        ));
    }
    let rig = CsrrRig {
        rate_hz: args.rate,
        speed_rpm: args.rpm,
        revolutions: args.revolutions,
        noise_arcsec: args.noise,
        quantization_arcsec: args.resolution,
    };
    angles_within("--sessions", args.sessions, "sessions")?;
    angles_within("--deltas", args.deltas.len(), "relative rotations")?;
    let proposed = args.deltas.is_empty();
    let plan = if proposed {
        let opts = CsrrPlanOptions {
            max_order: args.max_order,
            sessions: args.sessions,
            fixed: args.fixed.iter().map(|d| d.to_radians()).collect(),
            step: args.step.map(f64::to_radians),
        };
        calib_core::plan::csrr::plan(&opts, rig.run()).map_err(|e| usage(e.to_string()))?
    } else {
        if args.max_order == 0 || args.max_order > calib_core::plan::csrr::MAX_PLANNED_ORDER {
            return Err(usage(format!(
                "--max-order must be in 1..={}, not {}",
                calib_core::plan::csrr::MAX_PLANNED_ORDER,
                args.max_order
            )));
        }
        let deltas: Vec<f64> = args.deltas.iter().map(|d| d.to_radians()).collect();
        CsrrPlan::of(&deltas, args.max_order, rig.run())
    };
    let orders: Vec<usize> = if args.orders.is_empty() {
        (1..=args.max_order).collect()
    } else {
        args.orders.clone()
    };
    let u_map = plan.u_fit(&orders);

    let mut written = Vec::new();
    if let Some(path) = &args.procedure {
        let scenario_path = path.with_extension("toml");
        if scenario_path == *path {
            return Err(usage(format!(
                "--procedure {}: the scenario is written beside the procedure as <name>.toml; \
                 give the procedure another extension (e.g. {})",
                path.display(),
                path.with_extension("md").display()
            )));
        }
        for file in [path, &scenario_path] {
            crate::output::check_file_replaceable(file, "--procedure")?;
        }
        let text = render_csrr_procedure(&plan, &rig, args.max_order);
        calib_io::atomic::write_atomic(path, text.as_bytes())
            .with_context(|| format!("cannot write the procedure {}", path.display()))?;
        let scenario = rig.scenario(&plan.deltas, RAMP_S, PAUSE_S, TURN_S);
        let toml = toml::to_string(&scenario).context("cannot render the scenario")?;
        let text = format!(
            "# The run planned by `calib plan csrr --max-order {}` (see {}): sensors a (rotor A)\n\
             # and b (the shaft) with the planned noise and resolution and no error. Add each\n\
             # sensor's expected harmonics, e.g.\n\
             #   harmonics = [{{ order = 72, amplitude_arcsec = 20.0, phase_deg = 0.0 }}]\n\
             # then `calib simulate {} -o sim.mcap` and `calib csrr sim.mcap -o out/`.\n{toml}",
            args.max_order,
            file_name(path),
            file_name(&scenario_path),
        );
        calib_io::atomic::write_atomic(&scenario_path, text.as_bytes())
            .with_context(|| format!("cannot write the scenario {}", scenario_path.display()))?;
        written.push(path.clone());
        written.push(scenario_path);
        crate::output::record_written(&written);
    }

    if args.json {
        let value = csrr_json(&plan, proposed, &orders, u_map);
        return Ok(serde_json::to_string_pretty(&value)? + "\n");
    }
    let mut out = render_csrr(&plan, proposed, &orders, u_map, args.orders.is_empty());
    for path in written {
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}

fn multihead(args: &MultiheadArgs) -> anyhow::Result<String> {
    let usage = |m: String| anyhow::Error::new(Usage(m));
    for (name, v) in [
        ("--rate", args.rate),
        ("--rpm", args.rpm),
        ("--revolutions", args.revolutions),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(usage(format!("{name} must be a positive number, not {v}")));
        }
    }
    for (name, v) in [("--noise", args.noise), ("--resolution", args.resolution)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(usage(format!("{name} must be ≥ 0 arcsec, not {v}")));
        }
    }
    let samples = args.revolutions * args.rate * 60.0 / args.rpm;
    let sigma = (args.noise.powi(2) + args.resolution.powi(2) / 12.0).sqrt() / ARCSEC_PER_RAD;
    angles_within("--heads", args.heads.unwrap_or(0), "heads")?;
    angles_within("--positions", args.positions.len(), "head angles")?;
    let proposed = args.positions.is_empty();
    let plan = if proposed {
        let heads = args.heads.unwrap_or(0);
        calib_core::plan::multihead::plan(
            heads,
            args.max_order,
            args.step.map(f64::to_radians),
            samples,
            sigma,
        )
        .map_err(|e| usage(e.to_string()))?
    } else {
        if args.positions.len() < 2 || args.positions.iter().any(|p| !p.is_finite()) {
            return Err(usage(
                "--positions needs at least two head angles in degrees".into(),
            ));
        }
        if args.heads.is_some_and(|k| k != args.positions.len()) {
            return Err(usage(format!(
                "--heads {} but --positions gives {} angles",
                args.heads.unwrap_or(0),
                args.positions.len()
            )));
        }
        if args.max_order == 0 || args.max_order > calib_core::plan::csrr::MAX_PLANNED_ORDER {
            return Err(usage(format!(
                "--max-order must be in 1..={}, not {}",
                calib_core::plan::csrr::MAX_PLANNED_ORDER,
                args.max_order
            )));
        }
        let positions: Vec<f64> = args.positions.iter().map(|d| d.to_radians()).collect();
        MultiheadPlan::of(&positions, args.max_order, samples, sigma)
    };
    let worst = plan.worst();
    if args.json {
        let value = json!({
            "method": "multihead",
            "proposed": proposed,
            "positions_deg": plan.positions.iter().map(|d| d.to_degrees()).collect::<Vec<_>>(),
            "max_order": plan.orders.len(),
            "blind_orders": plan.blind_orders,
            "worst_observability": worst.map(|o| o.observability),
            "worst_order": worst.map(|o| o.order),
            "samples": plan.samples,
            "noise_per_sample_arcsec": plan.sigma * ARCSEC_PER_RAD,
            "u_fit_arcsec": plan.u_fit() * ARCSEC_PER_RAD,
            "orders": plan.orders.iter().map(|o| json!({
                "order": o.order,
                "observability": o.observability,
                "u_arcsec": finite(o.u * ARCSEC_PER_RAD),
            })).collect::<Vec<_>>(),
        });
        return Ok(serde_json::to_string_pretty(&value)? + "\n");
    }
    let mut out = String::new();
    let n = plan.orders.len();
    let _ = writeln!(
        out,
        "multi-head plan: {} heads, orders 1–{n}",
        plan.positions.len()
    );
    let _ = writeln!(
        out,
        "  head angles ({}): {} °",
        if proposed { "proposed" } else { "given" },
        degrees(&plan.positions)
    );
    if let Some(w) = worst {
        let _ = writeln!(
            out,
            "  worst observability {:.4} (order {})",
            w.observability, w.order
        );
    }
    if plan.blind_orders.is_empty() {
        let _ = writeln!(out, "  blind orders: none up to {n}");
    } else {
        let _ = writeln!(
            out,
            "  blind orders (the method leaves them out of the map): {}",
            list(&plan.blind_orders)
        );
    }
    let _ = writeln!(
        out,
        "  u of the map from the noise: {:.5}″ ({:.4}″ per head and sample, {:.0} samples, \
         every order up to {n} not left out)",
        plan.u_fit() * ARCSEC_PER_RAD,
        plan.sigma * ARCSEC_PER_RAD,
        plan.samples
    );
    Ok(out)
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn degrees(deltas: &[f64]) -> String {
    deltas
        .iter()
        .map(|d| format!("{:.3}", d.to_degrees()))
        .collect::<Vec<_>>()
        .join(", ")
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// The plan as JSON: `deltas_deg`, `blind_orders`, and per order its observability, phase
/// spread, noise gain and u (null where blind).
fn csrr_json(plan: &CsrrPlan, proposed: bool, orders: &[usize], u_map: f64) -> serde_json::Value {
    let worst = plan.worst();
    json!({
        "method": "csrr",
        "proposed": proposed,
        "deltas_deg": plan.deltas.iter().map(|d| d.to_degrees()).collect::<Vec<_>>(),
        "max_order": plan.orders.len(),
        "blind_orders": plan.blind_orders,
        "worst_observability": worst.map(|o| o.observability),
        "worst_order": worst.map(|o| o.order),
        "worst_phase_spread": plan.worst_phase_spread(),
        "samples_per_session": plan.samples_per_session,
        "noise_per_sample_arcsec": plan.sigma * ARCSEC_PER_RAD,
        "u_orders": orders,
        "u_fit_arcsec": u_map * ARCSEC_PER_RAD,
        "orders": plan.orders.iter().map(|o| json!({
            "order": o.order,
            "observability": o.observability,
            "phase_spread": o.phase_spread,
            "noise_gain": finite(o.noise_gain),
            "u_arcsec": finite(o.u * ARCSEC_PER_RAD),
        })).collect::<Vec<_>>(),
    })
}

/// How many of the worst-seen orders the text lists.
const LISTED: usize = 10;

fn render_csrr(
    plan: &CsrrPlan,
    proposed: bool,
    orders: &[usize],
    u_map: f64,
    all_orders: bool,
) -> String {
    let mut out = String::new();
    let n = plan.orders.len();
    let _ = writeln!(
        out,
        "CSRR plan: {} sessions, orders 1–{n}",
        plan.deltas.len()
    );
    let _ = writeln!(
        out,
        "  relative rotations Δ ({}): {} °",
        if proposed { "proposed" } else { "given" },
        degrees(&plan.deltas)
    );
    if let Some(w) = plan.worst() {
        let _ = writeln!(
            out,
            "  worst observability {:.4} (order {}), worst phase spread {:.4}",
            w.observability,
            w.order,
            plan.worst_phase_spread()
        );
    }
    if plan.blind_orders.is_empty() {
        let _ = writeln!(out, "  blind orders: none up to {n}");
    } else {
        let _ = writeln!(
            out,
            "  blind orders (the method leaves them out of the maps): {}",
            list(&plan.blind_orders)
        );
    }
    let _ = writeln!(
        out,
        "  noise {:.4}″ per sample of x − y, {:.0} samples per session",
        plan.sigma * ARCSEC_PER_RAD,
        plan.samples_per_session
    );
    let _ = writeln!(
        out,
        "  u of each map from the noise: {:.4}″ {}",
        u_map * ARCSEC_PER_RAD,
        if all_orders {
            format!(
                "if every order up to {n} stands above the noise (an upper bound; --orders for yours)"
            )
        } else {
            format!("for orders {}", list(orders))
        }
    );
    let mut worst: Vec<_> = plan.orders.iter().collect();
    worst.sort_by(|a, b| a.observability.total_cmp(&b.observability));
    let _ = writeln!(
        out,
        "\n  the {} orders seen worst:\n  order  observability  phase spread  noise gain   u per order",
        LISTED.min(n)
    );
    for o in worst.iter().take(LISTED) {
        let (gain, u) = if o.u.is_finite() {
            (
                format!("{:>10.2}", o.noise_gain),
                format!("{:>10.5}″", o.u * ARCSEC_PER_RAD),
            )
        } else {
            (format!("{:>10}", "blind"), format!("{:>11}", "—"))
        };
        let _ = writeln!(
            out,
            "  {:>5}  {:>13.4}  {:>12.4}  {gain}  {u}",
            o.order, o.observability, o.phase_spread
        );
    }
    out
}

fn list(orders: &[usize]) -> String {
    let shown: Vec<String> = orders.iter().take(20).map(|h| h.to_string()).collect();
    let more = orders.len().saturating_sub(20);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// The procedure as a Markdown checklist: each session's turn of rotor A, revolutions and speed.
fn render_csrr_procedure(plan: &CsrrPlan, rig: &CsrrRig, max_order: usize) -> String {
    let mut out = String::new();
    let session_s = rig.revolutions * 60.0 / rig.speed_rpm;
    let _ = writeln!(
        out,
        "# CSRR procedure for orders 1–{max_order} ({} sessions)\n",
        plan.deltas.len()
    );
    let _ = writeln!(
        out,
        "Record both sensors at {} Hz throughout. Each session: ramp up over {RAMP_S} s, turn {} \
         revolutions at {} r/min ({:.0} s), ramp down, pause {PAUSE_S} s. Between sessions, with \
         the shaft at rest, turn rotor A relative to the shaft to the next relative rotation \
         (about {TURN_S} s) and pause {PAUSE_S} s. Sessions are found from the motion.\n",
        rig.rate_hz, rig.revolutions, rig.speed_rpm, session_s
    );
    let _ = writeln!(
        out,
        "| session | relative rotation Δ | turn rotor A by | revolutions | speed |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|");
    let mut previous = plan.deltas[0];
    for (k, &d) in plan.deltas.iter().enumerate() {
        let turn = if k == 0 {
            "— (start here)".to_string()
        } else {
            format!("{:+.3}°", (d - previous).to_degrees())
        };
        previous = d;
        let _ = writeln!(
            out,
            "| {} | {:.3}° | {turn} | {} | {} r/min |",
            k + 1,
            d.to_degrees(),
            rig.revolutions,
            rig.speed_rpm
        );
    }
    let w = plan.worst();
    let _ = writeln!(
        out,
        "\nWorst observability {:.4} (order {}); blind orders: {}. Set each Δ to better than \
         the map's u divided by the largest error's slope; calib estimates each session's Δ from \
         the data.",
        w.map_or(0.0, |w| w.observability),
        w.map_or(0, |w| w.order),
        if plan.blind_orders.is_empty() {
            "none".to_string()
        } else {
            list(&plan.blind_orders)
        }
    );
    out
}

/// The planner that `calib plan WORDS…` names (the tests' parser of each planner's options).
#[cfg(test)]
pub(super) fn parse(words: &[&str]) -> Method {
    #[derive(clap::Parser)]
    struct P {
        #[command(subcommand)]
        m: Method,
    }
    use clap::Parser;
    P::try_parse_from(std::iter::once(&"plan").chain(words))
        .unwrap()
        .m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(extra: &[&str]) -> CsrrArgs {
        let mut v = vec!["csrr", "--max-order", "90"];
        v.extend_from_slice(extra);
        match parse(&v) {
            Method::Csrr(a) => a,
            _ => unreachable!("parsed csrr"),
        }
    }

    #[test]
    fn blind_set_is_named_in_text_and_json() {
        let a = args(&["--deltas", "0,40,96,172,288", "--json"]);
        let out = csrr(&a).unwrap();
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["blind_orders"], json!([90]));
        assert_eq!(v["deltas_deg"].as_array().unwrap().len(), 5);
        assert_eq!(v["orders"].as_array().unwrap().len(), 90);
        assert!(v["orders"][89]["observability"].as_f64().unwrap() < 1e-9);
        assert!(v["orders"][89]["u_arcsec"].is_null());
        let text = csrr(&CsrrArgs { json: false, ..a }).unwrap();
        assert!(
            text.contains("blind orders (the method leaves them out of the maps): 90"),
            "{text}"
        );
    }

    #[test]
    fn selfa_placement_is_blind_at_84() {
        let a = MultiheadArgs {
            heads: None,
            max_order: 100,
            step: None,
            positions: vec![
                0.0,
                120.0,
                240.0,
                90.0,
                180.0,
                270.0,
                51.428571428571,
                102.857142857143,
                154.285714285714,
                205.714285714286,
                257.142857142857,
                308.571428571429,
            ],
            rate: 400.0,
            rpm: 10.0,
            revolutions: 3.0,
            noise: 0.01,
            resolution: 0.01,
            json: true,
        };
        let v: serde_json::Value = serde_json::from_str(&multihead(&a).unwrap()).unwrap();
        assert_eq!(v["blind_orders"], json!([84]));
        assert_eq!(v["positions_deg"].as_array().unwrap().len(), 12);
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for extra in [
            &["--deltas", "10"][..],
            &["--rpm", "0"],
            &["--noise=-1"],
            &["--orders", "91"],
            &["--sessions", "1"],
        ] {
            let e = csrr(&args(extra)).unwrap_err();
            assert!(e.downcast_ref::<Usage>().is_some(), "{extra:?}: {e}");
        }
    }
}

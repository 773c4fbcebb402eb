//! `calib plan tdr`: the coast-down, its duration and sample rate, and the map's u.

use super::{file_name, finite, non_negative, num, positive, sample_sigma, write_procedure};
use crate::exit::Usage;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::plan::tdr::{CoastLaw, TdrPlan, TdrPlanError, TdrRig};
use serde_json::json;
use std::f64::consts::TAU;
use std::fmt::Write;
use std::path::PathBuf;

/// How the coasting shaft slows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Law {
    /// Air or oil shear: the deceleration is proportional to the speed, which falls
    /// exponentially.
    Viscous,
    /// Dry friction: a constant deceleration, the speed falls linearly.
    Coulomb,
}

/// `calib plan tdr`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct TdrArgs {
    /// The highest order the map must hold.
    #[arg(long, value_name = "N")]
    pub max_order: usize,
    /// Speed at which the shaft is released, r/min.
    #[arg(long, value_name = "RPM")]
    pub start_rpm: f64,
    /// Deceleration just after release, r/min per second: release the shaft once at the start
    /// speed and see how fast it slows (600 → 590 r/min in 1 s: 10).
    #[arg(long, value_name = "RPM_PER_S")]
    pub decel: f64,
    /// How the shaft slows.
    #[arg(long, value_enum, default_value_t = Law::Viscous)]
    pub law: Law,
    /// Sample rate, Hz. Default: proposed, N/0.4 samples per revolution at the start speed
    /// (rounded up to 100 Hz).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<f64>,
    /// Coast down to this speed, r/min. Default: proposed, where separating drag costs 1.5×
    /// the noise at the drag's orders (never below 10 % of the start, where calib tdr stops).
    #[arg(long, value_name = "RPM")]
    pub end_rpm: Option<f64>,
    /// The encoder's reading noise, arcsec (standard deviation per sample).
    #[arg(long, default_value_t = 0.05, value_name = "ARCSEC")]
    pub noise: f64,
    /// The encoder's resolution, arcsec (adds resolution²/12 to the noise's variance).
    #[arg(long, default_value_t = 0.09, value_name = "ARCSEC")]
    pub resolution: f64,
    /// The orders you expect the error to hold (e.g. 72,144,216): the map's u is for these.
    /// Default: every order up to N, an upper bound.
    #[arg(long, value_delimiter = ',', value_name = "H,...")]
    pub orders: Vec<usize>,
    /// Write the procedure (release, record, how long) to FILE and a matching simulator
    /// scenario beside it (FILE with the extension .toml).
    #[arg(long, value_name = "FILE")]
    pub procedure: Option<PathBuf>,
    /// Print the plan as JSON.
    #[arg(long)]
    pub json: bool,
}

const RPM: f64 = TAU / 60.0;

/// Runs `calib plan tdr`.
pub fn run(args: &TdrArgs) -> anyhow::Result<String> {
    positive("--start-rpm", args.start_rpm)?;
    positive("--decel", args.decel)?;
    if let Some(r) = args.rate {
        positive("--rate", r)?;
    }
    if let Some(r) = args.end_rpm {
        positive("--end-rpm", r)?;
    }
    non_negative("--noise", args.noise, "arcsec")?;
    non_negative("--resolution", args.resolution, "arcsec")?;
    let rig = TdrRig {
        start_speed: args.start_rpm * RPM,
        deceleration: args.decel * RPM,
        law: match args.law {
            Law::Viscous => CoastLaw::Viscous,
            Law::Coulomb => CoastLaw::Coulomb,
        },
        rate_hz: args.rate,
        sigma: sample_sigma(args.noise, args.resolution),
    };
    let plan = calib_core::plan::tdr::plan(
        rig,
        args.max_order,
        &args.orders,
        args.end_rpm.map(|r| r * RPM),
    )
    .map_err(|e| {
        let hint = if matches!(e, TdrPlanError::Invalid { .. }) {
            " (check --start-rpm, --decel, --rate, --end-rpm, --orders)"
        } else {
            ""
        };
        anyhow::Error::new(Usage(format!("{e}{hint}")))
    })?;

    let mut written = Vec::new();
    if let Some(path) = &args.procedure {
        let scenario = plan.scenario(args.noise, args.resolution);
        let toml = toml::to_string(&scenario).context("cannot render the scenario")?;
        let scenario_text = format!(
            "# The coast planned by `calib plan tdr --max-order {}` (see {}): sensor enc with the\n\
             # planned noise and resolution and no error. Add its expected harmonics, e.g.\n\
             #   harmonics = [{{ order = 2, amplitude_arcsec = 20.0, phase_deg = 0.0 }}]\n\
             # and any drag ([spin_down] drag_harmonics), then\n\
             # `calib simulate {} -o sim.mcap` and `calib tdr sim.mcap --channel enc --max-order {} -o out/`.\n{toml}",
            args.max_order,
            file_name(path),
            file_name(&path.with_extension("toml")),
            args.max_order,
        );
        written = write_procedure(
            path,
            &render_procedure(&plan),
            &[("toml", "scenario", scenario_text)],
        )?;
    }
    if args.json {
        return Ok(serde_json::to_string_pretty(&to_json(&plan, args))? + "\n");
    }
    let mut out = render(&plan, args);
    for path in written {
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}

fn law_name(law: CoastLaw) -> &'static str {
    match law {
        CoastLaw::Viscous => "viscous",
        CoastLaw::Coulomb => "coulomb",
    }
}

fn to_json(plan: &TdrPlan, args: &TdrArgs) -> serde_json::Value {
    json!({
        "method": "tdr",
        "max_order": plan.max_order,
        "law": law_name(plan.rig.law),
        "start_rpm": plan.rig.start_speed / RPM,
        "decel_rpm_per_s": plan.rig.deceleration / RPM,
        "end_rpm": plan.end_speed / RPM,
        "end_proposed": args.end_rpm.is_none(),
        "separating_rpm": plan.separating_speed / RPM,
        "duration_s": plan.duration_s,
        "revolutions": plan.revolutions,
        "rate_hz": plan.rate_hz,
        "rate_proposed": args.rate.is_none(),
        "samples": plan.samples,
        "samples_per_revolution_at_start": plan.samples_per_revolution,
        "speed_variation": plan.speed_variation,
        "drag_noise_gain": plan.drag_noise_gain,
        "separable": plan.separable,
        "motion_degree": plan.motion_degree,
        "noise_per_sample_arcsec": plan.rig.sigma * ARCSEC_PER_RAD,
        "u_orders": plan.orders,
        "u_fit_arcsec": plan.rms_u_fit() * ARCSEC_PER_RAD,
        "max_u_fit_arcsec": plan.max_u_fit() * ARCSEC_PER_RAD,
        "u_fit_at_drag_orders_arcsec": finite(plan.rms_u_fit() * plan.drag_noise_gain * ARCSEC_PER_RAD),
        "warnings": plan.warnings,
    })
}

fn render(plan: &TdrPlan, args: &TdrArgs) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "TDR plan: orders 1–{}, a {} coast from {} r/min ({} r/min per second at release)",
        plan.max_order,
        law_name(plan.rig.law),
        num(args.start_rpm),
        num(args.decel)
    );
    let _ = writeln!(
        out,
        "  coast down to {:.1} r/min ({}): {:.1} s, {:.0} revolutions",
        plan.end_speed / RPM,
        if args.end_rpm.is_none() {
            "proposed"
        } else {
            "given"
        },
        plan.duration_s,
        plan.revolutions
    );
    let _ = writeln!(
        out,
        "  drag separation: 1/ω² varies by {:.1} % RMS over it (calib tdr needs ≥ 10 %: a coast \
         below {:.1} r/min); {}",
        100.0 * plan.speed_variation,
        plan.separating_speed / RPM,
        if plan.separable {
            format!(
                "the drag's orders cost {:.2}× the noise",
                plan.drag_noise_gain
            )
        } else {
            "NOT separable: the map would keep any angle-dependent drag; coast further".into()
        }
    );
    let _ = writeln!(
        out,
        "  sample rate {} Hz ({}): {:.0} samples per revolution at the start, order {} at 0.4 of \
         them; {} samples",
        plan.rate_hz,
        if args.rate.is_none() {
            "proposed"
        } else {
            "given"
        },
        plan.samples_per_revolution,
        plan.max_order,
        plan.samples
    );
    let all = args.orders.is_empty();
    let _ = writeln!(
        out,
        "  u of the map from the noise: {:.5}″ RMS, {:.5}″ at most ({:.4}″ per sample; {})",
        plan.rms_u_fit() * ARCSEC_PER_RAD,
        plan.max_u_fit() * ARCSEC_PER_RAD,
        plan.rig.sigma * ARCSEC_PER_RAD,
        if all {
            format!(
                "every order up to {}, an upper bound; --orders for yours",
                plan.max_order
            )
        } else {
            format!("orders {}", super::list(&plan.orders))
        }
    );
    for w in &plan.warnings {
        let _ = writeln!(out, "  warning: {w}");
    }
    let _ = writeln!(
        out,
        "  then: calib tdr LOG --channel ENCODER --max-order {} -o out/",
        plan.max_order
    );
    out
}

fn render_procedure(plan: &TdrPlan) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Spin-down (TDR) procedure for orders 1–{}\n",
        plan.max_order
    );
    let _ = writeln!(
        out,
        "1. Record the encoder at {} Hz (or faster) from before the release to the end.\n\
         2. Spin the shaft up to {} r/min and hold it there for a few seconds.\n\
         3. Release it: open the clutch or cut the motor current (no drive torque, no braking).\n\
         4. Keep recording while it coasts down to {:.1} r/min or below: about {:.0} s and {:.0} \
         revolutions for a {} coast slowing by {} r/min per second at release.\n\
         5. `calib tdr LOG --channel ENCODER --max-order {} -o out/`.\n",
        plan.rate_hz,
        num(plan.rig.start_speed / RPM),
        plan.end_speed / RPM,
        plan.duration_s.ceil(),
        plan.revolutions,
        law_name(plan.rig.law),
        num(plan.rig.deceleration / RPM),
        plan.max_order
    );
    let _ = writeln!(
        out,
        "The coast must fall below {:.1} r/min for calib tdr to separate an angle-dependent drag \
         (1/ω² varying by ≥ 10 % RMS); to {:.1} r/min, the drag's orders cost {:.2}× the noise. \
         Expected u of the map from the noise: {:.5}″ RMS.",
        plan.separating_speed / RPM,
        plan.end_speed / RPM,
        plan.drag_noise_gain,
        plan.rms_u_fit() * ARCSEC_PER_RAD
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(extra: &[&str]) -> TdrArgs {
        let base = ["tdr", "--max-order", "16", "--start-rpm", "600"];
        let decel = if extra.contains(&"--decel") {
            &[][..]
        } else {
            &["--decel", "10"][..]
        };
        let words: Vec<&str> = base.iter().chain(decel).chain(extra).copied().collect();
        match super::super::parse(&words) {
            super::super::Method::Tdr(a) => a,
            _ => unreachable!("parsed tdr"),
        }
    }

    #[test]
    fn plan_in_text_and_json() {
        let v: serde_json::Value = serde_json::from_str(&run(&args(&["--json"])).unwrap()).unwrap();
        assert_eq!(v["rate_hz"], json!(400.0));
        assert_eq!(v["separable"], json!(true));
        assert!((v["drag_noise_gain"].as_f64().unwrap() - 1.5).abs() < 1e-6);
        let sep = v["separating_rpm"].as_f64().unwrap();
        assert!((490.0..520.0).contains(&sep), "{sep}");
        let text = run(&args(&[])).unwrap();
        assert!(text.contains("sample rate 400 Hz (proposed)"), "{text}");
        let narrow = run(&args(&["--end-rpm", "580"])).unwrap();
        assert!(narrow.contains("NOT separable"), "{narrow}");
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for extra in [
            &["--end-rpm", "30"][..],
            &["--orders", "17"],
            &["--rate", "0"],
            &["--noise=-1"],
            &["--decel", "3000"],
        ] {
            let e = run(&args(extra)).unwrap_err();
            assert!(e.downcast_ref::<Usage>().is_some(), "{extra:?}: {e}");
        }
    }
}

//! `calib plan reference`: ISO 230-2 targets, passes, the approach for a backlash, the sweep,
//! and the map's u.

use super::{file_name, list, non_negative, num, positive, sample_sigma, write_procedure};
use crate::exit::Usage;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::plan::reference::{
    ISO_PASSES, MIN_PHASES, ReferencePlan, ReferenceRig, SLOW_FRACTION,
};
use serde_json::json;
use std::fmt::Write;
use std::path::PathBuf;

/// `calib plan reference`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct ReferenceArgs {
    /// The orders the DUT's error is expected to hold (e.g. its pole pairs and their
    /// multiples: 72,144,216): the targets are chosen to see each at 8 phases or more.
    #[arg(long, value_delimiter = ',', value_name = "H,...")]
    pub orders: Vec<usize>,
    /// ISO 230-2 targets to evaluate instead of proposing a count.
    #[arg(long, value_name = "K")]
    pub targets: Option<usize>,
    /// Passes in each direction (ISO 230-2 asks for 5).
    #[arg(long, default_value_t = ISO_PASSES, value_name = "N")]
    pub passes: u32,
    /// Lost motion between the DUT and the reference (coupling, gears), arcsec: the approach
    /// after each reversal is twice it, at least calib reference's 1°.
    #[arg(long, default_value_t = 0.0, value_name = "ARCSEC")]
    pub backlash: f64,
    /// Sample rate of both channels, Hz: at least --speed ÷ the approach (30 Hz at the default
    /// 30°/s and 1°), a sample within the approach to each target.
    #[arg(long, default_value_t = 500.0, value_name = "HZ")]
    pub rate: f64,
    /// Cruise speed of the faster passes, degrees per second (the others at a third of it, so
    /// that calib reference can tell a lag between the channels from backlash).
    #[arg(long, default_value_t = 30.0, value_name = "DEG_PER_S")]
    pub speed: f64,
    /// The DUT's reading noise, arcsec.
    #[arg(long, default_value_t = 0.2, value_name = "ARCSEC")]
    pub noise: f64,
    /// The DUT's resolution, arcsec.
    #[arg(long, default_value_t = 0.5, value_name = "ARCSEC")]
    pub resolution: f64,
    /// The reference's reading noise, arcsec.
    #[arg(long, default_value_t = 0.01, value_name = "ARCSEC")]
    pub ref_noise: f64,
    /// The reference's resolution, arcsec.
    #[arg(long, default_value_t = 0.001, value_name = "ARCSEC")]
    pub ref_resolution: f64,
    /// The reference's stated standard uncertainty, arcsec (calib reference --ref-u).
    #[arg(long, default_value_t = 0.0, value_name = "ARCSEC")]
    pub ref_u: f64,
    /// Write the procedure (the sweep, passes, approach, targets) to FILE and a matching
    /// simulator scenario beside it (FILE with the extension .toml).
    #[arg(long, value_name = "FILE")]
    pub procedure: Option<PathBuf>,
    /// Print the plan as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib plan reference`.
pub fn run(args: &ReferenceArgs) -> anyhow::Result<String> {
    positive("--rate", args.rate)?;
    positive("--speed", args.speed)?;
    for (name, v) in [
        ("--noise", args.noise),
        ("--resolution", args.resolution),
        ("--ref-noise", args.ref_noise),
        ("--ref-resolution", args.ref_resolution),
        ("--ref-u", args.ref_u),
        ("--backlash", args.backlash),
    ] {
        non_negative(name, v, "arcsec")?;
    }
    let rig = ReferenceRig {
        dut_sigma: sample_sigma(args.noise, args.resolution),
        reference_sigma: sample_sigma(args.ref_noise, args.ref_resolution),
        reference_u: args.ref_u / ARCSEC_PER_RAD,
        rate_hz: args.rate,
        speed: args.speed.to_radians(),
        backlash: args.backlash / ARCSEC_PER_RAD,
        passes: args.passes,
    };
    let plan = calib_core::plan::reference::plan(rig, &args.orders, args.targets)
        .map_err(|e| anyhow::Error::new(Usage(e.to_string())))?;
    // Below one sample per approach a pass can reach a target with no sample on the way.
    let approach_deg = plan.approach.to_degrees();
    let min_rate = args.speed / approach_deg;
    if args.rate < min_rate {
        return Err(anyhow::Error::new(Usage(format!(
            "--rate {} Hz is below {} Hz, the least at which the faster passes (--speed {}°/s) \
             take a sample within the {}° approach to each target; give --rate {} or more (or a \
             lower --speed)",
            calib_io::limits::readable(args.rate),
            num(min_rate),
            num(args.speed),
            num(approach_deg),
            num(min_rate.ceil())
        ))));
    }
    let mut written = Vec::new();
    if let Some(path) = &args.procedure {
        let scenario = plan.scenario(
            (args.noise, args.resolution),
            (args.ref_noise, args.ref_resolution),
        );
        let toml = toml::to_string(&scenario).context("cannot render the scenario")?;
        let scenario_text = format!(
            "# The run planned by `calib plan reference` (see {}): sensors dut and ref with the\n\
             # planned noise and resolution, the DUT behind the planned backlash, no error. Add\n\
             # the DUT's expected harmonics, e.g.\n\
             #   harmonics = [{{ order = 1, amplitude_arcsec = 60.0, phase_deg = 0.0 }}]\n\
             # then `calib simulate {} -o sim.mcap` and `{}`.\n{toml}",
            file_name(path),
            file_name(&path.with_extension("toml")),
            then(&plan, "sim.mcap"),
        );
        written = write_procedure(
            path,
            &render_procedure(&plan),
            &[("toml", "scenario", scenario_text)],
        )?;
    }
    if args.json {
        return Ok(serde_json::to_string_pretty(&to_json(&plan))? + "\n");
    }
    let mut out = render(&plan);
    for path in written {
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}

/// The `calib reference` command for the planned run.
fn then(plan: &ReferencePlan, log: &str) -> String {
    let approach = plan.approach.to_degrees();
    format!(
        "calib reference {log} --dut dut --ref ref --targets {}{} -o out/",
        plan.targets,
        if approach > 1.0 + 1e-9 {
            format!(" --approach {approach:.4}")
        } else {
            String::new()
        }
    )
}

fn to_json(plan: &ReferencePlan) -> serde_json::Value {
    json!({
        "method": "reference",
        "targets": plan.targets,
        "targets_proposed": plan.proposed,
        "target_angles_deg": plan.target_angles.iter().map(|a| a.to_degrees()).collect::<Vec<_>>(),
        "orders": plan.phases.iter().map(|&(h, m)| json!({"order": h, "phases": m})).collect::<Vec<_>>(),
        "blind_orders": plan.blind_orders,
        "passes": plan.rig.passes,
        "approach_deg": plan.approach.to_degrees(),
        "sweep_deg": [plan.sweep.0.to_degrees(), plan.sweep.1.to_degrees()],
        "speeds_deg_per_s": [plan.rig.speed.to_degrees(), SLOW_FRACTION * plan.rig.speed.to_degrees()],
        "rate_hz": plan.rig.rate_hz,
        "duration_s": plan.duration_s,
        "sample_spacing_deg": plan.sample_spacing.to_degrees(),
        "crossing_sigma_arcsec": plan.crossing_sigma * ARCSEC_PER_RAD,
        "reference_u_arcsec": plan.rig.reference_u * ARCSEC_PER_RAD,
        "u_arcsec": plan.u * ARCSEC_PER_RAD,
        "warnings": plan.warnings,
    })
}

fn render(plan: &ReferencePlan) -> String {
    let mut out = String::new();
    let r = &plan.rig;
    let _ = writeln!(
        out,
        "reference plan (ISO 230-2): {} passes in each direction over a whole turn",
        r.passes
    );
    let seen = if plan.phases.is_empty() {
        "no DUT orders given (--orders)".to_string()
    } else {
        let p: Vec<String> = plan
            .phases
            .iter()
            .map(|(h, m)| format!("{h} at {m}"))
            .collect();
        format!("orders seen at phases: {}", p.join(", "))
    };
    let _ = writeln!(
        out,
        "  targets: {} ({}), at (j + ½)·{:.4}°; {seen}",
        plan.targets,
        if plan.proposed {
            format!("proposed: the first count from 20 that sees every order at ≥ {MIN_PHASES}")
        } else {
            "given".into()
        },
        360.0 / plan.targets as f64
    );
    if !plan.blind_orders.is_empty() {
        let _ = writeln!(
            out,
            "  blind orders of the targets (every target sees the same value; E and M miss them): {}",
            list(&plan.blind_orders)
        );
    }
    let _ = writeln!(
        out,
        "  approach after each reversal: {:.4}° ({})",
        plan.approach.to_degrees(),
        if r.backlash > 0.0 {
            format!(
                "twice the {:.1}″ backlash, at least 1°",
                r.backlash * ARCSEC_PER_RAD
            )
        } else {
            "calib reference's 1°".into()
        }
    );
    let _ = writeln!(
        out,
        "  run: sweep {}° → {}° and back, {} times, alternately at {}°/s and {}°/s, sampled at \
         {} Hz ({:.4}° between samples at the faster): about {:.0} s",
        num(plan.sweep.0.to_degrees()),
        num(plan.sweep.1.to_degrees()),
        r.passes,
        num(r.speed.to_degrees()),
        num(SLOW_FRACTION * r.speed.to_degrees()),
        r.rate_hz,
        plan.sample_spacing.to_degrees(),
        plan.duration_s
    );
    let _ = writeln!(
        out,
        "  u of each map point: {:.4}″ (a crossing's spread {:.4}″ over {} passes each way; \
         reference u {:.4}″)",
        plan.u * ARCSEC_PER_RAD,
        plan.crossing_sigma * ARCSEC_PER_RAD,
        r.passes,
        r.reference_u * ARCSEC_PER_RAD
    );
    for w in &plan.warnings {
        let _ = writeln!(out, "  warning: {w}");
    }
    let _ = writeln!(out, "  then: {}", then(plan, "LOG"));
    out
}

fn render_procedure(plan: &ReferencePlan) -> String {
    let r = &plan.rig;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Reference (ISO 230-2) procedure: {} passes in each direction\n",
        r.passes
    );
    let _ = writeln!(
        out,
        "1. Record the DUT and the reference together at {} Hz throughout.\n\
         2. Rest at {}°, then turn to {}° at {}°/s, pause 1 s, and back to {}°, pause 1 s: one \
         pass in each direction. The next pass the same at {}°/s, and so on, alternating; {} \
         passes in all (about {:.0} s).\n\
         3. `{}`.\n",
        r.rate_hz,
        num(plan.sweep.0.to_degrees()),
        num(plan.sweep.1.to_degrees()),
        num(r.speed.to_degrees()),
        num(plan.sweep.0.to_degrees()),
        num(SLOW_FRACTION * r.speed.to_degrees()),
        r.passes,
        plan.duration_s,
        then(plan, "LOG")
    );
    let _ = writeln!(
        out,
        "The first {:.4}° after each reversal take up the backlash and are not used; every grid \
         point is crossed {} times each way beyond them. ISO 230-2 targets: {} at \
         (j + ½)·{:.4}°. Expected u of each map point: {:.4}″.",
        plan.approach.to_degrees(),
        r.passes,
        plan.targets,
        360.0 / plan.targets as f64,
        plan.u * ARCSEC_PER_RAD
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(extra: &[&str]) -> ReferenceArgs {
        let words: Vec<&str> = ["reference"].iter().chain(extra).copied().collect();
        match super::super::parse(&words) {
            super::super::Method::Reference(a) => a,
            _ => unreachable!("parsed reference"),
        }
    }

    #[test]
    fn targets_for_a_72_pole_pair_dut_and_a_blind_count() {
        let v: serde_json::Value =
            serde_json::from_str(&run(&args(&["--orders", "72,144,216", "--json"])).unwrap())
                .unwrap();
        assert_eq!(v["targets_proposed"], json!(true));
        assert!(v["blind_orders"].as_array().unwrap().is_empty());
        let text = run(&args(&["--orders", "72", "--targets", "24"])).unwrap();
        assert!(
            text.contains("blind orders of the targets (every target sees the same value; E and M miss them): 72"),
            "{text}"
        );
        let backlash = run(&args(&["--backlash", "3600"])).unwrap();
        assert!(backlash.contains("--approach 2.0000"), "{backlash}");
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for extra in [
            &["--passes", "1"][..],
            &["--speed", "2.5"],
            &["--targets", "0"],
            &["--backlash=-1"],
            &["--orders", "0"],
        ] {
            let e = run(&args(extra)).unwrap_err();
            assert!(e.downcast_ref::<Usage>().is_some(), "{extra:?}: {e}");
        }
    }
}

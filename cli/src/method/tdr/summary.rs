//! The summary `calib tdr` prints: the coast (or the driven run's passes), the motion fit, the
//! map and the drag (or the motor's orders).

use super::Args;
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::report::tdr::rpm;
use calib_core::tdr::TdrCalibration;
use std::fmt::Write;
use std::path::Path;

pub(super) fn render_summary(
    args: &Args,
    out: &Path,
    cal: &TdrCalibration,
    report: &Report,
) -> String {
    let mut o = String::new();
    let m = &cal.motion;
    // The coast on the log's clock, as report.json gives it.
    let coast = match &report.details {
        calib_core::report::Details::Tdr(d) => (d.motion.start_s, d.motion.end_s),
        _ => (m.t_start, m.t_end),
    };
    match &cal.driven {
        None => {
            let _ = writeln!(
                o,
                "Spin-down (TDR) self-calibration of `{}` — coast {:.3}–{:.3} s, {:.1} revolutions, {:.1} → {:.1} r/min",
                args.channel,
                coast.0,
                coast.1,
                cal.revolutions,
                rpm(cal.speed_start),
                rpm(cal.speed_end)
            );
        }
        Some(d) => {
            // The passes on the log's clock, as report.json gives them.
            let shift = coast.0 - m.t_start;
            let passes: Vec<String> = d
                .passes
                .iter()
                .map(|p| {
                    format!(
                        "{:.3}–{:.3} s at {:.1} r/min ({:.1} revolutions)",
                        p.t_start + shift,
                        p.t_end + shift,
                        rpm(p.speed()),
                        p.revolutions
                    )
                })
                .collect();
            let _ = writeln!(
                o,
                "Driven-run (TDR) self-calibration of `{}` — {} pass{}: {}; the map from pass {}",
                args.channel,
                d.passes.len(),
                if d.passes.len() == 1 { "" } else { "es" },
                passes.join(", "),
                d.main_pass + 1
            );
        }
    }
    let _ = writeln!(
        o,
        "motion: Chebyshev series of degree {} in time; residual rms {:.4}″ over {} samples (the readings' noise, \
         from their third differences: {:.4}″)",
        m.degree,
        cal.residual_rms * ARCSEC_PER_RAD,
        cal.samples_used,
        cal.noise_rms * ARCSEC_PER_RAD
    );
    let ch = &report.channels[&args.channel];
    let top: Vec<String> = ch
        .harmonics
        .iter()
        .take(4)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    // A map with no order above the noise lists none (its warning gives u).
    let top = if top.is_empty() {
        vec!["none above the noise".to_string()]
    } else {
        top
    };
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
    if let Some(d) = &cal.driven {
        o += &motor_orders(d);
    } else if sep.separated && !cal.drag.is_empty() {
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

/// The summary's paragraph on a driven run's motor orders.
fn motor_orders(d: &calib_core::tdr::DrivenRun) -> String {
    if d.motor_orders.is_empty() {
        return "\nmotor orders: none named (--pole-pairs or --cogging-orders); any cogging is in the map\n"
            .to_string();
    }
    let list: Vec<String> = d
        .motor_orders
        .iter()
        .map(|m| {
            let measured: Vec<String> = m
                .measured
                .iter()
                .map(|p| format!("{:.2}″", p.harmonic.amplitude * ARCSEC_PER_RAD))
                .collect();
            match &m.separated {
                Some(s) => format!(
                    "order {}: measured {} → encoder {:.3}″ ± {:.3}″ (in the map), cogging {:.4} rad/s²",
                    m.order,
                    measured.join(" / "),
                    s.encoder.amplitude * ARCSEC_PER_RAD,
                    s.u_encoder * ARCSEC_PER_RAD,
                    s.deceleration.amplitude
                ),
                None => format!(
                    "order {}: {} (left out of the map)",
                    m.order,
                    measured.join(" / ")
                ),
            }
        })
        .collect();
    format!(
        "\nmotor orders (cogging, torque ripple; each pass measures encoder error and shake together): {}\n",
        list.join("; ")
    )
}

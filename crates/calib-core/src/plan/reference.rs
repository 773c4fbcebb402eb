//! Planning a cross-calibration against a reference encoder (`calib reference`, ISO 230-2):
//! targets, passes, the approach after each reversal, the run that gives them, and the `u` the
//! method will give.
//!
//! # Targets (ISO 230-2's target positions)
//! The method evaluates ISO 230-2's figures at `k` targets `(j + ½)·360°/k` (its
//! [`Targets::Count`](crate::reference_cal::Targets)). An error of order `h` takes at them only
//! `k/gcd(h, k)` distinct phases: at a multiple of `k` one (the targets see a constant, and the
//! systematic deviation `E` and the mean deviation `M` miss the order altogether), at few phases
//! the targets may straddle its crests. The plan takes the smallest `k` from the method's 20
//! up whose targets see every expected order of the DUT (`orders`, e.g. its pole pairs and their
//! multiples) at [`MIN_PHASES`] phases or more, so that some target is within `π/8` of every
//! crest (`cos π/8 = 0.92` of the amplitude). The map itself holds every grid point: the targets
//! matter for the ISO figures only.
//!
//! # Passes and approach
//! ISO 230-2 asks for 5 passes in each direction. After each reversal the method drops the
//! crossings of the first `approach` of travel (default 1°), where backlash is taken up: a
//! coupling with lost motion `b` moves the DUT `b` before the reference follows (or the other
//! way), so the plan asks for [`APPROACH_PER_BACKLASH`]` · b` (margin for wind-up), at least the
//! method's 1°. The run: a sweep from `−approach` to `360° + approach` and back, once per pass,
//! so that every grid point is crossed `passes` times in each direction after the approach; the
//! passes alternate between the speed given and a third of it (both directions at each), so that
//! the method can tell a lag between the channels from backlash (at one speed per direction the
//! two read the same, and it warns).
//!
//! # The uncertainty (the method's own)
//! The method's `u_i = √(u_mean² + u_ref²)`, `u_mean² = (s↑²/n↑ + s↓²/n↓)/4`
//! ([`mean_variance`], [`point_uncertainty`]), with `s` the spread of a crossing's value: the
//! difference of the two readings (noise and resolution of both, `σ_d² = σ_dut² + σ_ref²`)
//! interpolated at the crossing by the method's cubic, whose weights' squares sum on average
//! over the crossing's place between samples to [`cubic_noise_factor`] (0.77).
//!
//! # What a plan cannot see
//! The reference's own error (the map is DUT − reference) and a lag between the channels
//! (`calib reference` estimates it from passes at several speeds; the planned run has one).

use crate::angle::ARCSEC_PER_RAD;
use crate::reference_cal::{ReferenceOptions, lagrange, mean_variance, point_uncertainty};
use crate::simulate::{Scenario, Sensor, Sweep};
use std::f64::consts::{PI, TAU};

/// Fewest distinct phases at which the targets must see each expected order.
pub const MIN_PHASES: usize = 8;

/// The approach after a reversal, in backlashes.
pub const APPROACH_PER_BACKLASH: f64 = 2.0;

/// The passes in each direction ISO 230-2 asks for.
pub const ISO_PASSES: u32 = 5;

/// Why a reference run cannot be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what} must be {expected}, not {value}")]
pub struct ReferencePlanError {
    /// The setting.
    pub what: &'static str,
    /// What was given.
    pub value: f64,
    /// What it must be.
    pub expected: &'static str,
}

/// The set-up.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceRig {
    /// The DUT's noise per sample, rad (noise and resolution combined).
    pub dut_sigma: f64,
    /// The reference's noise per sample, rad.
    pub reference_sigma: f64,
    /// The reference's stated standard uncertainty, rad.
    pub reference_u: f64,
    /// Sample rate, Hz.
    pub rate_hz: f64,
    /// Cruise speed of the faster passes, rad/s (the others at [`SLOW_FRACTION`] of it).
    pub speed: f64,
    /// Lost motion between the DUT and the reference, rad.
    pub backlash: f64,
    /// Passes in each direction.
    pub passes: u32,
}

/// A planned run.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferencePlan {
    /// The set-up.
    pub rig: ReferenceRig,
    /// Targets `k`.
    pub targets: usize,
    /// Whether `k` was chosen by the plan.
    pub proposed: bool,
    /// The target angles `(j + ½)·2π/k`, rad.
    pub target_angles: Vec<f64>,
    /// Each expected order and the distinct phases the targets see it at.
    pub phases: Vec<(usize, usize)>,
    /// Expected orders the targets see at one phase (E and M miss them).
    pub blind_orders: Vec<usize>,
    /// The approach after each reversal, rad.
    pub approach: f64,
    /// The sweep's ends, rad.
    pub sweep: (f64, f64),
    /// About how long the run takes, s.
    pub duration_s: f64,
    /// Angle between samples at the faster passes' speed, rad.
    pub sample_spacing: f64,
    /// Spread of one crossing's value, rad.
    pub crossing_sigma: f64,
    /// The `u` of every map point, rad.
    pub u: f64,
    /// What the user should know.
    pub warnings: Vec<String>,
}

/// The slower passes' speed, as a fraction of the speed given.
pub const SLOW_FRACTION: f64 = 1.0 / 3.0;

impl ReferencePlan {
    /// The strokes' speeds in turn (the simulator's sweep repeats the list): up and down at the
    /// speed given, then up and down at [`SLOW_FRACTION`] of it, rad/s.
    pub fn speeds(&self) -> [f64; 4] {
        let (fast, slow) = (self.rig.speed, SLOW_FRACTION * self.rig.speed);
        [fast, fast, slow, slow]
    }

    /// The planned run as a simulator scenario: the sweep from `−approach` to `360° + approach`
    /// and back once per pass at the planned speed and rate, a sensor `dut` and a sensor `ref`
    /// with the given `(noise, resolution)` (arcsec) and no error (add the errors you expect),
    /// the DUT behind the planned backlash.
    pub fn scenario(&self, dut: (f64, f64), reference: (f64, f64)) -> Scenario {
        let sensor = |name: &str, (noise, q): (f64, f64), backlash: f64| Sensor {
            name: name.into(),
            mount: None,
            harmonics: Vec::new(),
            scale: None,
            head_deg: None,
            head_error_arcsec: None,
            quantization_arcsec: q,
            noise_arcsec: noise,
            delay_s: 0.0,
            backlash_arcsec: backlash,
            commanded: false,
            ratio: 1.0,
        };
        Scenario {
            rate_hz: self.rig.rate_hz,
            wrap: true,
            sensors: vec![
                sensor("dut", dut, self.rig.backlash * ARCSEC_PER_RAD),
                sensor("ref", reference, 0.0),
            ],
            sweep: Some(Sweep {
                from_deg: self.sweep.0.to_degrees(),
                to_deg: self.sweep.1.to_degrees(),
                cycles: self.rig.passes,
                speeds_deg_s: self.speeds().iter().map(|v| v.to_degrees()).collect(),
                ramp_s: RAMP_S,
                pause_s: PAUSE_S,
                random: false,
            }),
            ..Scenario::default()
        }
    }
}

/// The sweep's ramps and pauses, s (the simulator's defaults).
const RAMP_S: f64 = 0.5;
const PAUSE_S: f64 = 1.0;

/// The mean over a crossing's place `p ∈ [0, 1)` between two samples of the squared weights
/// of the method's centred cubic through the samples at `−1, 0, 1, 2`: the factor by which the
/// interpolation scales the variance of independent sample noise.
pub fn cubic_noise_factor() -> f64 {
    const K: usize = 1000;
    let nodes = |i: usize| -> [(f64, f64); 4] {
        std::array::from_fn(|j| (j as f64 - 1.0, if j == i { 1.0 } else { 0.0 }))
    };
    (0..K)
        .map(|s| {
            let p = (s as f64 + 0.5) / K as f64;
            (0..4).map(|i| lagrange(&nodes(i), p).powi(2)).sum::<f64>()
        })
        .sum::<f64>()
        / K as f64
}

/// Distinct phases of order `h` at `k` equally spaced targets.
fn distinct_phases(h: usize, k: usize) -> usize {
    fn gcd(a: usize, b: usize) -> usize {
        if b == 0 { a } else { gcd(b, a % b) }
    }
    k / gcd(h, k)
}

/// The run for the DUT's expected `orders` on `rig`; `targets` given, or proposed when `None`.
pub fn plan(
    rig: ReferenceRig,
    orders: &[usize],
    targets: Option<usize>,
) -> Result<ReferencePlan, ReferencePlanError> {
    let invalid = |what, value: f64, expected| ReferencePlanError {
        what,
        value,
        expected,
    };
    let method = ReferenceOptions::default();
    for (what, v) in [
        ("the DUT's noise", rig.dut_sigma),
        ("the reference's noise", rig.reference_sigma),
        ("the reference's u", rig.reference_u),
        ("the backlash", rig.backlash),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(invalid(what, v, "finite and ≥ 0"));
        }
    }
    if !(rig.rate_hz.is_finite() && rig.rate_hz > 0.0) {
        return Err(invalid("the sample rate", rig.rate_hz, "positive"));
    }
    if !(rig.speed.is_finite() && SLOW_FRACTION * rig.speed > method.min_speed) {
        return Err(invalid(
            "the speed (°/s)",
            rig.speed.to_degrees(),
            "above 3°/s (the slower passes go at a third of it, and calib reference takes the \
             shaft as stopped below 1°/s)",
        ));
    }
    if rig.passes < 2 {
        return Err(invalid(
            "the passes",
            f64::from(rig.passes),
            "at least 2 (ISO 230-2 asks for 5)",
        ));
    }
    if let Some(&h) = orders.iter().find(|&&h| h == 0) {
        return Err(invalid("every expected order", h as f64, "≥ 1"));
    }
    let default_targets = match method.targets {
        crate::reference_cal::Targets::Count(k) => k,
        crate::reference_cal::Targets::Angles(_) => 20,
    };
    let (k, proposed) = match targets {
        Some(0) => return Err(invalid("the targets", 0.0, "at least 1")),
        Some(k) => (k, false),
        None => (
            (default_targets..)
                .find(|&k| orders.iter().all(|&h| distinct_phases(h, k) >= MIN_PHASES))
                .unwrap_or(default_targets),
            true,
        ),
    };
    let phases: Vec<(usize, usize)> = orders.iter().map(|&h| (h, distinct_phases(h, k))).collect();
    let blind_orders = phases
        .iter()
        .filter(|p| p.1 == 1)
        .map(|p| p.0)
        .collect::<Vec<_>>();
    let mut warnings = Vec::new();
    let few: Vec<String> = phases
        .iter()
        .filter(|p| (2..MIN_PHASES).contains(&p.1))
        .map(|p| format!("order {} at {}", p.0, p.1))
        .collect();
    if !few.is_empty() {
        warnings.push(format!(
            "{k} targets see some expected orders at few phases ({}): the ISO figures may miss \
             up to {:.0} % of their peak-to-peak",
            few.join(", "),
            100.0
                * (1.0
                    - (PI
                        / phases
                            .iter()
                            .map(|p| p.1)
                            .filter(|&m| m >= 2)
                            .min()
                            .unwrap_or(2) as f64)
                        .cos())
        ));
    }
    let approach = (APPROACH_PER_BACKLASH * rig.backlash).max(method.approach);
    let sweep = (-approach, TAU + approach);
    // A stroke: the travel at its cruise speed plus its ramps, then a pause; the passes
    // alternate fast and slow, the fast ones first.
    let stroke_s = |v: f64| (sweep.1 - sweep.0) / v + RAMP_S + PAUSE_S;
    let fast = f64::from(rig.passes.div_ceil(2));
    let slow = f64::from(rig.passes / 2);
    let duration_s =
        PAUSE_S + 2.0 * (fast * stroke_s(rig.speed) + slow * stroke_s(SLOW_FRACTION * rig.speed));
    let sample_spacing = rig.speed / rig.rate_hz;
    let sd2 = rig.dut_sigma.powi(2) + rig.reference_sigma.powi(2);
    let crossing_sigma = (sd2 * cubic_noise_factor()).sqrt();
    let sem2 = crossing_sigma.powi(2) / f64::from(rig.passes);
    let u = point_uncertainty(mean_variance(Some(sem2), Some(sem2)), 0.0, rig.reference_u);
    if let Some(&top) = orders.iter().max() {
        let loss = 9.0 / 384.0 * (top as f64 * sample_spacing).powi(4);
        if loss > 1e-3 {
            warnings.push(format!(
                "at {:.4}° between samples the interpolation attenuates order {top} by {:.2} % \
                 ((9/384)·(hΔθ)⁴): sample faster or sweep slower",
                sample_spacing.to_degrees(),
                100.0 * loss
            ));
        }
    }
    Ok(ReferencePlan {
        targets: k,
        proposed,
        target_angles: (0..k).map(|j| (j as f64 + 0.5) * TAU / k as f64).collect(),
        phases,
        blind_orders,
        approach,
        sweep,
        duration_s,
        sample_spacing,
        crossing_sigma,
        u,
        warnings,
        rig,
    })
}

#[cfg(test)]
// The tests print the figures docs/plan.md quotes (run with --nocapture).
#[allow(clippy::print_stderr)]
mod tests {
    use super::*;
    use crate::reference_cal::{ReferenceCal, Targets};
    use crate::simulate::HarmonicSpec;

    fn rig(passes: u32, backlash_arcsec: f64) -> ReferenceRig {
        let s = |noise: f64, q: f64| (noise * noise + q * q / 12.0).sqrt() / ARCSEC_PER_RAD;
        ReferenceRig {
            dut_sigma: s(0.2, 0.5),
            reference_sigma: s(0.01, 0.001),
            reference_u: 0.0,
            rate_hz: 500.0,
            speed: 30f64.to_radians(),
            backlash: backlash_arcsec / ARCSEC_PER_RAD,
            passes,
        }
    }

    #[test]
    fn the_cubics_noise_factor() {
        // Σw² is 1 at a sample and 0.64 half-way ((1 + 81 + 81 + 1)/256).
        let f = cubic_noise_factor();
        assert!((0.64..1.0).contains(&f), "{f}");
        eprintln!("cubic noise factor {f:.4}");
    }

    /// The targets for a 72-pole-pair DUT (orders 72, 144, 216): 20 sees order 72 at 5
    /// phases, the plan takes the first count with ≥ 8 for all; 24 targets are blind to all
    /// three (every one a multiple of 24).
    #[test]
    fn targets_avoid_the_duts_orders() {
        let p = plan(rig(5, 0.0), &[72, 144, 216], None).unwrap();
        assert!(p.targets >= 20);
        assert!(
            p.phases.iter().all(|&(_, m)| m >= MIN_PHASES),
            "{:?}",
            p.phases
        );
        assert!(p.blind_orders.is_empty());
        eprintln!(
            "72-pole-pair DUT: {} targets, phases {:?}",
            p.targets, p.phases
        );
        let blind = plan(rig(5, 0.0), &[72, 144, 216], Some(24)).unwrap();
        assert_eq!(blind.blind_orders, vec![72, 144, 216]);
        let twenty = plan(rig(5, 0.0), &[72], Some(20)).unwrap();
        assert_eq!(twenty.phases, vec![(72, 5)]);
        assert_eq!(twenty.warnings.len(), 1, "{:?}", twenty.warnings);
    }

    /// The approach: twice the backlash, at least the method's 1°.
    #[test]
    fn the_approach_follows_the_backlash() {
        assert!(
            (plan(rig(5, 30.0), &[], None).unwrap().approach - 1f64.to_radians()).abs() < 1e-15
        );
        let big = plan(rig(5, 3600.0), &[], None).unwrap();
        assert!((big.approach - 2f64.to_radians()).abs() < 1e-12);
    }

    /// Simulates the planned sweep (the core's simulator) with a DUT of `errors` and a
    /// near-perfect reference, and runs the method with `targets`.
    fn simulate(
        p: &ReferencePlan,
        errors: &[(u32, f64)],
        targets: usize,
    ) -> crate::reference_cal::ReferenceCalibration {
        let mut scenario = p.scenario((0.2, 0.5), (0.01, 0.001));
        scenario.seed = 21;
        scenario.sensors[0].harmonics = errors
            .iter()
            .map(|&(order, a)| HarmonicSpec {
                order,
                amplitude_arcsec: a,
                phase_deg: 10.0 * order as f64,
            })
            .collect();
        let mut cal = ReferenceCal::new(ReferenceOptions {
            approach: p.approach,
            targets: Targets::Count(targets),
            ..ReferenceOptions::default()
        });
        for s in scenario.samples().unwrap() {
            cal.push(s.t, s.values[0], s.values[1]);
        }
        cal.finish().unwrap()
    }

    /// The planned `u` against the `u` the method reports on the simulated planned run (its
    /// median over the map; 5 passes give `s` to ±30 %, within the 1.5); every point
    /// crossed the planned passes in each direction; with 30″ of backlash the approach keeps
    /// the lost motion out (the reversal B is the backlash, the map the DUT's error).
    #[test]
    fn planned_u_matches_the_u_of_the_simulated_run() {
        for (passes, backlash) in [(5, 0.0), (3, 30.0)] {
            let p = plan(rig(passes, backlash), &[1, 4], None).unwrap();
            let cal = simulate(&p, &[(1, 60.0), (4, 20.0)], p.targets);
            assert_eq!(cal.min_passes, (passes, passes));
            let mut u = cal.u.clone();
            u.sort_by(f64::total_cmp);
            let median = u[u.len() / 2];
            let ratio = p.u / median;
            eprintln!(
                "{passes} passes, {backlash}″ backlash: planned u {:.4}″, method median {:.4}″, B {:.1}″",
                p.u * ARCSEC_PER_RAD,
                median * ARCSEC_PER_RAD,
                cal.iso.reversal.unwrap_or(0.0) * ARCSEC_PER_RAD
            );
            assert!((1.0 / 1.5..1.5).contains(&ratio), "ratio {ratio}");
        }
    }

    /// The blind set: a DUT erring only at order 72 (10″), 24 targets (a divisor of 72) see
    /// the same value at every target, so ISO 230-2's M is noise (< 1″) while the map spans 20″;
    /// the planned count sees at least cos(π/8) of it.
    #[test]
    fn targets_at_a_divisor_of_the_order_miss_it_in_the_method_too() {
        let r = ReferenceRig {
            rate_hz: 2000.0,
            speed: 10f64.to_radians(),
            ..rig(2, 0.0)
        };
        let planned = plan(r.clone(), &[72], None).unwrap();
        let m = |targets| {
            simulate(&planned, &[(72, 10.0)], targets)
                .iso
                .mean_bidirectional
                .unwrap()
                * ARCSEC_PER_RAD
        };
        let (blind, seen) = (m(24), m(planned.targets));
        eprintln!(
            "order 72, 10″: M {blind:.2}″ at 24 targets, {seen:.2}″ at {}",
            planned.targets
        );
        assert!(blind < 1.0, "{blind}");
        assert!(seen > 20.0 * (PI / 8.0).cos() - 1.0, "{seen}");
    }
}

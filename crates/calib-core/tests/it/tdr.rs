//! Spin-down (TDR) self-calibration against known truths: the simulator's air-bearing and
//! rolling-bearing coasts (`testdata/scenarios/spindown*.toml`), synthetic coasts with a driven
//! plateau and a stop, and logs with no spin-down.

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::simulate::Scenario;
use calib_core::tdr::{MotorOrders, RunKind, Tdr, TdrCalibration, TdrError, TdrOptions};
use calib_core::{ErrorMap, Harmonic};
use std::f64::consts::TAU;

fn scenario(file: &str) -> Scenario {
    let path = format!(
        "{}/../../testdata/scenarios/{file}",
        env!("CARGO_MANIFEST_DIR")
    );
    toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// Runs TDR on channel `enc` with `ref` as reference; also returns the true speed at each
/// sample time from the simulator's true angles (forward differences: the drag's speed ripple,
/// ≤ 0.1 %, averages out), the independent input of the predictions below.
fn run(s: &Scenario) -> (TdrCalibration, Vec<(f64, f64)>) {
    let mut tdr = Tdr::new(TdrOptions::default());
    let mut prev: Option<(f64, f64)> = None;
    let mut speeds = Vec::new();
    for st in s.samples().unwrap().with_truth() {
        let v = &st.sample.values;
        tdr.push_with_reference(st.sample.t, v[0], v[1]);
        let th = st.true_angles[0];
        if let Some((t0, th0)) = prev {
            speeds.push((t0, (th - th0) / (st.sample.t - t0)));
        }
        prev = Some((st.sample.t, th));
    }
    (tdr.finish().unwrap(), speeds)
}

/// The true speed near `t`, and `⟨ω⁻²⟩` over the samples the calibration used.
fn true_speed(speeds: &[(f64, f64)], t: f64) -> f64 {
    speeds
        .iter()
        .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
        .unwrap()
        .1
}

fn mean_inverse_square_speed(speeds: &[(f64, f64)], cal: &TdrCalibration) -> f64 {
    let used: Vec<f64> = speeds
        .iter()
        .filter(|(t, _)| (cal.motion.t_start..cal.motion.t_end).contains(t))
        .map(|(_, w)| w.powi(-2))
        .collect();
    used.iter().sum::<f64>() / used.len() as f64
}

fn arcsec(rad: f64) -> f64 {
    rad * ARCSEC_PER_RAD
}

#[test]
fn air_bearing_coast_recovers_the_encoder_map() {
    let s = scenario("spindown.toml");
    let (cal, speeds) = run(&s);
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let diff = arcsec(cal.map.minus(truth).max_abs_arcsec() / ARCSEC_PER_RAD);
    // Noise 0.05″ and the 0.09″ resolution (0.026″ rms) make σ ≈ 0.057″ per sample; 60 000
    // samples and 64 Fourier unknowns give a map rms of σ·√(64/N) ≈ 0.002″, its maximum over
    // 3600 points about 4× that. The motion's Chebyshev series (degree by BIC) leaves far less.
    // Measured: 0.0044″.
    assert!(diff < 0.02, "max |map − truth| = {diff}″");
    assert!(
        (arcsec(cal.residual_rms) - 0.057).abs() < 0.005,
        "{}",
        arcsec(cal.residual_rms)
    );
    // The whole coast but its first window (0.12 s) is used: 600 → ~322 r/min. The fitted
    // speeds match the truth to its 2-sample differences' error (ω̇·Δt/2 ≈ 4e-4 rad/s).
    assert!((cal.speed_start - true_speed(&speeds, cal.motion.t_start)).abs() < 1e-3);
    assert!((cal.speed_end - true_speed(&speeds, cal.motion.t_end)).abs() < 1e-3);
    assert!(cal.motion.t_start < 0.15 && cal.motion.t_end > 29.99);
    assert!(
        (200.0..240.0).contains(&cal.revolutions),
        "{}",
        cal.revolutions
    );
    assert!(
        cal.speed_dependence.is_empty(),
        "{:?}",
        cal.speed_dependence
    );
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
    let (covered, median_u) = coverage(&s, &cal);
    println!(
        "air bearing: max |map − truth| {diff:.4}″; ≤ 2u at {:.1} %, median u {median_u:.4}″",
        100.0 * covered
    );
    // The budget is honest: |map − truth| ≤ 2u at 90–99.9 % of the points (measured 96–99 %).
    assert!((0.90..=0.999).contains(&covered), "{covered}");
    assert!(median_u < 0.01, "{median_u}″");
    // The reference's own error is 0.05″ at order 3, so the check sees ≈ 0.05″.
    let check = cal.reference.as_ref().unwrap();
    assert!(check.max_abs_diff_arcsec < 0.07, "{check:?}");
}

/// Runs TDR with `opts` on channel `enc` (and `ref` as reference).
fn run_with(s: &Scenario, opts: TdrOptions) -> TdrCalibration {
    let mut tdr = Tdr::new(opts);
    for st in s.samples().unwrap() {
        tdr.push_with_reference(st.t, st.values[0], st.values[1]);
    }
    tdr.finish().unwrap()
}

/// Max |map − truth| in arcseconds.
fn max_error(s: &Scenario, cal: &TdrCalibration) -> f64 {
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    cal.map.minus(truth).max_abs_arcsec()
}

/// The fraction of table points with |map − truth| ≤ 2u, and the median u (arcsec).
fn coverage(s: &Scenario, cal: &TdrCalibration) -> (f64, f64) {
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let diff = cal.map.minus(truth);
    let u = &cal.uncertainty;
    let inside = diff
        .values()
        .iter()
        .zip(&u.u)
        .filter(|(d, u)| d.abs() <= 2.0 * **u)
        .count();
    (
        inside as f64 / diff.len() as f64,
        u.median() * ARCSEC_PER_RAD,
    )
}

#[test]
fn orders_come_from_the_data_and_order_128_is_kept() {
    // 600 → 120 r/min at 2 kHz: 200 samples per revolution at the start, 1000 at the end, so
    // the default tests orders to 0.4·1000 ≈ 400 and keeps those that stand above the noise.
    let s = scenario("spindown-wide.toml");
    let cal = run_with(&s, TdrOptions::default());
    let diff = max_error(&s, &cal);
    // σ ≈ 0.057″ per sample over 89 000 samples: each kept order's amplitude is uncertain by
    // σ·√(2/N) ≈ 3e-4″; ~15 orders kept give a map rms ≈ 1.5e-3″, its maximum a few times that.
    // Dropped orders are below the significance threshold (≈ 5σ per coefficient, 1.6e-3″).
    // Measured: 0.0085″. Bar of the issue: 0.05″.
    let (covered, median_u) = coverage(&s, &cal);
    println!(
        "wide coast, defaults: max |map − truth| {diff:.4}″, orders {:?} of {}; ≤ 2u at {:.1} %, median u {median_u:.4}″",
        cal.orders,
        cal.max_order,
        100.0 * covered
    );
    // The budget is honest: |map − truth| ≤ 2u at 90–99.9 % of the points (measured 96–99 %).
    assert!((0.90..=0.999).contains(&covered), "{covered}");
    assert!(median_u < 0.01, "{median_u}″");
    assert!(diff < 0.03, "max |map − truth| = {diff}″");
    assert!((350..=420).contains(&cal.max_order), "{}", cal.max_order);
    for k in [1, 2, 3, 16, 32, 128] {
        assert!(
            cal.orders.contains(&k),
            "order {k} missing: {:?}",
            cal.orders
        );
    }
    // The map as a function of the reading also holds the small intermodulation terms of e(θ)
    // (sidebands such as 128 ± 2 of ½·128·0.2″·25″/206265″ ≈ 1.5e-3″), not noise: far fewer
    // orders than tested are kept.
    assert!(cal.orders.len() < 30, "{:?}", cal.orders);
    assert!(
        cal.unresolved
            .iter()
            .all(|u| u.amplitude * ARCSEC_PER_RAD < 0.01),
        "{:?}",
        cal.unresolved
    );
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
    assert!(cal.drag.is_empty(), "{:?}", cal.drag);
    assert!(cal.drag_separation.separated);
    let check = cal.reference.as_ref().unwrap();
    assert!(check.max_abs_diff_arcsec < 0.08, "{check:?}");
}

#[test]
fn a_low_max_order_leaves_order_128_in_the_residual_and_says_so() {
    let s = scenario("spindown-wide.toml");
    let cal = run_with(
        &s,
        TdrOptions {
            max_order: Some(32),
            ..TdrOptions::default()
        },
    );
    // The 0.2″ of order 128 is not in the map…
    let diff = max_error(&s, &cal);
    assert!(diff > 0.15, "{diff}″");
    // …but the residual's projection on order 128 finds it: amplitude within its noise
    // (σ·√(2/N) ≈ 3e-4″) plus the leak of the non-uniform sampling into the projection (≈ 1 %).
    let top = cal.unresolved.first().expect("structure found");
    assert_eq!(top.order, 128, "{:?}", cal.unresolved);
    assert!(
        (top.amplitude * ARCSEC_PER_RAD - 0.2).abs() < 0.01,
        "{top:?}"
    );
    let w = cal
        .warnings
        .iter()
        .find(|w| w.contains("periodic structure"))
        .expect("warned");
    assert!(
        w.contains("order 128 0.2") && w.contains("the `max_order` option to at least 1"),
        "{w}"
    );
}

#[test]
fn drag_is_separated_from_the_encoder_error_over_a_wide_coast() {
    // The same coast with drag at orders 1 and 2 (6.5″ each at the slow end): fitted jointly as
    // an imprint ∝ 1/ω² (module docs, eq. 3).
    let s = scenario("spindown-drag.toml");
    let cal = run_with(&s, TdrOptions::default());
    let diff = max_error(&s, &cal);
    // What eq. (3) leaves out: the friction's slope, F′/(hω) ≤ 0.025/12.6 = 0.2 % of the 6.5″
    // imprint at the slow end (0.013″), and the noise of orders 1 and 2 amplified by the
    // separation (×1.5). Measured: 0.0075″. Bar of the issue: 0.3″ (aim 0.15″).
    let (covered, median_u) = coverage(&s, &cal);
    println!(
        "drag coast, defaults: max |map − truth| {diff:.4}″, drag {:?}; ≤ 2u at {:.1} %, median u {median_u:.4}″",
        cal.drag,
        100.0 * covered
    );
    // The budget is honest: |map − truth| ≤ 2u at 90–99.9 % of the points (measured 96–99 %).
    assert!((0.90..=0.999).contains(&covered), "{covered}");
    assert!(median_u < 0.01, "{median_u}″");
    assert!(diff < 0.06, "max |map − truth| = {diff}″");
    let sd = s.spin_down.as_ref().unwrap();
    let found: Vec<usize> = cal.drag.iter().map(|d| d.deceleration.order).collect();
    assert_eq!(found, [1, 2]);
    for (d, truth) in cal.drag.iter().zip(&sd.drag_harmonics) {
        // The deceleration amplitude and phase within 0.5 % and 0.01 rad: its imprint is
        // thousands of times its noise; the same 0.2 % model error as above remains.
        assert!(
            (d.deceleration.amplitude / truth.amplitude - 1.0).abs() < 0.005,
            "{d:?}"
        );
        assert!(
            (d.deceleration.phase - truth.phase_deg.to_radians()).abs() < 0.01,
            "{d:?}"
        );
        let h2 = (d.deceleration.order * d.deceleration.order) as f64;
        assert!((d.imprint - d.deceleration.amplitude / h2 * cal.drag_gain).abs() < 1e-12);
    }
    assert!(cal.speed_dependence.is_empty());
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
}

#[test]
fn rolling_bearing_drag_is_separated_over_a_coast_that_slows_by_half() {
    // 600 → 322 r/min: 1/ω² varies by 35 % RMS, the separation costs ×3 noise at the drag orders.
    let s = scenario("spindown-bearing.toml");
    let cal = run_with(&s, TdrOptions::default());
    let diff = max_error(&s, &cal);
    // Noise 3e-4″ per order ×3 at orders 2 and 4; the model error of eq. (3), F′/(hω) ≈ 0.03 %
    // of 3.9″. Measured: 0.0083″ (the unseparated fit was off by 5.3″).
    assert!(diff < 0.05, "max |map − truth| = {diff}″");
    let (covered, median_u) = coverage(&s, &cal);
    println!(
        "bearing coast: max |map − truth| {diff:.4}″; ≤ 2u at {:.1} %, median u {median_u:.4}″",
        100.0 * covered
    );
    // The budget is honest: |map − truth| ≤ 2u at 90–99.9 % of the points (measured 96–99 %).
    assert!((0.90..=0.999).contains(&covered), "{covered}");
    assert!(median_u < 0.01, "{median_u}″");
    let found: Vec<usize> = cal.drag.iter().map(|d| d.deceleration.order).collect();
    assert_eq!(found, [2, 4]);
    let sd = s.spin_down.as_ref().unwrap();
    for (d, truth) in cal.drag.iter().zip(&sd.drag_harmonics) {
        assert!(
            (d.deceleration.amplitude / truth.amplitude - 1.0).abs() < 0.005,
            "{d:?}"
        );
    }
    assert!((cal.drag_separation.noise_gain - 3.0).abs() < 0.3);
}

#[test]
fn a_narrow_coast_cannot_separate_drag_and_says_what_is_missing() {
    // Only the first 3 s of the rolling-bearing coast: 600 → 560 r/min, 1/ω² varies by ≈ 4 %.
    let mut s = scenario("spindown-bearing.toml");
    s.spin_down.as_mut().unwrap().duration_s = 3.0;
    let mut tdr = Tdr::new(TdrOptions::default());
    let mut prev: Option<(f64, f64)> = None;
    let mut speeds = Vec::new();
    for st in s.samples().unwrap().with_truth() {
        tdr.push(st.sample.t, st.sample.values[0]);
        let th = st.true_angles[0];
        if let Some((t0, th0)) = prev {
            speeds.push((t0, (th - th0) / (st.sample.t - t0)));
        }
        prev = Some((st.sample.t, th));
    }
    let cal = tdr.finish().unwrap();
    assert!(!cal.drag_separation.separated);
    assert!(cal.drag.is_empty());
    let w = cal
        .warnings
        .iter()
        .find(|w| w.contains("too narrow"))
        .expect("warned");
    assert!(w.contains("at least 10 %") && w.contains("r/min"), "{w}");
    // The drag stays in the map by what eq. (2) predicts, (a_h/h²)·⟨ω⁻²⟩ at phase φ_h:
    // corrections to (2) are O(ω̇/(hω²)) ≈ 2e-4 and O(F′(ω)/(hω)) ≈ 1e-4. Hence 2 %.
    let inv_omega2 = mean_inverse_square_speed(&speeds, &cal);
    assert!((cal.drag_gain / inv_omega2 - 1.0).abs() < 1e-3);
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let got = cal.map.minus(truth).series();
    for d in &s.spin_down.as_ref().unwrap().drag_harmonics {
        let h = f64::from(d.order);
        let p = Harmonic {
            order: d.order as usize,
            amplitude: d.amplitude / (h * h) * inv_omega2,
            phase: d.phase_deg.to_radians(),
        };
        let (a, b) = p.coefficients();
        let off = arcsec((got.cos[p.order - 1] - a).hypot(got.sin[p.order - 1] - b));
        assert!(
            off < 0.02 * arcsec(p.amplitude),
            "order {}: off {off}″",
            p.order
        );
    }
    // And the diagnostic still names the speed-dependent orders.
    let orders: Vec<usize> = cal
        .speed_dependence
        .iter()
        .map(|s| s.harmonic.order)
        .collect();
    assert_eq!(orders, [2, 4]);
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("angle-dependent drag would"))
    );
}

/// `e(θ)` of the synthetic tests: 5″ at order 3 and 2″ at order 7.
fn synthetic_error(theta: f64) -> f64 {
    (5.0 * (3.0 * theta + 0.4).cos() + 2.0 * (7.0 * theta - 1.0).cos()) / ARCSEC_PER_RAD
}

#[test]
fn driven_plateau_and_stop_are_left_out() {
    // 2 s driven at 20 rad/s, then a Coulomb coast (1 rad/s²) to rest at t = 22 s, 3 s at rest;
    // 500 Hz, no noise. Readings r = θ + e(θ) with e a function of the true angle: as a function
    // of the reading the error differs by e·e′ ≤ 7·(7″)²/206265″ = 2e-3″.
    let (w0, c0, rate) = (20.0, 1.0, 500.0);
    let theta = |t: f64| {
        if t < 2.0 {
            w0 * t
        } else {
            let tau = (t - 2.0).min(w0 / c0);
            w0 * 2.0 + w0 * tau - 0.5 * c0 * tau * tau
        }
    };
    let mut tdr = Tdr::new(TdrOptions::default());
    // The same shaft turning the other way (θ → −θ): the map, a function of the reading, is the
    // same.
    let mut backwards = Tdr::new(TdrOptions::default());
    for n in 0..(25.0 * rate) as usize {
        let t = n as f64 / rate;
        let th = theta(t);
        tdr.push(t, (th + synthetic_error(th)).rem_euclid(TAU));
        backwards.push(t, (-th + synthetic_error(-th)).rem_euclid(TAU));
    }
    let cal = tdr.finish().unwrap();
    let back = backwards.finish().unwrap();
    assert_eq!((cal.direction, back.direction), (1.0, -1.0));
    let twin = back.map.minus(&cal.map).max_abs_arcsec();
    assert!(twin < 0.005, "{twin}″");
    // The plateau ends within a window (25 s / 256) of 2 s; the coast is cut where the speed
    // falls below 10 % of the peak (t ≈ 20 s), before the stop.
    assert!(
        (cal.motion.t_start - 2.0).abs() < 0.1,
        "{}",
        cal.motion.t_start
    );
    assert!(
        (19.5..20.2).contains(&cal.motion.t_end),
        "{}",
        cal.motion.t_end
    );
    assert!(cal.warnings.iter().any(|w| w.contains("plateau")));
    // No drag here, though 1/ω² grows 100-fold over the coast: no false alarm.
    assert!(
        cal.speed_dependence.is_empty(),
        "{:?}",
        cal.speed_dependence
    );
    let truth = ErrorMap::new(
        (0..cal.map.len())
            .map(|i| synthetic_error(TAU * i as f64 / cal.map.len() as f64))
            .collect(),
    );
    let diff = cal.map.minus(&truth).max_abs_arcsec();
    // Noise-free, and a quadratic motion is exactly in the model: only the 2e-3″ above remains.
    assert!(diff < 0.005, "{diff}″");
    // The fitted motion is the coast: ω̇ = −1 rad/s².
    let (_, w, a) = cal.motion.eval(10.0);
    assert!((w - 12.0).abs() < 1e-6 && (a + 1.0).abs() < 1e-6, "{w} {a}");
}

fn finish(samples: impl Iterator<Item = (f64, f64)>) -> TdrError {
    let mut tdr = Tdr::new(TdrOptions::default());
    for (t, r) in samples {
        tdr.push(t, r);
    }
    tdr.finish().unwrap_err()
}

#[test]
fn logs_without_a_spin_down_are_refused_with_what_to_record() {
    let at = |n: usize| n as f64 / 100.0;
    let e = finish((0..50).map(|n| (at(n), 0.1)));
    assert!(matches!(e, TdrError::TooFewSamples { count: 50 }), "{e}");
    let e = finish((0..5000).map(|n| (at(n), 1.0 + 1e-6 * (n % 3) as f64)));
    assert!(matches!(e, TdrError::Stationary { .. }), "{e}");
    assert!(e.to_string().contains("stands still"));
    // Driven at constant speed: 2 rev/s for 50 s. A coast is refused; a driven run is what it
    // is (with the synthetic error: the map is that error).
    let driven = (0..5000).map(|n| {
        let th = 2.0 * TAU * at(n);
        (at(n), (th + synthetic_error(th)).rem_euclid(TAU))
    });
    let mut coast_only = Tdr::new(TdrOptions {
        run: RunKind::Coast,
        ..TdrOptions::default()
    });
    let mut auto = Tdr::new(TdrOptions::default());
    for (t, r) in driven {
        coast_only.push(t, r);
        auto.push(t, r);
    }
    let e = coast_only.finish().unwrap_err();
    assert!(matches!(e, TdrError::NotFalling { .. }), "{e}");
    assert!(e.to_string().contains("release the drive"), "{e}");
    let cal = auto.finish().unwrap();
    assert_eq!(cal.driven.as_ref().map(|d| d.passes.len()), Some(1));
    let truth = ErrorMap::new(
        (0..cal.map.len())
            .map(|i| synthetic_error(TAU * i as f64 / cal.map.len() as f64))
            .collect(),
    );
    // Noise-free, the motion a straight line: what remains is e·e′ ≤ 2e-3″ (as above).
    let diff = cal.map.minus(&truth).max_abs_arcsec();
    assert!(diff < 0.005, "{diff}″");
    // A driven run of too few revolutions: 2 rev/s for 4 s.
    let e = finish((0..400).map(|n| (at(n), (2.0 * TAU * at(n)).rem_euclid(TAU))));
    assert!(matches!(e, TdrError::NoSteadyRun { .. }), "{e}");
    // A coast of 5 revolutions: 4 rad/s falling at 0.1 rad/s² for 10 s (35 rad).
    let e = finish((0..1000).map(|n| {
        let t = at(n);
        (t, 4.0 * t - 0.05 * t * t)
    }));
    assert!(
        matches!(e, TdrError::TooFewRevolutions { needed: 10.0, .. }),
        "{e}"
    );
}

#[test]
fn mixing_samples_with_and_without_reference_skips_the_check_without_panicking() {
    // 30 rad/s slowing at 1 rad/s² for 10 s at 200 Hz: 250 rad, 40 revolutions.
    let mut tdr = Tdr::new(TdrOptions::default());
    for n in 0..2000 {
        let t = n as f64 / 200.0;
        let th = 30.0 * t - 0.5 * t * t;
        let r = (th + synthetic_error(th)).rem_euclid(TAU);
        if n < 1000 {
            tdr.push_with_reference(t, r, th.rem_euclid(TAU));
        } else {
            tdr.push(t, r);
        }
    }
    let cal = tdr.finish().unwrap();
    assert!(cal.reference.is_none());
    assert!(!cal.warnings.iter().any(|w| w.contains("motion degree")));
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("reference check is skipped"))
    );
}

#[test]
fn a_motion_degree_that_can_follow_the_error_is_warned_about() {
    // 40 revolutions as above; degree 25 > 40/2.
    let mut tdr = Tdr::new(TdrOptions {
        motion_degree: Some(25),
        ..TdrOptions::default()
    });
    for n in 0..2000 {
        let t = n as f64 / 200.0;
        let th = 30.0 * t - 0.5 * t * t;
        tdr.push(t, (th + synthetic_error(th)).rem_euclid(TAU));
    }
    let cal = tdr.finish().unwrap();
    assert_eq!(cal.motion.degree, 25);
    assert!(
        cal.warnings.iter().any(|w| w.contains("motion degree 25")),
        "{:?}",
        cal.warnings
    );
}

/// The fit's passes run on two threads (a block of rows made while the one before is summed)
/// but take every sum in the order of the samples: one thread and two give the same bits. The
/// rolling-bearing coast has drag separated, so the drag's columns and the second screening are
/// covered too.
#[test]
fn one_thread_and_two_give_the_same_bits() {
    let s = scenario("spindown-drag.toml");
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| run_with(&s, TdrOptions::default()))
    };
    let (one, two) = (on(1), on(2));
    assert!(
        !two.drag.is_empty(),
        "no drag separated: {:?}",
        two.warnings
    );
    // Debug prints every f64 with the digits that round-trip it: equal text, equal bits.
    assert_eq!(format!("{one:?}"), format!("{two:?}"));
}

/// The table's points come from the map, as csrr's and multihead's do (issue 31: one default
/// for the methods that fit harmonics): 3600 where linear interpolation between them errs by
/// at most 0.01″ (the bundled coast: at most 0.002″ at 0.1° steps), more where the map is
/// curved enough to ask for them — 300″ at order 40 errs by up to
/// 300″·(40·2π/3600)²/8 = 0.18″ on 0.1° steps.
#[test]
fn the_default_table_points_hold_linear_interpolation_to_a_hundredth_of_an_arcsecond() {
    let bound = |cal: &TdrCalibration| {
        let step = TAU / cal.map.len() as f64;
        let curvature: f64 = cal
            .series
            .harmonics()
            .iter()
            .map(|h| h.amplitude * (h.order as f64 * step).powi(2) / 8.0)
            .sum();
        arcsec(curvature)
    };
    let (plain, _) = run(&scenario("spindown.toml"));
    assert_eq!(plain.map.len(), 3600);
    assert!(bound(&plain) <= 0.01, "{}", bound(&plain));

    let text = std::fs::read_to_string(format!(
        "{}/../../testdata/scenarios/spindown.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
    .replace(
        "{ order = 16, amplitude_arcsec = 3.0, phase_deg = 75.0 },",
        "{ order = 16, amplitude_arcsec = 3.0, phase_deg = 75.0 },\n  \
         { order = 40, amplitude_arcsec = 300.0, phase_deg = 20.0 },",
    );
    let curved: Scenario = toml::from_str(&text).unwrap();
    let (cal, _) = run(&curved);
    assert!(cal.orders.contains(&40), "{:?}", cal.orders);
    assert!(
        cal.map.len() > 3600 && cal.map.len() % 3600 == 0,
        "{}",
        cal.map.len()
    );
    assert!(bound(&cal) <= 0.01, "{}", bound(&cal));
}

/// The fit of `benches/end-to-end.sh`'s coast log in memory, timed (`#[ignore]`d: ~2 GB and
/// tens of seconds to simulate):
///
/// ```text
/// cargo test --release -p calib-core --test it tdr::ten_million -- --ignored --nocapture
/// ```
///
/// `spindown.toml` at 100 kHz for 100 s (10,000,001 samples, 600 → 80 r/min), channel `enc`
/// pushed once; then three `finish`es of clones, each timed, which must agree to the bit.
#[test]
#[ignore = "full size (10⁷ samples): run by hand with --release"]
#[allow(clippy::print_stderr, reason = "the figures are the point of this run")]
fn ten_million_sample_coast() {
    let mut s = scenario("spindown.toml");
    s.rate_hz = 100_000.0;
    s.spin_down.as_mut().unwrap().duration_s = 100.0;
    let mut pushed = Tdr::new(TdrOptions::default());
    for sample in s.samples().unwrap() {
        pushed.push(sample.t, sample.values[0]);
    }
    let mut maps = Vec::new();
    for _ in 0..3 {
        let tdr = pushed.clone();
        let start = std::time::Instant::now();
        let cal = tdr.finish().unwrap();
        eprintln!("finish in {:.3} s", start.elapsed().as_secs_f64());
        maps.push(cal.map.values().to_vec());
    }
    assert!(maps.iter().all(|m| m == &maps[0]));
}

/// Runs TDR with `opts` on channel `enc` alone.
fn run_alone(s: &Scenario, opts: TdrOptions) -> TdrCalibration {
    let mut tdr = Tdr::new(opts);
    for st in s.samples().unwrap() {
        tdr.push(st.t, st.values[0]);
    }
    tdr.finish().unwrap()
}

/// The coefficients `(a, b)` of `a·cos kx + b·sin kx` in `map` (from its values on the
/// uniform grid: exact for orders below half its points).
fn coefficient(map: &ErrorMap, k: usize) -> (f64, f64) {
    let n = map.len() as f64;
    map.values()
        .iter()
        .enumerate()
        .fold((0.0, 0.0), |(a, b), (i, v)| {
            let (s, c) = (k as f64 * TAU * i as f64 / n).sin_cos();
            (a + 2.0 * v * c / n, b + 2.0 * v * s / n)
        })
}

/// The largest difference between the harmonics of `a` and `b` at `orders`, arcsec, and its
/// order.
fn worst_order(a: &ErrorMap, b: &ErrorMap, orders: impl Iterator<Item = usize>) -> (usize, f64) {
    orders
        .map(|k| {
            let ((p, q), (r, s)) = (coefficient(a, k), coefficient(b, k));
            (k, (p - r).hypot(q - s) * ARCSEC_PER_RAD)
        })
        .fold((0, 0.0), |w, x| if x.1 > w.1 { x } else { w })
}

/// `map` less its harmonics at `orders`.
fn without_orders(map: &ErrorMap, orders: &[usize]) -> ErrorMap {
    let n = map.len();
    let mut values = map.values().to_vec();
    for &k in orders {
        let (a, b) = coefficient(map, k);
        for (i, v) in values.iter_mut().enumerate() {
            let (s, c) = (k as f64 * TAU * i as f64 / n as f64).sin_cos();
            *v -= a * c + b * s;
        }
    }
    ErrorMap::new(values)
}

/// The driven options of the tests: a 7-pole-pair motor (orders 42 and 84).
fn driven_options() -> TdrOptions {
    TdrOptions {
        motor: MotorOrders::PolePairs(7),
        ..TdrOptions::default()
    }
}

#[test]
fn a_driven_run_recovers_the_map_off_the_motor_orders() {
    let s = scenario("driven.toml");
    let cal = run_alone(&s, driven_options());
    let d = cal.driven.as_ref().expect("a driven run");
    assert_eq!(d.passes.len(), 1, "{:?}", d.passes);
    let speed = d.passes[0].speed() * 60.0 / TAU;
    assert!((290.0..300.0).contains(&speed), "{speed} r/min");
    // k·6·7 up to the highest order tested (0.4 × 400 samples per revolution).
    let named: Vec<usize> = d.motor_orders.iter().map(|m| m.order).collect();
    assert_eq!(named, [42, 84, 126]);
    assert!(d.motor_orders.iter().all(|m| m.separated.is_none()));
    assert!(!cal.orders.contains(&42) && !cal.orders.contains(&84));
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("42 (") && w.contains("left out")),
        "{:?}",
        cal.warnings
    );
    // What was measured at order 42 is the encoder's 10″ at 100° and the shake's 18.1″ at 20°
    // together: |10·e^{i100°} + 18.1·e^{i20°}| = 22.1″.
    let at42 = d.motor_orders[0].measured[0].harmonic.amplitude * ARCSEC_PER_RAD;
    assert!((at42 - 22.1).abs() < 1.0, "{at42}″");

    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let off_motor = without_orders(truth, &[42, 84, 126]);
    let diff = cal.map.minus(&off_motor).max_abs_arcsec();
    let rest = cal.map.minus(&off_motor);
    let rms = (rest.values().iter().map(|v| v * v).sum::<f64>() / rest.len() as f64).sqrt()
        * ARCSEC_PER_RAD;
    let u = cal.uncertainty.max() * ARCSEC_PER_RAD;
    let (k, worst) = worst_order(&cal.map, truth, 1..=30);
    println!(
        "driven, one speed: orders 1–30 within {worst:.3}″ of the truth (worst order {k}); max |map − truth off orders 42, 84, 126| = {diff:.3}″ (rms {rms:.3}″), u max {u:.2}″"
    );
    // The 14-bit counts (79.1″, 22.8″ RMS) and 5″ of noise make σ ≈ 23.4″ per sample; ~37 600
    // samples give each coefficient σ·√(2/N) ≈ 0.17″, and the significance rule keeps an order
    // above ≈ 0.75″ (its detection limit). The truth, a function of the reading, also holds the
    // cross terms e·e′ of the encoder's orders (0.3–0.65″ at orders 6, 8, 13, 15, 20, 22),
    // below that limit and left out: each order of 1–30 (moteus' range, quoted at 1.4″ for the
    // same kind of run) is within the limit plus the noise. Measured: 0.65″ (order 15).
    assert!(worst < 1.0, "order {k}: {worst}″ off the truth");
    // Over the whole map those ~20 small orders and the cogging's sidebands in the reading
    // (orders 41, 43, 85: the shake at 42 and 84 is periodic in the true angle, which the
    // encoder's 600″ at order 1 shifts by up to 2.9 mrad) add up: measured 6.6″, rms 1.7″ (the
    // budget's "orders below the significance threshold" says 1.4″).
    assert!(
        diff < 8.0,
        "max |map − truth| off the motor's orders = {diff}″"
    );
    // Against the whole truth the map misses the encoder's 10″ at order 42: u covers it (the
    // motor's orders' component is 22.1″/√2 = 15.6″ and more).
    let full = cal.map.minus(truth);
    let covered = full
        .values()
        .iter()
        .zip(&cal.uncertainty.u)
        .all(|(e, u)| e.abs() <= 2.0 * u);
    assert!(covered, "|map − truth| ≤ 2u everywhere");
}

#[test]
fn two_speeds_separate_the_cogging_from_the_encoder_error() {
    let s = scenario("driven-two-speeds.toml");
    let cal = run_alone(&s, driven_options());
    let d = cal.driven.as_ref().expect("a driven run");
    assert_eq!(d.passes.len(), 2, "{:?}", d.passes);
    let rpm: Vec<f64> = d.passes.iter().map(|p| p.speed() * 60.0 / TAU).collect();
    assert!(
        (290.0..300.0).contains(&rpm[0]) && (440.0..450.0).contains(&rpm[1]),
        "{rpm:?}"
    );
    // Order 126 is above the faster pass's highest order (0.4 × 268 samples per revolution):
    // measured at one speed only, it is left out.
    let named: Vec<usize> = d.motor_orders.iter().map(|m| m.order).collect();
    assert_eq!(named, [42, 84, 126]);
    assert!(d.motor_orders[2].separated.is_none());
    assert_eq!(d.motor_orders[2].measured.len(), 1);
    for m in &d.motor_orders[..2] {
        let sep = m.separated.as_ref().expect("separated");
        let (want_e, want_a) = if m.order == 42 {
            (10.0, 150.0)
        } else {
            (0.0, 200.0)
        };
        let e = sep.encoder.amplitude * ARCSEC_PER_RAD;
        let u = sep.u_encoder * ARCSEC_PER_RAD;
        println!(
            "driven, two speeds: order {}: encoder {e:.2}″ ± {u:.2}″ (truth {want_e}″), deceleration {:.1} ± {:.1} rad/s² (truth {want_a}), noise gain {:.2}",
            m.order, sep.deceleration.amplitude, sep.u_deceleration, sep.noise_gain
        );
        // Within 4u: u is the noise of each coefficient (~0.2″·noise gain ~2.9).
        assert!(
            (e - want_e).abs() < 4.0 * u + 0.2,
            "order {}: {e}″ ± {u}″",
            m.order
        );
        assert!(
            (sep.deceleration.amplitude - want_a).abs() < 4.0 * sep.u_deceleration + 0.02 * want_a,
            "order {}: {sep:?}",
            m.order
        );
    }
    assert!(cal.orders.contains(&42));
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let diff = cal.map.minus(truth).max_abs_arcsec();
    let off = cal
        .map
        .minus(&without_orders(truth, &[126]))
        .max_abs_arcsec();
    println!(
        "driven, two speeds: max |map − truth| = {diff:.3}″ ({off:.3}″ against the truth off order 126)"
    );
    let (k, worst) = worst_order(&cal.map, truth, 1..=30);
    println!("driven, two speeds: orders 1–30 within {worst:.3}″ of the truth (worst order {k})");
    // As at one speed (the main pass is the slower one), and the encoder's 10″ at order 42 now
    // in the map (to 0.62″, within 2u); the shake's sidebands at 41, 43 and 85 given back:
    // measured 6.9″ over the map (rms 1.3″), from the orders below the detection limit.
    assert!(worst < 1.0, "order {k}: {worst}″ off the truth");
    assert!(diff < 8.0, "max |map − truth| = {diff}″");
    // And u, without the one-speed component now, still holds: |map − truth| ≤ 2u at 90 % of
    // the points or more, as on a coast (measured 94 %; 87 % before the sidebands were given
    // back).
    let full = cal.map.minus(truth);
    let inside = full
        .values()
        .iter()
        .zip(&cal.uncertainty.u)
        .filter(|(e, u)| e.abs() <= 2.0 * **u)
        .count() as f64
        / full.len() as f64;
    println!(
        "driven, two speeds: |map − truth| ≤ 2u at {:.1} % of the points",
        100.0 * inside
    );
    assert!(inside >= 0.9, "{inside}");
    assert!(
        cal.warnings.iter().any(|w| w.contains("orders 126 (")),
        "{:?}",
        cal.warnings
    );
}

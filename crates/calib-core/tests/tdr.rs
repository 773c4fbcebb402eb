//! Spin-down (TDR) self-calibration against known truths: the simulator's air-bearing and
//! rolling-bearing coasts (`testdata/scenarios/spindown*.toml`), synthetic coasts with a driven
//! plateau and a stop, and logs with no spin-down.

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::simulate::Scenario;
use calib_core::tdr::{Tdr, TdrCalibration, TdrError, TdrOptions};
use calib_core::{ErrorMap, FourierSeries, Harmonic};
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
    // The reference's own error is 0.05″ at order 3, so the check sees ≈ 0.05″.
    let check = cal.reference.as_ref().unwrap();
    assert!(check.max_abs_diff_arcsec < 0.07, "{check:?}");
}

#[test]
fn rolling_bearing_drag_appears_as_encoder_error_by_the_predicted_amount() {
    let s = scenario("spindown-bearing.toml");
    let (cal, speeds) = run(&s);
    let inv_omega2 = mean_inverse_square_speed(&speeds, &cal);
    let truth = &s.truth(cal.map.len()).unwrap()[0].1;
    let diff = cal.map.minus(truth);
    // Eq. (2) of the tdr module: a drag a_h·cos(hθ + φ) shakes the shaft by a_h/(hω)²·cos(hθ + φ),
    // which the constant-coefficient fit averages over the samples: the map's order h is off by
    // (a_h/h²)·⟨ω⁻²⟩ at phase φ. Corrections to (2) are O(ω̇/(hω²)) ≈ 2e-4 and O(F′(ω)/(hω))
    // ≈ 1e-4; the spread of 1/ω² over the coast (×3.5) is what the mean absorbs. Hence 2 %.
    let sd = s.spin_down.as_ref().unwrap();
    let predicted: Vec<Harmonic> = sd
        .drag_harmonics
        .iter()
        .map(|d| {
            let h = f64::from(d.order);
            Harmonic {
                order: d.order as usize,
                amplitude: d.amplitude / (h * h) * inv_omega2,
                phase: d.phase_deg.to_radians(),
            }
        })
        .collect();
    let got = diff.series();
    for p in &predicted {
        let (a, b) = p.coefficients();
        let (ga, gb) = (got.cos[p.order - 1], got.sin[p.order - 1]);
        let off = arcsec((ga - a).hypot(gb - b));
        let want = arcsec(p.amplitude);
        assert!(
            off < 0.02 * want,
            "order {}: off {off}″ of {want}″",
            p.order
        );
    }
    // 3.94″ at order 2 and 1.97″ at order 4: the map is off by up to their sum's peak.
    let predicted_map =
        ErrorMap::from_series(&FourierSeries::from_harmonics(&predicted, 8), cal.map.len());
    let (worst, expected) = (diff.max_abs_arcsec(), predicted_map.max_abs_arcsec());
    assert!(expected > 4.0, "{expected}");
    assert!(
        (worst - expected).abs() < 0.03 * expected,
        "max |map − truth| {worst}″, predicted {expected}″"
    );
    // Other orders are untouched (within the air-bearing case's accuracy plus the leak of the
    // varying amplitude into neighbouring chirps).
    for k in (1..=32).filter(|k| ![2, 4].contains(k)) {
        let off = arcsec(got.cos[k - 1].hypot(got.sin[k - 1]));
        assert!(off < 0.05, "order {k}: {off}″");
    }
    // The fit's drag gain is the samples' ⟨ω⁻²⟩ from the fitted motion.
    assert!((cal.drag_gain / inv_omega2 - 1.0).abs() < 1e-3);
    // The diagnostic sees exactly these two orders, with the predicted amplitude (its
    // ω⁻²-shaped part has the same amplitude as the mean the map absorbed).
    let orders: Vec<usize> = cal
        .speed_dependence
        .iter()
        .map(|s| s.harmonic.order)
        .collect();
    assert_eq!(orders, [2, 4]);
    for (s, p) in cal.speed_dependence.iter().zip(&predicted) {
        assert!(
            (s.harmonic.amplitude / p.amplitude - 1.0).abs() < 0.03,
            "{s:?}"
        );
    }
    assert!(cal.warnings.iter().any(|w| w.contains("drag")));
    // The reference check exposes it.
    assert!(cal.reference.as_ref().unwrap().max_abs_diff_arcsec > 4.0);
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
    // Driven at constant speed: 2 rev/s for 50 s.
    let e = finish((0..5000).map(|n| (at(n), (2.0 * TAU * at(n)).rem_euclid(TAU))));
    assert!(matches!(e, TdrError::NotFalling { .. }), "{e}");
    assert!(e.to_string().contains("release the drive"), "{e}");
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

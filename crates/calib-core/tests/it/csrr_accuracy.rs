//! CSRR accuracy against a known truth, on simulated runs that mirror the seed paper's
//! experiments (5 sessions × 3 revolutions, 400 Hz, 10 r/min, quantization 0.09″, noise 0.05″:
//! `testdata/scenarios/csrr{72,84,90}.toml`), and the paper method's behaviour on dense-Δ runs.
//!
//! Tolerances: the per-sample noise is ~0.08″ RMS in `x − y` (two sensors' 0.05″ noise and
//! 0.09″/√12 quantization); of the ~1000 orders tested the significance rule keeps the 6–16
//! the sensors hold, whose coefficients from ~47000 samples leave a map error of ~0.002″ RMS
//! (~0.03″ when every order was kept), its maximum over 10⁵ grid points ~4–5× that. Each bound
//! below is the issue's bar; the measured figures are in the comments.

use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::channel_index;
use calib_core::csrr::{Csrr, CsrrOptions, Method};
use calib_core::simulate::Scenario;
use calib_core::uncertainty::MapUncertainty;
use std::f64::consts::PI;

fn scenario(text: &str) -> Scenario {
    toml::from_str(text).expect("scenario parses")
}

fn run(sc: &Scenario, opts: CsrrOptions) -> calib_core::csrr::Calibration {
    let channels = sc.channels();
    let ia = channel_of(&channels, "a");
    let ib = channel_of(&channels, "b");
    let mut csrr = Csrr::new(opts);
    for s in sc.samples().expect("valid scenario") {
        csrr.push(s.t, s.values[ia], s.values[ib], None);
    }
    csrr.finish().expect("calibration succeeds")
}

fn channel_of(channels: &[calib_core::Channel], name: &str) -> usize {
    channel_index(channels, name).expect("scenario names its sensors a and b")
}

fn truth(sc: &Scenario, name: &str) -> ErrorMap {
    truth_on(sc, name, 36000)
}

/// The true map of sensor `name` on `points` grid points.
fn truth_on(sc: &Scenario, name: &str, points: usize) -> ErrorMap {
    sc.truth(points)
        .expect("truth")
        .into_iter()
        .find(|(n, _)| n == name)
        .expect("sensor exists")
        .1
}

/// Largest |map − truth| after mean removal, arcsec, on the truth's grid.
fn max_error(map: &ErrorMap, truth: &ErrorMap) -> f64 {
    truth.minus(map).max_abs_arcsec()
}

/// The fraction of table points with |map − truth| ≤ k·u, and the median u (arcsec).
fn coverage(map: &ErrorMap, u: &MapUncertainty, truth: &ErrorMap, k: f64) -> (f64, f64) {
    let diff = map.minus(truth);
    let inside = diff
        .values()
        .iter()
        .zip(&u.u)
        .filter(|(d, u)| d.abs() <= k * **u)
        .count();
    (
        inside as f64 / map.len() as f64,
        u.median() * ARCSEC_PER_RAD,
    )
}

fn load(file: &str) -> Scenario {
    scenario(
        &std::fs::read_to_string(format!(
            "{}/../../testdata/scenarios/{file}",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap(),
    )
}

/// The accuracy bar, and the uncertainty's: on both sensors |map − truth| ≤ 2u at 90–99.9 % of
/// the table's points, with a median u ≤ 0.1″ (issue 16).
fn check(file: &str, bar_arcsec: f64) {
    let sc = load(file);
    let cal = run(&sc, CsrrOptions::default());
    assert_eq!(cal.sessions.len(), 5);
    let ea = max_error(&cal.a, &truth(&sc, "a"));
    let eb = max_error(&cal.b, &truth(&sc, "b"));
    let (ua, ub) = cal.uncertainty.as_ref().expect("the joint method gives u");
    let (ca, ma) = coverage(&cal.a, ua, &truth_on(&sc, "a", cal.a.len()), 2.0);
    let (cb, mb) = coverage(&cal.b, ub, &truth_on(&sc, "b", cal.b.len()), 2.0);
    println!(
        "{file}: max |map − truth| A {ea:.4}″ B {eb:.4}″; |map − truth| ≤ 2u at A {:.1} % B {:.1} % of {} points; median u A {ma:.4}″ B {mb:.4}″",
        100.0 * ca,
        100.0 * cb,
        cal.a.len()
    );
    assert!(
        ea <= bar_arcsec && eb <= bar_arcsec,
        "{file}: max error A {ea:.4}″, B {eb:.4}″ (bar {bar_arcsec}″)"
    );
    for (c, m) in [(ca, ma), (cb, mb)] {
        assert!((0.90..=0.999).contains(&c), "{file}: coverage {c}");
        assert!(m <= 0.1, "{file}: median u {m}″");
    }
}

/// Bar 1: Table II's 72-pole-pair sensors, 1 % speed variation: ≤ 0.2″ (measured 0.0048″/0.0049″,
/// 0.083″/0.088″ with every order kept; the paper reports ±1.5″).
#[test]
fn table_ii_72_pole_pairs_within_0_2_arcsec() {
    check("csrr72.toml", 0.2);
}

/// Bar 2: 84 pole pairs at ±680″ with Table III's ε_θ: ≤ 1.0″ (measured 0.0135″/0.0074″, 0.087″/0.088″
/// with every order kept; paper ±2″).
#[test]
fn table_iv_84_pole_pairs_at_680_arcsec_within_1_arcsec() {
    check("csrr84.toml", 1.0);
}

/// Bar 3: 90 pole pairs at ±250″, ε_θ sharing order 90: ≤ 0.3″ (measured 0.0086″/0.0112″, 0.087″/0.073″
/// with every order kept; paper ±10″).
#[test]
fn table_v_90_pole_pairs_sharing_order_90_within_0_3_arcsec() {
    check("csrr90.toml", 0.3);
}

/// A dense-Δ run for the paper method (`paper40.toml`: 40 sessions 9° apart, low-order
/// sensors, short ramps) with the sampling non-uniformity ε_θ at order `eps_order`, `m` arcsec.
fn dense_run(eps_order: u32, m: f64) -> Scenario {
    let mut sc = load("paper40.toml");
    sc.speed.harmonics[0].order = eps_order;
    sc.speed.harmonics[0].amplitude_arcsec = m;
    sc
}

/// The paper method's own output: one point of A's map per session. Max |point − truth|, mean
/// removed over the points, arcsec.
fn paper_point_error(eps_order: u32, m: f64) -> f64 {
    let sc = dense_run(eps_order, m);
    let cal = run(
        &sc,
        CsrrOptions {
            method: Method::Paper,
            ..CsrrOptions::default()
        },
    );
    assert!(
        cal.paper_points.len() >= 38,
        "{} points",
        cal.paper_points.len()
    );
    let t = truth(&sc, "a");
    let diffs: Vec<f64> = cal
        .paper_points
        .iter()
        .map(|p| p.a_error - t.eval_linear(p.a_angle))
        .collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    diffs.iter().fold(0.0f64, |m, d| m.max((d - mean).abs())) * ARCSEC_PER_RAD
}

/// Bar 4: the paper method as published. With ε_θ at order 11, which the sensors do not share,
/// it is accurate (measured 0.099″: the noise of one crossing per revolution). With ε_θ at
/// order 3 — A's largest harmonic, 100″ — the DC estimate of Δ (eqs. 4–5) is a time average, and
/// A's error sampled at non-uniform positions `θ = φ + m cos(3φ + ψ)` averages to
/// `−½·h·m·A·sin(φ_a − ψ)` to first order (eq. 14 read in angle units), which moves with `hΔ_k`
/// from session to session: the map degrades by `½·h·m·A` = 0.436″ for m = 600″ (measured
/// 0.452″), and in proportion to `|Y_h|·A_h` — twice the modulation, twice the residual
/// (measured 0.920″ for m = 1200″).
///
/// The paper's indicator as tabulated predicts `|Y_h|·A_h = π²·h·m·A` = 8.6″ here (eqs. 18–20,
/// with the `Ω = 2π·h` that reproduces its Table V): 2π² times the first-order shift, because
/// Table V takes `Ω` per revolution where eq. 11's Bessel argument needs it per radian, and eq.
/// 20 compares a Fourier-domain `F_JΩ` (a constant `c` appears as `2π·c`) with an angle. calib
/// reports `|Y|` and `|Y|·A` as published beside `|Y|·A/(2π²)` (`csrr::reference`); this test
/// checks the mechanism, with the constant derived from eq. 14.
#[test]
fn paper_method_is_accurate_unless_eps_theta_shares_an_order() {
    let m = 600.0;
    let clean = paper_point_error(11, m);
    let shared = paper_point_error(3, m);
    let doubled = paper_point_error(3, 2.0 * m);
    let y_times_a = |m: f64| PI * PI * 3.0 * (m / ARCSEC_PER_RAD) * 100.0;
    let first_order = |m: f64| y_times_a(m) / (2.0 * PI * PI);
    assert!(clean < 0.15, "clean run: {clean:.4}″");
    for (err, m) in [(shared, m), (doubled, 2.0 * m)] {
        assert!(
            err > 0.7 * first_order(m) && err < 1.5 * first_order(m),
            "m = {m}″: {err:.4}″, |Y|·A/(2π²) = {:.4}″",
            first_order(m)
        );
    }
    let ratio = doubled / shared;
    assert!(
        (1.7..2.3).contains(&ratio),
        "residual ratio {ratio:.3} for m doubled"
    );
}

/// The paper method's `u` (issue 16) on the dense-Δ run with ε_θ sharing sensor a's order 3
/// (`paper40-shared.toml`, one seed). Its map error is mostly deterministic: the linear
/// interpolation between points 9° apart (at a midpoint `A·(1 − cos(hδ/2))` per harmonic, 3.52″
/// for a's 100″ at order 3 and 10″ at order 5) and ε_θ's bias of the time-averaged `Δ̂_k`
/// (`½·h·m·A` = 0.436″ to first order, eq. 14). Both enter `u` as rectangular bounds, so `2u`
/// covers nearly every point (measured 97.6 % / 97.1 % of A's / B's 3600 points, over five seeds
/// 97.9 % / 95.5 %); the bar is the issue's lower end, 90 %, and at most every point. The
/// budget's bounds are checked against those closed forms: the harmonic content found in the
/// sessions' profiles is the truth's within 0.01″, so the interpolation bound's largest value is
/// within 5 % of 3.52″ (measured 3.55″: the points are not exactly 9° apart); the ε_θ bound
/// measures the bias in each session, whose spread is the first-order shift within the 10 % the
/// second-order terms leave (measured 0.436″).
#[test]
fn paper_method_u_bounds_interpolation_and_eps_theta() {
    let sc = load("paper40-shared.toml");
    let cal = run(
        &sc,
        CsrrOptions {
            method: Method::Paper,
            ..CsrrOptions::default()
        },
    );
    let (ua, ub) = cal.uncertainty.as_ref().expect("the paper method gives u");
    let (ca, ma) = coverage(&cal.a, ua, &truth_on(&sc, "a", cal.a.len()), 2.0);
    let (cb, mb) = coverage(&cal.b, ub, &truth_on(&sc, "b", cal.b.len()), 2.0);
    let bound = |u: &calib_core::uncertainty::MapUncertainty, name: &str| {
        let c = u
            .components
            .iter()
            .find(|c| c.name.starts_with(name))
            .unwrap_or_else(|| panic!("component {name}"));
        c.u.iter().copied().fold(0.0, f64::max) * 3f64.sqrt() * ARCSEC_PER_RAD
    };
    let interpolation = bound(ua, "linear interpolation");
    let eps = bound(ua, "sampling non-uniformity");
    let step = 9f64.to_radians();
    let midpoint = [(3.0, 100.0), (5.0, 10.0)]
        .iter()
        .map(|(h, a)| a * (1.0 - (h * step / 2.0).cos()))
        .sum::<f64>();
    let first_order = 0.5 * 3.0 * (600.0 / ARCSEC_PER_RAD) * 100.0;
    println!(
        "paper40-shared: ≤ 2u at A {:.1} % B {:.1} %, median u A {ma:.3}″ B {mb:.3}″; interpolation bound {interpolation:.3}″ (closed form {midpoint:.3}″), ε_θ bound {eps:.3}″ (½·h·m·A {first_order:.3}″)",
        100.0 * ca,
        100.0 * cb
    );
    for c in [ca, cb] {
        assert!((0.90..=1.0).contains(&c), "coverage {c}");
    }
    assert!(
        (interpolation / midpoint - 1.0).abs() < 0.05,
        "{interpolation}″ vs {midpoint}″"
    );
    assert!(
        (eps / first_order - 1.0).abs() < 0.1,
        "{eps}″ vs {first_order}″"
    );
}

/// Sessions at 0°, 90°, 180°, 270° cannot see orders that are multiples of 4: they are left out
/// of both maps and named, with advice; recording the advised extra rotation reveals them.
#[test]
fn blind_orders_are_named_and_the_advice_reveals_them() {
    let text = |deltas: &str| {
        format!(
            r#"
seed = 3
rate_hz = 200.0
speed_rpm = 60.0
[[sensor]]
name = "a"
mount = "a"
harmonics = [{{ order = 8, amplitude_arcsec = 20.0, phase_deg = 30.0 }}, {{ order = 3, amplitude_arcsec = 5.0, phase_deg = 0.0 }}]
quantization_arcsec = 0.09
noise_arcsec = 0.05
[[sensor]]
name = "b"
mount = "b"
harmonics = [{{ order = 5, amplitude_arcsec = 10.0, phase_deg = -30.0 }}]
quantization_arcsec = 0.09
noise_arcsec = 0.05
[procedure]
relative_deg = [{deltas}]
revolutions = 2.0
ramp_s = 0.2
pause_s = 0.2
turn_s = 0.3
"#
        )
    };
    let opts = || CsrrOptions {
        max_order: Some(40),
        ..CsrrOptions::default()
    };
    let sc = scenario(&text("0.0, 90.0, 180.0, 270.0"));
    let cal = run(&sc, opts());
    let excluded: Vec<usize> = cal.excluded.iter().map(|e| e.order).collect();
    assert_eq!(excluded, (1..=10).map(|k| 4 * k).collect::<Vec<_>>());
    // A's 20″ at order 8 is missing from its map: the error against the truth is that harmonic,
    // plus what the unmodelled harmonic leaks into neighbouring orders over sessions that are not
    // whole revolutions (measured 22.7″ in all).
    let err = max_error(&cal.a, &truth(&sc, "a"));
    assert!((18.0..25.0).contains(&err), "{err}");
    let advice = cal.advice.expect("advice for blind orders");
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("8") && w.contains("left out"))
    );

    let extra = advice.extra_rotation.to_degrees();
    let sc = scenario(&text(&format!("0.0, 90.0, 180.0, 270.0, {extra:.1}")));
    let cal = run(&sc, opts());
    assert!(cal.excluded.is_empty(), "{:?}", cal.excluded);
    // Noise-limited again (5 sessions of 2 revolutions at 200 Hz): within 0.2″.
    let err = max_error(&cal.a, &truth(&sc, "a"));
    assert!(err < 0.2, "{err}");
}

/// Issue 16, orders from the data: with the default highest order (40 % of the densest
/// session's 2400 samples per revolution) the significance rule keeps the orders the sensors
/// hold — 1, 2, 72, 144, 216, 432 in both, the smallest 0.96″ against a detection limit of
/// about 0.02″ — and, for noise alone, any other order with a chance below 1 % in all; asking
/// for fewer orders that still hold them all changes the maps by less than the noise.
#[test]
fn the_significant_orders_are_kept_and_too_many_orders_cost_nothing() {
    let sc = load("csrr72.toml");
    let cal = run(&sc, CsrrOptions::default());
    println!(
        "csrr72: max order {}, kept {:?}, unresolved {:?}",
        cal.max_order, cal.orders, cal.unresolved
    );
    assert!(cal.max_order >= 900, "default max order {}", cal.max_order);
    for h in [1, 2, 72, 144, 216, 432] {
        assert!(
            cal.orders.contains(&h),
            "order {h} dropped: {:?}",
            cal.orders
        );
    }
    // Orders beyond the truth's that pass would be false alarms or real sidebands; a handful at
    // most (measured: none).
    assert!(cal.orders.len() <= 10, "kept {:?}", cal.orders);
    assert!(cal.unresolved.is_empty(), "{:?}", cal.unresolved);
    let fewer = run(
        &sc,
        CsrrOptions {
            max_order: Some(500),
            ..CsrrOptions::default()
        },
    );
    assert_eq!(fewer.orders, cal.orders);
    // The same orders fitted from the same data: the maps agree far within their noise
    // (median u ≈ 0.01″); only the sub-noise residual of the dropped orders differs.
    let d = fewer.a.minus(&cal.a).max_abs_arcsec();
    assert!(d < 0.005, "maps differ by {d}″");
}

/// Issue 16, structure above the fitted orders: with `--max-order 300` the sensors' order 432
/// (0.96″ in A, 1.12″ in B) is beyond the fit; the residual check finds it, warns with its
/// order and amplitudes, and puts it in the budget (`u` ≥ its RMS `A/√2`).
#[test]
fn structure_above_the_fitted_orders_is_named_with_its_amplitude() {
    let sc = load("csrr72.toml");
    let cal = run(
        &sc,
        CsrrOptions {
            max_order: Some(300),
            ..CsrrOptions::default()
        },
    );
    println!(
        "unresolved {:?}; warnings {:?}",
        cal.unresolved, cal.warnings
    );
    let found = cal
        .unresolved
        .iter()
        .find(|u| u.order == 432)
        .expect("order 432 found in the residual");
    // Within 10 %: the projection of a residual that the fit has already partly absorbed into
    // lower orders over sessions of whole revolutions (measured below 1 %).
    let (a, b) = (found.a * ARCSEC_PER_RAD, found.b * ARCSEC_PER_RAD);
    assert!(
        (a - 0.96).abs() < 0.1 && (b - 1.12).abs() < 0.11,
        "A {a}″ B {b}″"
    );
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("432") && w.contains("periodic structure")),
        "{:?}",
        cal.warnings
    );
    let (ua, _) = cal.uncertainty.as_ref().unwrap();
    assert!(
        ua.u.iter()
            .all(|u| *u * ARCSEC_PER_RAD >= 0.96 / 2f64.sqrt())
    );
}

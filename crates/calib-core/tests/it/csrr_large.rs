//! CSRR of magnetic-class sensors (issue 24 items 1 and 2): errors of ±1700″ over orders 1–12, a
//! 14-bit quantum of 79.1″, six sessions of 2–3.2 revolutions at 20–45 r/min of which three turn
//! backwards (`testdata/scenarios/csrr-large.toml`).
//!
//! The per-sample noise of `x − y` is the two quanta's, `√2·79.1″/√12` ≈ 32″ (the 3″ reading
//! noise adds little); ~33 000 samples in the sessions give each coefficient of a well-observed
//! order a standard deviation of about `32″·√(2/33000)` ≈ 0.25″, and the ~16 orders the sensors
//! hold a map error of a few tenths of an arcsecond RMS, ~1–2″ at worst over the circle.

use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::channel_index;
use calib_core::csrr::{Calibration, Csrr, CsrrOptions};
use calib_core::segment::SegmentOptions;
use calib_core::simulate::Scenario;
use calib_core::uncertainty::MapUncertainty;

fn load() -> Scenario {
    let text = std::fs::read_to_string(format!(
        "{}/../../testdata/scenarios/csrr-large.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("scenario file");
    toml::from_str(&text).expect("scenario parses")
}

/// Calibrates the scenario's run, from its session marks (`marks`) or from the motion.
fn run(sc: &Scenario, marks: bool) -> Calibration {
    let channels = sc.channels();
    let ia = channel_index(&channels, "a").expect("a");
    let ib = channel_index(&channels, "b").expect("b");
    let mut csrr = Csrr::new(CsrrOptions {
        segments: SegmentOptions {
            use_marks: marks,
            ..SegmentOptions::default()
        },
        ..CsrrOptions::default()
    });
    for s in sc.samples().expect("valid scenario") {
        csrr.push(
            s.t,
            s.values[ia],
            s.values[ib],
            if marks { s.session } else { None },
        );
    }
    csrr.finish().expect("calibration succeeds")
}

fn truth(sc: &Scenario, name: &str, points: usize) -> ErrorMap {
    sc.truth(points)
        .expect("truth")
        .into_iter()
        .find(|(n, _)| n == name)
        .expect("sensor exists")
        .1
}

/// Largest |map − truth| (means removed), arcsec, and the fraction of points within 2u.
fn figures(map: &ErrorMap, u: &MapUncertainty, truth: &ErrorMap) -> (f64, f64) {
    let diff = map.minus(truth);
    let inside = diff
        .values()
        .iter()
        .zip(&u.u)
        .filter(|(d, u)| d.abs() <= 2.0 * **u)
        .count();
    (diff.max_abs_arcsec(), inside as f64 / map.len() as f64)
}

/// Max errors and 2u coverage of both maps: `[(max A, cov A), (max B, cov B)]`.
fn accuracy(sc: &Scenario, cal: &Calibration) -> [(f64, f64); 2] {
    let (ua, ub) = cal.uncertainty.as_ref().expect("u");
    [
        figures(&cal.a, ua, &truth(sc, "a", cal.a.len())),
        figures(&cal.b, ub, &truth(sc, "b", cal.b.len())),
    ]
}

fn describe(label: &str, cal: &Calibration, acc: [(f64, f64); 2]) {
    let (ua, ub) = cal.uncertainty.as_ref().expect("u");
    println!(
        "{label}: {} sessions at {:?}°; orders kept {:?}; residual {:.2}″; {} iterations; \
         max |map − truth| A {:.3}″ B {:.3}″, within 2u {:.1} % / {:.1} %, u max A {:.3}″ B {:.3}″; warnings {:?}",
        cal.sessions.len(),
        cal.sessions
            .iter()
            .map(|s| (s.relative_rotation.to_degrees() * 10.0).round() / 10.0)
            .collect::<Vec<_>>(),
        cal.orders,
        cal.residual_rms.unwrap_or(0.0) * ARCSEC_PER_RAD,
        cal.iterations,
        acc[0].0,
        acc[1].0,
        100.0 * acc[0].1,
        100.0 * acc[1].1,
        ua.max() * ARCSEC_PER_RAD,
        ub.max() * ARCSEC_PER_RAD,
        cal.warnings
    );
}

/// Item 1: the six sessions (three backwards, 20–45 r/min, 2–3.2 revolutions) are found from
/// the motion, at the marked sessions' relative rotations, and the maps are as accurate as with
/// the marks. Item 2: the solver converges and the residual check reports no structure (the run
/// holds none above order 12: the quantization's residual differs from session to session).
#[test]
fn sessions_found_from_the_motion_reach_the_marked_accuracy() {
    let sc = load();
    let marked = run(&sc, true);
    let found = run(&sc, false);
    let (am, af) = (accuracy(&sc, &marked), accuracy(&sc, &found));
    describe("marked", &marked, am);
    describe("found", &found, af);
    assert_eq!(found.sessions.len(), 6, "sessions found");
    for (m, f) in marked.sessions.iter().zip(&found.sessions) {
        // The relative rotations agree to the noise of the sessions' means (a few arcsec).
        let diff = (m.relative_rotation - f.relative_rotation).abs() * ARCSEC_PER_RAD;
        assert!(diff < 5.0, "relative rotation differs by {diff:.2}″");
    }
    assert!(found.segmentation.short_segments().next().is_none());
    for cal in [&marked, &found] {
        for w in &cal.warnings {
            assert!(!w.contains("stopped after"), "{w}");
            assert!(!w.contains("periodic structure"), "{w}");
        }
    }
    for ((em, _), (ef, cf)) in am.iter().zip(&af) {
        // Found sessions hold ~2 % fewer samples than marked ones (their edge blocks are left
        // out): the same accuracy within the noise (measured 1.40″/2.82″ found, 2.28″/4.42″
        // marked, whose fit kept one order, 1190, that the quantization's residual put at the
        // detection limit), 3″ at most — a few times the 0.25″ per coefficient over ~10 orders.
        assert!(
            *ef <= 3.0 && *ef <= 1.3 * em + 0.2,
            "found {ef:.3}″, marked {em:.3}″"
        );
        assert!(*cf >= 0.9, "2u coverage {cf:.3}");
    }
}

/// Item 2's Monte Carlo: over 10 seeds of the large-error run (new noise, the same sensors and
/// sessions, found from the motion), the fraction of table points with |map − truth| ≤ 2u,
/// pooled per sensor, and the largest error. Near 95 % is the target for a standard `u`; the bar
/// is the coverage tests' 90–99.9 % for A. B's `u` carries what the dropped orders hold together
/// beyond the white-noise estimate (the quantization's uneven spectrum), which on this run makes
/// it cover more: its bar is at least 90 %. Run with `-- --ignored --nocapture`.
#[test]
#[ignore = "Monte Carlo over 10 seeds, about a minute"]
fn u_covers_the_large_error_maps_over_seeds() {
    let mut inside = [0.0; 2];
    let mut worst = [0.0f64; 2];
    let seeds = 1..=10u64;
    for seed in seeds.clone() {
        let mut sc = load();
        sc.seed = seed;
        let cal = run(&sc, false);
        assert_eq!(cal.sessions.len(), 6, "seed {seed}");
        let acc = accuracy(&sc, &cal);
        describe(&format!("seed {seed}"), &cal, acc);
        for i in 0..2 {
            inside[i] += acc[i].1;
            worst[i] = worst[i].max(acc[i].0);
        }
    }
    let n = seeds.count() as f64;
    let (ca, cb) = (inside[0] / n, inside[1] / n);
    println!(
        "over {n} seeds: within 2u A {:.1} % B {:.1} %; largest |map − truth| A {:.3}″ B {:.3}″",
        100.0 * ca,
        100.0 * cb,
        worst[0],
        worst[1]
    );
    assert!((0.90..=0.999).contains(&ca), "A: {ca}");
    assert!(cb >= 0.90, "B: {cb}");
}

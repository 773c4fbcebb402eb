//! Multi-head self-calibration against the simulator's truth: the SelfA encoder of the
//! shift-angle paper (12 heads in sets of 3, 4 and 7, `testdata/scenarios/multihead.toml`:
//! scale error ±1.2″ with orders up to 100, head angle errors up to 3.4″, quantization 0.01″,
//! noise 0.01″, 3 revolutions at 400 Hz and 10 r/min, 8801 samples).
//!
//! Why 0.05″ is within reach: each difference `r_j − r_1` carries √2·(0.01″ ⊕ 0.01″/√12) ≈
//! 0.015″ of noise per sample (the fit's residual is 0.0147″). Each Fourier coefficient of a
//! difference averages all 8801 samples (σ ≈ 0.015″/√8801 ≈ 1.6·10⁻⁴″), and each order of the map
//! combines the 11 differences (σ ≈ 3·10⁻⁵″ per coefficient); over the 512 orders fitted the map
//! carries ≈ 0.001″ RMS of noise, whose largest value on a 36000-point grid is a few times that.
//! Quantization of 0.01″, as the readings sweep through its steps, averages like noise.

use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::multihead::{
    Head, Method, Multihead, MultiheadCalibration, MultiheadOptions, Readings,
};
use calib_core::simulate::Scenario;

fn selfa() -> Scenario {
    let text = std::fs::read_to_string(format!(
        "{}/../../testdata/scenarios/multihead.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("the scenario is in testdata");
    toml::from_str(&text).expect("scenario parses")
}

/// The scenario's heads with their nominal angles, in channel order (h1 first).
fn heads(sc: &Scenario) -> Vec<Head> {
    sc.sensors
        .iter()
        .map(|s| Head {
            name: s.name.clone(),
            nominal: s.head_deg.expect("every sensor is a head").to_radians(),
        })
        .collect()
}

fn run(sc: &Scenario, opts: MultiheadOptions) -> MultiheadCalibration {
    let mut mh = Multihead::new(heads(sc), opts).expect("valid heads");
    for s in sc.samples().expect("valid scenario") {
        mh.push(&s.values);
    }
    mh.finish().expect("calibration succeeds")
}

/// The scale's error as the first head reads it, on a 0.01° grid.
fn truth(sc: &Scenario) -> ErrorMap {
    let (name, map) = sc.truth(36000).expect("truth").swap_remove(0);
    assert_eq!(name, "h1");
    map
}

/// Largest |truth − estimate| on the truth's grid: of the written table (interpolated linearly)
/// and of the fitted series itself.
fn errors(cal: &MultiheadCalibration, truth: &ErrorMap) -> (f64, f64) {
    let table = truth.minus(&cal.map).max_abs_arcsec();
    let series = truth
        .minus(&ErrorMap::from_series(&cal.series, truth.len()))
        .max_abs_arcsec();
    (table, series)
}

fn amplitude(cal: &MultiheadCalibration, h: usize) -> f64 {
    cal.series.cos[h - 1].hypot(cal.series.sin[h - 1]) * ARCSEC_PER_RAD
}

#[test]
fn selfa_twelve_heads_joint_meets_the_bar() {
    let sc = selfa();
    let cal = run(&sc, MultiheadOptions::default());
    let truth = truth(&sc);
    // The bar is 0.05″. Measured: 0.0075″ (table and series alike).
    let (table, series) = errors(&cal, &truth);
    assert!(table < 0.05 && series < 0.05, "{table}″ / {series}″");
    assert!(
        (truth.peak_to_peak() - cal.map.peak_to_peak()).abs() * ARCSEC_PER_RAD < 0.02,
        "peak to peak"
    );
    // Head angle errors against the simulator's: measured within 0.0004″.
    let truths = sc.sensor_truths().unwrap();
    for (h, t) in cal.heads.iter().zip(&truths) {
        let want = t.head_angle_error().unwrap() * ARCSEC_PER_RAD;
        let got = h.angle_error * ARCSEC_PER_RAD;
        assert!((got - want).abs() < 0.01, "{}: {got}″ vs {want}″", h.name);
        if h.name != "h1" {
            assert_eq!(h.readings, Some(Readings::RelativeToNominal));
        }
    }
    // 2400 samples per revolution fill 2048 bins: orders up to 512; only the multiples of
    // lcm(3, 4, 7) = 84 are blind, and nothing is merely ill-conditioned.
    assert_eq!((cal.bins, cal.max_order), (2048, 512));
    let blind: Vec<usize> = cal.blind.iter().map(|e| e.order).collect();
    assert_eq!(blind, [84, 168, 252, 336, 420, 504]);
    assert!(cal.ill_conditioned.is_empty());
    // The residual is the readings' noise (0.0147″ measured): the model explains the rest.
    let residual = cal.residual_rms.unwrap() * ARCSEC_PER_RAD;
    assert!((0.012..0.018).contains(&residual), "{residual}″");
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
}

#[test]
fn selfa_eda_per_set_is_blind_to_multiples_of_its_head_count() {
    let sc = selfa();
    let truth = truth(&sc);
    // The three sets inferred from the nominal angles are the paper's: heads 1, 5, 9; 1, 3, 7,
    // 11; 1, 2, 4, 6, 8, 10, 12. Combined, they see all but the multiples of 84; the map meets
    // the bar too (measured 0.0116″: a set of 3 averages less noise than 11 differences).
    let eda = run(
        &sc,
        MultiheadOptions {
            method: Method::Eda,
            ..MultiheadOptions::default()
        },
    );
    let sets: Vec<Vec<usize>> = eda.sets.iter().map(|s| s.heads.clone()).collect();
    assert_eq!(
        sets,
        [vec![0, 4, 8], vec![0, 2, 6, 10], vec![0, 1, 3, 5, 7, 9, 11]]
    );
    let (table, _) = errors(&eda, &truth);
    assert!(table < 0.05, "{table}″");
    let blind: Vec<usize> = eda.blind.iter().map(|e| e.order).collect();
    assert_eq!(blind, [84, 168, 252, 336, 420, 504]);

    // The square set alone misses the scale's orders 4, 12, 24, 36 and 72 (0.02–0.10″); the
    // joint method, from the same log, finds them.
    let square = run(
        &sc,
        MultiheadOptions {
            method: Method::Eda,
            sets: Some(vec![vec![0, 2, 6, 10]]),
            ..MultiheadOptions::default()
        },
    );
    let joint = run(&sc, MultiheadOptions::default());
    let spectrum = truth.series();
    for h in [4, 12, 24, 36, 72] {
        let want = spectrum.cos[h - 1].hypot(spectrum.sin[h - 1]) * ARCSEC_PER_RAD;
        assert!(want > 0.015, "the scale has order {h}");
        assert!(amplitude(&square, h) < 0.002, "EDA-4 order {h}");
        assert!(
            (amplitude(&joint, h) - want).abs() < 0.002,
            "joint order {h}"
        );
    }
    assert!(truth.minus(&square.map).max_abs_arcsec() > 0.1);
}

/// Fraction of table points with |map − truth| ≤ 2u, and the median u (arcsec).
fn coverage(sc: &Scenario, cal: &MultiheadCalibration) -> (f64, f64) {
    let (_, truth) = sc.truth(cal.map.len()).expect("truth").swap_remove(0);
    let diff = cal.map.minus(&truth);
    let within = diff
        .values()
        .iter()
        .zip(&cal.uncertainty.u)
        .filter(|(d, u)| d.abs() <= 2.0 * **u)
        .count();
    (
        within as f64 / cal.map.len() as f64,
        cal.uncertainty.median() * ARCSEC_PER_RAD,
    )
}

#[test]
fn selfa_uncertainty_covers_the_truth() {
    // The bar for one run: 90–99.9 % of the table points within 2u of the truth (a
    // standard uncertainty of a normal error gives 95 %). The noise estimate comes from the
    // bins' residuals and the truth is the simulator's, so the check is independent of the fit.
    let sc = selfa();
    for method in [Method::Joint, Method::Eda] {
        let cal = run(
            &sc,
            MultiheadOptions {
                method,
                ..MultiheadOptions::default()
            },
        );
        let (f2, median) = coverage(&sc, &cal);
        assert!((0.90..=0.999).contains(&f2), "{method:?}: {f2}");
        assert!(median <= 0.1, "{method:?}: {median}″");
        let names: Vec<&str> = cal
            .uncertainty
            .components
            .iter()
            .map(|c| c.name.as_str())
            .collect();
        // The fit's noise, the interpolation, and the floor of what was tested and not found
        // (issue 30; below the fit's noise here, so it changes no u).
        assert_eq!(names.len(), 3, "{names:?}");
        assert_eq!(names[2], calib_core::detection::DETECTION_FLOOR);
        println!(
            "{method:?}: {:.1} % within 2u, median u {median:.5}″",
            100.0 * f2
        );
    }
}

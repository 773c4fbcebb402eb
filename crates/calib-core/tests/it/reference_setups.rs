//! Reference calibration on the real set-ups of issue 24, simulated with a known truth from the
//! scenarios under `testdata/scenarios/`: a lag between the channels, backlash at the ends of a
//! swept range, and an open-loop (commanded) reference with the motor's ripple.

use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{
    LatencySource, ReferenceCal, ReferenceCalibration, ReferenceKind, ReferenceOptions,
};
use calib_core::simulate::Scenario;

fn scenario(name: &str) -> Scenario {
    let path = format!(
        "{}/../../testdata/scenarios/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn calibrate(
    s: &Scenario,
    dut: usize,
    reference: usize,
    opts: ReferenceOptions,
) -> ReferenceCalibration {
    let mut cal = ReferenceCal::new(opts);
    for sample in s.samples().unwrap() {
        cal.push(sample.t, sample.values[dut], sample.values[reference]);
    }
    cal.finish().unwrap()
}

/// `(map − truth)` at every map point, the common constant removed, with the map's u: arcsec.
fn errors(cal: &ReferenceCalibration, truth: impl Fn(f64) -> Option<f64>) -> Vec<(f64, f64)> {
    let pairs: Vec<(f64, f64)> = (0..cal.map.len())
        .filter_map(|i| truth(cal.map.grid_angle(i)).map(|t| (cal.map.values()[i] - t, cal.u[i])))
        .collect();
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len() as f64;
    pairs
        .into_iter()
        .map(|(d, u)| ((d - mean) * ARCSEC_PER_RAD, u * ARCSEC_PER_RAD))
        .collect()
}

fn summary(e: &[(f64, f64)]) -> (f64, f64, f64) {
    let max = e.iter().map(|p| p.0.abs()).fold(0.0, f64::max);
    let rms = (e.iter().map(|p| p.0 * p.0).sum::<f64>() / e.len() as f64).sqrt();
    let covered = e.iter().filter(|p| p.0.abs() <= 2.0 * p.1).count() as f64 / e.len() as f64;
    (max, rms, covered)
}

#[test]
fn latency_is_estimated_and_removed() {
    let s = scenario("latency.toml");
    let cal = calibrate(&s, 0, 1, ReferenceOptions::default());
    let l = cal.latency.unwrap();
    let f = l.fit.unwrap();
    eprintln!("{l:?}");
    let truth = &s.truth(3600).unwrap()[0].1;
    let e = errors(&cal, |a| Some(truth.eval_linear(a)));
    let (max, rms, covered) = summary(&e);
    eprintln!(
        "max {max} rms {rms} covered {covered} warnings {:?}",
        cal.warnings
    );
    assert_eq!(l.source, LatencySource::Estimated);
    // τ within 5 % (issue 24's bar; measured 20.0000 ms), the map within 1.5″ (measured 0.59″;
    // the reasons are in cli/tests/it/reference_setups_cli.rs).
    assert!((f.tau - 0.02).abs() < 0.001, "{}", f.tau);
    assert!(max < 1.5 && covered >= 0.85, "{max} {rms} {covered}");
}

#[test]
fn backlash_at_the_ends() {
    let s = scenario("backlash.toml");
    let cal = calibrate(&s, 0, 1, ReferenceOptions::default());
    let truth = s.range_truth(36000).unwrap().unwrap()[0].1.clone().unwrap();
    let TableMap::Range(m) = &cal.map else {
        panic!()
    };
    eprintln!(
        "range {} {} ends {:?} latency {:?}",
        m.start().to_degrees(),
        m.end().to_degrees(),
        cal.ends,
        cal.latency
    );
    let e = errors(&cal, |a| truth.eval_linear(a));
    let (max, rms, covered) = summary(&e);
    eprintln!(
        "max {max} rms {rms} covered {covered} n {} warnings {:?}",
        e.len(),
        cal.warnings
    );
    for k in [
        0,
        1,
        2,
        10,
        50,
        100,
        e.len() - 101,
        e.len() - 50,
        e.len() - 11,
        e.len() - 1,
    ] {
        eprintln!("{k} {:?}", e[k]);
    }
}

#[test]
fn commanded_reference_ripple() {
    let s = scenario("commanded.toml");
    let opts = ReferenceOptions {
        reference_kind: ReferenceKind::Commanded { pole_pairs: 21 },
        ..ReferenceOptions::default()
    };
    let cal = calibrate(&s, 0, 1, opts);
    let truth = &s.truth(3600).unwrap()[0].1;
    let e = errors(&cal, |a| Some(truth.eval_linear(a)));
    let (max, rms, covered) = summary(&e);
    eprintln!("ripple {:?}", cal.ripple);
    eprintln!(
        "max {max} rms {rms} covered {covered} warnings {:?} lat {:?}",
        cal.warnings, cal.latency
    );
}

//! Tests of the multi-head calibration against a simulated scale and head layout.

use super::*;
use crate::angle::ARCSEC_PER_RAD;
use crate::harmonics::Harmonic;

const ARCSEC: f64 = 1.0 / ARCSEC_PER_RAD;

/// Heads at 0°, 90°, 180°, 270° (a set of 4) and 120°, 240° (with the first, a set of 3),
/// and their angle errors, arcsec.
const DEG: [f64; 6] = [0.0, 90.0, 180.0, 270.0, 120.0, 240.0];
const ERR: [f64; 6] = [0.0, 2.0, -1.5, 3.0, -2.5, 1.0];

/// The scale's error as a function of the true angle: orders 3, 4, 5, 8 and 12.
fn scale() -> FourierSeries {
    let terms = [
        (3, 1.0, 10.0),
        (4, 0.5, -30.0),
        (5, 0.4, 60.0),
        (8, 0.3, 100.0),
        (12, 0.2, 0.0),
    ];
    let h: Vec<Harmonic> = terms
        .iter()
        .map(|&(h, a, p)| Harmonic::from_arcsec_deg(h, a, p))
        .collect();
    FourierSeries::from_harmonics(&h, 12)
}

fn heads(deg: &[f64]) -> Vec<Head> {
    deg.iter()
        .enumerate()
        .map(|(j, d)| Head {
            name: format!("h{}", j + 1),
            nominal: d.to_radians(),
        })
        .collect()
}

/// `per_rev·revs` noise-free samples of heads at `deg` with angle errors `err` (arcsec), each
/// reading `s + e(s)` at its scale position `s`, less its nominal angle unless `raw`.
fn feed(mh: &mut Multihead, deg: &[f64], err: &[f64], raw: bool, per_rev: usize, revs: f64) {
    let e = scale();
    let mut r = vec![0.0; deg.len()];
    for k in 0..(per_rev as f64 * revs) as usize {
        let theta = TAU * k as f64 / per_rev as f64 + 0.1234;
        for j in 0..deg.len() {
            let alpha = deg[j].to_radians();
            let s = theta + alpha + err[j] * ARCSEC;
            r[j] = s + e.eval(s) - if raw { 0.0 } else { alpha };
        }
        mh.push(&r);
    }
}

fn calibrate(opts: MultiheadOptions, raw: bool) -> MultiheadCalibration {
    let mut mh = Multihead::new(heads(&DEG), opts).unwrap();
    feed(&mut mh, &DEG, &ERR, raw, 2400, 2.0);
    mh.finish().unwrap()
}

/// The first head's map: `x − θ` with `θ + e(θ) = x`, on `points` readings `x`.
fn truth(points: usize) -> ErrorMap {
    let e = scale();
    ErrorMap::new(
        (0..points)
            .map(|i| {
                let x = TAU * i as f64 / points as f64;
                let mut th = x;
                for _ in 0..5 {
                    let de: f64 = (1..=12)
                        .map(|h| {
                            let hf = h as f64;
                            hf * (e.sin[h - 1] * (hf * th).cos() - e.cos[h - 1] * (hf * th).sin())
                        })
                        .sum();
                    th -= (th + e.eval(th) - x) / (1.0 + de);
                }
                x - th
            })
            .collect(),
    )
}

/// Amplitude of order `h` in a series, arcsec.
fn amplitude(s: &FourierSeries, h: usize) -> f64 {
    s.cos[h - 1].hypot(s.sin[h - 1]) * ARCSEC_PER_RAD
}

fn opts(method: Method) -> MultiheadOptions {
    MultiheadOptions {
        method,
        max_order: Some(16),
        ..MultiheadOptions::default()
    }
}

#[test]
fn joint_recovers_the_map_and_the_head_angles() {
    let cal = calibrate(opts(Method::Joint), false);
    // Every head is at a multiple of 30°: order 12 is blind, and named.
    let blind: Vec<usize> = cal.blind.iter().map(|e| e.order).collect();
    assert_eq!(blind, [12]);
    assert!(cal.ill_conditioned.is_empty());
    // The truth without its (unobservable) order 12; noise-free, so only the method's own
    // error remains: 10⁻⁴″ is far above rounding and far below any harmonic.
    let mut expected = truth(3600).series();
    expected.cos[11] = 0.0;
    expected.sin[11] = 0.0;
    let got = ErrorMap::from_series(&cal.series, 3600);
    let err = ErrorMap::from_series(&expected, 3600)
        .minus(&got)
        .max_abs_arcsec();
    assert!(err < 1e-4, "{err}″");
    for (h, want) in cal.heads.iter().zip(ERR) {
        let got = h.angle_error * ARCSEC_PER_RAD;
        assert!((got - want).abs() < 1e-4, "{}: {got}″ vs {want}″", h.name);
    }
    assert_eq!(cal.heads[1].readings, Some(Readings::RelativeToNominal));
    assert!(cal.residual_rms.unwrap() * ARCSEC_PER_RAD < 1e-4);
    assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
}

#[test]
fn eda_is_blind_to_multiples_of_its_head_count_and_the_joint_method_is_not() {
    let set4 = MultiheadOptions {
        sets: Some(vec![vec![0, 1, 2, 3]]),
        ..opts(Method::Eda)
    };
    let eda4 = calibrate(set4, false);
    let joint = calibrate(opts(Method::Joint), false);
    let blind: Vec<usize> = eda4.blind.iter().map(|e| e.order).collect();
    assert_eq!(blind, [4, 8, 12, 16]);
    for (h, truth) in [(3, 1.0), (4, 0.5), (5, 0.4), (8, 0.3)] {
        // The joint method sees every order but 12 ...
        assert!(
            (amplitude(&joint.series, h) - truth).abs() < 1e-4,
            "joint {h}"
        );
        // ... EDA with 4 heads only the orders 4 does not divide.
        let eda = amplitude(&eda4.series, h);
        let want = if h % 4 == 0 { 0.0 } else { truth };
        assert!((eda - want).abs() < 1e-3, "EDA order {h}: {eda}″");
    }
    // Eq. 9 itself gives (nearly) nothing at the multiples of 4: 1 − (1/N)Σe^{ihψ_j} ≈ h·δ.
    assert!(amplitude(&eda4.sets[0].series, 4) < 1e-3);
    assert!(amplitude(&eda4.sets[0].series, 8) < 1e-3);

    // With both sets inferred, each order one set misses comes from the other; only the
    // multiples of lcm(3, 4) = 12 stay blind.
    let both = calibrate(opts(Method::Eda), false);
    let sets: Vec<Vec<usize>> = both.sets.iter().map(|s| s.heads.clone()).collect();
    assert_eq!(sets, [vec![0, 4, 5], vec![0, 1, 2, 3]]);
    let blind: Vec<usize> = both.blind.iter().map(|e| e.order).collect();
    assert_eq!(blind, [12]);
    for (h, truth) in [(3, 1.0), (4, 0.5), (5, 0.4), (8, 0.3)] {
        assert!((amplitude(&both.series, h) - truth).abs() < 1e-3, "{h}");
    }
}

#[test]
fn raw_scale_readings_give_the_same_result() {
    let relative = calibrate(opts(Method::Joint), false);
    let raw = calibrate(opts(Method::Joint), true);
    assert_eq!(raw.heads[3].readings, Some(Readings::Raw));
    let d = relative.map.minus(&raw.map).max_abs_arcsec();
    assert!(d < 1e-6, "{d}″");
    for (a, b) in relative.heads.iter().zip(&raw.heads) {
        assert!((a.angle_error - b.angle_error).abs() * ARCSEC_PER_RAD < 1e-6);
    }
}

#[test]
fn selfa_sets_are_inferred_from_equal_spacing() {
    let step = 360.0 / 7.0;
    // Heads numbered as in the paper: 1, 5, 9 at 120° steps; 1, 3, 7, 11 at 90°; 1, 2, 4, …
    // 12 at 360°/7 (angles as a user types them, to 6 decimals).
    let mut deg = [0.0; 12];
    for (k, j) in [0, 4, 8].into_iter().enumerate() {
        deg[j] = 120.0 * k as f64;
    }
    for (k, j) in [0, 2, 6, 10].into_iter().enumerate() {
        deg[j] = 90.0 * k as f64;
    }
    for (k, j) in [0, 1, 3, 5, 7, 9, 11].into_iter().enumerate() {
        deg[j] = (step * k as f64 * 1e6).round() / 1e6;
    }
    let rel: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
    let sets = infer_sets(&rel, 0.01f64.to_radians());
    assert_eq!(
        sets,
        [vec![0, 4, 8], vec![0, 2, 6, 10], vec![0, 1, 3, 5, 7, 9, 11]]
    );
}

#[test]
fn bad_heads_and_sets_are_errors() {
    let new = |deg: &[f64], opts: MultiheadOptions| Multihead::new(heads(deg), opts).err();
    let eda = |sets: Vec<Vec<usize>>| MultiheadOptions {
        method: Method::Eda,
        sets: Some(sets),
        ..MultiheadOptions::default()
    };
    assert!(matches!(
        new(&[0.0], MultiheadOptions::default()),
        Some(MultiheadError::TooFewHeads { found: 1 })
    ));
    let mut twice = heads(&[0.0, 90.0, 180.0]);
    twice[2].name = "h2".into();
    assert!(matches!(
        Multihead::new(twice, MultiheadOptions::default()).err(),
        Some(MultiheadError::DuplicateHead { name }) if name == "h2"
    ));
    assert!(matches!(
        new(&[0.0, f64::NAN], MultiheadOptions::default()),
        Some(MultiheadError::NonFiniteAngle { .. })
    ));
    assert!(matches!(
        new(&[0.0, 100.0], opts(Method::Eda)),
        Some(MultiheadError::NoEquallySpacedSet { .. })
    ));
    assert!(matches!(
        new(&DEG, eda(vec![vec![0, 1, 4]])),
        Some(MultiheadError::SetNotEquallySpaced { head, count: 3, .. }) if head == "h2"
    ));
    assert!(matches!(
        new(&DEG, eda(vec![vec![1, 3]])),
        Some(MultiheadError::SetWithoutFirstHead { .. })
    ));
    assert!(matches!(
        new(&DEG, eda(vec![vec![0]])),
        Some(MultiheadError::SetTooSmall { .. })
    ));
    assert!(matches!(
        new(&DEG, eda(vec![vec![0, 2, 2]])),
        Some(MultiheadError::DuplicateHead { .. })
    ));
    assert!(matches!(
        new(&DEG, eda(vec![vec![0, 9]])),
        Some(MultiheadError::Options(_))
    ));
    let bins = MultiheadOptions {
        bins_per_rev: 1000,
        ..MultiheadOptions::default()
    };
    assert!(matches!(new(&DEG, bins), Some(MultiheadError::Options(_))));
}

#[test]
fn bad_data_are_errors_not_panics() {
    let run = |deg_declared: &[f64], deg_true: &[f64], per_rev: usize, revs: f64, opts| {
        let mut mh = Multihead::new(heads(deg_declared), opts).unwrap();
        feed(&mut mh, deg_true, &ERR, false, per_rev, revs);
        mh.finish().err()
    };
    let deg = &DEG[..3];
    assert!(matches!(
        Multihead::new(heads(deg), MultiheadOptions::default())
            .unwrap()
            .finish()
            .err(),
        Some(MultiheadError::NoSamples { skipped: 0 })
    ));
    // Half a turn: the travel is said first, over the solve's own error.
    let half = run(deg, deg, 2400, 0.5, MultiheadOptions::default());
    match half {
        Some(MultiheadError::NoWholeTurn { turn, cause }) => {
            assert!((turn.span_deg - 180.0).abs() < 0.5, "{}", turn.span_deg);
            match *cause {
                MultiheadError::NotCovered { gap_deg, .. } => {
                    assert!((gap_deg - 180.0).abs() < 0.5, "{gap_deg}")
                }
                other => panic!("{other:?}"),
            }
        }
        other => panic!("{other:?}"),
    }
    let too_high = MultiheadOptions {
        max_order: Some(200),
        ..MultiheadOptions::default()
    };
    assert!(matches!(
        run(deg, deg, 400, 2.0, too_high),
        Some(MultiheadError::TooFewSamplesPerRevolution {
            requested: 200,
            needed: 800,
            available: 256
        })
    ));
    // A head declared at 60° that sits at 120°, reading raw scale angles: its mean difference
    // is neither 0 nor 60°.
    let mut mh = Multihead::new(heads(&[0.0, 60.0, 180.0]), MultiheadOptions::default()).unwrap();
    feed(&mut mh, &[0.0, 120.0, 180.0], &ERR, true, 2400, 1.5);
    assert!(matches!(
        mh.finish().err(),
        Some(MultiheadError::HeadAngleMismatch { head, .. }) if head == "h2"
    ));
    // Reading relative to its nominal angle, the same head shows only in the fit's residual.
    let mut mh = Multihead::new(heads(&[0.0, 60.0, 180.0]), opts(Method::Joint)).unwrap();
    feed(&mut mh, &[0.0, 120.0, 180.0], &ERR, false, 2400, 1.5);
    let cal = mh.finish().unwrap();
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("head `h2` disagrees")),
        "{:?}",
        cal.warnings
    );
    // A head counting the other way round.
    let mut mh = Multihead::new(heads(deg), MultiheadOptions::default()).unwrap();
    for k in 0..3000 {
        let th = TAU * k as f64 / 2000.0;
        mh.push(&[th, -th, th]);
    }
    assert!(matches!(
        mh.finish().err(),
        Some(MultiheadError::NotFollowing { head, .. }) if head == "h2"
    ));
    // Non-finite readings are skipped and counted.
    let mut mh = Multihead::new(heads(deg), opts(Method::Joint)).unwrap();
    mh.push(&[f64::NAN, 0.0, 0.0]);
    feed(&mut mh, deg, &ERR, false, 2400, 1.5);
    let cal = mh.finish().unwrap();
    assert_eq!(cal.skipped, 1);
    assert!(cal.warnings[0].contains("skipped"), "{:?}", cal.warnings);
}

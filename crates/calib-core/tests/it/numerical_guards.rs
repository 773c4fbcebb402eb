//! Singular and ill-conditioned systems: detected, reported by order, and never turned into
//! NaN or huge values in a map.

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::{Csrr, CsrrError, CsrrOptions};
use calib_core::segment::SegmentOptions;
use calib_core::shift_angle::{self, Readings, Shift, ShiftAngleError, StartFaceRow};
use calib_core::{FourierSeries, Harmonic};
use std::f64::consts::TAU;

const MAX_ORDER: usize = 8;

/// A CSRR run with sessions at `deltas_deg`, sensors erring 20″ at order 3 (A) and 15″ at
/// orders 2 and 5 (B), solved with session marks.
fn csrr(deltas_deg: &[f64]) -> Result<calib_core::csrr::Calibration, CsrrError> {
    let ea = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(3, 20.0, 10.0)], 3);
    let eb = FourierSeries::from_harmonics(
        &[
            Harmonic::from_arcsec_deg(2, 15.0, -40.0),
            Harmonic::from_arcsec_deg(5, 15.0, 70.0),
        ],
        5,
    );
    let mut csrr = Csrr::new(CsrrOptions {
        max_order: Some(MAX_ORDER),
        points: Some(720),
        bins_per_rev: 4096,
        segments: SegmentOptions {
            use_marks: true,
            ..SegmentOptions::default()
        },
        ..CsrrOptions::default()
    });
    let mut t = 0.0;
    for (k, delta) in deltas_deg.iter().map(|d| d.to_radians()).enumerate() {
        for n in 0..800 {
            let theta = TAU * n as f64 / 400.0 + k as f64;
            let tb = theta - delta;
            csrr.push(t, theta + ea.eval(theta), tb + eb.eval(tb), Some(k as u32));
            t += 0.001;
        }
    }
    csrr.finish()
}

fn assert_sane(cal: &calib_core::csrr::Calibration) {
    for v in cal.a.values().iter().chain(cal.b.values()) {
        assert!(v.is_finite() && v.abs() * ARCSEC_PER_RAD < 100.0, "{v}");
    }
}

#[test]
fn sessions_at_one_rotation_but_a_tiny_offset_observe_nothing() {
    // Four sessions at 0° and one 0.001° off: every order's observability is ~1e-10.
    let err = csrr(&[0.0, 0.0, 0.0, 0.0, 0.001]).unwrap_err();
    assert_eq!(
        err,
        CsrrError::NothingObservable {
            max_order: MAX_ORDER
        }
    );
}

#[test]
fn nearly_blind_orders_are_left_out_and_named_with_their_observability() {
    // Four sessions near 0° and one at 120°: orders 3 and 6 are nearly blind (the 0.001° offset
    // keeps them from being exactly so), all others well determined.
    let cal = csrr(&[0.0, 0.0, 0.001, 0.0, 120.0]).unwrap();
    let orders: Vec<usize> = cal.excluded.iter().map(|e| e.order).collect();
    assert_eq!(orders, [3, 6]);
    for e in &cal.excluded {
        assert!(e.observability < 0.01, "{e:?}");
    }
    // The excluded orders are zero in both maps, not noise-amplified guesses.
    let (ea, eb) = cal.true_angle_series.as_ref().unwrap();
    for s in [ea, eb] {
        let h = s.harmonics();
        assert_eq!(h[2].amplitude, 0.0);
        assert_eq!(h[5].amplitude, 0.0);
    }
    assert_sane(&cal);
    let advice = cal.advice.expect("advice for the blind orders");
    assert!(advice.min_observability > 0.01, "{advice:?}");
    assert!(
        cal.warnings.iter().any(|w| w.contains("3, 6")),
        "{:?}",
        cal.warnings
    );
}

#[test]
fn exactly_blind_orders_are_reported_with_zero_observability() {
    let cal = csrr(&[0.0, 90.0, 180.0, 270.0]).unwrap();
    let orders: Vec<usize> = cal.excluded.iter().map(|e| e.order).collect();
    assert_eq!(orders, [4, 8]);
    for e in &cal.excluded {
        assert!(e.observability < 1e-9, "{e:?}");
    }
    assert_sane(&cal);
    // The determined orders are right: A's order 3 and B's order 2.
    let (ea, eb) = cal.true_angle_series.as_ref().unwrap();
    assert!((ea.harmonics()[2].amplitude * ARCSEC_PER_RAD - 20.0).abs() < 1e-3);
    assert!((eb.harmonics()[1].amplitude * ARCSEC_PER_RAD - 15.0).abs() < 1e-3);
}

fn rows(faces: usize, starts: &[usize]) -> Vec<StartFaceRow> {
    starts
        .iter()
        .map(|&j| StartFaceRow {
            start_face: j,
            readings_arcsec: (0..faces).map(|i| (i * j) as f64 * 0.1).collect(),
        })
        .collect()
}

#[test]
fn shift_angle_readings_that_leave_the_polygon_free_are_refused() {
    // One start face per shift: nothing separates the polygon from the encoder.
    let single = Readings::new(
        6,
        vec![
            Shift {
                shift_deg: 0.0,
                rows: rows(6, &[1]),
            },
            Shift {
                shift_deg: 10.0,
                rows: rows(6, &[1]),
            },
        ],
    )
    .unwrap();
    for method in [shift_angle::Method::Joint, shift_angle::Method::Paper] {
        let err = shift_angle::calibrate(&single, method).unwrap_err();
        assert!(
            matches!(err, ShiftAngleError::PolygonUndetermined { .. }),
            "{err}"
        );
    }
    // Start faces 1, 3, 5 of 6: a pattern of period 2 faces stays free.
    let even = Readings::new(
        6,
        vec![Shift {
            shift_deg: 0.0,
            rows: rows(6, &[1, 3, 5]),
        }],
    )
    .unwrap();
    let err = shift_angle::calibrate(&even, shift_angle::Method::Joint).unwrap_err();
    assert!(err.to_string().contains("multiples of 2"), "{err}");
}

#[test]
fn shift_angle_results_stay_finite_for_extreme_readings() {
    // Readings of 1e12″ are finite; the solve must not turn them into NaN (the CLI refuses to
    // write a table of such values: see cli/tests/it/reliability.rs).
    let mut r = rows(6, &[1, 2, 3, 4, 5, 6]);
    r[2].readings_arcsec[4] = 1e12;
    let readings = Readings::new(
        6,
        vec![Shift {
            shift_deg: 0.0,
            rows: r,
        }],
    )
    .unwrap();
    let result = shift_angle::calibrate(&readings, shift_angle::Method::Joint).unwrap();
    assert!(result.points.iter().all(|p| p.error_arcsec.is_finite()));
    assert!(result.points.iter().any(|p| p.error_arcsec.abs() > 1e9));
}

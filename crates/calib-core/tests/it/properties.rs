//! Properties of the solvers that hold for any error model within range (proptest).
//!
//! Each case simulates a small CSRR run in memory (5 sessions of 2 revolutions, 400 samples per
//! revolution, errors up to order 6) or a small shift-angle measurement, so the default run stays
//! fast. `PROPTEST_CASES=N` runs every property N times instead of its default count.

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::observability;
use calib_core::csrr::{Calibration, Csrr, CsrrOptions};
use calib_core::segment::SegmentOptions;
use calib_core::shift_angle::{self, Readings, Shift, StartFaceRow};
use calib_core::{ErrorMap, FourierSeries, Harmonic};
use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use std::f64::consts::TAU;

const MAX_ORDER: usize = 6;
const PER_REV: usize = 400;
const REVS: usize = 2;
const POINTS: usize = 720;
/// Relative rotations of the five sessions before jitter, degrees.
/// How far (arcsec) a map may move under a change that leaves the problem the same up to a
/// relabelling of angles. The solver synthesizes both series on a grid of 16 points per order
/// and interpolates between them; that interpolation errs by ~2·10⁻⁶ of the errors' size
/// (1.2–1.9·10⁻⁴″ for 60″ errors in the shrunk cases of proptest-regressions/properties.txt),
/// and differently at shifted positions.
const SHIFT_TOL: f64 = 1e-3;
/// Relative rotations of the five sessions before jitter, degrees.
const BASE_DELTAS_DEG: [f64; 5] = [0.0, 37.0, 101.0, 190.0, 275.0];

/// `default` cases, or `PROPTEST_CASES` when set (for a long run).
fn cases(default: u32) -> ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default);
    ProptestConfig {
        cases,
        // Shrunk failures are kept here and replayed first on every run (commit the file).
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct(
            "proptest-regressions/properties.txt",
        ))),
        ..ProptestConfig::default()
    }
}

/// A run's truth: both sensors' errors as functions of the true angle, the sessions' relative
/// rotations (rad), and the reading noise.
#[derive(Debug, Clone)]
struct Truth {
    a: FourierSeries,
    b: FourierSeries,
    deltas: Vec<f64>,
    /// Standard deviation of each reading's noise, rad.
    sigma: f64,
    seed: u64,
}

fn series(max_arcsec: f64) -> impl Strategy<Value = FourierSeries> {
    prop::collection::vec((0.0..max_arcsec, -180.0..180.0f64), MAX_ORDER).prop_map(|terms| {
        let harmonics: Vec<Harmonic> = terms
            .iter()
            .enumerate()
            .map(|(i, &(amp, phase))| Harmonic::from_arcsec_deg(i + 1, amp, phase))
            .collect();
        FourierSeries::from_harmonics(&harmonics, MAX_ORDER)
    })
}

/// Sessions at the base rotations jittered by up to ±8°, every order up to [`MAX_ORDER`]
/// observable with `q_h ≥ 0.2` (so noise is amplified at most 2.2×).
fn deltas() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-8.0..8.0f64, 4)
        .prop_map(|jitter| {
            let mut d = vec![0.0];
            d.extend(
                BASE_DELTAS_DEG[1..]
                    .iter()
                    .zip(&jitter)
                    .map(|(b, j)| (b + j).to_radians()),
            );
            d
        })
        .prop_filter("every order observable", |d| {
            (1..=MAX_ORDER).all(|h| observability(h, d, &[1.0; 5]) >= 0.2)
        })
}

fn truth(max_arcsec: f64, max_sigma_arcsec: f64) -> impl Strategy<Value = Truth> {
    (
        series(max_arcsec),
        series(max_arcsec),
        deltas(),
        0.0..=max_sigma_arcsec,
        any::<u64>(),
    )
        .prop_map(|(a, b, deltas, sigma, seed)| Truth {
            a,
            b,
            deltas,
            sigma: sigma / ARCSEC_PER_RAD,
            seed,
        })
}

/// Normal deviates from a seed (xorshift and Box–Muller): the same seed gives the same noise.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
    }
}

/// The samples `(t, x, y, session)` of a run, before any transformation.
fn samples(truth: &Truth) -> Vec<(f64, f64, f64, u32)> {
    let mut noise = Noise(truth.seed | 1);
    let mut out = Vec::new();
    let mut t = 0.0;
    for (k, &delta) in truth.deltas.iter().enumerate() {
        let start = 0.7 * k as f64;
        for n in 0..PER_REV * REVS {
            let theta = start + TAU * n as f64 / PER_REV as f64;
            let x = theta + truth.a.eval(theta) + truth.sigma * noise.normal();
            let tb = theta - delta;
            let y = tb + truth.b.eval(tb) + truth.sigma * noise.normal();
            out.push((t, x, y, k as u32));
            t += 0.001;
        }
    }
    out
}

/// Calibrates from `samples`, each passed through `f(x, y) -> (A's reading, B's reading)`.
fn calibrate(samples: &[(f64, f64, f64, u32)], f: impl Fn(f64, f64) -> (f64, f64)) -> Calibration {
    let mut csrr = Csrr::new(CsrrOptions {
        max_order: Some(MAX_ORDER),
        points: Some(POINTS),
        bins_per_rev: 4096,
        segments: SegmentOptions {
            use_marks: true,
            ..SegmentOptions::default()
        },
        ..CsrrOptions::default()
    });
    for &(t, x, y, k) in samples {
        let (a, b) = f(x, y);
        csrr.push(t, a, b, Some(k));
    }
    let cal = csrr.finish().expect("calibration");
    assert!(
        cal.excluded.is_empty(),
        "excluded orders: {:?}",
        cal.excluded
    );
    cal
}

/// Largest difference of two maps' values, arcsec.
fn map_diff(a: &ErrorMap, b: &ErrorMap) -> f64 {
    assert_eq!(a.len(), b.len());
    a.values()
        .iter()
        .zip(b.values())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        * ARCSEC_PER_RAD
}

/// Largest difference, arcsec, between `s(r)` and `t(r − shift)` over a fine grid of `r`.
fn shifted_diff(s: &FourierSeries, t: &FourierSeries, shift: f64) -> f64 {
    (0..1440)
        .map(|i| {
            let r = TAU * i as f64 / 1440.0;
            (s.eval(r) - t.eval(r - shift)).abs()
        })
        .fold(0.0, f64::max)
        * ARCSEC_PER_RAD
}

/// Largest coefficient difference of two series over orders `1..=MAX_ORDER`, arcsec.
fn coef_diff(s: &FourierSeries, t: &FourierSeries, scale: f64) -> f64 {
    let (hs, ht) = (s.harmonics(), t.harmonics());
    (0..MAX_ORDER)
        .map(|i| {
            let (a, b) = hs[i].coefficients();
            let (c, d) = ht[i].coefficients();
            (a - scale * c).hypot(b - scale * d)
        })
        .fold(0.0, f64::max)
        * ARCSEC_PER_RAD
}

fn true_angle(cal: &Calibration) -> &(FourierSeries, FourierSeries) {
    cal.true_angle_series.as_ref().expect("joint method")
}

proptest! {
    #![proptest_config(cases(24))]

    /// A constant offset on one sensor's readings is absorbed by the sessions' rotations: the
    /// other sensor's map does not change, its own only relabels its argument (`e(r) → e(r − c)`).
    #[test]
    fn a_reading_offset_changes_no_map(truth in truth(60.0, 0.3), c in -3.0..3.0f64) {
        let s = samples(&truth);
        let base = calibrate(&s, |x, y| (x, y));
        let on_b = calibrate(&s, |x, y| (x, y + c));
        let d = [map_diff(&on_b.a, &base.a), shifted_diff(&on_b.b_series, &base.b_series, c)];
        prop_assert!(d.iter().all(|&d| d < SHIFT_TOL), "offset on B: {d:?}");
        let on_a = calibrate(&s, |x, y| (x + c, y));
        let d = [map_diff(&on_a.b, &base.b), shifted_diff(&on_a.a_series, &base.a_series, c)];
        prop_assert!(d.iter().all(|&d| d < SHIFT_TOL), "offset on A: {d:?}");
        // The relative rotations between sessions do not change.
        for (p, q) in on_a.sessions.iter().zip(&base.sessions) {
            prop_assert!((p.relative_rotation - q.relative_rotation).abs() * ARCSEC_PER_RAD < 1e-4);
        }
    }

    /// Turning the whole log by φ (both sensors) shifts both maps by φ and changes nothing else.
    #[test]
    fn rotating_the_log_shifts_the_maps(truth in truth(60.0, 0.3), phi in -7.0..7.0f64) {
        let s = samples(&truth);
        let base = calibrate(&s, |x, y| (x, y));
        let turned = calibrate(&s, |x, y| (x + phi, y + phi));
        let d = [shifted_diff(&turned.a_series, &base.a_series, phi), shifted_diff(&turned.b_series, &base.b_series, phi)];
        prop_assert!(d.iter().all(|&d| d < SHIFT_TOL), "{d:?}");
        let (r0, r1) = (base.residual_rms.unwrap(), turned.residual_rms.unwrap());
        prop_assert!((r0 - r1).abs() * ARCSEC_PER_RAD < SHIFT_TOL, "residual {r0} vs {r1}");
        for (p, q) in turned.sessions.iter().zip(&base.sessions) {
            prop_assert!((p.relative_rotation - q.relative_rotation).abs() * ARCSEC_PER_RAD < 1e-4);
        }
    }

    /// Swapping the two sensors swaps their maps and negates the relative rotations.
    #[test]
    fn swapping_the_sensors_swaps_the_maps(truth in truth(60.0, 0.3)) {
        let s = samples(&truth);
        let base = calibrate(&s, |x, y| (x, y));
        let swapped = calibrate(&s, |x, y| (y, x));
        prop_assert!(map_diff(&swapped.a, &base.b) < 1e-4);
        prop_assert!(map_diff(&swapped.b, &base.a) < 1e-4);
        for (p, q) in swapped.sessions.iter().zip(&base.sessions) {
            let sum = calib_core::angle::wrap_pi(p.relative_rotation + q.relative_rotation);
            prop_assert!(sum.abs() * ARCSEC_PER_RAD < 1e-4);
        }
    }

    /// A truth made of observable orders only is recovered to within the noise: each
    /// coefficient within 5 standard deviations of its estimate (plus 0.001″ of numerics).
    #[test]
    fn observable_truth_is_recovered_within_the_noise(truth in truth(200.0, 1.0)) {
        let cal = calibrate(&samples(&truth), |x, y| (x, y));
        let (ea, eb) = true_angle(&cal);
        // Noise σ on each of x and y: σ√2 on x − y; a coefficient from N samples has standard
        // deviation √2·σ_d/√N, amplified at most 1/√0.2 by observability.
        let n = (PER_REV * REVS * truth.deltas.len()) as f64;
        let sd = (2.0f64).sqrt() * truth.sigma * (2.0f64).sqrt() / n.sqrt() / 0.2f64.sqrt();
        let tol = 5.0 * sd * ARCSEC_PER_RAD + 1e-3;
        prop_assert!(coef_diff(ea, &truth.a, 1.0) < tol, "A {} ≥ {tol}", coef_diff(ea, &truth.a, 1.0));
        prop_assert!(coef_diff(eb, &truth.b, 1.0) < tol, "B {} ≥ {tol}", coef_diff(eb, &truth.b, 1.0));
    }

    /// Scaling the reading noise down by s scales the fit's residual and the maps' departure
    /// from the truth down by s (the same noise draws, scaled).
    #[test]
    fn scaling_the_noise_scales_the_residual(truth in truth(60.0, 0.0), seed in any::<u64>(), s in 0.05..1.0f64) {
        let sigma = 0.5 / ARCSEC_PER_RAD;
        let noisy = Truth { sigma, seed, ..truth.clone() };
        let quiet = Truth { sigma: s * sigma, ..noisy.clone() };
        let full = calibrate(&samples(&noisy), |x, y| (x, y));
        let scaled = calibrate(&samples(&quiet), |x, y| (x, y));
        let (r1, rs) = (full.residual_rms.unwrap(), scaled.residual_rms.unwrap());
        prop_assert!((rs - s * r1).abs() <= 0.01 * s * r1, "residual {rs} vs s·{r1}");
        let (fa, _) = true_angle(&full);
        let (sa, _) = true_angle(&scaled);
        let (d1, ds) = (coef_diff(fa, &truth.a, 1.0), coef_diff(sa, &truth.a, 1.0));
        prop_assert!((ds - s * d1).abs() <= 0.02 * s * d1 + 1e-4, "departure {ds} vs s·{d1}");
    }
}

proptest! {
    #![proptest_config(cases(256))]

    /// Harmonic analysis followed by synthesis returns the map: exactly for an odd number of
    /// points, and for an even number once the Nyquist term (which has no phase) is removed.
    #[test]
    fn analysis_then_synthesis_returns_the_map(values in prop::collection::vec(-1e-3..1e-3f64, 2..400)) {
        let n = values.len();
        let nyquist = if n % 2 == 0 {
            values.iter().enumerate().map(|(i, v)| if i % 2 == 0 { *v } else { -*v }).sum::<f64>() / n as f64
        } else {
            0.0
        };
        let band_limited: Vec<f64> = values
            .iter()
            .enumerate()
            .map(|(i, v)| v - nyquist * if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let map = ErrorMap::new(band_limited);
        let back = ErrorMap::from_series(&map.series(), n);
        prop_assert!(map_diff(&back, &map) < 1e-9);
    }

    /// Synthesis followed by analysis returns the series, for any order below half the grid.
    #[test]
    fn synthesis_then_analysis_returns_the_series(
        terms in prop::collection::vec((0.0..500.0f64, -180.0..180.0f64), 1..40),
        extra in 1usize..50,
    ) {
        let max_order = terms.len();
        let harmonics: Vec<Harmonic> = terms
            .iter()
            .enumerate()
            .map(|(i, &(a, p))| Harmonic::from_arcsec_deg(i + 1, a, p))
            .collect();
        let series = FourierSeries::from_harmonics(&harmonics, max_order);
        let n = 2 * max_order + extra;
        let back = ErrorMap::from_series(&series, n).series();
        for (h, g) in series.harmonics().iter().zip(back.harmonics()) {
            let ((a, b), (c, d)) = (h.coefficients(), g.coefficients());
            prop_assert!((a - c).hypot(b - d) * ARCSEC_PER_RAD < 1e-9);
        }
    }
}

/// Shift-angle readings of a polygon with `beta` (arcsec, zero sum) on an encoder with `alpha`
/// (arcsec, a function of degrees): the full matrix at S = 0, start face 1 at the other shifts.
fn shift_readings(
    faces: usize,
    shifts: &[f64],
    alpha: &dyn Fn(f64) -> f64,
    beta: &[f64],
    setup: &[f64],
) -> Readings {
    let pitch = 360.0 / faces as f64;
    let mut u = setup.iter().cycle();
    let shifts = shifts
        .iter()
        .enumerate()
        .map(|(s, &shift_deg)| {
            let starts: Vec<usize> = if s == 0 {
                (1..=faces).collect()
            } else {
                vec![1]
            };
            let rows = starts
                .into_iter()
                .map(|j| {
                    let setup = *u.next().expect("cycle");
                    StartFaceRow {
                        start_face: j,
                        readings_arcsec: (0..faces)
                            .map(|i| {
                                let pitch_sum: f64 =
                                    (0..=i).map(|m| beta[(j - 1 + m) % faces]).sum();
                                alpha(i as f64 * pitch + shift_deg) + pitch_sum + setup
                            })
                            .collect(),
                    }
                })
                .collect();
            Shift { shift_deg, rows }
        })
        .collect();
    Readings::new(faces, shifts).expect("valid readings")
}

/// Faces, shifts (degrees), the encoder's harmonics `(order, arcsec, phase°)`, the polygon's
/// pitch deviations and setup errors (arcsec).
type ShiftCase = (usize, Vec<f64>, Vec<(usize, f64, f64)>, Vec<f64>, Vec<f64>);

fn shift_case() -> impl Strategy<Value = ShiftCase> {
    (5usize..16).prop_flat_map(|faces| {
        (
            Just(faces),
            prop::collection::btree_set(1u32..1000, 0..4).prop_map(move |s| {
                let pitch = 360.0 / faces as f64;
                let mut v = vec![0.0];
                v.extend(s.into_iter().map(|k| pitch * k as f64 / 1000.0));
                v
            }),
            prop::collection::vec((1usize..faces, 0.0..5.0f64, -180.0..180.0f64), 1..4),
            prop::collection::vec(-2.0..2.0f64, faces),
            prop::collection::vec(-3.0..3.0f64, 1..8),
        )
    })
}

proptest! {
    #![proptest_config(cases(128))]

    /// Noise-free readings give back the polygon and the encoder's error (its orders below the
    /// number of faces, which are all visible) with either method.
    #[test]
    fn shift_angle_recovers_a_noise_free_truth((faces, shifts, alpha, beta, setup) in shift_case()) {
        let mean = beta.iter().sum::<f64>() / faces as f64;
        let beta: Vec<f64> = beta.iter().map(|b| b - mean).collect();
        let alpha_fn = |deg: f64| alpha.iter().map(|&(h, a, p)| a * (h as f64 * deg.to_radians() + p.to_radians()).cos()).sum::<f64>();
        let readings = shift_readings(faces, &shifts, &alpha_fn, &beta, &setup);
        for method in [shift_angle::Method::Joint, shift_angle::Method::Paper] {
            let r = shift_angle::calibrate(&readings, method).expect("calibrate");
            for (f, b) in r.polygon.iter().zip(&beta) {
                prop_assert!((f.pitch_deviation_arcsec - b).abs() < 1e-9);
            }
            for p in &r.points {
                prop_assert!((p.error_arcsec - alpha_fn(p.angle_deg)).abs() < 1e-9, "{method:?} at {}°", p.angle_deg);
            }
        }
    }

    /// A constant added to one start-face row (a different setup error) changes only that row's
    /// setup error, by the constant: neither the encoder's map nor the polygon moves.
    #[test]
    fn a_rows_offset_moves_only_its_setup_error(
        (faces, shifts, alpha, beta, setup) in shift_case(),
        c in -50.0..50.0f64,
        row in any::<prop::sample::Index>(),
    ) {
        let alpha_fn = |deg: f64| alpha.iter().map(|&(h, a, p)| a * (h as f64 * deg.to_radians() + p.to_radians()).cos()).sum::<f64>();
        let readings = shift_readings(faces, &shifts, &alpha_fn, &beta, &setup);
        let base = shift_angle::calibrate(&readings, shift_angle::Method::Joint).expect("calibrate");
        let mut moved: Vec<Shift> = readings.shifts().to_vec();
        let rows: Vec<(usize, usize)> = moved
            .iter()
            .enumerate()
            .flat_map(|(s, sh)| (0..sh.rows.len()).map(move |r| (s, r)))
            .collect();
        let (s, r) = rows[row.index(rows.len())];
        moved[s].rows[r].readings_arcsec.iter_mut().for_each(|v| *v += c);
        let changed = shift_angle::calibrate(&Readings::new(faces, moved).expect("valid"), shift_angle::Method::Joint)
            .expect("calibrate");
        for (p, q) in changed.points.iter().zip(&base.points) {
            prop_assert!((p.error_arcsec - q.error_arcsec).abs() < 1e-9);
        }
        for (p, q) in changed.polygon.iter().zip(&base.polygon) {
            prop_assert!((p.pitch_deviation_arcsec - q.pitch_deviation_arcsec).abs() < 1e-9);
        }
        let start_face = readings.shifts()[s].rows[r].start_face;
        for (p, q) in changed.setup_errors.iter().zip(&base.setup_errors) {
            let expected = if p.shift_deg == shifts[s] && p.start_face == start_face { c } else { 0.0 };
            prop_assert!((p.value_arcsec - q.value_arcsec - expected).abs() < 1e-9);
        }
    }
}

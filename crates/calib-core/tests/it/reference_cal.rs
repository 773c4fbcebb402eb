//! Reference calibration against synthetic runs with a known truth (fixed seed): the map, the
//! ISO 230-2 figures, the uncertainty, and the refusals.

use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{ReferenceCal, ReferenceError, ReferenceOptions, Targets};
use calib_core::{FourierSeries, Harmonic};
use std::f64::consts::TAU;

const AS: f64 = 1.0 / ARCSEC_PER_RAD;

/// A small deterministic Gaussian-ish noise source (sum of 4 uniforms, unit variance).
struct Noise(u64);
impl Noise {
    fn next(&mut self) -> f64 {
        let mut s = 0.0;
        for _ in 0..4 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            s += (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        s * 3f64.sqrt()
    }
}

fn dut_error() -> FourierSeries {
    FourierSeries::from_harmonics(
        &[
            Harmonic::from_arcsec_deg(8, 20.0, 30.0),
            Harmonic::from_arcsec_deg(16, 6.0, -45.0),
            Harmonic::from_arcsec_deg(1, 3.0, 100.0),
        ],
        16,
    )
}

fn ref_error() -> FourierSeries {
    FourierSeries::from_harmonics(
        &[
            Harmonic::from_arcsec_deg(1, 0.45, 30.0),
            Harmonic::from_arcsec_deg(2, 0.30, -50.0),
        ],
        2,
    )
}

/// Pushes a run at 1000 Hz: `revs_up` revolutions forward at 1 r/s, a stop, `revs_down` back.
/// The DUT reads `θ + e(θ) ± backlash/2` (+ going up), the reference `ref_of(θ)`; both with
/// `noise` arcsec of noise, wrapped to [0, 2π).
fn run(
    revs_up: f64,
    revs_down: f64,
    backlash: f64,
    noise: f64,
    ref_of: impl Fn(f64) -> f64,
) -> ReferenceCal {
    // ISO 230-2 at every grid point (the default is 20 targets), so M is the map's p-p.
    let mut cal = ReferenceCal::new(ReferenceOptions {
        targets: Targets::Count(3600),
        ..ReferenceOptions::default()
    });
    let (e, mut rng) = (dut_error(), Noise(7));
    let mut t = 0.0;
    let mut push = |cal: &mut ReferenceCal, th: f64, sign: f64| {
        let dut = th + e.eval(th) + sign * backlash * AS / 2.0 + noise * AS * rng.next();
        let r = ref_of(th) + noise * AS * rng.next();
        cal.push(t, dut.rem_euclid(TAU), r.rem_euclid(TAU));
        t += 0.001;
    };
    let n_up = (revs_up * 1000.0) as usize;
    let start = 0.3;
    for k in 0..=n_up {
        push(&mut cal, start + TAU * k as f64 / 1000.0, 1.0);
    }
    let top = start + TAU * n_up as f64 / 1000.0;
    for _ in 0..200 {
        push(&mut cal, top, 1.0);
    }
    let n_down = (revs_down * 1000.0) as usize;
    for k in 1..=n_down {
        push(&mut cal, top - TAU * k as f64 / 1000.0, -1.0);
    }
    cal
}

fn with_ref_error(th: f64) -> f64 {
    th + ref_error().eval(th)
}

/// Largest |map − (e_DUT − e_ref)| over the grid, arcsec, both zero-mean. The truth is evaluated
/// at the grid angle as a true angle; the map is a function of the DUT's reading, which differs
/// from the true angle by e (≤ 29″), moving the truth by at most e·|de/dθ| ≈ 29″ · 232″/rad ≈
/// 0.03″.
fn max_error(map: &TableMap) -> f64 {
    let (e, r) = (dut_error(), ref_error());
    let truth: Vec<f64> = (0..map.len())
        .map(|i| e.eval(map.grid_angle(i)) - r.eval(map.grid_angle(i)))
        .collect();
    let mean = truth.iter().sum::<f64>() / truth.len() as f64;
    map.values()
        .iter()
        .zip(&truth)
        .map(|(m, t)| (m - (t - mean)).abs() * ARCSEC_PER_RAD)
        .fold(0.0, f64::max)
}

/// Tolerance of the map against the truth: noise 0.05″ on each reading, interpolated at each
/// crossing, averaged over 10 passes (5 per direction) → σ ≈ 0.05·√2/√10 ≈ 0.022″, and the worst
/// of 3600 points is ~4σ ≈ 0.09″; plus ≤ 0.03″ from reading vs true angle, ≤ 0.003″ of linear
/// interpolation (order 16, 0.36° spacing: 16²·0.0063²/8·6″). A lost harmonic or sign error
/// would be ≥ 0.3″ off (the smallest truth term).
const TOL_ARCSEC: f64 = 0.15;

#[test]
fn bidirectional_run_gives_the_error_difference_and_the_reversal() {
    let cal = run(5.0, 5.0, 4.0, 0.05, with_ref_error).finish().unwrap();
    let err = max_error(&cal.map);
    println!("bidirectional: max |map − truth| = {err:.4}″");
    assert!(err < TOL_ARCSEC, "{err}″");
    assert_eq!(cal.map.len(), 3600);
    assert!((cal.revolutions - 10.0).abs() < 0.01, "{}", cal.revolutions);
    // The first degree after the start and after the reversal is approach: points there have one
    // pass fewer.
    assert_eq!(cal.min_passes, (4, 4));
    let iso = cal.iso;
    let a = |v: Option<f64>| v.unwrap() * ARCSEC_PER_RAD;
    // Backlash 4″: the DUT reads 2″ high going up and 2″ low going down.
    let b_mean = a(iso.mean_reversal);
    assert!((b_mean - 4.0).abs() < 0.01, "B̄ = {b_mean}″");
    // B = max |B_i|: 4″ plus the noise of a difference of two 5-pass means (σ ≈ 0.03″).
    let b = a(iso.reversal);
    assert!(b > 4.0 && b < 4.2, "B = {b}″");
    // Repeatability 4s: s of one pass ≈ 0.05″·√2·(0.82 for the interpolation mix) ≈ 0.06″, and
    // the max over 3600 points of 5-pass estimates runs up to ~2× that.
    let r = a(iso.repeatability_up);
    assert!(r > 0.2 && r < 0.7, "R↑ = {r}″");
    // E↑ is the p-p of e_DUT − e_ref, E adds the reversal, A adds ±2s on top.
    let pp = cal.map.peak_to_peak() * ARCSEC_PER_RAD;
    let (e_up, e, m, acc) = (
        a(iso.systematic_up),
        a(iso.systematic),
        a(iso.mean_bidirectional),
        a(iso.accuracy),
    );
    assert!((m - pp).abs() < 1e-9, "M = {m}, p-p = {pp}");
    assert!((e_up - pp).abs() < 0.3, "E↑ = {e_up}, p-p = {pp}");
    assert!((e - (pp + 4.0)).abs() < 0.5, "E = {e}, p-p = {pp}");
    assert!(acc > e && acc < e + 1.0, "A = {acc}, E = {e}");
    // u: the standard error of a 10-pass mean (≈ 0.02″), no reference uncertainty given.
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    assert!(u_max > 0.005 && u_max < 0.06, "u = {u_max}″");
    // 4 passes near the start and the reversal: ISO 230-2's 5 are not met there. And one speed
    // per direction with a 4″ reversal: latency and backlash read the same (issue 24's warning).
    assert_eq!(cal.warnings.len(), 3, "{:?}", cal.warnings);
    assert_eq!(
        cal.warnings
            .iter()
            .filter(|w| w.contains("only 4 pass(es)"))
            .count(),
        2
    );
    assert!(cal.warnings.iter().any(|w| w.contains("either a latency")));
}

#[test]
fn reference_uncertainty_is_combined_in_quadrature() {
    let opts = ReferenceOptions {
        reference_u: 0.5 * AS,
        ..ReferenceOptions::default()
    };
    let mut cal = ReferenceCal::new(opts);
    let e = dut_error();
    for k in 0..=3000 {
        let th = TAU * k as f64 / 1000.0;
        cal.push(k as f64 * 0.001, (th + e.eval(th)).rem_euclid(TAU), th);
    }
    let cal = cal.finish().unwrap();
    // Noise-free: the passes agree, u is the reference's alone — except that the last step of
    // the run is interpolated linearly (no sample after it), which differs from the cubic by up
    // to (16·0.0063)²/8·6″ ≈ 0.008″ in one pass: √(0.5² + 0.008²) − 0.5 < 1e-4″.
    for u in &cal.u {
        assert!(
            (u * ARCSEC_PER_RAD - 0.5).abs() < 1e-4,
            "{}",
            u * ARCSEC_PER_RAD
        );
    }
    // 3 revolutions, less the approach (first degree) at the start.
    assert_eq!(cal.min_passes, (2, 0));
    assert!(cal.iso.reversal.is_none());
    assert!(
        cal.warnings
            .iter()
            .any(|w| w.contains("ISO 230-2 asks for 5"))
    );
}

#[test]
fn one_direction_only_matches_the_truth() {
    let cal = run(5.0, 0.0, 0.0, 0.05, with_ref_error).finish().unwrap();
    let err = max_error(&cal.map);
    println!("forward only: max |map − truth| = {err:.4}″");
    // 5 passes instead of 10: σ ≈ 0.03″, worst of 3600 ≈ 0.13″.
    assert!(err < 0.2, "{err}″");
    assert!(cal.iso.repeatability.is_some());
    assert_eq!(cal.iso.repeatability, cal.iso.repeatability_up);
}

#[test]
fn a_still_reference_is_refused() {
    let r = run(3.0, 0.0, 0.0, 0.05, |_| 1.0).finish();
    assert!(
        matches!(r, Err(ReferenceError::ReferenceStill { .. })),
        "{r:?}"
    );
}

#[test]
fn a_reference_turning_the_other_way_is_refused() {
    let r = run(3.0, 0.0, 0.0, 0.05, |th| -th).finish();
    assert!(
        matches!(r, Err(ReferenceError::NotRepeating { .. })),
        "{r:?}"
    );
    // Less than a turn one way: no reading crossed twice, so the change over the run decides.
    let r = run(0.8, 0.0, 0.0, 0.05, |th| -th).finish();
    assert!(
        matches!(r, Err(ReferenceError::NotFollowing { .. })),
        "{r:?}"
    );
}

#[test]
fn a_reference_on_a_slightly_faster_shaft_is_refused() {
    // 1 % faster: 3.6° per revolution, 18° over 5 revolutions.
    let r = run(5.0, 0.0, 0.0, 0.05, |th| 1.01 * th).finish();
    assert!(
        matches!(r, Err(ReferenceError::NotRepeating { spread_deg, .. }) if spread_deg > 10.0),
        "{r:?}"
    );
}

#[test]
fn less_than_a_revolution_gives_a_range_map() {
    // 0.8 revolution one way from 0.3 rad: the range from the end of the 1° approach to the last
    // grid point crossed, matching the truth there.
    let cal = run(0.8, 0.0, 0.0, 0.05, with_ref_error).finish().unwrap();
    let TableMap::Range(m) = &cal.map else {
        panic!("{:?}", cal.map.range())
    };
    let (lo, hi) = (0.3 + 1f64.to_radians(), 0.3 + 0.8 * TAU);
    assert!(
        (m.start() - lo).abs() <= 0.1f64.to_radians(),
        "{}",
        m.start()
    );
    assert!((m.end() - hi).abs() <= 0.1f64.to_radians(), "{}", m.end());
    // One pass: σ ≈ 0.05·√2″ ≈ 0.07″ per point, the worst of ~2900 ≈ 4σ.
    let err = max_error(&cal.map);
    println!("0.8 revolution: max |map − truth| = {err:.4}″");
    assert!(err < 0.4, "{err}″");
    // Half a revolution up and half down: half the circle, both directions.
    let cal = run(0.5, 0.5, 0.0, 0.05, with_ref_error).finish().unwrap();
    assert!(cal.map.range().is_some());
    assert_eq!((cal.min_passes.0, cal.min_passes.1), (1, 1));
}

#[test]
fn garbage_samples_do_not_panic() {
    let mut cal = ReferenceCal::new(ReferenceOptions::default());
    for (t, a, b) in [
        (f64::NAN, 0.0, 0.0),
        (0.0, f64::INFINITY, 0.0),
        (0.0, 0.0, 0.0),
        (0.0, 1.0, 1.0),
        (-1.0, 1e300, -1e300),
        (1.0, 2.0, f64::NAN),
    ] {
        cal.push(t, a, b);
    }
    assert!(cal.finish().is_err());
    assert!(
        ReferenceCal::new(ReferenceOptions::default())
            .finish()
            .is_err()
    );
}

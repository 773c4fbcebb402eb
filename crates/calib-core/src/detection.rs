//! What a self-calibration tested and did not find, and what its fit leaves unexplained — the
//! rules every self-calibration (CSRR's joint and paper methods, multi-head, spin-down) applies
//! to its result, so that an empty map never looks certain (issue 30).
//!
//! # The floor of u
//! A method that keeps only the orders standing above the noise by a significance rule
//! (`|x|²/v > T`, [`crate::tdr::significance_threshold`]) cannot see an order of amplitude below
//! its **detection limit** `A_det = sqrt(T·v_min)`, `v_min` the variance of each coefficient at
//! the best-determined order tested ([`detection_limit`]). One harmonic below it, its amplitude
//! anywhere in `[0, A_det]` (rectangular) and its phase unknown, has the standard uncertainty
//! `A_det/√6` over the circle (`E[a²]/2 = A_det²/6`): [`detection_floor`]. The map's `u` is never
//! below it ([`apply_floor`]): the floor is listed in the budget by name ([`DETECTION_FLOOR`])
//! and applied as a lower bound, not added in quadrature (where the kept orders' noise already
//! exceeds it, it is inside `u`).
//!
//! # A map with no kept order
//! says so ([`empty_map_warning`]): "no order above the noise: the map is zero within u = …″".
//!
//! # A residual above the noise
//! The fit's residual per sample is compared with a noise figure the method measures without the
//! map's model (CSRR: the change of `a − b` from one revolution to the next; multi-head: the
//! differences' scatter within the bins; spin-down: the readings' third differences in time).
//! Above [`RESIDUAL_WARN_RATIO`] times that figure the maps lack structure larger than the noise
//! itself: a warning naming both figures ([`residual_warning`]). Above [`RESIDUAL_FAIL_RATIO`]
//! with no order kept the (zero) map explains none of the data: the method refuses the result
//! ([`Verdict::Unexplained`]).

use crate::angle::ARCSEC_PER_RAD;
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty};

/// The name of the floor of a self-calibration's `u` in its budget ([`detection_floor`]).
pub const DETECTION_FLOOR: &str =
    "floor: detection limit of the orders tested (u is never below it)";

/// The detection limit, as an amplitude (radians), of a significance rule with chi-square
/// threshold `threshold` whose best-determined order's coefficients each have the variance
/// `v_min` (rad²): `sqrt(threshold·v_min)`; 0 where no variance is known.
pub fn detection_limit(threshold: f64, v_min: f64) -> f64 {
    if v_min.is_finite() && v_min > 0.0 {
        (threshold * v_min).sqrt()
    } else {
        0.0
    }
}

/// The floor of a map's `u` for what the significance rule tested and did not find, `A_det/√6`
/// (module docs).
pub fn detection_floor(detection_limit: f64) -> f64 {
    detection_limit / 6f64.sqrt()
}

/// `u` raised to at least `floor` at every point, the floor listed in the budget as
/// [`DETECTION_FLOOR`] (nothing changes where `floor` is 0).
pub fn apply_floor(mut combined: MapUncertainty, floor: f64) -> MapUncertainty {
    if floor > 0.0 {
        combined.u.iter_mut().for_each(|u| *u = u.max(floor));
        combined.components.push(MapComponent {
            name: DETECTION_FLOOR.into(),
            evaluation: Evaluation::TypeB,
            u: vec![floor],
        });
    }
    combined
}

/// The warning of a map with no order kept: `u` its largest standard uncertainty, `tested`
/// the orders tested (e.g. `1–86`), `detection_limit` an amplitude; radians.
pub fn empty_map_warning(u: f64, tested: &str, detection_limit: f64) -> String {
    format!(
        "no order above the noise: the map is zero within u = {:.4}″ (orders {tested} tested, none kept; \
         the detection limit is {:.4}″ of amplitude)",
        u * ARCSEC_PER_RAD,
        detection_limit * ARCSEC_PER_RAD
    )
}

/// How far a fit's residual is from the noise the method measured without its model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Within [`RESIDUAL_WARN_RATIO`] of the noise, or below [`RESIDUAL_FLOOR_ARCSEC`].
    Explained,
    /// Above it by this ratio: a warning.
    Above(f64),
    /// Above [`RESIDUAL_FAIL_RATIO`] times the noise with no order kept: the map cannot
    /// explain the data.
    Unexplained(f64),
}

/// A fit residual above this many times the model-free noise figure is warned about. The noise
/// figures are a little above the readings' noise (they hold some of the motion's or the
/// error's curvature between samples), and the residual of a fit that explains the data is that
/// noise: ≈ 1×. Three times is structure the map lacks that is larger than the noise itself.
pub const RESIDUAL_WARN_RATIO: f64 = 3.0;

/// A fit residual above this many times the noise figure, with no order kept, is an error
/// (exit 1): the map (zero) explains none of what the data hold beyond the noise — e.g. every
/// CSRR session at a multiple of the same angle with the error all in the orders this makes
/// blind. Where some orders are kept the map holds those and the excess is a warning.
pub const RESIDUAL_FAIL_RATIO: f64 = 10.0;

/// A residual below this, arcsec per sample, explains the data whatever the ratio (noise-free
/// simulations, where the noise figure is only rounding).
pub const RESIDUAL_FLOOR_ARCSEC: f64 = 0.01;

/// The verdict on a fit residual `residual` against the noise figure `noise` (both radians per
/// sample), `kept` whether the map holds any order.
pub fn residual_verdict(residual: f64, noise: f64, kept: bool) -> Verdict {
    if residual * ARCSEC_PER_RAD < RESIDUAL_FLOOR_ARCSEC {
        return Verdict::Explained;
    }
    let ratio = residual / noise.max(f64::MIN_POSITIVE);
    if ratio > RESIDUAL_FAIL_RATIO && !kept {
        Verdict::Unexplained(ratio)
    } else if ratio > RESIDUAL_WARN_RATIO {
        Verdict::Above(ratio)
    } else {
        Verdict::Explained
    }
}

/// The warning of a residual `ratio` times the noise: `residual` and `noise` per sample
/// (radians), `noise_is` what the noise figure measures, `maps` what the result holds ("the
/// map", "the maps"), `causes` what most likely lacks.
pub fn residual_warning(
    residual: f64,
    noise: f64,
    ratio: f64,
    noise_is: &str,
    maps: &str,
    causes: &str,
) -> String {
    format!(
        "the fit leaves {:.4}″ RMS per sample where {noise_is} {:.4}″ ({ratio:.1}× the noise): {maps} not \
         explain all of the data ({causes})",
        residual * ARCSEC_PER_RAD,
        noise * ARCSEC_PER_RAD
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_verdict_follows_the_ratios() {
        let arcsec = |a: f64| a / ARCSEC_PER_RAD;
        assert_eq!(
            residual_verdict(arcsec(0.005), arcsec(0.0001), false),
            Verdict::Explained
        );
        assert_eq!(
            residual_verdict(arcsec(0.2), arcsec(0.1), false),
            Verdict::Explained
        );
        assert!(matches!(
            residual_verdict(arcsec(0.5), arcsec(0.1), false),
            Verdict::Above(r) if (r - 5.0).abs() < 1e-9
        ));
        assert!(matches!(
            residual_verdict(arcsec(5.0), arcsec(0.1), true),
            Verdict::Above(_)
        ));
        assert!(matches!(
            residual_verdict(arcsec(5.0), arcsec(0.1), false),
            Verdict::Unexplained(_)
        ));
    }

    /// One harmonic of amplitude uniform in `[0, A]`: `E[a²/2] = A²/6`.
    #[test]
    fn the_floor_is_a_harmonic_below_the_limit() {
        let a = 6f64.sqrt();
        assert!((detection_floor(a) - 1.0).abs() < 1e-12);
        assert_eq!(detection_limit(10.0, 0.0), 0.0);
        assert!((detection_limit(4.0, 0.25) - 1.0).abs() < 1e-12);
        let u = MapUncertainty::combine(
            4,
            vec![MapComponent {
                name: "noise".into(),
                evaluation: Evaluation::TypeA,
                u: vec![0.5],
            }],
        );
        let floored = apply_floor(u, 1.0);
        assert!(floored.u.iter().all(|&u| u == 1.0));
        assert!(floored.components.iter().any(|c| c.name == DETECTION_FLOOR));
    }
}

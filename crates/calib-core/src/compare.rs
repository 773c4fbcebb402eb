//! Comparison of two calibrations of the same sensor by the En number (the shift-angle paper's
//! section 3.2 and eq. 13; ISO/IEC 17043 for the En number).
//!
//! At each angle of the first map, the second map is evaluated (periodic linear interpolation
//! between its nearest points where its grid differs; exactly where an angle coincides within
//! 1e-9°) and
//!
//! ```text
//! En = |x₁ − x₂| / sqrt(U₁² + U₂²)
//! ```
//!
//! with `U₁`, `U₂` the expanded uncertainties. The paper's eq. 13 prints `sqrt(U_shift² − U_self²)`
//! with a minus sign; that is a misprint (it would be undefined whenever the second calibration
//! is the more uncertain, and the uncertainties of two independent results add in quadrature).
//! calib uses the standard plus sign. `|En| ≤ 1` means the two results agree within their
//! uncertainties.
//!
//! # What it cannot see
//! Both maps see only what their methods see (a shift-angle map is blind to orders that are
//! multiples of the polygon's faces): the comparison cannot reveal an error both are blind to.
//! Linear interpolation of the second map adds an error of up to `h²Δθ²/8` times a harmonic's
//! amplitude, `Δθ` the second map's spacing; compare on a common grid where you can.

/// One point of a map to compare.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapPoint {
    /// Angle, degrees.
    pub angle_deg: f64,
    /// Error, arcsec.
    pub error_arcsec: f64,
    /// Expanded uncertainty `U` of the error, arcsec.
    pub expanded_uncertainty_arcsec: f64,
}

/// One compared point.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ComparedPoint {
    /// The first map's angle, degrees.
    pub angle_deg: f64,
    /// The first map's error, arcsec.
    pub error1_arcsec: f64,
    /// The second map's error there, arcsec.
    pub error2_arcsec: f64,
    /// `error1 − error2` (less the mean difference if asked), arcsec.
    pub difference_arcsec: f64,
    /// `U₁`, arcsec.
    pub expanded1_arcsec: f64,
    /// `U₂` there, arcsec.
    pub expanded2_arcsec: f64,
    /// The En number.
    pub en: f64,
    /// Whether the second map was interpolated here.
    pub interpolated: bool,
}

/// The result of [`compare`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// Every compared point, in the first map's order.
    pub points: Vec<ComparedPoint>,
    /// The mean of `error1 − error2` before any removal, arcsec.
    pub mean_difference_arcsec: f64,
    /// Whether that mean was removed from the differences.
    pub mean_removed: bool,
    /// Largest `|difference|`, arcsec.
    pub max_abs_difference_arcsec: f64,
    /// RMS of the differences, arcsec.
    pub rms_difference_arcsec: f64,
    /// Largest En.
    pub max_en: f64,
    /// Points with En > 1.
    pub failures: usize,
}

/// Why two maps cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CompareError {
    /// A map has no points.
    #[error("map {map} has no points")]
    Empty {
        /// 1 or 2.
        map: u8,
    },
    /// Two points of the second map at the same angle.
    #[error(
        "map 2 has two points at {angle_deg}° (modulo 360°): it cannot be interpolated; remove one"
    )]
    DuplicateAngle {
        /// The angle.
        angle_deg: f64,
    },
    /// A value that is not finite, or a negative uncertainty.
    #[error("map {map}, point at {angle_deg}°: {message}")]
    BadValue {
        /// 1 or 2.
        map: u8,
        /// The angle.
        angle_deg: f64,
        /// What is wrong.
        message: String,
    },
    /// Both uncertainties are zero where the maps differ.
    #[error(
        "at {angle_deg}° both expanded uncertainties are 0: En is undefined; give the uncertainties"
    )]
    ZeroUncertainty {
        /// The angle.
        angle_deg: f64,
    },
}

fn check(map: u8, points: &[MapPoint]) -> Result<(), CompareError> {
    if points.is_empty() {
        return Err(CompareError::Empty { map });
    }
    for p in points {
        let bad = |message: &str| CompareError::BadValue {
            map,
            angle_deg: p.angle_deg,
            message: message.into(),
        };
        if !(p.angle_deg.is_finite() && p.error_arcsec.is_finite()) {
            return Err(bad("angle and error must be finite numbers"));
        }
        if !(p.expanded_uncertainty_arcsec.is_finite() && p.expanded_uncertainty_arcsec >= 0.0) {
            return Err(bad("the expanded uncertainty must be a finite number ≥ 0"));
        }
    }
    Ok(())
}

/// Compares `map1` with `map2` at `map1`'s angles; `remove_mean` subtracts the mean difference
/// first (maps are defined up to a constant: self-calibration cannot see an offset).
pub fn compare(
    map1: &[MapPoint],
    map2: &[MapPoint],
    remove_mean: bool,
) -> Result<Comparison, CompareError> {
    check(1, map1)?;
    check(2, map2)?;
    let mut sorted: Vec<MapPoint> = map2
        .iter()
        .map(|p| MapPoint {
            angle_deg: p.angle_deg.rem_euclid(360.0),
            ..*p
        })
        .collect();
    sorted.sort_by(|a, b| a.angle_deg.total_cmp(&b.angle_deg));
    const SAME: f64 = 1e-9;
    let wrap_dup = sorted.len() > 1
        && (sorted[0].angle_deg + 360.0 - sorted[sorted.len() - 1].angle_deg) < SAME;
    if let Some(w) = sorted
        .windows(2)
        .find(|w| w[1].angle_deg - w[0].angle_deg < SAME)
    {
        return Err(CompareError::DuplicateAngle {
            angle_deg: w[0].angle_deg,
        });
    }
    if wrap_dup {
        return Err(CompareError::DuplicateAngle {
            angle_deg: sorted[0].angle_deg,
        });
    }
    let mut points = Vec::with_capacity(map1.len());
    for p in map1 {
        let (x2, u2, interpolated) = interpolate(&sorted, p.angle_deg.rem_euclid(360.0));
        points.push(ComparedPoint {
            angle_deg: p.angle_deg,
            error1_arcsec: p.error_arcsec,
            error2_arcsec: x2,
            difference_arcsec: p.error_arcsec - x2,
            expanded1_arcsec: p.expanded_uncertainty_arcsec,
            expanded2_arcsec: u2,
            en: 0.0,
            interpolated,
        });
    }
    let mean = points.iter().map(|p| p.difference_arcsec).sum::<f64>() / points.len() as f64;
    let (mut max_abs, mut ss, mut max_en, mut failures) = (0.0f64, 0.0, 0.0f64, 0);
    for p in &mut points {
        if remove_mean {
            p.difference_arcsec -= mean;
        }
        let d = p.difference_arcsec;
        let scale = p.expanded1_arcsec.hypot(p.expanded2_arcsec);
        p.en = if scale > 0.0 {
            d.abs() / scale
        } else if d == 0.0 {
            0.0
        } else {
            return Err(CompareError::ZeroUncertainty {
                angle_deg: p.angle_deg,
            });
        };
        max_abs = max_abs.max(d.abs());
        ss += d * d;
        max_en = max_en.max(p.en);
        failures += usize::from(p.en > 1.0);
    }
    Ok(Comparison {
        rms_difference_arcsec: (ss / points.len() as f64).sqrt(),
        points,
        mean_difference_arcsec: mean,
        mean_removed: remove_mean,
        max_abs_difference_arcsec: max_abs,
        max_en,
        failures,
    })
}

/// `(error, U, interpolated)` of the sorted, wrapped map at `angle` in `[0, 360)`.
fn interpolate(sorted: &[MapPoint], angle: f64) -> (f64, f64, bool) {
    const SAME: f64 = 1e-9;
    let n = sorted.len();
    // Index of the first point at or after `angle`.
    let hi = sorted.partition_point(|p| p.angle_deg < angle - SAME);
    for idx in [hi % n, (hi + n - 1) % n] {
        let d = (sorted[idx].angle_deg - angle).rem_euclid(360.0);
        if d < SAME || 360.0 - d < SAME {
            let p = sorted[idx];
            return (p.error_arcsec, p.expanded_uncertainty_arcsec, false);
        }
    }
    if n == 1 {
        return (
            sorted[0].error_arcsec,
            sorted[0].expanded_uncertainty_arcsec,
            true,
        );
    }
    let (lo, hi) = ((hi + n - 1) % n, hi % n);
    let (a, b) = (sorted[lo], sorted[hi]);
    let span = (b.angle_deg - a.angle_deg).rem_euclid(360.0);
    let f = (angle - a.angle_deg).rem_euclid(360.0) / span;
    let lerp = |x: f64, y: f64| x + (y - x) * f;
    (
        lerp(a.error_arcsec, b.error_arcsec),
        lerp(a.expanded_uncertainty_arcsec, b.expanded_uncertainty_arcsec),
        true,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(step: f64, offset: f64, f: impl Fn(f64) -> f64, u: f64) -> Vec<MapPoint> {
        let n = (360.0 / step).round() as usize;
        (0..n)
            .map(|i| {
                let a = i as f64 * step + offset;
                MapPoint {
                    angle_deg: a,
                    error_arcsec: f(a),
                    expanded_uncertainty_arcsec: u,
                }
            })
            .collect()
    }

    #[test]
    fn identical_grids_are_compared_pointwise() {
        let m1 = map(1.0, 0.0, |a| (a.to_radians() * 2.0).sin(), 0.15);
        let m2 = map(1.0, 0.0, |a| (a.to_radians() * 2.0).sin() + 0.1, 0.02);
        let c = compare(&m1, &m2, false).unwrap();
        assert!(c.points.iter().all(|p| !p.interpolated));
        // En = 0.1 / sqrt(0.15² + 0.02²) = 0.6608.
        assert!((c.max_en - 0.1 / 0.15f64.hypot(0.02)).abs() < 1e-9);
        assert_eq!(c.failures, 0);
        let c = compare(&m1, &m2, true).unwrap();
        assert!(c.max_abs_difference_arcsec < 1e-12);
        assert!((c.mean_difference_arcsec + 0.1).abs() < 1e-12);
    }

    #[test]
    fn different_grids_are_interpolated_periodically() {
        let f = |a: f64| a.to_radians().cos();
        let m1 = map(7.5, 3.0, f, 0.1);
        let m2 = map(1.0, 0.5, f, 0.1);
        let c = compare(&m1, &m2, false).unwrap();
        // Linear interpolation error ≤ h²Δθ²/8 · A = (π/180)²/8 = 3.81e-5 for h = 1, A = 1.
        assert!(
            c.max_abs_difference_arcsec < 3.9e-5,
            "{}",
            c.max_abs_difference_arcsec
        );
        // Across the wrap: 359.5 → 0.5 (m1 has 358.5 … but evaluate at 0.0 explicitly).
        let at0 = [MapPoint {
            angle_deg: 0.0,
            error_arcsec: 1.0,
            expanded_uncertainty_arcsec: 0.1,
        }];
        let c = compare(&at0, &m2, false).unwrap();
        assert!(c.points[0].difference_arcsec.abs() < 3.9e-5);
    }

    #[test]
    fn failures_are_counted_and_bad_maps_rejected() {
        let m1 = map(90.0, 0.0, |a| if a == 90.0 { 1.0 } else { 0.0 }, 0.3);
        let m2 = map(90.0, 0.0, |_| 0.0, 0.4);
        let c = compare(&m1, &m2, false).unwrap();
        assert_eq!(c.failures, 1);
        assert!((c.max_en - 2.0).abs() < 1e-12);
        let dup = [m2[0], m2[0]];
        assert!(matches!(
            compare(&m1, &dup, false),
            Err(CompareError::DuplicateAngle { .. })
        ));
        assert!(matches!(
            compare(&[], &m2, false),
            Err(CompareError::Empty { map: 1 })
        ));
        let zero = map(90.0, 0.0, |_| 0.0, 0.0);
        let one = map(90.0, 0.0, |_| 1.0, 0.0);
        assert!(matches!(
            compare(&zero, &one, false),
            Err(CompareError::ZeroUncertainty { .. })
        ));
    }
}

//! The report section of a shift-angle calibration ([`crate::shift_angle`]): the checks of the
//! result (grid, outlying reading, redundancy, budget against fit) and its figures.

use super::{ChannelReport, Details, ReportSection};
use crate::angle::ARCSEC_PER_RAD;
use crate::error_map::ErrorMap;
use crate::shift_angle::{
    Method, PolygonFace, Readings, Residuals, SetupError, ShiftAngleResult, SinFit,
};
use crate::uncertainty::BudgetResult;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A reading whose residual exceeds this many σ̂ is named in a warning: for Gaussian noise a
/// 5σ residual has a chance below 1e-6 per reading, so it is almost surely a misreading.
pub const OUTLIER_SIGMAS: f64 = 5.0;

/// `details` of `calib shift-angle`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ShiftAngleDetails {
    /// The estimator: `joint` or `paper`.
    pub estimator: Method,
    /// Faces of the polygon, n.
    pub faces: usize,
    /// 360°/n.
    pub pitch_deg: f64,
    /// Autocollimator readings used.
    pub readings: usize,
    /// The shifts, degrees, increasing.
    pub shifts_deg: Vec<f64>,
    /// The harmonic orders of the encoder error this method cannot see.
    pub blind_harmonic_orders: String,
    /// Pitch deviation of every face.
    pub polygon: Vec<PolygonFace>,
    /// Setup error of every start face at every shift.
    pub setup_errors: Vec<SetupError>,
    /// The fit's residuals.
    pub residuals: Residuals,
    /// The sin-fit check of the paper's section 3.1.
    pub sin_fit: SinFit,
    /// Largest standard uncertainty of a point from the fit, arcsec (where the fit gives any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_u_fit_arcsec: Option<f64>,
    /// The uncertainty budget, where one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<BudgetResult>,
}

impl ShiftAngleResult {
    /// The encoder's map as a uniform whole-turn grid, where the points lie on `i·360°/N` (then
    /// it has harmonics); `None` when the shifts are not evenly spaced over one pitch.
    pub fn uniform_map(&self) -> Option<ErrorMap> {
        let n = self.points.len();
        let step = 360.0 / n as f64;
        let uniform = self
            .points
            .iter()
            .enumerate()
            .all(|(i, p)| (p.angle_deg - i as f64 * step).abs() < 1e-6);
        uniform.then(|| {
            ErrorMap::new(
                self.points
                    .iter()
                    .map(|p| p.error_arcsec / ARCSEC_PER_RAD)
                    .collect(),
            )
        })
    }

    /// The largest standard uncertainty of a point from the fit, arcsec (`None` where the fit
    /// gives none: the paper's method, or no redundancy).
    pub fn max_u_fit(&self) -> Option<f64> {
        self.points
            .iter()
            .filter_map(|p| p.u_arcsec)
            .fold(None, |m: Option<f64>, u| Some(m.map_or(u, |m| m.max(u))))
    }

    /// What the user should know about the result, with the `budget` where one was given: a
    /// map without harmonics (not a uniform grid), a reading beyond [`OUTLIER_SIGMAS`], no
    /// redundancy, no uncertainties at all, or a fit noisier than the budget.
    pub fn warnings(&self, budget: Option<&BudgetResult>) -> Vec<String> {
        let mut warnings = Vec::new();
        if self.uniform_map().is_none() {
            warnings.push(
                "the measured angles are not a uniform grid over the circle (shifts not evenly spaced over one pitch): no harmonics in the report".to_string(),
            );
        }
        let res = &self.residuals;
        if let Some(sigma) = res.sigma_arcsec
            && res.max_abs_arcsec > OUTLIER_SIGMAS * sigma
        {
            warnings.push(format!(
                "the reading at shift {}°, start face {}, step {} deviates from the fit by {:.4}″ ({:.1} σ̂): check it",
                super::trimmed(res.max_at_shift_deg, 9),
                res.max_at_start_face,
                res.max_at_step,
                res.max_abs_arcsec,
                res.max_abs_arcsec / sigma
            ));
        }
        if res.dof == 0 {
            warnings.push(
                "the readings have no redundancy (0 residual degrees of freedom): no fit uncertainties and no check of the measurement".into(),
            );
        }
        match (budget, self.max_u_fit()) {
            (None, None) => warnings.push(
                "encoder.csv has no uncertainties: the paper's method gives none per point; give an uncertainty budget (the `budget` option) or use the joint method".into(),
            ),
            (Some(b), Some(u)) if u > b.combined_standard_uncertainty => warnings.push(format!(
                "the fit's standard uncertainty reaches {u:.4}″, more than the budget's u_c = {:.4}″: the budget may underestimate the measurement's noise",
                b.combined_standard_uncertainty
            )),
            _ => {}
        }
        warnings
    }

    /// The report section of the calibration from `readings`, with the `budget` where one was
    /// given: the encoder's map as channel `encoder` (table `encoder.csv`).
    pub fn report_section(
        &self,
        readings: &Readings,
        budget: Option<&BudgetResult>,
    ) -> ReportSection {
        let channel = match self.uniform_map() {
            Some(map) => ChannelReport::of_map("encoder.csv", &map, 10),
            None => {
                let values: Vec<f64> = self.points.iter().map(|p| p.error_arcsec).collect();
                ChannelReport::of_values("encoder.csv", &values)
            }
        };
        let n = readings.faces();
        let details = ShiftAngleDetails {
            estimator: self.method,
            faces: n,
            pitch_deg: 360.0 / n as f64,
            readings: readings.len(),
            shifts_deg: readings.shifts().iter().map(|s| s.shift_deg).collect(),
            blind_harmonic_orders: format!(
                "multiples of {n} (orders {n}, {}, …): removed by the closure of each shift (eq. 2)",
                2 * n
            ),
            polygon: self.polygon.clone(),
            setup_errors: self.setup_errors.clone(),
            residuals: self.residuals,
            sin_fit: self.sin_fit.clone(),
            max_u_fit_arcsec: self.max_u_fit(),
            budget: budget.cloned(),
        };
        ReportSection {
            method: "shift-angle",
            channels: BTreeMap::from([("encoder".to_string(), channel)]),
            sessions: Vec::new(),
            warnings: self.warnings(budget),
            details: Details::ShiftAngle(details),
        }
    }
}

/// The spread of a set of values, as a summary shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Smallest value.
    pub min: f64,
    /// Largest value.
    pub max: f64,
    /// Root mean square.
    pub rms: f64,
}

impl Spread {
    /// The spread of `values`; `None` for none.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Self> {
        let (mut min, mut max, mut sum2, mut n) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0usize);
        for v in values {
            min = min.min(v);
            max = max.max(v);
            sum2 += v * v;
            n += 1;
        }
        (n > 0).then(|| Spread {
            min,
            max,
            rms: (sum2 / n as f64).sqrt(),
        })
    }
}

impl ShiftAngleResult {
    /// The spread of the polygon's pitch deviations β, arcsec.
    pub fn pitch_spread(&self) -> Option<Spread> {
        Spread::of(self.polygon.iter().map(|f| f.pitch_deviation_arcsec))
    }
    /// The spread of the points' standard uncertainties from the fit, arcsec.
    pub fn point_u_spread(&self) -> Option<Spread> {
        Spread::of(self.points.iter().filter_map(|p| p.u_arcsec))
    }
    /// The spread of the faces' standard uncertainties from the fit, arcsec.
    pub fn face_u_spread(&self) -> Option<Spread> {
        Spread::of(self.polygon.iter().filter_map(|f| f.u_arcsec))
    }
    /// The largest |U_fit − U| of the sin-fit check, arcsec.
    pub fn sin_fit_worst_difference(&self) -> f64 {
        self.sin_fit
            .shifts
            .iter()
            .map(|x| x.difference_arcsec.abs())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shift_angle::{Shift, StartFaceRow, calibrate};

    /// Readings of a 6-face polygon at `shifts_deg`, every start face at every shift: the
    /// encoder errs by 1.2″·sin(2θ + 0.4) + 0.5″·cos θ, the faces by a fixed pattern, each start
    /// face has its own setup error, and every reading gets a deterministic ±`noise` (a
    /// sequence with no structure at the method's orders) plus `outlier` at shift 0, face 2,
    /// step 3.
    fn readings(shifts_deg: &[f64], noise: f64, outlier: f64) -> Readings {
        let n = 6;
        let beta: Vec<f64> = [0.3, -0.6, 0.0, 0.6, -0.3, 0.0].to_vec();
        let alpha = |deg: f64| {
            let t = deg.to_radians();
            1.2 * (2.0 * t + 0.4).sin() + 0.5 * t.cos()
        };
        let mut k = 0u32;
        let mut jitter = move || {
            k = k.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            noise * ((k >> 16) as f64 / 32_768.0 - 1.0)
        };
        let shifts = shifts_deg
            .iter()
            .map(|&s| Shift {
                shift_deg: s,
                rows: (1..=n)
                    .map(|j| StartFaceRow {
                        start_face: j,
                        readings_arcsec: (0..n)
                            .map(|i| {
                                let faces: f64 = (0..=i).map(|m| beta[(j - 1 + m) % n]).sum();
                                let bad = if s == 0.0 && j == 2 && i == 2 {
                                    outlier
                                } else {
                                    0.0
                                };
                                alpha(i as f64 * 60.0 + s) + faces + 0.1 * j as f64 + jitter() + bad
                            })
                            .collect(),
                    })
                    .collect(),
            })
            .collect();
        Readings::new(n, shifts).unwrap()
    }

    #[test]
    fn a_clean_uniform_measurement_has_harmonics_and_no_warnings() {
        let r = readings(&[0.0, 20.0, 40.0], 0.01, 0.0);
        let result = calibrate(&r, Method::Joint).unwrap();
        let section = result.report_section(&r, None);
        assert!(section.warnings.is_empty(), "{:?}", section.warnings);
        let enc = &section.channels["encoder"];
        assert_eq!(enc.points, 18);
        // The map holds orders 1 and 2 (1.2″ at order 2, the largest).
        assert_eq!(enc.harmonics[0].order, 2);
        assert!((enc.harmonics[0].amplitude_arcsec - 1.2).abs() < 0.05);
        assert!(result.max_u_fit().is_some());
    }

    #[test]
    fn the_checks_are_warned_about() {
        // One reading 1″ off with 0.01″ noise: far beyond 5σ̂, named by its place.
        let r = readings(&[0.0, 20.0, 40.0], 0.01, 1.0);
        let w = calibrate(&r, Method::Joint).unwrap().warnings(None);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("shift 0°, start face 2, step 3"), "{w:?}");

        // Shifts not spread evenly over the 60° pitch: no harmonics, figures from the values.
        let r = readings(&[0.0, 5.0], 0.01, 0.0);
        let result = calibrate(&r, Method::Joint).unwrap();
        let section = result.report_section(&r, None);
        assert!(section.warnings[0].contains("not a uniform grid"));
        let enc = &section.channels["encoder"];
        assert!(enc.harmonics.is_empty());
        let values: Vec<f64> = result.points.iter().map(|p| p.error_arcsec).collect();
        let max = values.iter().copied().fold(f64::MIN, f64::max);
        let min = values.iter().copied().fold(f64::MAX, f64::min);
        assert_eq!(enc.peak_to_peak_arcsec, max - min);

        // The paper's method gives no uncertainty per point, and without a budget none at all.
        let r = readings(&[0.0, 20.0, 40.0], 0.01, 0.0);
        let w = calibrate(&r, Method::Paper).unwrap().warnings(None);
        assert!(
            w.iter().any(|w| w.contains("has no uncertainties")),
            "{w:?}"
        );
    }
}

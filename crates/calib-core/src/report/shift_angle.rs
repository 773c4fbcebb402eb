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

/// Degrees with at most 9 decimals, trailing zeros trimmed (shifts are usually whole or tenths).
pub fn degrees_text(v: f64) -> String {
    let s = format!("{v:.9}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
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
                degrees_text(res.max_at_shift_deg),
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
                "encoder.csv has no uncertainties: the paper's method gives none per point; pass --budget FILE or use the joint method".into(),
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

//! Planning a shift-angle cross-calibration: which shifts and readings give every angle of the
//! encoder a point, what the method cannot see, and the GUM budget that follows.
//!
//! Units as in [`crate::shift_angle`], the method planned: angles in degrees, errors and
//! uncertainties in arcseconds (the paper's and the readings' units).
//!
//! # The layout (the shift-angle paper, Hsieh, Watanabe, Hsu 2022, eq. 3 and Table 1)
//! An `n`-face polygon puts a point every pitch `P = 360°/n`; a shift `S` moves the whole set.
//! Shifts `S = k·d`, `k = 0 … P/d − 1`, give a point every `d` degrees. The paper's design, planned
//! here: the full `n × n` matrix of start faces at `S = 0` (it determines the polygon's pitch
//! deviations, Table 2) and start face 1 at every other shift: `n² + (P/d − 1)·n` readings (912
//! for its 24 faces and `d = 1°`).
//!
//! # What it cannot see
//! Eq. 2 removes from every shift the encoder's harmonics of orders `n, 2n, …` (the module docs of
//! [`crate::shift_angle`]): those orders are blind whatever the shifts. The points `d` apart
//! resolve orders up to `180°/d`; higher orders alias onto lower ones.
//!
//! # The uncertainty
//! Two figures, each the method's own:
//! - the joint fit's `u` of every point for readings of noise `σ` each,
//!   [`crate::shift_angle::joint_point_uncertainty`] — what `calib shift-angle` reports without
//!   a budget (with `σ̂` from the residuals);
//! - the GUM budget of the paper's Table 3 ([`Table3`]), evaluated by
//!   [`crate::uncertainty::evaluate`] as `calib shift-angle --budget` evaluates a budget file,
//!   with the sensitivity of the pitch deviations `1/n − 8/(9n²)` (Estler, eq. 11) for the
//!   planned polygon and the repeatabilities divided by `√r` for `r` repeats.

use crate::shift_angle::{Readings, Shift, ShiftAngleError, StartFaceRow, joint_point_uncertainty};
use crate::uncertainty::{
    Budget, BudgetResult, Component, Distribution, UncertaintyError, dof_from_relative_uncertainty,
    estler_sensitivity, evaluate,
};

/// Why a shift-angle plan cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShiftAnglePlanError {
    /// A value out of its range.
    #[error("{what} must be {expected}, not {value}")]
    Invalid {
        /// The setting.
        what: &'static str,
        /// What was given.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The point spacing does not divide the pitch.
    #[error(
        "a point every {spacing_deg}° does not divide the pitch {pitch_deg}° into equal shifts; choose a divisor of it, e.g. {suggestion}°"
    )]
    Spacing {
        /// The spacing asked for.
        spacing_deg: f64,
        /// The polygon's pitch.
        pitch_deg: f64,
        /// The nearest divisor.
        suggestion: f64,
    },
    /// The method's layout check failed.
    #[error(transparent)]
    Layout(#[from] ShiftAngleError),
    /// The budget could not be evaluated.
    #[error(transparent)]
    Budget(#[from] UncertaintyError),
}

/// The inputs of the paper's Table 3 budget, arcseconds (section 3.3's figures by default).
#[derive(Debug, Clone, PartialEq)]
pub struct Table3 {
    /// Standard deviation of one autocollimator reading (0.13″, the largest of the paper's).
    pub repeatability: f64,
    /// Repeats averaged into each reading (6).
    pub repeats: usize,
    /// Standard deviation of one pitch-deviation determination (0.12″).
    pub pitch_repeatability: f64,
    /// Autocollimator's resolution (0.001″), rectangular over ± half of it.
    pub autocollimator_resolution: f64,
    /// Autocollimator's calibration, expanded uncertainty at k = 2 (0.01″).
    pub autocollimator_calibration: f64,
    /// Autocollimator's angle error, half-width of a rectangular distribution (0.07″).
    pub autocollimator_error: f64,
    /// Encoder's resolution (0.04″), rectangular over ± half of it.
    pub encoder_resolution: f64,
    /// Residual of the setup-error calculation, half-width (0.00005″).
    pub setup_residual: f64,
    /// Polygon's misalignment (0.05″), rectangular over ± half of it.
    pub polygon_setup: f64,
}

impl Default for Table3 {
    fn default() -> Self {
        Table3 {
            repeatability: 0.13,
            repeats: 6,
            pitch_repeatability: 0.12,
            autocollimator_resolution: 0.001,
            autocollimator_calibration: 0.01,
            autocollimator_error: 0.07,
            encoder_resolution: 0.04,
            setup_residual: 0.00005,
            polygon_setup: 0.05,
        }
    }
}

/// Relative uncertainty of the Type B components, as the paper's 50 degrees of freedom (GUM
/// G.4.2: `ν = ½·0.1⁻² = 50`).
const TYPE_B_RELATIVE_UNCERTAINTY: f64 = 0.10;

impl Table3 {
    /// The budget for an `faces`-face polygon, component by component as Table 3 (and
    /// `testdata/shift-angle/derived.toml`) has it.
    pub fn budget(&self, faces: usize) -> Budget {
        let r = self.repeats as f64;
        let type_b = dof_from_relative_uncertainty(TYPE_B_RELATIVE_UNCERTAINTY);
        let rect = |half_width: f64| half_width / Distribution::Rectangular.divisor();
        let component = |name: &str, u: f64, sensitivity: f64, dof: f64| Component {
            name: name.into(),
            standard_uncertainty: u,
            sensitivity,
            dof,
        };
        Budget {
            level: 0.95,
            components: vec![
                component(
                    "Repeatability of angle error measurement",
                    self.repeatability / r.sqrt(),
                    1.0,
                    r - 1.0,
                ),
                component(
                    "Resolution of the autocollimator",
                    rect(self.autocollimator_resolution / 2.0),
                    1.0,
                    type_b,
                ),
                component(
                    "Traceability of the autocollimator",
                    self.autocollimator_calibration / 2.0,
                    1.0,
                    type_b,
                ),
                component(
                    "Angle error of the autocollimator",
                    rect(self.autocollimator_error),
                    1.0,
                    type_b,
                ),
                component(
                    "Resolution of the rotary encoder",
                    rect(self.encoder_resolution / 2.0),
                    1.0,
                    type_b,
                ),
                component(
                    "Residual setup error calculation",
                    rect(self.setup_residual),
                    1.0,
                    type_b,
                ),
                component(
                    "Repeatability of the pitch angle deviation",
                    self.pitch_repeatability / r.sqrt(),
                    estler_sensitivity(faces),
                    r - 1.0,
                ),
                component(
                    "Setup error of the polygon",
                    rect(self.polygon_setup / 2.0),
                    1.0,
                    type_b,
                ),
            ],
        }
    }

    /// The noise of one reading, the mean of the repeats: `repeatability/√r`.
    pub fn reading_noise(&self) -> f64 {
        self.repeatability / (self.repeats as f64).sqrt()
    }
}

/// A planned shift-angle measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftAnglePlan {
    /// Polygon faces `n`.
    pub faces: usize,
    /// The shifts `S`, degrees, ascending from 0.
    pub shifts_deg: Vec<f64>,
    /// The readings' layout: the full matrix at `S = 0`, start face 1 elsewhere (values 0).
    pub layout: Readings,
    /// Orders the method cannot see: the multiples of `n` up to `max_order`.
    pub blind_orders: Vec<usize>,
    /// The highest order the points resolve, `180°/d`.
    pub max_order: usize,
    /// The joint fit's `u` of every point (shift-major, then step), arcsec.
    pub u_fit: Vec<f64>,
    /// The noise of one reading used for `u_fit`, arcsec.
    pub reading_noise: f64,
    /// Table 3's budget for this polygon, evaluated.
    pub budget: BudgetResult,
    /// The budget's inputs.
    pub table3: Table3,
}

impl ShiftAnglePlan {
    /// Readings in all.
    pub fn readings(&self) -> usize {
        self.layout.len()
    }

    /// Encoder points in all (`n` per shift).
    pub fn points(&self) -> usize {
        self.u_fit.len()
    }

    /// The largest of the fit's point uncertainties, arcsec.
    pub fn max_u_fit(&self) -> f64 {
        self.u_fit.iter().copied().fold(0.0, f64::max)
    }

    /// The RMS of the fit's point uncertainties, arcsec.
    pub fn rms_u_fit(&self) -> f64 {
        (self.u_fit.iter().map(|u| u * u).sum::<f64>() / self.u_fit.len() as f64).sqrt()
    }
}

/// The plan for an `faces`-face polygon with a point every `spacing_deg` degrees and the budget
/// inputs `table3`.
pub fn plan(
    faces: usize,
    spacing_deg: f64,
    table3: Table3,
) -> Result<ShiftAnglePlan, ShiftAnglePlanError> {
    let invalid = |what, value: f64, expected| ShiftAnglePlanError::Invalid {
        what,
        value,
        expected,
    };
    if !(3..=360).contains(&faces) {
        return Err(invalid("the faces", faces as f64, "in 3..=360"));
    }
    let pitch = 360.0 / faces as f64;
    if !(spacing_deg.is_finite() && spacing_deg > 0.0 && spacing_deg <= pitch) {
        return Err(invalid(
            "the point spacing",
            spacing_deg,
            "in (0°, the pitch 360°/faces]",
        ));
    }
    let per_pitch = pitch / spacing_deg;
    let shifts = per_pitch.round() as usize;
    if (per_pitch - shifts as f64).abs() > 1e-9 * per_pitch || shifts > 3600 {
        return Err(ShiftAnglePlanError::Spacing {
            spacing_deg,
            pitch_deg: pitch,
            suggestion: pitch / (per_pitch.round().clamp(1.0, 3600.0)),
        });
    }
    if table3.repeats < 2 {
        return Err(invalid(
            "the repeats",
            table3.repeats as f64,
            "at least 2 (the repeatability needs a standard deviation)",
        ));
    }
    let inputs = [
        table3.repeatability,
        table3.pitch_repeatability,
        table3.autocollimator_resolution,
        table3.autocollimator_calibration,
        table3.autocollimator_error,
        table3.encoder_resolution,
        table3.setup_residual,
        table3.polygon_setup,
    ];
    if let Some(&v) = inputs.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(invalid("every budget input", v, "finite and ≥ 0 arcsec"));
    }
    let step = pitch / shifts as f64;
    let shifts_deg: Vec<f64> = (0..shifts).map(|k| k as f64 * step).collect();
    let row = |start_face| StartFaceRow {
        start_face,
        readings_arcsec: vec![0.0; faces],
    };
    let layout = Readings::new(
        faces,
        shifts_deg
            .iter()
            .enumerate()
            .map(|(k, &s)| Shift {
                shift_deg: s,
                rows: if k == 0 {
                    (1..=faces).map(row).collect()
                } else {
                    vec![row(1)]
                },
            })
            .collect(),
    )?;
    let reading_noise = table3.reading_noise();
    let u_fit = joint_point_uncertainty(&layout, reading_noise)?
        .into_iter()
        .flatten()
        .collect();
    let max_order = faces * shifts / 2;
    let budget = evaluate(&table3.budget(faces))?;
    Ok(ShiftAnglePlan {
        faces,
        shifts_deg,
        layout,
        blind_orders: (1..=max_order / faces).map(|k| k * faces).collect(),
        max_order,
        u_fit,
        reading_noise,
        budget,
        table3,
    })
}

#[cfg(test)]
// The tests print the figures docs/plan.md quotes (run with --nocapture).
#[allow(clippy::print_stderr)]
mod tests {
    use super::*;
    use crate::shift_angle::{Method, calibrate};
    use crate::simulate::rng::Rng;

    /// The paper's measurement: 24 faces, a point every degree — shifts 0…14°, 912 readings
    /// (testdata/shift-angle/readings.csv has them), orders 24, 48, … blind, and the budget of
    /// Table 3 from section 3.3's inputs: u_c 0.0694″, ν_eff 14, k 2.145, U 0.149″ (the figures
    /// `calib shift-angle --budget testdata/shift-angle/derived.toml` prints).
    #[test]
    fn the_papers_24_face_shifts() {
        let p = plan(24, 1.0, Table3::default()).unwrap();
        assert_eq!(p.shifts_deg, (0..15).map(f64::from).collect::<Vec<_>>());
        assert_eq!(p.readings(), 912);
        assert_eq!(p.points(), 360);
        assert_eq!(p.max_order, 180);
        assert_eq!(p.blind_orders, vec![24, 48, 72, 96, 120, 144, 168]);
        let b = &p.budget;
        assert!(
            (b.combined_standard_uncertainty - 0.0694).abs() < 5e-5,
            "{b:?}"
        );
        assert_eq!(b.effective_dof, Some(14));
        assert!((b.coverage_factor - 2.145).abs() < 5e-4);
        assert!((b.expanded_uncertainty - 0.149).abs() < 5e-4);
        eprintln!(
            "24 faces, 1°: u_fit max {:.4}″ RMS {:.4}″ for {:.4}″ per reading",
            p.max_u_fit(),
            p.rms_u_fit(),
            p.reading_noise
        );
    }

    /// Readings of a known encoder, polygon and setup errors with noise `sigma` on the planned
    /// layout; the encoder errs by `harmonics` (order, amplitude″).
    fn simulated(p: &ShiftAnglePlan, harmonics: &[(usize, f64)], sigma: f64) -> Readings {
        let n = p.faces;
        let pitch = 360.0 / n as f64;
        let mut rng = Rng::new(5, 0);
        let beta: Vec<f64> = (0..n).map(|_| 0.5 * rng.normal()).collect();
        let mean = beta.iter().sum::<f64>() / n as f64;
        let alpha = |deg: f64| -> f64 {
            harmonics
                .iter()
                .map(|&(h, a)| a * (h as f64 * deg.to_radians() + 0.3 * h as f64).cos())
                .sum()
        };
        let shifts = p
            .layout
            .shifts()
            .iter()
            .map(|s| Shift {
                shift_deg: s.shift_deg,
                rows: s
                    .rows
                    .iter()
                    .map(|row| {
                        let setup = 2.0 * rng.normal();
                        let mut sum = 0.0;
                        StartFaceRow {
                            start_face: row.start_face,
                            readings_arcsec: (0..n)
                                .map(|i| {
                                    sum += beta[(row.start_face - 1 + i) % n] - mean;
                                    alpha(i as f64 * pitch + s.shift_deg)
                                        + sum
                                        + setup
                                        + sigma * rng.normal()
                                })
                                .collect(),
                        }
                    })
                    .collect(),
            })
            .collect();
        Readings::new(n, shifts).unwrap()
    }

    /// The planned `u` of every point against the `u` the joint method reports on readings
    /// simulated on the planned layout (its σ̂ from the residuals, 576 − 71 − … degrees of
    /// freedom, so within a few percent): the factor 1.5, on the paper's 24 faces and on
    /// a 12-face polygon at 2°. And the blind orders: an order-n error is missing from the
    /// method's map, an order below n is recovered.
    #[test]
    fn planned_u_and_blind_orders_match_the_method_on_simulated_readings() {
        for (faces, spacing) in [(24, 1.0), (12, 2.0)] {
            let p = plan(faces, spacing, Table3::default()).unwrap();
            let sigma = p.reading_noise;
            let readings = simulated(&p, &[(2, 1.0), (faces, 0.5), (7, 0.3)], sigma);
            let result = calibrate(&readings, Method::Joint).unwrap();
            let u: Vec<f64> = result.points.iter().map(|q| q.u_arcsec.unwrap()).collect();
            let rms = (u.iter().map(|u| u * u).sum::<f64>() / u.len() as f64).sqrt();
            let ratio = p.rms_u_fit() / rms;
            eprintln!(
                "{faces} faces, {spacing}°: planned u RMS {:.4}″, method {:.4}″",
                p.rms_u_fit(),
                rms
            );
            assert!((1.0 / 1.5..1.5).contains(&ratio), "ratio {ratio}");
            // The map against the truth without the blind order: errors within 4u; with it,
            // the order-n amplitude 0.5″ (≫ 4u) would show.
            for q in &result.points {
                let x = q.angle_deg.to_radians();
                let seen = (2.0 * x + 0.6).cos() + 0.3 * (7.0 * x + 2.1).cos();
                let u = q.u_arcsec.unwrap();
                assert!((q.error_arcsec - seen).abs() < 4.0 * u + 1e-9, "{q:?}");
            }
            assert!(p.blind_orders.iter().all(|h| h % faces == 0));
            assert_eq!(p.blind_orders[0], faces);
        }
    }

    #[test]
    fn bad_layouts_are_refused() {
        assert!(matches!(
            plan(24, 0.7, Table3::default()),
            Err(ShiftAnglePlanError::Spacing { .. })
        ));
        assert!(plan(2, 1.0, Table3::default()).is_err());
        assert!(plan(24, 16.0, Table3::default()).is_err());
        let one = Table3 {
            repeats: 1,
            ..Table3::default()
        };
        assert!(plan(24, 1.0, one).is_err());
    }
}

//! The report section of a spin-down (TDR) calibration ([`crate::tdr`]).

use super::{
    AfterCorrection, ChannelReport, Details, ReportSection, UncertaintyReport, arcsec, table_name,
};
use crate::harmonics::HarmonicReport;
use crate::tdr::{DrivenRun, FALSE_ORDER_PROBABILITY, TdrCalibration, significance_threshold};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `details` of `calib tdr`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TdrDetails {
    /// The fitted motion of the coast.
    pub motion: MotionReport,
    /// Revolutions of the coast used.
    pub revolutions: f64,
    /// Samples of the coast used.
    pub samples_used: usize,
    /// Highest order tested.
    pub max_order: usize,
    /// Which orders were kept, and by what rule.
    pub orders: OrdersReport,
    /// RMS of the fit's residual, arcsec.
    pub residual_rms_arcsec: f64,
    /// The readings' noise per sample from their third differences in time (no model), what
    /// the residual is judged against, arcsec.
    #[serde(default)]
    pub noise_rms_arcsec: f64,
    /// The standard uncertainty of the map, by channel.
    pub uncertainty: BTreeMap<String, UncertaintyReport>,
    /// Angle-dependent drag: separated from the map, or what could not be.
    pub drag: DragReport,
    /// The check against a reference channel, where one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<TdrReferenceReport>,
    /// A driven run's passes and the motor's orders; absent for a coast.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driven: Option<DrivenReport>,
    /// How the channels were aligned on one clock, where anything was interpolated or dropped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment: Option<super::Alignment>,
    /// How the log was read where the reader decided something the user did not say (copies
    /// dropped, a time unit chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading: Option<super::Reading>,
}

/// The coast's motion: a Chebyshev series of time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MotionReport {
    /// The model.
    pub model: String,
    /// Degree of the series.
    pub degree: usize,
    /// Start of the coast used, seconds.
    pub start_s: f64,
    /// End of the coast used, seconds.
    pub end_s: f64,
    /// Speed at the start, r/min.
    pub speed_start_rpm: f64,
    /// Speed at the end, r/min.
    pub speed_end_rpm: f64,
    /// Acceleration at the start, in the direction of motion, rad/s².
    pub acceleration_start_rad_s2: f64,
    /// Acceleration at the end, rad/s².
    pub acceleration_end_rad_s2: f64,
    /// `increasing` or `decreasing` readings.
    pub direction: String,
}

/// The orders kept from the data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OrdersReport {
    /// Highest order tested.
    pub max_order_tested: usize,
    /// Samples per revolution where the coast is slowest.
    pub samples_per_revolution_densest: f64,
    /// The orders kept (ascending).
    pub kept: Vec<usize>,
    /// The significance rule.
    pub rule: String,
    /// Periodic structure left in the residual above the orders tested, largest first.
    pub residual_structure: Vec<HarmonicReport>,
}

/// Angle-dependent drag.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DragReport {
    /// What the method cannot separate.
    pub ambiguity: String,
    /// Whether drag was fitted jointly with the map.
    pub separated: bool,
    /// Relative RMS variation of 1/ω² over the coast.
    pub inverse_square_speed_variation: f64,
    /// Factor by which separating drag multiplies the noise of the orders it is fitted at.
    pub separation_noise_gain: f64,
    /// Highest drag order fitted (`--max-drag-order`).
    pub max_drag_order: usize,
    /// The drag found and separated.
    pub terms: Vec<DragTermReport>,
    /// ⟨ω⁻²⟩ over the coast, s².
    pub mean_inverse_square_speed_s2: f64,
    /// Shift of the map's order h by a deceleration of 1 rad/s² at order h, times h², arcsec.
    pub map_shift_arcsec_per_rad_s2_over_order_squared: f64,
    /// Where drag was not separated: orders whose amplitude changes with speed as drag would
    /// make it.
    pub speed_dependent_orders: Vec<SpeedDependentOrder>,
}

/// One separated drag order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DragTermReport {
    /// The order.
    pub order: usize,
    /// Amplitude of the deceleration, rad/s².
    pub deceleration_rad_s2: f64,
    /// Its phase, degrees.
    pub phase_deg: f64,
    /// Its imprint on the map at the mean 1/ω², arcsec.
    pub imprint_arcsec: f64,
    /// Standard uncertainty of the imprint, arcsec.
    pub u_imprint_arcsec: f64,
}

/// An order whose amplitude changes with speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SpeedDependentOrder {
    /// The order.
    pub order: usize,
    /// Amplitude of the speed-dependent part, arcsec.
    pub amplitude_arcsec: f64,
    /// Its phase, degrees.
    pub phase_deg: f64,
    /// Standard uncertainty of the amplitude, arcsec.
    pub u_arcsec: f64,
}

/// A driven run (`calib_core::tdr`'s module docs, "Driven runs").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DrivenReport {
    /// The passes at steady speed, in time order.
    pub passes: Vec<PassReport>,
    /// The pass (from 0) whose fit gives the map outside the motor's orders, and `motion`.
    pub main_pass: usize,
    /// The motor's orders (cogging, torque ripple): what each pass measured there, and the
    /// encoder's part where passes at different speeds separate it.
    pub motor_orders: Vec<MotorOrderReport>,
    /// Where the motor's orders go.
    pub rule: String,
}

/// One pass of a driven run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PassReport {
    /// Start, seconds.
    pub start_s: f64,
    /// End, seconds.
    pub end_s: f64,
    /// Speed `1/√⟨ω⁻²⟩`, r/min.
    pub speed_rpm: f64,
    /// ⟨ω⁻²⟩ over the pass, s².
    pub mean_inverse_square_speed_s2: f64,
    /// Revolutions.
    pub revolutions: f64,
    /// Samples.
    pub samples: usize,
    /// RMS of the pass's fit residual, arcsec.
    pub residual_rms_arcsec: f64,
}

/// One of the motor's orders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MotorOrderReport {
    /// The order.
    pub order: usize,
    /// Whether the map holds it (the encoder's part, separated by speed).
    pub in_map: bool,
    /// What each pass measured there (encoder error and shake together), arcsec.
    pub measured: Vec<PassHarmonic>,
    /// The encoder's error at this order, where separated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder: Option<HarmonicReport>,
    /// Standard uncertainty of the encoder's part (each coefficient), arcsec.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub u_encoder_arcsec: Option<f64>,
    /// Amplitude of the deceleration that shakes the shaft at this order, where separated,
    /// rad/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deceleration_rad_s2: Option<f64>,
    /// Its phase, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deceleration_phase_deg: Option<f64>,
    /// Standard uncertainty of the deceleration, rad/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub u_deceleration_rad_s2: Option<f64>,
    /// Factor by which separating multiplies the noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub separation_noise_gain: Option<f64>,
}

/// What one pass measured at a motor order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PassHarmonic {
    /// The pass (from 0).
    pub pass: usize,
    /// Amplitude, arcsec.
    pub amplitude_arcsec: f64,
    /// Phase, degrees.
    pub phase_deg: f64,
    /// Standard uncertainty of each coefficient, arcsec.
    pub u_arcsec: f64,
}

/// The check against a reference channel.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TdrReferenceReport {
    /// The reference's channel.
    pub channel: String,
    /// Largest |TDR map − reference map|, arcsec.
    pub max_difference_arcsec: f64,
    /// RMS of TDR map − reference map, arcsec.
    pub rms_difference_arcsec: f64,
}

/// `rad_s` rad/s in revolutions per minute.
pub fn rpm(rad_s: f64) -> f64 {
    rad_s * 60.0 / std::f64::consts::TAU
}

impl TdrCalibration {
    /// What correcting by the map leaves of the reference channel's measurement of the error
    /// (see [`AfterCorrection`]); `None` without a reference.
    pub fn after_correction(&self) -> Option<AfterCorrection> {
        let r = self.reference.as_ref()?;
        let check: Vec<(f64, f64)> = (0..r.map.len())
            .map(|i| (r.map.grid_angle(i), r.map.values()[i]))
            .collect();
        AfterCorrection::of_map("reference", &self.map, &check)
    }

    /// The report section of `channel`, checked against the `reference` channel where one was
    /// pushed; `max_drag_order` as asked for.
    pub fn report_section(
        &self,
        channel: &str,
        reference: Option<&str>,
        max_drag_order: usize,
    ) -> ReportSection {
        let mut ch = ChannelReport::of_map(&table_name(channel), &self.map, 10);
        ch.after_correction = self.after_correction();
        let m = &self.motion;
        let (_, _, accel_start) = m.eval(m.t_start);
        let (_, _, accel_end) = m.eval(m.t_end);
        let sep = &self.drag_separation;
        let details = TdrDetails {
            motion: MotionReport {
                model: "Chebyshev series of time".to_string(),
                degree: m.degree,
                start_s: m.t_start,
                end_s: m.t_end,
                speed_start_rpm: rpm(self.speed_start),
                speed_end_rpm: rpm(self.speed_end),
                acceleration_start_rad_s2: accel_start * self.direction,
                acceleration_end_rad_s2: accel_end * self.direction,
                direction: if self.direction > 0.0 {
                    "increasing"
                } else {
                    "decreasing"
                }
                .to_string(),
            },
            revolutions: self.revolutions,
            samples_used: self.samples_used,
            max_order: self.max_order,
            orders: OrdersReport {
                max_order_tested: self.max_order,
                samples_per_revolution_densest: self.samples_per_revolution_densest,
                kept: self.orders.clone(),
                rule: format!(
                    "an order is kept when its coefficients' chi-square against their covariance exceeds 2·ln(M/α) = {:.2} (M = {} orders tested, α = {})",
                    significance_threshold(self.max_order),
                    self.max_order,
                    FALSE_ORDER_PROBABILITY
                ),
                residual_structure: self.unresolved.iter().map(|h| h.to_report()).collect(),
            },
            residual_rms_arcsec: arcsec(self.residual_rms),
            noise_rms_arcsec: arcsec(self.noise_rms),
            uncertainty: BTreeMap::from([(
                channel.to_string(),
                UncertaintyReport::of(&self.uncertainty),
            )]),
            drag: DragReport {
                ambiguity: self.ambiguity.to_string(),
                separated: sep.separated,
                inverse_square_speed_variation: sep.variation,
                separation_noise_gain: sep.noise_gain,
                max_drag_order,
                terms: self
                    .drag
                    .iter()
                    .map(|d| DragTermReport {
                        order: d.deceleration.order,
                        deceleration_rad_s2: d.deceleration.amplitude,
                        phase_deg: d.deceleration.to_report().phase_deg,
                        imprint_arcsec: arcsec(d.imprint),
                        u_imprint_arcsec: arcsec(d.u_imprint),
                    })
                    .collect(),
                mean_inverse_square_speed_s2: self.drag_gain,
                map_shift_arcsec_per_rad_s2_over_order_squared: arcsec(self.drag_gain),
                speed_dependent_orders: self
                    .speed_dependence
                    .iter()
                    .map(|s| {
                        let h = s.harmonic.to_report();
                        SpeedDependentOrder {
                            order: h.order,
                            amplitude_arcsec: h.amplitude_arcsec,
                            phase_deg: h.phase_deg,
                            u_arcsec: arcsec(s.u),
                        }
                    })
                    .collect(),
            },
            reference: reference
                .zip(self.reference.as_ref())
                .map(|(name, r)| TdrReferenceReport {
                    channel: name.to_string(),
                    max_difference_arcsec: r.max_abs_diff_arcsec,
                    rms_difference_arcsec: r.rms_diff_arcsec,
                }),
            driven: self.driven.as_ref().map(driven_report),
            alignment: None,
            reading: None,
        };
        ReportSection {
            method: "tdr",
            channels: BTreeMap::from([(channel.to_string(), ch)]),
            sessions: Vec::new(),
            warnings: self.warnings.clone(),
            details: Details::Tdr(details),
        }
    }
}

/// The report of a driven run.
fn driven_report(d: &DrivenRun) -> DrivenReport {
    DrivenReport {
        passes: d
            .passes
            .iter()
            .map(|p| PassReport {
                start_s: p.t_start,
                end_s: p.t_end,
                speed_rpm: rpm(p.speed()),
                mean_inverse_square_speed_s2: p.mean_inverse_square_speed,
                revolutions: p.revolutions,
                samples: p.samples,
                residual_rms_arcsec: arcsec(p.residual_rms),
            })
            .collect(),
        main_pass: d.main_pass,
        motor_orders: d
            .motor_orders
            .iter()
            .map(|m| {
                let s = m.separated.as_ref();
                let decel = s.map(|s| s.deceleration.to_report());
                MotorOrderReport {
                    order: m.order,
                    in_map: s.is_some(),
                    measured: m
                        .measured
                        .iter()
                        .map(|p| {
                            let h = p.harmonic.to_report();
                            PassHarmonic {
                                pass: p.pass,
                                amplitude_arcsec: h.amplitude_arcsec,
                                phase_deg: h.phase_deg,
                                u_arcsec: arcsec(p.u),
                            }
                        })
                        .collect(),
                    encoder: s.map(|s| s.encoder.to_report()),
                    u_encoder_arcsec: s.map(|s| arcsec(s.u_encoder)),
                    // The deceleration's amplitude is in rad/s², not an angle.
                    deceleration_rad_s2: s.map(|s| s.deceleration.amplitude),
                    deceleration_phase_deg: decel.map(|h| h.phase_deg),
                    u_deceleration_rad_s2: s.map(|s| s.u_deceleration),
                    separation_noise_gain: s.map(|s| s.noise_gain),
                }
            })
            .collect(),
        rule: DRIVEN_RULE.to_string(),
    }
}

/// Where a driven run's motor orders go, for reports.
const DRIVEN_RULE: &str = "at one speed the motor's orders are left out of the map (their measured amplitude enters the map's u); with passes at two or more speeds each is fitted as e + D/ω² over the passes, the encoder's e put into the map with its u and the deceleration a = |D|·k² reported";

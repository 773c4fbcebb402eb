//! The report section of a multi-head calibration ([`crate::multihead`]).

use super::{ChannelReport, Details, ReportSection, UncertaintyReport, arcsec, table_name};
use crate::error_map::ErrorMap;
use crate::multihead::{Head, Method, MultiheadCalibration, Readings};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// `details` of `calib multihead`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MultiheadDetails {
    /// The solver.
    pub solver: Solver,
    /// Every head, in the order given.
    pub heads: Vec<HeadReport>,
    /// Highest order fitted.
    pub max_order: usize,
    /// Uniform bins per revolution of the fit.
    pub bins_per_revolution: usize,
    /// Orders no head pair (joint) or no set (EDA) sees, left out.
    pub blind_orders: Vec<usize>,
    /// Orders seen too weakly, left out (joint solver).
    pub ill_conditioned_orders: Vec<IllConditionedOrder>,
    /// RMS per sample of the joint fit's residual, arcsec (`null` for EDA).
    pub residual_rms_arcsec: Option<f64>,
    /// Joint solves made.
    pub iterations: usize,
    /// Samples used.
    pub samples: u64,
    /// Samples skipped (a non-finite reading).
    pub skipped_samples: u64,
    /// Travel of the first head, revolutions.
    pub revolutions: f64,
    /// The standard uncertainty of the map, by channel (the first head's).
    pub uncertainty: BTreeMap<String, UncertaintyReport>,
    /// The EDA sets (EDA only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sets: Vec<SetReport>,
    /// How the channels were aligned on one clock, where anything was interpolated or dropped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment: Option<super::Alignment>,
    /// How the log was read where the reader decided something the user did not say (copies
    /// dropped, a time unit chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading: Option<super::Reading>,
}

/// The multi-head solver (as [`Method`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Solver {
    /// Joint least squares of all heads.
    Joint,
    /// The published equal-division average per set of equally spaced heads.
    Eda,
}

/// How a head's readings relate to its place on the scale (as [`Readings`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum HeadReadings {
    /// The head's reading minus its nominal angle.
    RelativeToNominal,
    /// The scale's reading under the head.
    Raw,
}

/// One head.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HeadReport {
    /// Its channel.
    pub name: String,
    /// Its nominal angle as given, degrees.
    pub nominal_deg: f64,
    /// Its nominal angle from the first head, degrees in [0, 360).
    pub nominal_from_first_deg: f64,
    /// Estimated actual minus nominal angle, relative to the first head (0 for it), arcsec.
    pub angle_error_arcsec: f64,
    /// How its readings were taken (`null` for the first head).
    pub readings: Option<HeadReadings>,
    /// RMS per sample of its difference's residual, arcsec (`null` for the first head).
    pub residual_rms_arcsec: Option<f64>,
    /// RMS per sample of its difference's scatter within the bins, arcsec.
    pub noise_rms_arcsec: Option<f64>,
}

/// An order left out because the heads see it too weakly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct IllConditionedOrder {
    /// The order.
    pub order: usize,
    /// Its observability `o_h`.
    pub observability: f64,
}

/// One EDA set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SetReport {
    /// Its heads' channels.
    pub heads: Vec<String>,
    /// The set is blind to multiples of its head count.
    pub blind_to_multiples_of: usize,
    /// Peak to peak of the set's own map, arcsec.
    pub peak_to_peak_arcsec: f64,
}

impl MultiheadCalibration {
    /// The report section of the calibration of `heads` (as given): the map of the first head.
    pub fn report_section(&self, heads: &[Head]) -> ReportSection {
        let first = &heads[0].name;
        let channels = BTreeMap::from([(
            first.clone(),
            ChannelReport::of_map(&table_name(first), &self.map, 10),
        )]);
        let names = |set: &[usize]| set.iter().map(|&j| heads[j].name.clone()).collect();
        let details = MultiheadDetails {
            solver: match self.method {
                Method::Joint => Solver::Joint,
                Method::Eda => Solver::Eda,
            },
            heads: heads
                .iter()
                .zip(&self.heads)
                .map(|(given, est)| HeadReport {
                    name: est.name.clone(),
                    nominal_deg: given.nominal.to_degrees(),
                    nominal_from_first_deg: est.nominal.to_degrees(),
                    angle_error_arcsec: arcsec(est.angle_error),
                    readings: est.readings.map(|r| match r {
                        Readings::RelativeToNominal => HeadReadings::RelativeToNominal,
                        Readings::Raw => HeadReadings::Raw,
                    }),
                    residual_rms_arcsec: est.residual_rms.map(arcsec),
                    noise_rms_arcsec: est.noise_rms.map(arcsec),
                })
                .collect(),
            max_order: self.max_order,
            bins_per_revolution: self.bins,
            blind_orders: self.blind.iter().map(|e| e.order).collect(),
            ill_conditioned_orders: self
                .ill_conditioned
                .iter()
                .map(|e| IllConditionedOrder {
                    order: e.order,
                    observability: e.observability,
                })
                .collect(),
            residual_rms_arcsec: self.residual_rms.map(arcsec),
            iterations: self.iterations,
            samples: self.samples,
            skipped_samples: self.skipped,
            revolutions: self.revolutions,
            uncertainty: BTreeMap::from([(
                first.clone(),
                UncertaintyReport::of(&self.uncertainty),
            )]),
            sets: self
                .sets
                .iter()
                .map(|s| SetReport {
                    heads: names(&s.heads),
                    blind_to_multiples_of: s.heads.len(),
                    peak_to_peak_arcsec: arcsec(
                        ErrorMap::from_series(&s.series, self.map.len()).peak_to_peak(),
                    ),
                })
                .collect(),
            alignment: None,
            reading: None,
        };
        ReportSection {
            method: "multihead",
            channels,
            sessions: Vec::new(),
            warnings: self.warnings.clone(),
            details: Details::Multihead(details),
        }
    }
}

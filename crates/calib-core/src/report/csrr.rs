//! The report section of a CSRR calibration ([`crate::csrr`]).

use super::{
    AfterCorrection, ChannelReport, Details, ReferenceSplit, ReportSection, SessionReport,
    UncertaintyReport, arcsec,
};

use crate::csrr::{Calibration, EffectiveRange, EpsHarmonic, Method, observability};
use crate::error_map::ErrorMap;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Observability below which a fitted order counts as ill-conditioned: the joint solve
/// amplifies the noise at that order by about `1/√o_h`, more than 3× below 0.1.
pub const ILL_CONDITIONED: f64 = 0.1;

/// `details` of `calib csrr`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CsrrDetails {
    /// The solver: `joint` or `paper`.
    pub solver: Method,
    /// Highest harmonic order tested.
    pub max_order: usize,
    /// The orders the maps hold: those up to `max_order` that stand above the noise by the
    /// significance rule (joint solver; `docs/uncertainty.md`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub orders_kept: Vec<usize>,
    /// Orders above `max_order` where the residual still holds periodic structure above the
    /// noise (joint solver), with the amplitudes A's and B's errors would have there.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unresolved_orders: Vec<UnresolvedOrderReport>,
    /// Segments the log was cut into (moving, stopped, sessions).
    pub segments: usize,
    /// Orders left out: the sessions' relative rotations cannot separate them.
    pub excluded_orders: Vec<ExcludedOrderReport>,
    /// Fitted orders whose observability is below 0.1 ([`ILL_CONDITIONED`]; joint solver).
    pub ill_conditioned_orders: Vec<usize>,
    /// Where one more session would help most.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub advice: Option<AdviceReport>,
    /// RMS of the joint fit's residual per sample, arcsec (joint solver).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub residual_rms_arcsec: Option<f64>,
    /// Solver iterations (joint solver; written with the residual).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// The standard uncertainty of each map, by channel (both solvers; `docs/uncertainty.md`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<BTreeMap<String, UncertaintyReport>>,
    /// The paper solver's map points, one per session.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub paper_points: Vec<PaperPointReport>,
    /// The check against a reference encoder on B's shaft, where one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<CsrrReferenceReport>,
    /// How the channels were aligned on one clock, where anything was interpolated or dropped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment: Option<super::Alignment>,
    /// How the log was read where the reader decided something the user did not say (copies
    /// dropped, a time unit chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading: Option<super::Reading>,
    /// B's lag behind A removed, seconds (positive: B's sample is older than its stamp says;
    /// 0 where none was); absent where the calibration did not look (a library caller of
    /// `Csrr::finish`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency_s: Option<f64>,
    /// How the lag was found and what the sessions show after its removal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<CsrrLatencyReport>,
}

/// The lag between the two channels (`csrr::latency`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CsrrLatencyReport {
    /// `auto` (found from the sessions) or `given` (--latency SECONDS, 0 included).
    pub mode: String,
    /// The lag removed, seconds.
    pub applied_s: f64,
    /// Its standard uncertainty, seconds (the last reading's `u` of what was left).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub u_s: Option<f64>,
    /// The lag the sessions still show after the removal, seconds.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub left_s: Option<f64>,
    /// Whether that is significant (more than 3 u from 0 and moving `a − b` by more than 3
    /// noise standard deviations at the run's top speed): then a warning says so.
    pub left_significant: bool,
    /// Readings of the log (one per correction in `auto`).
    pub passes: usize,
    /// RMS change of speed over one revolution that the estimate rests on, degrees per second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_change_rms_deg_s: Option<f64>,
}

/// Periodic structure the residual holds above the orders tested.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UnresolvedOrderReport {
    /// The order.
    pub order: usize,
    /// The amplitude A's error would have at that order, arcsec.
    pub a_arcsec: f64,
    /// The amplitude B's error would have at that order, arcsec.
    pub b_arcsec: f64,
}

/// An order left out of the maps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExcludedOrderReport {
    /// The order.
    pub order: usize,
    /// Its observability (0 blind … 1 ideal).
    pub observability: f64,
}

/// The relative rotation of one more session that would raise the worst observability most.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AdviceReport {
    /// The relative rotation, degrees.
    pub extra_relative_rotation_deg: f64,
    /// The worst observability with it.
    pub min_observability_after: f64,
}

/// One map point of the paper solver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PaperPointReport {
    /// The session's relative rotation Δ, degrees.
    pub delta_deg: f64,
    /// A's reading at the point, degrees.
    pub a_angle_deg: f64,
    /// A's error there, arcsec.
    pub a_error_arcsec: f64,
    /// B's reading at the point, degrees.
    pub b_angle_deg: f64,
    /// B's error there, arcsec.
    pub b_error_arcsec: f64,
}

/// What a reference encoder on B's shaft says about the calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CsrrReferenceReport {
    /// The reference's channel.
    pub channel: String,
    /// Largest |A's map − A against the reference|, mean removed, arcsec.
    pub a_max_difference_arcsec: f64,
    /// The same for B.
    pub b_max_difference_arcsec: f64,
    /// The largest orders of the sampling non-uniformity ε_θ.
    pub sampling_nonuniformity: Vec<EpsHarmonic>,
    /// The paper's effective-range indicator at those orders.
    pub effective_range: Vec<EffectiveRange>,
}

impl Calibration {
    /// The fitted orders whose observability is below [`ILL_CONDITIONED`] (left in the maps;
    /// their noise is amplified). Empty for the paper solver, which fits no orders.
    pub fn ill_conditioned_orders(&self) -> Vec<usize> {
        if self.method != Method::Joint {
            return Vec::new();
        }
        let deltas: Vec<f64> = self.sessions.iter().map(|s| s.absolute_rotation).collect();
        let weights: Vec<f64> = self.sessions.iter().map(|s| s.samples as f64).collect();
        self.orders
            .iter()
            .copied()
            .filter(|h| !self.excluded.iter().any(|e| e.order == *h))
            .filter(|&h| observability(h, &deltas, &weights) < ILL_CONDITIONED)
            .collect()
    }

    /// What correcting A's map (`a = true`) or B's leaves of the check: the truth where given,
    /// else the reference encoder's measurement of the error (see [`AfterCorrection`]).
    pub fn after_correction(
        &self,
        truth: Option<(&ErrorMap, &ErrorMap)>,
        a: bool,
    ) -> Option<AfterCorrection> {
        let map = if a { &self.a } else { &self.b };
        if let Some((ta, tb)) = truth {
            let t = if a { ta } else { tb };
            let check: Vec<(f64, f64)> = (0..t.len())
                .map(|i| (t.grid_angle(i), t.values()[i]))
                .collect();
            return AfterCorrection::of_map("truth", map, &check);
        }
        let r = self.reference.as_ref()?;
        let check = if a {
            &r.a_vs_reference
        } else {
            &r.b_vs_reference
        };
        AfterCorrection::of_map("reference", map, check)
    }

    /// How B's error left after correction against the reference splits into the reference's
    /// own error `reference_error` (known from its calibration or a simulation) and the rest
    /// ([`ReferenceSplit`]). Only B's: the reference is on B's shaft, so B's check sees its error
    /// at B's own angle, while A's sees it shifted by each session's relative rotation.
    pub fn reference_split(&self, reference_error: &ErrorMap) -> Option<ReferenceSplit> {
        let check = &self.reference.as_ref()?.b_vs_reference;
        ReferenceSplit::of(&self.b, check, reference_error)
    }

    /// The report section of channels `a` and `b`: their maps, each with what correction
    /// leaves of the `truth` maps (where given) or of the `reference` channel's check.
    pub fn report_section(
        &self,
        (a, b): (&str, &str),
        reference: Option<&str>,
        truth: Option<(&ErrorMap, &ErrorMap)>,
    ) -> ReportSection {
        let mut channels = BTreeMap::new();
        for (name, map, is_a) in [(a, &self.a, true), (b, &self.b, false)] {
            let mut ch = ChannelReport::of_map(&crate::report::table_name(name), map, 10);
            // A map with no kept order lists no harmonics of zero amplitude.
            ch.harmonics.retain(|h| h.amplitude_arcsec > 0.0);
            ch.after_correction = self.after_correction(truth, is_a);
            channels.insert(name.to_string(), ch);
        }
        let sessions = self
            .sessions
            .iter()
            .map(|s| SessionReport {
                index: s.index,
                start_s: s.start_s,
                end_s: s.end_s,
                revolutions: s.revolutions,
                relative_rotation_deg: s.relative_rotation.to_degrees(),
            })
            .collect();
        let details = CsrrDetails {
            solver: self.method,
            max_order: self.max_order,
            orders_kept: self.orders.clone(),
            unresolved_orders: self
                .unresolved
                .iter()
                .map(|u| UnresolvedOrderReport {
                    order: u.order,
                    a_arcsec: arcsec(u.a),
                    b_arcsec: arcsec(u.b),
                })
                .collect(),
            segments: self.segmentation.segments.len(),
            excluded_orders: self
                .excluded
                .iter()
                .map(|e| ExcludedOrderReport {
                    order: e.order,
                    observability: e.observability,
                })
                .collect(),
            ill_conditioned_orders: self.ill_conditioned_orders(),
            advice: self.advice.map(|adv| AdviceReport {
                extra_relative_rotation_deg: adv.extra_rotation.to_degrees(),
                min_observability_after: adv.min_observability,
            }),
            residual_rms_arcsec: self.residual_rms.map(arcsec),
            iterations: self.residual_rms.map(|_| self.iterations),
            uncertainty: self.uncertainty.as_ref().map(|(ua, ub)| {
                BTreeMap::from([
                    (a.to_string(), UncertaintyReport::of(ua)),
                    (b.to_string(), UncertaintyReport::of(ub)),
                ])
            }),
            paper_points: self
                .paper_points
                .iter()
                .map(|p| PaperPointReport {
                    delta_deg: p.delta.to_degrees(),
                    a_angle_deg: p.a_angle.to_degrees(),
                    a_error_arcsec: arcsec(p.a_error),
                    b_angle_deg: p.b_angle.to_degrees(),
                    b_error_arcsec: arcsec(p.b_error),
                })
                .collect(),
            reference: self.reference.as_ref().zip(reference).map(|(r, name)| {
                CsrrReferenceReport {
                    channel: name.to_string(),
                    a_max_difference_arcsec: r.a_max_diff_arcsec,
                    b_max_difference_arcsec: r.b_max_diff_arcsec,
                    sampling_nonuniformity: r.eps_theta.clone(),
                    effective_range: r.effective_range.clone(),
                }
            }),
            alignment: None,
            reading: None,
            latency_s: self.latency.map(|l| l.applied),
            latency: self.latency.map(|l| CsrrLatencyReport {
                mode: match l.mode {
                    crate::reference_cal::Latency::Auto => "auto",
                    crate::reference_cal::Latency::Fixed(_) => "given",
                }
                .to_string(),
                applied_s: l.applied,
                u_s: l.u_applied,
                left_s: l.left.map(|e| e.tau),
                left_significant: l.left_significant(),
                passes: l.passes,
                speed_change_rms_deg_s: l.left.map(|e| e.speed_change_rms.to_degrees()),
            }),
        };
        ReportSection {
            method: "csrr",
            channels,
            sessions,
            warnings: self.warnings.clone(),
            details: Details::Csrr(details),
        }
    }
}

//! The report section of a calibration against a reference encoder ([`crate::reference_cal`]).

use super::{AfterCorrection, ChannelReport, Details, ReportSection, arcsec, table_name};
use crate::TableMap;
use crate::reference_cal::{
    GearResult, LatencySource, PointStats, RatioSource, ReferenceCalibration,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The warning of a calibration whose reference's uncertainty is not known: its u leaves the
/// reference out. A map against a reference measures DUT − reference, so the reference's own
/// error is in the map and its uncertainty belongs in u (GUM, JCGM 100:2008 §5.1); without it
/// u states only how repeatably the DUT was measured against it.
pub const U_EXCLUDES_REFERENCE: &str = "u excludes the reference: its uncertainty is not known, \
     so every u here is the DUT's repeatability against it alone and the map may be off by the \
     reference's own error; give the reference's stated standard uncertainty in arcseconds (the \
     `ref_u` option) or its calibrated table (the `ref_table` option)";

/// `details` of `calib reference`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceDetails {
    /// The reference's channel.
    pub reference: String,
    /// The reference's own standard uncertainty combined into every point's u (`--ref-u`, or
    /// the largest u of its calibrated table), arcsec; 0 where it is not known.
    pub reference_u_arcsec: f64,
    /// The reference's uncertainty is not known, so no u of the table includes it: u is the
    /// DUT's repeatability alone, and the map may be off by the reference's own error.
    #[serde(default)]
    pub u_excludes_reference: bool,
    /// Revolutions (or, over a range, passes' travel in revolutions) of the run.
    pub revolutions: f64,
    /// The fewest passes over any grid point, per direction.
    pub min_passes: MinPasses,
    /// Largest standard uncertainty of the table, arcsec.
    pub max_u_arcsec: f64,
    /// The figures of ISO 230-2 over the targets, arcsec (`null` where a direction has none).
    pub iso230_2: Iso230_2Report,
    /// The per-target statistics of ISO 230-2.
    pub iso230_2_targets: Vec<TargetReport>,
    /// The range a range table covers (`null` for a whole turn).
    pub range: Option<RangeReport>,
    /// The part of a whole turn never reached and bridged (`null` if none).
    pub gap: Option<GapReport>,
    /// Largest difference between passes at the same reading (the follow check), degrees.
    pub repeat_spread_deg: Option<f64>,
    /// How the channels were aligned on one clock, where anything was interpolated or dropped.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alignment: Option<super::Alignment>,
    /// How the log was read where the reader decided something the user did not say (copies
    /// dropped, a time unit chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reading: Option<super::Reading>,
    /// The DUT's lag behind the reference, seconds (positive: the DUT's sample is older), as
    /// removed from the map (0 where none was); absent with `--latency 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency_s: Option<f64>,
    /// How the lag was found and what the run says of it; absent with `--latency 0`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<Box<LatencyReport>>,
    /// Points measured in one direction only, corrected by half the reversal next to them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub one_direction_points: Option<Box<EndsReport>>,
    /// The motor's ripple taken out of the map of a commanded reference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ripple: Option<Box<RippleReport>>,
    /// The DUT's quantum found from its readings and the part of it that averaging passes does
    /// not take out, in every point's u (absent where the readings are not quantized).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quantization: Option<QuantizationReport>,
    /// Turns of the reference per turn of the DUT, through a gear (`--ref-ratio`; absent on one
    /// shaft).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
    /// The ratio's standard uncertainty, where it was estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ratio_u: Option<f64>,
    /// The gear: where the ratio comes from, the reference's own map, what cannot be separated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gear: Option<Box<GearReport>>,
}

/// A reference through a gear (module `reference_cal::gear`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GearReport {
    /// `given` or `estimated`.
    pub ratio_source: String,
    /// Turns of the reference over the DUT's travel.
    pub reference_turns: f64,
    /// The reference's table (its error over one of its turns), where its map was separated.
    pub reference_table: Option<String>,
    /// Largest standard uncertainty of the reference's table, arcsec of its own angle.
    pub reference_max_u_arcsec: Option<f64>,
    /// The terms of the reference's map, `amplitude·cos(k·r + phase)` in its own angle.
    pub reference_terms: Vec<ReferenceTermReport>,
    /// Orders of the DUT that are the reference's over this run: in the reference's map.
    pub coincident: Vec<CoincidenceReport>,
    /// What this run cannot tell apart, and where it was put.
    pub not_separable: Vec<String>,
}

/// One term of the reference's map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceTermReport {
    /// Cycles per turn of the reference.
    pub order: u32,
    /// Amplitude, arcsec of the reference's angle.
    pub amplitude_arcsec: f64,
    /// Its standard uncertainty, arcsec.
    pub u_amplitude_arcsec: f64,
    /// Phase, degrees.
    pub phase_deg: f64,
    /// Passed the significance rule: in the reference's table (else left out, its variance in
    /// the table's u).
    pub kept: bool,
}

/// A DUT order that is a reference order over the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CoincidenceReport {
    /// Cycles per turn of the DUT.
    pub dut_order: u32,
    /// Cycles per turn of the reference.
    pub reference_order: u32,
}

/// The DUT's quantization in a reference calibration's u.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct QuantizationReport {
    /// The quantum found from the readings (the greatest common divisor of their steps), arcsec.
    pub quantum_arcsec: f64,
    /// The noise in front of the quantizer, arcsec, from the repeatability of points crossed
    /// more than once in a direction (`null`: none was, taken as 0).
    pub noise_arcsec: Option<f64>,
    /// The term in every point's u, `(Δ/√12)·exp(−2π²σ²/Δ²)`: the quantization no averaging
    /// of passes takes out (all of `Δ/√12` where no noise dithers the readings), arcsec.
    pub u_arcsec: f64,
}

/// The lag between the channels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LatencyReport {
    /// `given` (--latency SECONDS), `estimated` (fitted and removed), `insignificant` (fitted,
    /// within 3 u of 0, not removed), `ambiguous` (one speed per direction: latency and backlash
    /// read the same, not removed), `unavailable` (the run cannot give it).
    pub source: String,
    /// The lag removed, seconds.
    pub applied_s: f64,
    /// The fitted lag (jointly with a constant reversal), seconds.
    pub estimate_s: Option<f64>,
    /// Its standard uncertainty, seconds.
    pub u_s: Option<f64>,
    /// The lag if the whole reversal were latency, seconds.
    pub if_no_backlash_s: Option<f64>,
    /// The reversal if it were all backlash, arcsec.
    pub if_no_latency_reversal_arcsec: Option<f64>,
    /// Squared correlation of direction and speed within points (1: one speed each way).
    pub speed_direction_correlation: Option<f64>,
    /// Mean absolute speed of the reference at the crossings, degrees per second.
    pub mean_speed_deg_s: Option<f64>,
}

/// Points measured in one direction only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EndsReport {
    /// Points corrected.
    pub points: usize,
    /// How: `half the reversal next to them`.
    pub corrected_by: String,
    /// Largest correction applied, arcsec.
    pub max_correction_arcsec: f64,
    /// Largest standard uncertainty of the correction, arcsec (in u_arcsec).
    pub max_u_arcsec: f64,
}

/// The ripple of a commanded reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RippleReport {
    /// Pole pairs of the motor.
    pub pole_pairs: u32,
    /// Peak-to-peak of the ripple removed, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// Grid points the fit used.
    pub fitted_points: usize,
    /// The terms `amplitude·cos(k·φ + phase)`, `φ` the reference's electrical angle.
    pub terms: Vec<RippleTermReport>,
}

/// One term of the ripple.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RippleTermReport {
    /// Cycles per electrical turn.
    pub harmonic: usize,
    /// Cycles per revolution (harmonic × pole pairs).
    pub order: usize,
    /// Amplitude, arcsec.
    pub amplitude_arcsec: f64,
    /// Its standard uncertainty, arcsec.
    pub u_amplitude_arcsec: f64,
    /// Phase, degrees.
    pub phase_deg: f64,
}

/// Passes per direction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MinPasses {
    /// Increasing readings.
    pub increasing: u32,
    /// Decreasing readings.
    pub decreasing: u32,
}

/// The figures of ISO 230-2, arcsec (as [`crate::reference_cal::Iso230_2`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Iso230_2Report {
    /// Unidirectional systematic deviation E↑ (increasing readings).
    pub systematic_up_arcsec: Option<f64>,
    /// Unidirectional systematic deviation E↓ (decreasing readings).
    pub systematic_down_arcsec: Option<f64>,
    /// Bidirectional systematic deviation E.
    pub systematic_arcsec: Option<f64>,
    /// Mean bidirectional positional deviation M.
    pub mean_bidirectional_arcsec: Option<f64>,
    /// Reversal value B = max |B_i| (needs both directions).
    pub reversal_arcsec: Option<f64>,
    /// Mean reversal value, increasing minus decreasing.
    pub mean_reversal_arcsec: Option<f64>,
    /// Unidirectional repeatability R↑ = max 4 s_i↑.
    pub repeatability_up_arcsec: Option<f64>,
    /// Unidirectional repeatability R↓ = max 4 s_i↓.
    pub repeatability_down_arcsec: Option<f64>,
    /// Bidirectional repeatability R.
    pub repeatability_arcsec: Option<f64>,
    /// Unidirectional accuracy A↑.
    pub accuracy_up_arcsec: Option<f64>,
    /// Unidirectional accuracy A↓.
    pub accuracy_down_arcsec: Option<f64>,
    /// Bidirectional accuracy A.
    pub accuracy_arcsec: Option<f64>,
}

/// One target of ISO 230-2.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TargetReport {
    /// The target, degrees of the DUT's reading.
    pub target_deg: f64,
    /// Passes with increasing readings.
    pub increasing: DirectionReport,
    /// Passes with decreasing readings.
    pub decreasing: DirectionReport,
    /// Mean of both directions' means (or the one there is), arcsec.
    pub mean_bidirectional_arcsec: Option<f64>,
    /// Increasing minus decreasing mean, arcsec (both directions needed).
    pub reversal_arcsec: Option<f64>,
}

/// One direction at one target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DirectionReport {
    /// Passes.
    pub passes: u32,
    /// Mean deviation, arcsec.
    pub mean_arcsec: Option<f64>,
    /// Standard deviation of the passes, arcsec.
    pub s_arcsec: Option<f64>,
    /// Repeatability `4s`, arcsec.
    pub repeatability_arcsec: Option<f64>,
}

/// A range table's range, degrees: `start` in `[0, 360)`, or negative for a range across the
/// reading 0 (−40 to 95), as the table writes it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RangeReport {
    /// First grid point.
    pub start_deg: f64,
    /// Last grid point.
    pub end_deg: f64,
    /// `end − start`.
    pub span_deg: f64,
}

/// A gap bridged in a whole-turn map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GapReport {
    /// Where it starts, degrees.
    pub from_deg: f64,
    /// Where it ends, degrees (may exceed 360 across the wrap).
    pub to_deg: f64,
    /// Its size, degrees.
    pub size_deg: f64,
    /// Grid points inside it.
    pub points: usize,
    /// How it was bridged.
    pub bridged: String,
}

impl DirectionReport {
    fn of(p: &PointStats) -> Self {
        DirectionReport {
            passes: p.n,
            mean_arcsec: (p.n > 0).then(|| arcsec(p.mean)),
            s_arcsec: p.s.map(arcsec),
            repeatability_arcsec: p.s.map(|s| arcsec(4.0 * s)),
        }
    }
}

impl ReferenceCalibration {
    /// What the correction leaves of the DUT's error, measured in each direction (see
    /// [`AfterCorrection`]): the check points are each direction's mean deviation at each grid
    /// point. The map is the mean of the two directions, so this is the hysteresis a single
    /// table cannot correct.
    pub fn after_correction(&self) -> Option<AfterCorrection> {
        let pairs = self
            .up
            .iter()
            .zip(&self.down)
            .zip(self.map.values())
            .flat_map(|((up, down), &map)| {
                [up, down]
                    .into_iter()
                    .filter(|p| p.n > 0)
                    .map(move |p| (p.mean, map))
            });
        AfterCorrection::from_pairs("each direction", pairs)
    }

    /// The report section of the DUT channel `dut` against the `reference` channel, whose own
    /// standard uncertainty combined into u was `reference_u_arcsec` (`None`: not known, and
    /// left out of u).
    pub fn report_section(
        &self,
        dut: &str,
        reference: &str,
        reference_u_arcsec: Option<f64>,
    ) -> ReportSection {
        let mut ch = match &self.map {
            TableMap::Turn(m) => ChannelReport::of_map(&table_name(dut), m, 10),
            // A range has no Fourier series: harmonics need a whole turn.
            TableMap::Range(m) => ChannelReport {
                table: table_name(dut),
                points: m.len(),
                peak_to_peak_arcsec: arcsec(m.peak_to_peak()),
                rms_arcsec: arcsec(m.rms()),
                harmonics: Vec::new(),
                after_correction: None,
            },
        };
        ch.after_correction = self.after_correction();
        let iso = &self.iso;
        let a = |v: Option<f64>| v.map(arcsec);
        let details = ReferenceDetails {
            reference: reference.to_string(),
            reference_u_arcsec: reference_u_arcsec.unwrap_or(0.0),
            u_excludes_reference: reference_u_arcsec.is_none(),
            revolutions: self.revolutions,
            min_passes: MinPasses {
                increasing: self.min_passes.0,
                decreasing: self.min_passes.1,
            },
            max_u_arcsec: arcsec(self.u.iter().fold(0.0f64, |m, u| m.max(*u))),
            iso230_2: Iso230_2Report {
                systematic_up_arcsec: a(iso.systematic_up),
                systematic_down_arcsec: a(iso.systematic_down),
                systematic_arcsec: a(iso.systematic),
                mean_bidirectional_arcsec: a(iso.mean_bidirectional),
                reversal_arcsec: a(iso.reversal),
                mean_reversal_arcsec: a(iso.mean_reversal),
                repeatability_up_arcsec: a(iso.repeatability_up),
                repeatability_down_arcsec: a(iso.repeatability_down),
                repeatability_arcsec: a(iso.repeatability),
                accuracy_up_arcsec: a(iso.accuracy_up),
                accuracy_down_arcsec: a(iso.accuracy_down),
                accuracy_arcsec: a(iso.accuracy),
            },
            iso230_2_targets: self
                .targets
                .iter()
                .map(|t| TargetReport {
                    target_deg: t.angle.to_degrees(),
                    increasing: DirectionReport::of(&t.up),
                    decreasing: DirectionReport::of(&t.down),
                    mean_bidirectional_arcsec: match (t.up.n, t.down.n) {
                        (0, 0) => None,
                        (0, _) => Some(arcsec(t.down.mean)),
                        (_, 0) => Some(arcsec(t.up.mean)),
                        _ => Some(arcsec(0.5 * (t.up.mean + t.down.mean))),
                    },
                    reversal_arcsec: (t.up.n > 0 && t.down.n > 0)
                        .then(|| arcsec(t.up.mean - t.down.mean)),
                })
                .collect(),
            range: self.map.range().map(|(lo, hi)| {
                // Across the reading 0: the signed form, as the table writes it.
                let turn = if hi > std::f64::consts::TAU {
                    360.0
                } else {
                    0.0
                };
                RangeReport {
                    start_deg: lo.to_degrees() - turn,
                    end_deg: hi.to_degrees() - turn,
                    span_deg: (hi - lo).to_degrees(),
                }
            }),
            gap: self.gap.map(|g| GapReport {
                from_deg: g.from.to_degrees(),
                to_deg: g.to.to_degrees(),
                size_deg: g.size.to_degrees(),
                points: g.points,
                bridged: "linear interpolation".to_string(),
            }),
            repeat_spread_deg: self.repeat_spread.map(f64::to_degrees),
            alignment: None,
            reading: None,
            latency_s: self.latency.map(|l| l.applied),
            latency: self.latency.map(|l| {
                Box::new(LatencyReport {
                    source: match l.source {
                        LatencySource::Given => "given",
                        LatencySource::Estimated => "estimated",
                        LatencySource::Insignificant => "insignificant",
                        LatencySource::Ambiguous => "ambiguous",
                        LatencySource::Unavailable => "unavailable",
                    }
                    .to_string(),
                    applied_s: l.applied,
                    estimate_s: l.fit.map(|f| f.tau),
                    u_s: l.fit.map(|f| f.u_tau).filter(|u| u.is_finite()),
                    if_no_backlash_s: l.fit.map(|f| f.tau_if_no_backlash),
                    if_no_latency_reversal_arcsec: l.fit.map(|f| arcsec(f.reversal_if_no_latency)),
                    speed_direction_correlation: l.fit.map(|f| f.speed_direction_correlation),
                    mean_speed_deg_s: l.fit.map(|f| f.mean_speed.to_degrees()),
                })
            }),
            one_direction_points: self.ends.map(|e| {
                Box::new(EndsReport {
                    points: e.points,
                    corrected_by: "half the reversal next to them".to_string(),
                    max_correction_arcsec: arcsec(e.max_correction),
                    max_u_arcsec: arcsec(e.max_u),
                })
            }),
            quantization: self.quantization.map(|q| QuantizationReport {
                quantum_arcsec: arcsec(q.quantum),
                noise_arcsec: q.noise.map(arcsec),
                u_arcsec: arcsec(q.u),
            }),
            ripple: self.ripple.as_ref().map(|r| {
                Box::new(RippleReport {
                    pole_pairs: r.pole_pairs,
                    peak_to_peak_arcsec: arcsec(r.peak_to_peak),
                    fitted_points: r.fitted_points,
                    terms: r
                        .terms
                        .iter()
                        .map(|t| RippleTermReport {
                            harmonic: t.harmonic,
                            order: t.order,
                            amplitude_arcsec: arcsec(t.amplitude),
                            u_amplitude_arcsec: arcsec(t.u_amplitude),
                            phase_deg: t.phase.to_degrees(),
                        })
                        .collect(),
                })
            }),
            ratio: None,
            ratio_u: None,
            gear: None,
        };
        let gear = self.gear.as_ref().map(|g| gear_report(g, reference));
        let details = ReferenceDetails {
            ratio: self.gear.as_ref().map(|g| g.ratio),
            ratio_u: self.gear.as_ref().and_then(|g| g.ratio_u),
            gear: gear.map(Box::new),
            ..details
        };
        let mut channels = BTreeMap::from([(dut.to_string(), ch)]);
        if let Some(m) = self.gear.as_ref().and_then(|g| g.reference_map.as_ref()) {
            channels.insert(
                reference.to_string(),
                ChannelReport::of_map(&table_name(reference), &m.map, 10),
            );
        }
        let mut warnings = self.warnings.clone();
        if reference_u_arcsec.is_none() {
            warnings.push(U_EXCLUDES_REFERENCE.to_string());
        }
        ReportSection {
            method: "reference",
            channels,
            sessions: Vec::new(),
            warnings,
            details: Details::Reference(details),
        }
    }
}

/// The report of a reference through a gear, `reference` its channel.
fn gear_report(g: &GearResult, reference: &str) -> GearReport {
    let mut not_separable = Vec::new();
    if g.reference_map.is_none() {
        not_separable.push(format!(
            "the reference turned {:.2} time(s) over the DUT's travel, too few to separate: its own error is in \
             the DUT's map",
            g.reference_turns
        ));
    }
    if !g.coincident.is_empty() {
        not_separable.push(format!(
            "the DUT's orders {} are the reference's over this run: both in the reference's map",
            g.coincident
                .iter()
                .map(|c| c.dut_order.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if g.range && g.reference_map.is_some() {
        not_separable.push(format!(
            "over a range, what repeats every turn of the reference (the DUT's error at {:.3}, {:.3}, … cycles per turn) \
             is in the reference's map",
            g.ratio.abs(),
            2.0 * g.ratio.abs()
        ));
    }
    if g.line_in_ratio {
        not_separable.push(
            "over a range with the ratio estimated, the DUT's straight-line part (a scale error) is in the ratio: the \
             map has none"
                .to_string(),
        );
    }
    not_separable.push(
        "a gear's transmission error periodic in the reference's angle is in the reference's map, periodic in the \
         DUT's angle in the DUT's map"
            .to_string(),
    );
    GearReport {
        ratio_source: match g.source {
            RatioSource::Given => "given",
            RatioSource::Estimated => "estimated",
        }
        .to_string(),
        reference_turns: g.reference_turns,
        reference_table: g.reference_map.as_ref().map(|_| table_name(reference)),
        reference_max_u_arcsec: g
            .reference_map
            .as_ref()
            .map(|m| arcsec(m.u.iter().fold(0.0f64, |a, &u| a.max(u)))),
        reference_terms: g
            .reference_map
            .iter()
            .flat_map(|m| &m.terms)
            .map(|t| ReferenceTermReport {
                order: t.order,
                amplitude_arcsec: arcsec(t.amplitude),
                u_amplitude_arcsec: arcsec(t.u_amplitude),
                phase_deg: t.phase.to_degrees(),
                kept: t.kept,
            })
            .collect(),
        coincident: g
            .coincident
            .iter()
            .map(|c| CoincidenceReport {
                dut_order: c.dut_order,
                reference_order: c.reference_order,
            })
            .collect(),
        not_separable,
    }
}

//! The machine-readable report (`report.json`) every method command writes, as types.
//!
//! Each method's result provides its own part of the report — channels, sessions, warnings and
//! its `details` — through a `report_section` method (one module here per method:
//! [`csrr`], [`multihead`], [`tdr`], [`reference`](mod@reference), [`shift_angle`]), and [`Report::new`]
//! assembles the report from it. A program using the crates writes the same `report.json` as the
//! command line by serializing the [`Report`].
//!
//! Floats are written as computed; renderers round for people, never here.
//!
//! # Schema and versions
//!
//! Every type here derives [`schemars::JsonSchema`]; the repository's `docs/report.schema.json`
//! is generated from [`Report`]. [`SCHEMA_VERSION`] is written into every report: it changes
//! when a key is removed or renamed or its meaning or unit changes, not when one is added.
//!
//! # Key order
//!
//! The top level and the channels are written in the order of their fields; the keys of
//! `details` are written in alphabetical order at every depth (see [`Details`]).

pub mod csrr;
pub mod multihead;
pub mod reference;
pub mod shift_angle;
pub mod tdr;

use crate::angle::ARCSEC_PER_RAD;
use crate::error_map::ErrorMap;
use crate::harmonics::HarmonicReport;
use crate::uncertainty::{Evaluation, MapUncertainty};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The version of the shape of `report.json` (and of `summary.json`): raised when a key is
/// removed or renamed, or its meaning or unit changes; adding a key leaves it.
pub const SCHEMA_VERSION: u32 = 1;

/// `report.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Report {
    /// The version of this report's shape: raised when a key is removed or renamed, or its
    /// meaning or unit changes ([`SCHEMA_VERSION`]).
    pub schema_version: u32,
    /// Version of calib that wrote it.
    pub calib_version: String,
    /// The method (`csrr`, `multihead`, `tdr`, `reference`, `shift-angle`).
    pub method: String,
    /// Input files, as given.
    pub inputs: Vec<String>,
    /// The exact command line, where the report came from the CLI.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command_line: Option<String>,
    /// One entry per calibrated channel, by channel name.
    pub channels: BTreeMap<String, ChannelReport>,
    /// The sessions the method used, where it uses sessions.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sessions: Vec<SessionReport>,
    /// Things the user should know about the result.
    pub warnings: Vec<String>,
    /// The method's own section.
    #[serde(serialize_with = "sorted_keys")]
    pub details: Details,
}

/// What a method's result contributes to its report: everything but the provenance.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportSection {
    /// The method's name in `report.json`.
    pub method: &'static str,
    /// The calibrated channels.
    pub channels: BTreeMap<String, ChannelReport>,
    /// The sessions used (CSRR).
    pub sessions: Vec<SessionReport>,
    /// The method's warnings.
    pub warnings: Vec<String>,
    /// The method's details.
    pub details: Details,
}

impl ReportSection {
    /// The section with how the log's channels were aligned on one clock, for the methods that
    /// read logs (shift-angle reads none and is left as it is).
    pub fn with_alignment(mut self, alignment: Option<Alignment>) -> Self {
        let slot = match &mut self.details {
            Details::Csrr(d) => &mut d.alignment,
            Details::Multihead(d) => &mut d.alignment,
            Details::Tdr(d) => &mut d.alignment,
            Details::Reference(d) => &mut d.alignment,
            Details::ShiftAngle(_) => return self,
        };
        *slot = alignment;
        self
    }

    /// The section with how the log was read where the reader decided something the user did
    /// not say (`details.reading`), for the methods that read logs; `None` leaves it out.
    pub fn with_reading(mut self, reading: Option<Reading>) -> Self {
        let slot = match &mut self.details {
            Details::Csrr(d) => &mut d.reading,
            Details::Multihead(d) => &mut d.reading,
            Details::Tdr(d) => &mut d.reading,
            Details::Reference(d) => &mut d.reading,
            Details::ShiftAngle(_) => return self,
        };
        *slot = reading;
        self
    }

    /// The section with its times on the log's own clock: the times the method was given plus
    /// `origin_s`, the stamp they were counted from (readers count stamps since 1970 from the
    /// first one's second, to keep their nanoseconds in a double).
    pub fn with_time_origin(mut self, origin_s: f64) -> Self {
        for s in &mut self.sessions {
            s.start_s += origin_s;
            s.end_s += origin_s;
        }
        if let Details::Tdr(d) = &mut self.details {
            d.motion.start_s += origin_s;
            d.motion.end_s += origin_s;
        }
        self
    }
}

impl Report {
    /// The report of `section`, calibrated from `inputs` by `command_line`; `warnings` (e.g. the
    /// reader's) come before the method's own.
    pub fn new(
        section: ReportSection,
        inputs: Vec<String>,
        command_line: Option<String>,
        mut warnings: Vec<String>,
    ) -> Self {
        warnings.extend(section.warnings);
        Report {
            schema_version: SCHEMA_VERSION,
            calib_version: env!("CARGO_PKG_VERSION").to_string(),
            method: section.method.to_string(),
            inputs,
            command_line,
            channels: section.channels,
            sessions: section.sessions,
            warnings,
            details: section.details,
        }
    }
}

/// The `details` of each method; which one a report holds is named by its `method`.
///
/// Written with its keys in alphabetical order at every depth, as `report.json` always had them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Details {
    /// `calib csrr`.
    Csrr(csrr::CsrrDetails),
    /// `calib multihead`.
    Multihead(multihead::MultiheadDetails),
    /// `calib tdr`.
    Tdr(tdr::TdrDetails),
    /// `calib reference`.
    Reference(reference::ReferenceDetails),
    /// `calib shift-angle`.
    ShiftAngle(shift_angle::ShiftAngleDetails),
}

/// Serializes `value` with the keys of every object in alphabetical order (through
/// [`serde_json::Value`], whose maps are sorted).
fn sorted_keys<T: Serialize, S: serde::Serializer>(value: &T, s: S) -> Result<S::Ok, S::Error> {
    serde_json::to_value(value)
        .map_err(serde::ser::Error::custom)?
        .serialize(s)
}

/// One calibrated channel in the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ChannelReport {
    /// File name of its correction table, relative to the report.
    pub table: String,
    /// Grid points in the table.
    pub points: usize,
    /// Peak-to-peak error, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// RMS error, arcsec.
    pub rms_arcsec: f64,
    /// The map's harmonics, largest first (none for a map that is not a uniform whole turn).
    pub harmonics: Vec<HarmonicReport>,
    /// What correcting by the map leaves of an independent check, where the run has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub after_correction: Option<AfterCorrection>,
}

impl ChannelReport {
    /// The summary of `map`, with its `top` largest harmonics (orders below `max_order`).
    pub fn of_map(table: &str, map: &ErrorMap, top: usize) -> Self {
        let mut harmonics: Vec<HarmonicReport> = map
            .series()
            .harmonics()
            .iter()
            .map(|h| h.to_report())
            .collect();
        harmonics.sort_by(|a, b| b.amplitude_arcsec.total_cmp(&a.amplitude_arcsec));
        harmonics.truncate(top);
        ChannelReport {
            table: table.to_string(),
            points: map.len(),
            peak_to_peak_arcsec: map.peak_to_peak() * ARCSEC_PER_RAD,
            rms_arcsec: map.rms() * ARCSEC_PER_RAD,
            harmonics,
            after_correction: None,
        }
    }

    /// The summary of a map given as values (arcsec) that are not a uniform grid over a whole
    /// turn: peak to peak and RMS, no harmonics (a Fourier series needs a whole turn).
    pub fn of_values(table: &str, values_arcsec: &[f64]) -> Self {
        let max = values_arcsec
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let min = values_arcsec.iter().copied().fold(f64::INFINITY, f64::min);
        ChannelReport {
            table: table.to_string(),
            points: values_arcsec.len(),
            peak_to_peak_arcsec: max - min,
            rms_arcsec: (values_arcsec.iter().map(|v| v * v).sum::<f64>()
                / values_arcsec.len() as f64)
                .sqrt(),
            harmonics: Vec::new(),
            after_correction: None,
        }
    }
}

/// The error left after correction: how far an independent check of the error still differs
/// from the map, peak to peak.
///
/// The one definition every method uses: at each point θ_j where the check measured the error
/// `c_j`, the residual is `r_j = c_j − m(θ_j)` with `m` the calibrated map (linear
/// interpolation between its grid points where θ_j is not one of them), and the figure is
/// `max_j r_j − min_j r_j`. A constant offset between check and map is not an error left (maps
/// are zero mean), so peak to peak is the measure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AfterCorrection {
    /// What the map was checked against: `truth` (the simulator's true error), `reference`
    /// (a reference encoder on the same shaft), or `each direction` (the reference method's
    /// per-direction means: what is left is the hysteresis one table cannot correct).
    pub against: String,
    /// `max r − min r` over the checked points, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// Against a reference whose own error is known (it was calibrated, or simulated): how
    /// much of the figure that error explains, and the rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_split: Option<ReferenceSplit>,
}

/// The error left after correction against a reference, split into the part the reference's
/// own error explains and the rest.
///
/// The check measures `c_j = e(θ_j) − e_ref(θ_j)` (reading − reference reading, on one shaft),
/// so `r_j = c_j − m(θ_j)` holds the reference's error `−e_ref` besides what the map `m` misses.
/// With `e_ref` known the rest is `r_j + e_ref(θ_j) = e(θ_j) − m(θ_j)`: what the correction
/// leaves of the sensor's own error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceSplit {
    /// Peak to peak of the reference's own error `e_ref(θ_j)` over the checked points, arcsec.
    pub reference_error_arcsec: f64,
    /// Peak to peak of `r_j + e_ref(θ_j)`, the rest: what the map leaves of the sensor's own
    /// error, arcsec.
    pub rest_arcsec: f64,
}

impl ReferenceSplit {
    /// The split of the check `(θ, c)` (radians) of `map` against a reference whose own error
    /// is `reference_error` (a whole turn, as a function of its reading); `None` without points.
    pub fn of(map: &ErrorMap, check: &[(f64, f64)], reference_error: &ErrorMap) -> Option<Self> {
        let own = AfterCorrection::from_pairs(
            "reference",
            check
                .iter()
                .map(|&(theta, _)| (reference_error.eval_linear(theta), 0.0)),
        )?;
        let rest = AfterCorrection::from_pairs(
            "reference",
            check.iter().map(|&(theta, c)| {
                (
                    c + reference_error.eval_linear(theta),
                    map.eval_linear(theta),
                )
            }),
        )?;
        Some(ReferenceSplit {
            reference_error_arcsec: own.peak_to_peak_arcsec,
            rest_arcsec: rest.peak_to_peak_arcsec,
        })
    }
}

impl AfterCorrection {
    /// The figure from `(check, map)` pairs at the same angles, radians; `None` without any.
    pub fn from_pairs(against: &str, pairs: impl IntoIterator<Item = (f64, f64)>) -> Option<Self> {
        let (lo, hi) = pairs
            .into_iter()
            .map(|(check, map)| check - map)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                (lo.min(r), hi.max(r))
            });
        (lo <= hi).then(|| AfterCorrection {
            against: against.to_string(),
            peak_to_peak_arcsec: (hi - lo) * ARCSEC_PER_RAD,
            reference_split: None,
        })
    }

    /// The figure of a whole-turn `map` against check points `(θ, error)`, radians.
    pub fn of_map(against: &str, map: &ErrorMap, check: &[(f64, f64)]) -> Option<Self> {
        Self::from_pairs(
            against,
            check.iter().map(|&(theta, e)| (e, map.eval_linear(theta))),
        )
    }
}

/// One session of a session-based method (CSRR).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SessionReport {
    /// Index, from 0 in log order.
    pub index: usize,
    /// Start, seconds.
    pub start_s: f64,
    /// End, seconds.
    pub end_s: f64,
    /// Revolutions covered.
    pub revolutions: f64,
    /// Relative rotation of the two sensors, degrees, relative to the first session.
    pub relative_rotation_deg: f64,
}

/// A map's standard uncertainty as the report gives it: summary figures over the table and the
/// budget (GUM style), arcsec.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyReport {
    /// Largest `u` over the table points.
    pub u_max_arcsec: f64,
    /// RMS of `u` over the table points.
    pub u_rms_arcsec: f64,
    /// Median of `u` over the table points.
    pub u_median_arcsec: f64,
    /// How the components are combined.
    pub combination: String,
    /// The components.
    pub components: Vec<UncertaintyComponentReport>,
}

/// One component of a map's uncertainty budget.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyComponentReport {
    /// The component.
    pub name: String,
    /// How it was evaluated: `A` (statistics of the data) or `B` (a model).
    #[serde(rename = "type")]
    pub evaluation: Evaluation,
    /// Its RMS over the table points.
    pub u_rms_arcsec: f64,
    /// Its largest value.
    pub u_max_arcsec: f64,
}

impl UncertaintyReport {
    /// The report of `u`.
    pub fn of(u: &MapUncertainty) -> Self {
        UncertaintyReport {
            u_max_arcsec: u.max() * ARCSEC_PER_RAD,
            u_rms_arcsec: u.rms() * ARCSEC_PER_RAD,
            u_median_arcsec: u.median() * ARCSEC_PER_RAD,
            combination:
                "root sum of squares of independent components, unit sensitivities (GUM 5.1.2)"
                    .to_string(),
            components: u
                .components
                .iter()
                .map(|c| UncertaintyComponentReport {
                    name: c.name.clone(),
                    evaluation: c.evaluation,
                    u_rms_arcsec: c.rms() * ARCSEC_PER_RAD,
                    u_max_arcsec: c.u.iter().copied().fold(0.0, f64::max) * ARCSEC_PER_RAD,
                })
                .collect(),
        }
    }
}

/// How a log's channels were aligned to one clock (its first selected channel), written in
/// `details.alignment` where anything was interpolated or dropped.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Alignment {
    /// The clock channel.
    pub clock: String,
    /// Samples of the clock channel read.
    pub clock_samples: u64,
    /// Samples emitted.
    pub samples: u64,
    /// Every other selected channel, in the order selected.
    pub channels: Vec<ChannelAlignment>,
}

impl Alignment {
    /// Whether every channel was read at the clock's exact stamps with nothing dropped.
    pub fn is_exact(&self) -> bool {
        self.clock_samples == self.samples
            && self
                .channels
                .iter()
                .all(|c| c.interpolated == 0 && c.dropped == 0 && c.out_of_order == 0)
    }
}

/// How a log was read, written in `details.reading` where the reader decided something the
/// user did not say: messages it dropped as copies, a time unit it chose.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Reading {
    /// Messages (CSV rows) dropped because they repeated the one before exactly, stamp and
    /// readings: a message recorded twice (a recorder or bridge subscribed twice, a replayed
    /// segment). Conflicting repeats (the same stamp, other readings) are refused instead.
    #[serde(default)]
    pub duplicates_dropped: u64,
    /// The unit a CSV time column that names none was read in, chosen from its stamps'
    /// magnitude; absent where the option, the column's name or a units row gave it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_unit: Option<TimeUnitChoice>,
}

/// The unit a CSV time column was read in when neither the `time_unit` option, its name nor a
/// units row gave one, and why: its first stamp is a date between 1990 and 2100 counted in that
/// unit since 1970.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeUnitChoice {
    /// The time column.
    pub column: String,
    /// The unit taken: `ms`, `us` or `ns`.
    pub unit: String,
    /// Why, in words: the first stamp and the date it is in that unit.
    pub reason: String,
}

/// How one channel was aligned to the clock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ChannelAlignment {
    /// The channel.
    pub channel: String,
    /// Median of (the channel's sample nearest to a clock stamp − that stamp), seconds, over the
    /// first 65,536 samples emitted; `None` if none was.
    pub median_offset_s: Option<f64>,
    /// The maximum gap used, seconds.
    pub max_gap_s: f64,
    /// Samples emitted with this channel's reading at exactly the clock's stamp.
    pub exact: u64,
    /// Samples emitted with this channel's reading interpolated.
    pub interpolated: u64,
    /// Clock samples dropped because this channel could not be aligned there (a gap, or before
    /// its first or after its last sample).
    pub dropped: u64,
    /// Samples of this channel not used because their stamp did not increase.
    pub out_of_order: u64,
}

/// The table file name of a channel: `<channel>.csv`, made safe as a file name (see
/// [`file_stem`]).
pub fn table_name(channel: &str) -> String {
    format!("{}.csv", file_stem(channel))
}

/// A channel name as a file name: a leading `/` is dropped and characters other than letters,
/// digits, `-`, `_` and `.` become `_` (`/sensor_a/joint_states/encoder` →
/// `sensor_a_joint_states_encoder`; JointState names such as `arm/joint1` stay usable).
pub fn file_stem(channel: &str) -> String {
    let s: String = channel
        .strip_prefix('/')
        .unwrap_or(channel)
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("_{s}")
    } else {
        s
    }
}

/// `x` radians in arcseconds.
fn arcsec(x: f64) -> f64 {
    x * ARCSEC_PER_RAD
}

/// `x` with at most `decimals` decimals, trailing zeros dropped (`117.3`, `360`, `-0.5`), and a
/// negative zero written `0`: how tables, headers and summaries write a plain number. The one
/// copy for every crate: the standard library formats either all decimals or the shortest
/// round-trip form, neither of which a table header wants.
pub fn trimmed(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        &s
    };
    if s == "-0" { "0".into() } else { s.into() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn after_correction_is_the_peak_to_peak_of_check_minus_map() {
        // A map 10″·cos θ checked against 10″·cos θ + 2″·cos 2θ + 5″: the offset is not left
        // after correction, the second order is (4″ peak to peak).
        let a = 1.0 / ARCSEC_PER_RAD;
        let map = ErrorMap::new(
            (0..360)
                .map(|i| 10.0 * a * (TAU * i as f64 / 360.0).cos())
                .collect(),
        );
        let check: Vec<(f64, f64)> = (0..720)
            .map(|j| {
                let th = TAU * j as f64 / 720.0;
                (th, (10.0 * th.cos() + 2.0 * (2.0 * th).cos() + 5.0) * a)
            })
            .collect();
        let after = AfterCorrection::of_map("truth", &map, &check).unwrap();
        assert_eq!(after.against, "truth");
        // Linear interpolation of the 1° grid costs at most 10″·(π/360)²/2 ≈ 4e-4″.
        assert!((after.peak_to_peak_arcsec - 4.0).abs() < 1e-3, "{after:?}");
        assert!(AfterCorrection::of_map("truth", &map, &[]).is_none());
    }

    #[test]
    fn details_are_written_with_sorted_keys() {
        #[derive(Serialize)]
        struct Inner {
            zeta: u8,
            alpha: u8,
        }
        #[derive(Serialize)]
        struct Outer {
            second: Inner,
            first: u8,
        }
        let value = Outer {
            second: Inner { zeta: 1, alpha: 2 },
            first: 3,
        };
        let mut out = Vec::new();
        sorted_keys(&value, &mut serde_json::Serializer::new(&mut out)).unwrap();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            r#"{"first":3,"second":{"alpha":2,"zeta":1}}"#
        );
    }

    #[test]
    fn numbers_are_trimmed_to_their_decimals() {
        assert_eq!(trimmed(117.300_000_000_1, 9), "117.3");
        assert_eq!(trimmed(360.0, 6), "360");
        assert_eq!(trimmed(100.0, 0), "100");
        assert_eq!(trimmed(-0.5, 6), "-0.5");
        assert_eq!(trimmed(-1e-12, 6), "0");
        assert_eq!(trimmed(0.123_456_789, 4), "0.1235");
    }
}

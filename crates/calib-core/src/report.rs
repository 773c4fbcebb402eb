//! The machine-readable report (`report.json`) every method command writes.
//!
//! The fields named in the interface document are fixed; methods add their own sections through
//! [`Report::details`]. Floats are written as computed; renderers round for people, never here.

use crate::angle::ARCSEC_PER_RAD;
use crate::error_map::ErrorMap;
use crate::harmonics::HarmonicReport;
use std::collections::BTreeMap;

/// `report.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// Version of calib that wrote it.
    pub calib_version: String,
    /// The method (`csrr`, `shift-angle`, …).
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
    /// Method-specific sections.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub details: BTreeMap<String, serde_json::Value>,
}

/// One calibrated channel in the report.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChannelReport {
    /// File name of its correction table, relative to the report.
    pub table: String,
    /// Grid points in the table.
    pub points: usize,
    /// Peak-to-peak error, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// RMS error, arcsec.
    pub rms_arcsec: f64,
    /// The map's harmonics, largest first.
    pub harmonics: Vec<HarmonicReport>,
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
        }
    }
}

/// One session of a session-based method (CSRR).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
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

//! `calib-core`: the mathematics and domain types of calib, the offline calibration of angular
//! encoders and angle sensors from recorded runs.
//!
//! The crate does no file or terminal I/O. It takes samples (from `calib-io`'s readers, or from a
//! caller's own acquisition code) and returns typed results:
//!
//! - [`angle`]: radians inside, [`AngleUnit`] conversions at the edges, [`Unwrapper`].
//! - [`sample`]: [`Sample`]s of named [`Channel`]s.
//! - [`ErrorMap`]: a sensor's error over one revolution of its own reading; [`FourierSeries`] and
//!   [`Harmonic`]s in the convention `amplitude·cos(h·θ + phase)`.
//! - [`Report`]: what `report.json` holds.
//! - [`shift_angle`]: cross-calibration of an encoder with a polygon and an autocollimator at
//!   every angle (Hsieh, Watanabe, Hsu 2022), by the paper's steps or one constrained fit.
//! - [`uncertainty`]: GUM budgets — combined and expanded uncertainty, Welch–Satterthwaite.
//! - [`reference_cal`]: cross-calibration against a better reference encoder, with ISO 230-2 figures.
//! - [`compare`]: two calibrations of one sensor compared point by point with the En number.
//!
//! # Conventions
//! Error `e = reading − true angle`, correction `= −e`; maps are functions of the sensor's own
//! reading with zero mean; angles in degrees and errors in arcseconds only at the edges.
#![deny(missing_docs)]
#![warn(clippy::print_stdout, clippy::print_stderr)]

pub mod angle;
pub mod compare;
pub mod csrr;
pub mod error_map;
pub mod harmonics;
pub mod inspect;
pub mod reference_cal;
pub mod report;
pub mod sample;
pub mod segment;
pub mod shift_angle;
pub mod simulate;
pub mod uncertainty;

pub use angle::{Angle, AngleUnit, Unwrapper};
pub use error_map::ErrorMap;
pub use harmonics::{FourierSeries, Harmonic, HarmonicReport};
pub use report::{ChannelReport, Report, SessionReport};
pub use sample::{Channel, Sample};

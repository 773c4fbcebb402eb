//! `calib-core`: the mathematics and domain types of calib, the offline calibration of angular
//! encoders and angle sensors from recorded runs.
//!
//! The crate does no file or terminal I/O. It takes samples (from `calib-io`'s readers, or from a
//! caller's own acquisition code) and returns typed results:
//!
//! - [`angle`]: radians inside, [`AngleUnit`] conversions at the edges, [`Unwrapper`].
//! - [`Sample`]s of named [`Channel`]s, or a [`SampleBatch`] of them: what the methods take.
//! - [`ErrorMap`]: a sensor's error over one revolution of its own reading; [`FourierSeries`] and
//!   [`Harmonic`]s in the convention `amplitude·cos(h·θ + phase)`; [`RangeMap`] over part of a
//!   revolution; [`TableMap`], either of them: what a correction table holds.
//! - [`Report`]: what `report.json` holds, assembled by [`Report::new`] from a method result's
//!   `report_section` ([`report`], one module per method).
//! - [`shift_angle`]: cross-calibration of an encoder with a polygon and an autocollimator at
//!   every angle (Hsieh, Watanabe, Hsu 2022), by the paper's steps or one constrained fit.
//! - [`uncertainty`]: GUM budgets — combined and expanded uncertainty, Welch–Satterthwaite.
//! - [`reference_cal`]: cross-calibration against a better reference encoder, with ISO 230-2 figures.
//! - [`compare`]: two calibrations of one sensor compared point by point with the En number.
//! - [`correction`]: readings corrected with a map, as `calib apply` does; [`compose`]: one map
//!   for a map already in use followed by the residual calibrated through it.
//! - [`csrr`]: CSRR self-calibration of two coaxial sensors (joint least squares, or the seed
//!   paper's method); [`segment`] finds its sessions; [`inspect`] summarizes a log.
//! - [`multihead`]: self-calibration of one scale read by several heads (joint least squares,
//!   or the equal-division average of the SelfA paper), head angle errors included.
//! - [`simulate`]: realistic runs with a known truth; [`plan`]: the set-up that lets a method see
//!   the orders asked for, and the `u` it will give, before recording.
//! - [`tdr`]: self-calibration of one encoder from a free spin-down (Lu & Trumper's TDR).
//! - [`nufft2d`]: sums `Σ w_n e^{i(j·a_n + m·b_n)}` over millions of samples by a type-1
//!   non-uniform FFT (the spin-down fit's normal equations come from two of them).
//!
//! The crate's `examples/` folder holds one program per method, each fed from the simulator in
//! memory and checking its result against the truth: `cargo run -p calib-core --example
//! csrr_joint` (also `csrr_paper`, `multihead`, `tdr`, `reference`, `shift_angle`,
//! `uncertainty`, `compare`, `simulate`).
//!
//! # Conventions
//! Error `e = reading − true angle`, correction `= −e`; maps are functions of the sensor's own
//! reading with zero mean; angles in degrees and errors in arcseconds only at the edges.
//!
//! # Example
//! Calibrate two sensors from samples of your own acquisition code (no files involved): feed
//! every synchronized sample to [`csrr::Csrr`] and read the maps.
//!
//! ```
//! use calib_core::csrr::{Csrr, CsrrOptions};
//! use calib_core::{FourierSeries, Harmonic};
//! use std::f64::consts::TAU;
//!
//! // Sensor A errs by 20″ at order 3, sensor B by 15″ at order 2 (functions of the true angle).
//! let ea = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(3, 20.0, 10.0)], 3);
//! let eb = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(2, 15.0, -40.0)], 2);
//! let mut csrr = Csrr::new(CsrrOptions { max_order: Some(8), ..CsrrOptions::default() });
//! let mut t = 0.0;
//! // Five sessions of two revolutions at different relative rotations, with pauses between.
//! for (k, delta_deg) in [0.0f64, 37.0, 101.0, 190.0, 275.0].into_iter().enumerate() {
//!     let delta = delta_deg.to_radians();
//!     for n in 0..1000 {
//!         let theta = TAU * n as f64 / 500.0 + k as f64;
//!         csrr.push(t, theta + ea.eval(theta), theta - delta + eb.eval(theta - delta), None);
//!         t += 0.002;
//!     }
//!     for _ in 0..100 {
//!         csrr.push(t, 0.0, 0.0, None);
//!         t += 0.002;
//!     }
//! }
//! let cal = csrr.finish()?;
//! let order3 = cal.a_series.harmonics()[2].to_report();
//! assert!((order3.amplitude_arcsec - 20.0).abs() < 0.05);
//! println!("A: {:.2}″ peak to peak, {} sessions", cal.a.peak_to_peak() * calib_core::angle::ARCSEC_PER_RAD, cal.sessions.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]
#![warn(clippy::print_stdout, clippy::print_stderr)]

pub mod angle;
pub mod compare;
pub mod compose;
pub mod correction;
pub mod csrr;
pub mod detection;
mod error_map;
mod harmonics;
pub mod inspect;
pub mod multihead;
pub(crate) mod nufft;
pub mod nufft2d;
pub mod plan;
pub mod purpose;
mod range_map;
pub mod reference_cal;
pub mod reference_points;
pub mod report;
mod sample;
pub mod segment;
pub mod shift_angle;
pub mod simulate;
mod table_map;
pub mod tdr;
pub mod uncertainty;

pub use angle::{AngleUnit, PartialTurn, Travel, Unwrapper};
pub use error_map::{ErrorMap, interpolate_periodic};
pub use harmonics::{FourierSeries, Harmonic, HarmonicReport};
pub use range_map::{RangeMap, RangeMapError};
pub use report::{ChannelReport, Report, SessionReport};
pub use sample::{Channel, Sample, SampleBatch, SampleRef, UnknownChannel, channel_index};
pub use table_map::TableMap;

//! The unit of a log's readings checked against the readings themselves.
//!
//! CSV columns and JSON fields carry no unit: calib reads them in `--unit`, degrees by default.
//! A log in radians (ROS logs radians, REP 103) or in encoder counts read as degrees gives a
//! wrong map, or a method's error that points the wrong way ("never turned a whole
//! revolution"). So where the unit was not given, each channel read in the default unit is
//! checked once its readings are all read ([`UnitCheck`]): readings whose span fits another
//! unit and not degrees are a usage error that names the likely unit and the option to give.
//!
//! - **radians**: the readings lie within [−π, 2π] and span at least [`RAD_TURN_SPAN`] (0.9 of
//!   a turn in radians), so they are a whole turn in radians, and 5.7° or less in degrees; no
//!   method calibrates a sensor from a few degrees starting at zero without being told so.
//! - **counts**: the readings are whole numbers, none negative, reaching [`COUNTS_MIN`] or
//!   more: far beyond a turn in degrees, and whole-number degrees are not a reading any
//!   calibration can use.
//!
//! An explicit `--unit` (even `--unit deg`) is taken as it is.

use crate::exit::Usage;
use calib_core::AngleUnit;
use calib_io::LogReader;
use std::f64::consts::{PI, TAU};
use std::path::Path;
use std::sync::OnceLock;

/// Smallest span of readings, in the readings' own numbers, taken as a whole turn in radians:
/// 0.9 of 2π.
pub const RAD_TURN_SPAN: f64 = 0.9 * TAU;

/// Smallest largest reading taken as encoder counts: 1024 (a 10-bit encoder's turn), almost
/// three turns in degrees.
pub const COUNTS_MIN: f64 = 1024.0;

/// The `--unit` the running command was given (`None`: the default); set once.
static DECLARED: OnceLock<Option<AngleUnit>> = OnceLock::new();

/// Records the `--unit` the running command was given; the first call wins.
pub fn declare(unit: Option<AngleUnit>) {
    let _ = DECLARED.set(unit);
}

/// The range of one channel's readings, in the unit they were read in.
#[derive(Debug, Clone)]
struct Span {
    name: String,
    lo: f64,
    hi: f64,
    whole: bool,
}

/// The readings of the channels read in the default unit (degrees), checked against it.
#[derive(Debug, Clone, Default)]
pub struct UnitCheck {
    /// Per channel of the reader (in its selection's order), its span if it is checked.
    channels: Vec<Option<Span>>,
}

impl UnitCheck {
    /// A check of the channels of `reader` that were read in degrees because no `--unit` was
    /// given (none where one was: the user said what the readings are).
    pub fn new(reader: &LogReader) -> Self {
        if DECLARED.get().copied().flatten().is_some() {
            return UnitCheck::default();
        }
        UnitCheck::of(reader.channels().iter().map(|c| (c.name.as_str(), c.unit)))
    }

    /// A check of the channels `(name, unit read in)`: those read in degrees.
    fn of<'a>(channels: impl Iterator<Item = (&'a str, AngleUnit)>) -> Self {
        UnitCheck {
            channels: channels
                .map(|(name, unit)| {
                    (unit == AngleUnit::Deg).then(|| Span {
                        name: name.to_string(),
                        lo: f64::INFINITY,
                        hi: f64::NEG_INFINITY,
                        whole: true,
                    })
                })
                .collect(),
        }
    }

    /// A check of one channel's readings known by their range in the unit `unit` they were read
    /// in, and whether all are whole numbers (`calib apply`'s first pass finds them), where no
    /// `--unit` was given (`declared`): a channel read in degrees is checked, others are not.
    pub fn of_range(
        name: &str,
        declared: Option<AngleUnit>,
        unit: AngleUnit,
        (lo, hi): (f64, f64),
        whole: bool,
    ) -> Self {
        if declared.is_some() || unit != AngleUnit::Deg {
            return UnitCheck::default();
        }
        UnitCheck {
            channels: vec![Some(Span {
                name: name.to_string(),
                lo,
                hi,
                whole,
            })],
        }
    }

    /// Adds one sample's readings (radians, in the reader's channel order).
    pub fn push(&mut self, values: &[f64]) {
        for (span, v) in self.channels.iter_mut().zip(values) {
            if let Some(span) = span
                && v.is_finite()
            {
                let x = v.to_degrees();
                span.lo = span.lo.min(x);
                span.hi = span.hi.max(x);
                // Degrees back from radians are whole numbers only to rounding.
                span.whole &= (x - x.round()).abs() < 1e-9 * x.abs().max(1.0);
            }
        }
    }

    /// The usage error for the first channel whose readings fit another unit, naming it.
    pub fn finish(&self, log: &Path) -> Result<(), Usage> {
        for span in self.channels.iter().flatten() {
            if span.hi < span.lo {
                continue;
            }
            let (lo, hi) = (span.lo, span.hi);
            let shown = crate::ui::shown(log);
            let name = &span.name;
            let r = calib_io::limits::readable;
            if span.whole && lo >= 0.0 && hi >= COUNTS_MIN {
                let turn = (hi + 1.0).log2().ceil().exp2();
                return Err(Usage(format!(
                    "{shown}: the readings of `{name}` are whole numbers from {} to {}: far \
                     beyond a turn in degrees (readings are taken as degrees without --unit); \
                     if they are encoder counts, give --unit counts:N with N the counts per turn \
                     (counts:{} if they wrap there), or --unit deg if they are degrees",
                    r(lo),
                    r(hi),
                    r(turn)
                )));
            }
            if lo >= -PI - 1e-9 && hi <= TAU + 1e-9 && hi - lo >= RAD_TURN_SPAN {
                return Err(Usage(format!(
                    "{shown}: the readings of `{name}` lie from {lo:.4} to {hi:.4}: a whole turn \
                     in radians, but only {:.2}° in degrees (readings are taken as degrees \
                     without --unit); if they are radians (as ROS logs them, REP 103), give \
                     --unit rad, or --unit deg if they are degrees",
                    hi - lo
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(unit: AngleUnit, readings: &[f64]) -> Result<(), Usage> {
        let mut c = UnitCheck::of([("a", unit)].into_iter());
        for r in readings {
            c.push(&[unit.to_rad(*r)]);
        }
        c.finish(Path::new("run.csv"))
    }

    /// A turn in [0, 2π) or [−π, π) read as degrees is called radians; one in counts is
    /// called counts with its power of two.
    #[test]
    fn readings_that_fit_another_unit_are_named() {
        let turn: Vec<f64> = (0..1000).map(|k| k as f64 * TAU / 1000.0).collect();
        let err = check(AngleUnit::Deg, &turn).unwrap_err().to_string();
        assert!(err.contains("--unit rad") && err.contains("`a`"), "{err}");
        let signed: Vec<f64> = turn.iter().map(|x| x - PI).collect();
        assert!(check(AngleUnit::Deg, &signed).is_err());
        let counts: Vec<f64> = (0..16384).map(f64::from).collect();
        let err = check(AngleUnit::Deg, &counts).unwrap_err().to_string();
        assert!(err.contains("counts:16384"), "{err}");
    }

    /// Degrees over a turn, a sweep of a few degrees away from zero, accumulated degrees, and a
    /// channel read in radians (a JointState position) are left as they are.
    #[test]
    fn readings_that_fit_degrees_pass() {
        let turn: Vec<f64> = (0..3600).map(|k| k as f64 * 0.1 + 0.05).collect();
        assert!(check(AngleUnit::Deg, &turn).is_ok());
        let sweep: Vec<f64> = (0..100).map(|k| 30.0 + k as f64 * 0.06).collect();
        assert!(check(AngleUnit::Deg, &sweep).is_ok());
        let accumulated: Vec<f64> = (0..7200).map(|k| k as f64 * 0.5 + 0.25).collect();
        assert!(check(AngleUnit::Deg, &accumulated).is_ok());
        let radians: Vec<f64> = (0..1000).map(|k| k as f64 * TAU / 1000.0).collect();
        assert!(check(AngleUnit::Rad, &radians).is_ok());
    }
}

//! The unit of a log's readings checked against the readings themselves.
//!
//! CSV columns and JSON fields carry no unit: calib reads them in `--unit`, degrees by default.
//! A log in radians (ROS logs radians, REP 103) or in encoder counts read as degrees gives a
//! wrong map, or a method's error that points the wrong way ("never turned a whole
//! revolution"). So where the unit was not given, each channel read in the default unit is
//! checked once its readings are all read ([`UnitCheck`]): readings whose span fits another
//! unit and not degrees are a data error (exit 1, [`WrongUnit`]: what the readings hold, not how
//! calib was called, is at fault) that names the likely unit and the option to give.
//!
//! - **radians**: the readings lie within [−π, 2π] and span at least [`RAD_TURN_SPAN`] (0.9 of
//!   a turn in radians), so they are a whole turn in radians, and 5.7° or less in degrees; no
//!   method calibrates a sensor from a few degrees starting at zero without being told so.
//! - **counts**: the readings are whole numbers, none negative, reaching [`COUNTS_MIN`] or
//!   more: far beyond a turn in degrees, and whole-number degrees are not a reading any
//!   calibration can use.
//!
//! An explicit `--unit` (even `--unit deg`) is taken as it is.
//!
//! The mirror mistake, **degrees read as radians** (`--unit rad`, or a CSV units row or TwinCAT
//! `Unit` row saying `rad` over readings in degrees), turns a reading of 359° into 57 turns: a
//! log of four wrapped turns becomes 229 revolutions and a map of the wrong orders. So each
//! channel read in radians because the user or the file said so (not a JointState position,
//! radians by REP 103, unless `--unit rad` was given) is checked the same way
//! ([`UnitCheck`]): readings within [−180, 360] that either step by [`DEG_WRAP_STEP`] or more
//! between two samples (a wrap at 360° in degrees; 28 turns between two samples in radians) or
//! span at least [`DEG_TURN_SPAN`] (a whole turn in degrees; 51 turns in radians, within
//! [−180, 360] rad only for a joint that turned 51 to 57 times from near zero) are the same
//! data error naming `--unit deg`.

use calib_core::AngleUnit;
use calib_io::LogReader;
use std::f64::consts::{PI, TAU};
use std::path::Path;
use std::sync::OnceLock;

/// Smallest span of readings, in the readings' own numbers, taken as a whole turn in radians:
/// 0.9 of 2π.
pub const RAD_TURN_SPAN: f64 = 0.9 * TAU;

/// Smallest span of readings, in the readings' own numbers, taken as a whole turn in degrees:
/// 0.9 of 360.
pub const DEG_TURN_SPAN: f64 = 0.9 * 360.0;

/// Smallest step between two consecutive readings, in their own numbers, taken as a wrap at 360
/// in degrees: half a turn in degrees, 28 turns between two samples in radians.
pub const DEG_WRAP_STEP: f64 = 180.0;

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
    /// The unit the readings were read in: degrees (checked against radians and counts) or
    /// radians (checked against degrees).
    unit: AngleUnit,
    lo: f64,
    hi: f64,
    whole: bool,
    /// The previous reading, in its own numbers (NaN before the first).
    prev: f64,
    /// The largest step between two consecutive readings, in their own numbers.
    max_step: f64,
}

impl Span {
    fn new(name: &str, unit: AngleUnit) -> Self {
        Span {
            name: name.to_string(),
            unit,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            whole: true,
            prev: f64::NAN,
            max_step: 0.0,
        }
    }
}

/// The readings of the channels read in the default unit (degrees), checked against it.
#[derive(Debug, Clone, Default)]
pub struct UnitCheck {
    /// Per channel of the reader (in its selection's order), its span if it is checked.
    channels: Vec<Option<Span>>,
}

impl UnitCheck {
    /// A check of the channels of `reader` that were read in degrees because no `--unit` was
    /// given, and of those read in radians because `--unit rad` or the CSV file's units said so
    /// (see the [module docs](self)).
    pub fn new(reader: &LogReader) -> Self {
        let declared = DECLARED.get().copied().flatten();
        // A CSV file's radians come from --unit or its units row; other logs' from --unit, or
        // from the message type (JointState), which is not checked.
        let stated_rad = declared == Some(AngleUnit::Rad) || reader.csv_dialect().is_some();
        UnitCheck::of(
            reader.channels().iter().map(|c| (c.name.as_str(), c.unit)),
            declared,
            stated_rad,
        )
    }

    /// A check of the channels `(name, unit read in)`: those read in degrees where no unit was
    /// `declared`, those read in radians where the radians were stated (`stated_rad`).
    fn of<'a>(
        channels: impl Iterator<Item = (&'a str, AngleUnit)>,
        declared: Option<AngleUnit>,
        stated_rad: bool,
    ) -> Self {
        UnitCheck {
            channels: channels
                .map(|(name, unit)| {
                    let checked = match unit {
                        AngleUnit::Deg => declared.is_none(),
                        AngleUnit::Rad => stated_rad,
                        _ => false,
                    };
                    checked.then(|| Span::new(name, unit))
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
        let checked = match unit {
            AngleUnit::Deg => declared.is_none(),
            AngleUnit::Rad => true,
            _ => false,
        };
        if !checked {
            return UnitCheck::default();
        }
        // The range is in the unit read in; the steps between readings are not known here.
        UnitCheck {
            channels: vec![Some(Span {
                lo,
                hi,
                whole,
                ..Span::new(name, unit)
            })],
        }
    }

    /// Adds one sample's readings (radians, in the reader's channel order).
    pub fn push(&mut self, values: &[f64]) {
        for (span, v) in self.channels.iter_mut().zip(values) {
            if let Some(span) = span
                && v.is_finite()
            {
                // The reading in its own numbers, as the log writes it.
                let x = if span.unit == AngleUnit::Deg {
                    v.to_degrees()
                } else {
                    *v
                };
                span.lo = span.lo.min(x);
                span.hi = span.hi.max(x);
                // Degrees back from radians are whole numbers only to rounding.
                span.whole &= (x - x.round()).abs() < 1e-9 * x.abs().max(1.0);
                span.max_step = span.max_step.max((x - span.prev).abs());
                span.prev = x;
            }
        }
    }

    /// The error for the first channel whose readings fit another unit, naming it and the
    /// option to give: a data error ([`WrongUnit`], exit 1) for readings read in degrees by
    /// default that are radians or counts, and for degrees read as radians.
    pub fn finish(&self, log: &Path) -> anyhow::Result<()> {
        for span in self.channels.iter().flatten() {
            if span.hi < span.lo {
                continue;
            }
            if span.unit == AngleUnit::Rad {
                degrees_as_radians(span, log)?;
                continue;
            }
            let (lo, hi) = (span.lo, span.hi);
            let shown = crate::ui::shown(log);
            let name = &span.name;
            let r = calib_io::limits::readable;
            if span.whole && lo >= 0.0 && hi >= COUNTS_MIN {
                let turn = (hi + 1.0).log2().ceil().exp2();
                return Err(WrongUnit(format!(
                    "{shown}: the readings of `{name}` are whole numbers from {} to {}: far \
                     beyond a turn in degrees (readings are taken as degrees without --unit); \
                     if they are encoder counts, give --unit counts:N with N the counts per turn \
                     (counts:{} if they wrap there), or --unit deg if they are degrees",
                    r(lo),
                    r(hi),
                    r(turn)
                ))
                .into());
            }
            if lo >= -PI - 1e-9 && hi <= TAU + 1e-9 && hi - lo >= RAD_TURN_SPAN {
                return Err(WrongUnit(format!(
                    "{shown}: the readings of `{name}` lie from {lo:.4} to {hi:.4}: a whole turn \
                     in radians, but only {:.2}° in degrees (readings are taken as degrees \
                     without --unit); if they are radians (as ROS logs them, REP 103), give \
                     --unit rad, or --unit deg if they are degrees",
                    hi - lo
                ))
                .into());
            }
        }
        Ok(())
    }
}

/// Readings that fit another unit than the one they were read in (see the
/// [module docs](self)): a data error, exit 1.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct WrongUnit(pub String);

/// Refuses `span`, read in radians, if its readings are degrees.
fn degrees_as_radians(span: &Span, log: &Path) -> Result<(), WrongUnit> {
    let (lo, hi) = (span.lo, span.hi);
    let within = lo >= -DEG_WRAP_STEP - 1e-9 && hi <= 360.0 + 1e-9;
    let wraps = span.max_step >= DEG_WRAP_STEP;
    if !within || !(wraps || hi - lo >= DEG_TURN_SPAN) {
        return Ok(());
    }
    let turns = (hi - lo) / TAU;
    let why = if wraps {
        format!(
            " and step by up to {:.1} between two samples: {:.0} turns in radians between two \
             samples, which no rig moves, but a wrap at 360 in degrees",
            span.max_step,
            span.max_step / TAU
        )
    } else {
        format!(
            ": {turns:.0} turns in radians, but a whole turn ({:.1}°) in degrees",
            hi - lo
        )
    };
    Err(WrongUnit(format!(
        "{}: the readings of `{}`, read in radians (--unit rad or the file's units), lie from \
         {lo:.4} to {hi:.4}{why}; if they are degrees, give --unit deg",
        crate::ui::shown(log),
        span.name
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(unit: AngleUnit, readings: &[f64]) -> anyhow::Result<()> {
        let mut c = UnitCheck::of([("a", unit)].into_iter(), None, true);
        for r in readings {
            c.push(&[unit.to_rad(*r)]);
        }
        c.finish(Path::new("run.csv"))
    }

    /// A turn in [0, 2π) or [−π, π) read as degrees is called radians; one in counts is
    /// called counts with its power of two. Both are data errors (exit 1), as degrees read as
    /// radians are: the readings, not the command line, are at fault.
    #[test]
    fn readings_that_fit_another_unit_are_named() {
        let turn: Vec<f64> = (0..1000).map(|k| k as f64 * TAU / 1000.0).collect();
        let err = check(AngleUnit::Deg, &turn).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("--unit rad") && text.contains("`a`"),
            "{text}"
        );
        assert_eq!(crate::exit::code_of(&err), crate::exit::DATA, "{text}");
        let signed: Vec<f64> = turn.iter().map(|x| x - PI).collect();
        assert!(check(AngleUnit::Deg, &signed).is_err());
        let counts: Vec<f64> = (0..16384).map(f64::from).collect();
        let err = check(AngleUnit::Deg, &counts).unwrap_err();
        assert!(err.to_string().contains("counts:16384"), "{err}");
        assert_eq!(crate::exit::code_of(&err), crate::exit::DATA, "{err}");
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
        // Radians accumulated over 60 turns (beyond 360 rad), or wrapped to [−π, π).
        let many: Vec<f64> = (0..60_000).map(|k| k as f64 * TAU / 1000.0).collect();
        assert!(check(AngleUnit::Rad, &many).is_ok());
        let wrapped: Vec<f64> = many.iter().map(|x| x.rem_euclid(TAU) - PI).collect();
        assert!(check(AngleUnit::Rad, &wrapped).is_ok());
    }

    /// Degrees read as radians: four turns wrapped at 360, and one turn there and back without
    /// a wrap (a TwinCAT `Unit` row saying `rad`), are a data error naming --unit deg.
    #[test]
    fn degrees_read_as_radians_are_named() {
        let wrapped: Vec<f64> = (0..14_400).map(|k| (k as f64 * 0.1) % 360.0).collect();
        let err = check(AngleUnit::Rad, &wrapped).unwrap_err();
        let text = err.to_string();
        assert!(err.downcast_ref::<WrongUnit>().is_some(), "{text}");
        assert!(
            text.contains("--unit deg") && text.contains("`a`") && text.contains("wrap at 360"),
            "{text}"
        );
        let there_and_back: Vec<f64> = (0..=3600)
            .chain((0..=3600).rev())
            .map(|k| k as f64 * 0.1)
            .collect();
        let text = check(AngleUnit::Rad, &there_and_back)
            .unwrap_err()
            .to_string();
        assert!(
            text.contains("whole turn") && text.contains("--unit deg"),
            "{text}"
        );
    }
}

//! Angles and angle units.
//!
//! # Units
//! Inside calib every angle is an `f64` in **radians**. Users see degrees (angles) and
//! arcseconds (errors); [`AngleUnit`] converts readings at the edges, where logs are read and
//! tables written.

use std::f64::consts::{PI, TAU};
use std::fmt;
use std::str::FromStr;

/// Arcseconds in one radian (648000/π).
pub const ARCSEC_PER_RAD: f64 = 648_000.0 / PI;
/// Degrees in one radian.
pub const DEG_PER_RAD: f64 = 180.0 / PI;

/// `x` wrapped to `[0, 2π)`.
pub fn wrap_2pi(x: f64) -> f64 {
    let r = x.rem_euclid(TAU);
    // rem_euclid can return TAU itself for tiny negative inputs.
    if r >= TAU { 0.0 } else { r }
}

/// `x` wrapped to `[−π, π)`.
pub fn wrap_pi(x: f64) -> f64 {
    wrap_2pi(x + PI) - PI
}

/// The unit a log's readings are written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AngleUnit {
    /// Degrees.
    Deg,
    /// Radians.
    Rad,
    /// Arcseconds.
    Arcsec,
    /// Revolutions.
    Rev,
    /// Encoder counts, with this many counts per revolution.
    Counts(u64),
}

impl AngleUnit {
    /// Radians in one of this unit.
    pub fn radians_per_unit(self) -> f64 {
        match self {
            AngleUnit::Deg => 1.0 / DEG_PER_RAD,
            AngleUnit::Rad => 1.0,
            AngleUnit::Arcsec => 1.0 / ARCSEC_PER_RAD,
            AngleUnit::Rev => TAU,
            AngleUnit::Counts(n) => TAU / n as f64,
        }
    }
    /// A reading in this unit, in radians.
    pub fn to_rad(self, value: f64) -> f64 {
        value * self.radians_per_unit()
    }
    /// Radians, in this unit.
    pub fn from_rad(self, rad: f64) -> f64 {
        rad / self.radians_per_unit()
    }
}

impl fmt::Display for AngleUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AngleUnit::Deg => f.write_str("deg"),
            AngleUnit::Rad => f.write_str("rad"),
            AngleUnit::Arcsec => f.write_str("arcsec"),
            AngleUnit::Rev => f.write_str("rev"),
            AngleUnit::Counts(n) => write!(f, "counts:{n}"),
        }
    }
}

/// A unit name that is not one of `deg`, `rad`, `arcsec`, `rev`, `counts:N`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown angle unit `{given}`: use deg, rad, arcsec, rev or counts:N (N counts per revolution)"
)]
pub struct UnknownUnit {
    /// What was given.
    pub given: String,
}

impl FromStr for AngleUnit {
    type Err = UnknownUnit;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = || UnknownUnit {
            given: s.to_string(),
        };
        match s.trim() {
            "deg" | "degree" | "degrees" => Ok(AngleUnit::Deg),
            "rad" | "radian" | "radians" => Ok(AngleUnit::Rad),
            "arcsec" | "arcseconds" => Ok(AngleUnit::Arcsec),
            "rev" | "revolution" | "revolutions" => Ok(AngleUnit::Rev),
            other => {
                let n = other.strip_prefix("counts:").ok_or_else(err)?;
                match n.parse::<u64>() {
                    Ok(n) if n > 0 => Ok(AngleUnit::Counts(n)),
                    _ => Err(err()),
                }
            }
        }
    }
}

/// Turns wrapped readings into a continuous angle.
///
/// A reading that jumps by more than half a revolution between consecutive samples is taken to
/// have wrapped (e.g. 359.9° → 0.1° continues at 360.1°). Readings that already accumulate over
/// revolutions pass through unchanged. This requires less than half a revolution of motion between
/// samples, which any log sampled fast enough to calibrate from satisfies.
#[derive(Debug, Clone, Default)]
pub struct Unwrapper {
    last: Option<f64>,
    offset: f64,
}

impl Unwrapper {
    /// A new unwrapper with no history.
    pub fn new() -> Self {
        Self::default()
    }
    /// The continuous angle of this reading (radians in, radians out).
    pub fn unwrap(&mut self, reading: f64) -> f64 {
        if let Some(last) = self.last {
            let step = reading - last;
            if step > PI {
                self.offset -= TAU * ((step + PI) / TAU).floor();
            } else if step < -PI {
                self.offset += TAU * ((-step + PI) / TAU).floor();
            }
        }
        self.last = Some(reading);
        reading + self.offset
    }
}

/// The extent of a channel's continuous (unwrapped) reading: what a method that needs whole
/// turns checks before blaming anything else when it fails.
#[derive(Debug, Clone, Default)]
pub struct Travel {
    unwrapper: Unwrapper,
    range: Option<(f64, f64)>,
}

impl Travel {
    /// The travel of no reading yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a reading (radians); non-finite ones are skipped.
    pub fn push(&mut self, reading: f64) {
        if reading.is_finite() {
            let u = self.unwrapper.unwrap(reading);
            let (lo, hi) = self.range.unwrap_or((u, u));
            self.range = Some((lo.min(u), hi.max(u)));
        }
    }

    /// Largest minus smallest continuous reading, radians (0 without readings).
    pub fn span(&self) -> f64 {
        self.range.map_or(0.0, |(lo, hi)| hi - lo)
    }

    /// [`PartialTurn`] for a method that `needs` whole turns, if the channel moved but never
    /// turned one.
    pub fn partial_turn(&self, needs: &'static str) -> Option<PartialTurn> {
        PartialTurn::of(self.span().to_degrees(), needs)
    }
}

/// A channel that moved but never turned a whole revolution, given to a method that needs whole
/// turns: what the method says first when it fails, since it is the likely reason.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "never turned a whole revolution (its readings span {span_deg:.3}°): {needs}; to map a joint that \
     never turns a whole revolution, calibrate it against a reference encoder on its shaft with the \
     reference method (`calib reference`), which writes a range table"
)]
pub struct PartialTurn {
    /// Largest minus smallest continuous reading, degrees.
    pub span_deg: f64,
    /// Why the method needs whole turns.
    pub needs: &'static str,
}

impl PartialTurn {
    /// A travel of `span_deg` (largest minus smallest continuous reading) as a partial turn: if
    /// it moved (more than 1°) but less than a revolution.
    pub fn of(span_deg: f64, needs: &'static str) -> Option<PartialTurn> {
        (span_deg > 1.0 && span_deg < 360.0).then_some(PartialTurn { span_deg, needs })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn travel_tells_a_partial_turn_from_a_whole_one_across_the_wrap() {
        let mut t = Travel::new();
        assert_eq!(t.partial_turn("").map(|p| p.span_deg), None);
        // 350° → 10° → 80°: 90° of travel across the wrap; NaN skipped.
        for deg in [350.0f64, 0.0, 10.0, f64::NAN, 80.0] {
            t.push(deg.to_radians());
        }
        assert!((t.partial_turn("").map(|p| p.span_deg).unwrap() - 90.0).abs() < 1e-9);
        for deg in [170.0f64, 260.0, 350.0, 80.0] {
            t.push(deg.to_radians());
        }
        assert_eq!(
            t.partial_turn("").map(|p| p.span_deg),
            None,
            "{}",
            t.span().to_degrees()
        );
        let mut still = Travel::new();
        still.push(0.3);
        still.push(0.3001);
        assert_eq!(still.partial_turn("").map(|p| p.span_deg), None);
    }

    #[test]
    fn conversions_round_trip() {
        assert!((1.0 / DEG_PER_RAD * ARCSEC_PER_RAD - 3600.0).abs() < 1e-9);
        for unit in [
            AngleUnit::Deg,
            AngleUnit::Rad,
            AngleUnit::Arcsec,
            AngleUnit::Rev,
            AngleUnit::Counts(4096),
        ] {
            let x = 1.234;
            assert!((unit.from_rad(unit.to_rad(x)) - x).abs() < 1e-12, "{unit}");
            assert_eq!(unit.to_string().parse::<AngleUnit>().unwrap(), unit);
        }
        assert!((AngleUnit::Counts(4096).to_rad(1024.0) - PI / 2.0).abs() < 1e-15);
    }

    #[test]
    fn unit_typos_are_rejected() {
        for bad in ["degs", "counts:", "counts:0", "counts:x", ""] {
            assert!(bad.parse::<AngleUnit>().is_err(), "{bad}");
        }
    }

    #[test]
    fn wrapping() {
        assert_eq!(wrap_2pi(-1e-300), 0.0);
        assert!((wrap_2pi(TAU + 1.0) - 1.0).abs() < 1e-12);
        assert!((wrap_pi(PI + 0.5) - (-PI + 0.5)).abs() < 1e-12);
    }

    #[test]
    fn unwrapper_continues_across_wraps_both_ways() {
        let mut u = Unwrapper::new();
        let deg = |d: f64| d.to_radians();
        let seq = [350.0, 355.0, 359.0, 3.0, 8.0, 2.0, 358.0, 355.0];
        let out: Vec<f64> = seq.iter().map(|&d| u.unwrap(deg(d)).to_degrees()).collect();
        let want = [350.0, 355.0, 359.0, 363.0, 368.0, 362.0, 358.0, 355.0];
        for (o, w) in out.iter().zip(want) {
            assert!((o - w).abs() < 1e-9, "{out:?}");
        }
        let mut acc = Unwrapper::new();
        for k in 0..1000 {
            let x = k as f64 * 0.1;
            assert!((acc.unwrap(x) - x).abs() < 1e-12);
        }
    }
}

//! The range of values a reader accepts: beyond it a value cannot be a real reading or time stamp,
//! or an `f64` can no longer hold it to the precision calibration needs, so a reader reports it
//! (naming file, line or message, and channel) instead of passing on a wrong number.

use std::f64::consts::TAU;

/// The largest reading magnitude, in revolutions from zero (10 million: a shaft at 6000 rpm turns
/// that far in 28 hours). At this magnitude an `f64` in radians resolves 7·10⁻⁹ rad (0.0015″);
/// a billion revolutions would blur readings to 0.2″.
pub const MAX_READING_REV: f64 = 1e7;

/// The largest time stamp magnitude, seconds (10¹⁰ s: the year 2286 as a Unix time). Larger
/// stamps are in another unit (milliseconds, nanoseconds), and an `f64` of them no longer
/// resolves the microseconds between samples.
pub const MAX_TIME_S: f64 = 1e10;

/// Why a reading of `value` in the log's unit (written `shown` in the log), `rad` radians, cannot
/// be used, if it cannot.
pub(crate) fn reading_problem(
    shown: impl std::fmt::Display,
    value: f64,
    rad: f64,
) -> Option<String> {
    if !value.is_finite() {
        return Some(format!(
            "reading `{shown}` is not a finite number; remove the row or repair the recording \
             (calib cannot calibrate from missing readings)"
        ));
    }
    let rev = rad / TAU;
    if rev.abs() <= MAX_READING_REV {
        return None;
    }
    Some(format!(
        "reading {shown} is {rev:.3e} revolutions from zero, beyond the {MAX_READING_REV:e} an \
         angle can be held to 0.002″; check the channel's unit (--unit), or subtract a whole \
         number of revolutions from the readings"
    ))
}

/// Why a time stamp of `t` seconds cannot be used, if it cannot.
pub(crate) fn time_problem(t: f64) -> Option<String> {
    if t.abs() <= MAX_TIME_S {
        return None;
    }
    Some(format!(
        "time stamp {t} s is beyond ±{MAX_TIME_S:e} s (the year 2286); time stamps must be in \
         seconds — convert milliseconds or nanoseconds"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_up_to_ten_million_revolutions_pass() {
        assert_eq!(reading_problem(360.0, 360.0, TAU), None);
        assert_eq!(reading_problem(-3.6e9, -3.6e9, -1e7 * TAU), None);
        let far = reading_problem(1e12, 1e12, 1e12_f64.to_radians()).expect("1e12 degrees");
        assert!(far.contains("revolutions from zero"), "{far}");
        assert!(reading_problem("nan", f64::NAN, f64::NAN).is_some());
        // A finite reading whose conversion overflows (1e308 revolutions).
        assert!(reading_problem("1e308", 1e308, f64::INFINITY).is_some());
    }

    #[test]
    fn time_stamps_beyond_the_year_2286_fail() {
        assert_eq!(time_problem(1.7e9), None);
        assert_eq!(time_problem(-1.7e9), None);
        assert!(time_problem(1.7e18).expect("ns").contains("nanoseconds"));
        assert!(time_problem(f64::INFINITY).is_some());
    }
}

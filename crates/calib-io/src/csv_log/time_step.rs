//! The time column's step, and the unit it suggests when it does not fit an encoder log.
//!
//! A column in milliseconds read as seconds makes every speed 1000× too slow: a run at 60 r/min
//! reads as 0.36°/s, under the methods' speed threshold, and the log "never moves". A column in
//! seconds read as milliseconds (a `time_ms` column that is not) makes it 1000× too fast. The
//! median step between the first rows' stamps shows either: an encoder is sampled at between
//! about 2 Hz and 500 kHz ([`PLAUSIBLE_STEP_S`]), so a step outside that range in the unit read,
//! and inside it in another, names that unit.

use super::dialect::TimeUnit;

/// Steps between rows, seconds, an encoder log is sampled at: 2 µs (500 kHz) to 0.5 s (2 Hz).
/// A lab export in ms steps by 1, 2, 5 or 10 (1 to 10 s read as seconds, outside); one in s
/// read as ms by 0.001 to 0.01 (1 to 10 µs, inside only above 2 µs: a 1 kHz log read as ms
/// steps by 1 µs, outside).
pub const PLAUSIBLE_STEP_S: std::ops::Range<f64> = 2e-6..0.5;

/// Steps kept for the median: those between the first this many + 1 rows.
const KEPT_STEPS: usize = 1000;

/// Where the unit of the time column came from, for the hint's wording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnitFrom {
    /// `--time-unit`.
    Option,
    /// The column's name (`time_ms`, `t [s]`).
    Name,
    /// The units row under the header.
    UnitsRow,
    /// Nothing said: seconds.
    Default,
}

/// The time column of a CSV log and the steps between its first rows' stamps.
#[derive(Debug, Clone)]
pub struct TimeStep {
    column: String,
    unit: TimeUnit,
    from: UnitFrom,
    /// The previous stamp, seconds.
    prev: Option<f64>,
    /// The steps between the first [`KEPT_STEPS`] + 1 stamps, seconds (positive ones only: a
    /// repeated stamp is refused by the reader, or counted by `inspect`).
    steps: Vec<f64>,
}

impl TimeStep {
    /// The column `column`, read in `unit` as `from` says.
    pub(crate) fn new(column: &str, unit: TimeUnit, from: UnitFrom) -> Self {
        TimeStep {
            column: column.to_string(),
            unit,
            from,
            prev: None,
            steps: Vec::new(),
        }
    }

    /// Adds a row's stamp, seconds.
    pub(crate) fn push(&mut self, t: f64) {
        if self.steps.len() < KEPT_STEPS
            && let Some(prev) = self.prev
            && t > prev
        {
            self.steps.push(t - prev);
        }
        self.prev = Some(t);
    }

    /// The median step between the first rows, seconds (`None` before two rows).
    pub fn median_s(&self) -> Option<f64> {
        let mut s = self.steps.clone();
        if s.is_empty() {
            return None;
        }
        let mid = s.len() / 2;
        let (_, m, _) = s.select_nth_unstable_by(mid, f64::total_cmp);
        Some(*m)
    }

    /// The unit the column would have to be in for its median step to be an encoder log's
    /// ([`PLAUSIBLE_STEP_S`]) when it is not one in the unit read, and what to say: "the time
    /// column `t` steps by 1 (median of its first rows), read as seconds (the default …): 1
    /// sample per 1 s, outside …; if it is in milliseconds, say `--time-unit ms`". `None` when
    /// the step is plausible or no other unit makes it so.
    pub fn unit_hint(&self) -> Option<String> {
        let step_s = self.median_s()?;
        if PLAUSIBLE_STEP_S.contains(&step_s) {
            return None;
        }
        let raw = step_s / self.unit.seconds();
        let other = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us, TimeUnit::Ns]
            .into_iter()
            .filter(|&u| u != self.unit)
            .find(|u| PLAUSIBLE_STEP_S.contains(&(raw * u.seconds())))?;
        let from = match self.from {
            UnitFrom::Option => "as --time-unit says",
            UnitFrom::Name => "as its name says",
            UnitFrom::UnitsRow => "as the units row says",
            UnitFrom::Default => "the default for a column without a unit",
        };
        let rate = if step_s >= 1.0 {
            format!("1 sample per {} s", crate::limits::readable(step_s))
        } else {
            format!(
                "{} samples per second",
                crate::limits::readable(1.0 / step_s)
            )
        };
        Some(format!(
            "the time column `{}` steps by {} (median of its first rows), read as {} ({from}): \
             {rate}, outside the 2 Hz to 500 kHz encoders are logged at; if it is in {}, say \
             `--time-unit {}`",
            self.column,
            crate::limits::readable(raw),
            name(self.unit),
            name(other),
            suffix(other),
        ))
    }
}

/// The unit's name in a sentence.
fn name(unit: TimeUnit) -> &'static str {
    match unit {
        TimeUnit::S => "seconds",
        TimeUnit::Ms => "milliseconds",
        TimeUnit::Us => "microseconds",
        TimeUnit::Ns => "nanoseconds",
        TimeUnit::Ticks => "100 ns ticks",
    }
}

/// The unit as `--time-unit` takes it.
fn suffix(unit: TimeUnit) -> &'static str {
    match unit {
        TimeUnit::S => "s",
        TimeUnit::Ms => "ms",
        TimeUnit::Us => "us",
        TimeUnit::Ns => "ns",
        TimeUnit::Ticks => "100ns",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stepped(unit: TimeUnit, from: UnitFrom, step: f64) -> TimeStep {
        let mut s = TimeStep::new("t", unit, from);
        for i in 0..2000 {
            s.push(i as f64 * step * unit.seconds());
        }
        s
    }

    #[test]
    fn milliseconds_read_as_seconds_are_named() {
        let hint = stepped(TimeUnit::S, UnitFrom::Default, 1.0)
            .unit_hint()
            .unwrap();
        assert!(hint.contains("steps by 1 "), "{hint}");
        assert!(hint.contains("say `--time-unit ms`"), "{hint}");
        assert!(hint.contains("1 sample per 1 s"), "{hint}");
    }

    #[test]
    fn microseconds_read_as_seconds_skip_milliseconds() {
        // 1000 µs read as ms is 1 s: outside; as µs 1 ms.
        let hint = stepped(TimeUnit::S, UnitFrom::Default, 1000.0)
            .unit_hint()
            .unwrap();
        assert!(hint.contains("say `--time-unit us`"), "{hint}");
    }

    #[test]
    fn seconds_read_as_milliseconds_are_named() {
        let hint = stepped(TimeUnit::Ms, UnitFrom::Name, 0.001)
            .unit_hint()
            .unwrap();
        assert!(
            hint.contains("read as milliseconds (as its name says)"),
            "{hint}"
        );
        assert!(hint.contains("say `--time-unit s`"), "{hint}");
    }

    #[test]
    fn plausible_steps_give_no_hint() {
        for (unit, step) in [
            (TimeUnit::S, 0.005),
            (TimeUnit::S, 0.25),
            (TimeUnit::Ms, 1.0),
            (TimeUnit::Us, 50.0),
            (TimeUnit::Ns, 1e6),
        ] {
            assert_eq!(
                stepped(unit, UnitFrom::Option, step).unit_hint(),
                None,
                "{step}"
            );
        }
        // Too slow in every unit: nothing to suggest.
        assert_eq!(
            TimeStep::new("t", TimeUnit::S, UnitFrom::Default).unit_hint(),
            None
        );
    }

    #[test]
    fn the_median_ignores_a_pause() {
        let mut s = TimeStep::new("t", TimeUnit::S, UnitFrom::Default);
        for t in [0.0, 0.001, 0.002, 60.0, 60.001, 60.002] {
            s.push(t);
        }
        assert!((s.median_s().unwrap() - 0.001).abs() < 1e-12);
        assert_eq!(s.unit_hint(), None);
    }
}

//! The time column's step and the readings' speed, and the unit they suggest when they do not
//! fit an encoder log.
//!
//! A column in milliseconds read as seconds makes every speed 1000× too slow: a run at 60 r/min
//! reads as 0.36°/s, under the methods' speed threshold, and the log "never moves". A column in
//! seconds read as milliseconds (a `time_ms` column that is not) makes it 1000× too fast. Two
//! things the data holds show it, whatever the rate:
//! - the median step between the first rows' stamps: an encoder is sampled at between about
//!   2 Hz and 500 kHz ([`PLAUSIBLE_STEP_S`]), so a step outside that range in the unit read, and
//!   inside it in another, names that unit ([`TimeStep::unit_hint`]);
//! - the readings' speed: over the first [`MOTION_ROWS`] rows, the farthest any channel gets
//!   from where it first moved [`MIN_TRAVEL_RAD`] from its first reading (so that noise and a
//!   pause before the run are not counted), over the time it took. A shaft turning faster than [`MAX_SPEED_RAD_S`] (30,000 r/min) in the unit read,
//!   and at an ordinary speed and rate in a larger one, names that unit
//!   ([`TimeStep::unit_hint`]); a run the methods find too slow to count as moving, whose
//!   readings do move and would turn fast enough in a smaller unit, names that one
//!   ([`TimeStep::unit_hint_when_still`]). The speed alone cannot tell a slow run from one in
//!   the wrong unit, so this hint is given only where a method found the run too slow.

use super::dialect::TimeUnit;

/// Steps between rows, seconds, an encoder log is sampled at: 2 µs (500 kHz) to 0.5 s (2 Hz).
/// A lab export in ms steps by 1, 2, 5 or 10 (1 to 10 s read as seconds, outside); one in s
/// read as ms by 0.001 to 0.01 (1 to 10 µs, inside only above 2 µs: a 1 kHz log read as ms
/// steps by 1 µs, outside).
pub const PLAUSIBLE_STEP_S: std::ops::Range<f64> = 2e-6..0.5;

/// Steps kept for the median: those between the first this many + 1 rows.
const KEPT_STEPS: usize = 1000;

/// Rows the readings' motion is followed over: enough to get past a pause at the start of a run
/// (20 s at 1 kHz), few enough to cost nothing on a long log.
pub const MOTION_ROWS: u64 = 20_000;

/// The least travel of a channel from its first reading that counts as motion, radians (1°:
/// far above any encoder's noise and quantisation).
pub const MIN_TRAVEL_RAD: f64 = std::f64::consts::PI / 180.0;

/// The fastest an encoder log's shaft is taken to turn, rad/s: 30,000 r/min, about what common
/// encoder ICs are rated for (AS5047P: 28,000 r/min). A log in seconds read as milliseconds turns
/// 1000× faster than it did: any run above 30 r/min then exceeds it.
pub const MAX_SPEED_RAD_S: f64 = 30_000.0 * std::f64::consts::TAU / 60.0;

/// Where the unit of the time column came from, for the hint's wording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnitFrom {
    /// the `time_unit` option.
    Option,
    /// The column's name (`time_ms`, `t [s]`).
    Name,
    /// The units row under the header.
    UnitsRow,
    /// The first stamp's magnitude: a date since 1970 in this unit
    /// ([`epoch_unit`](super::dialect::epoch_unit)).
    Magnitude,
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
    /// Rows seen.
    rows: u64,
    /// Each channel's motion so far.
    channels: Vec<Travel>,
    /// The farthest any channel got from where it started moving, radians, and in how long,
    /// seconds.
    farthest: (f64, f64),
}

/// One channel's travel from its first reading.
#[derive(Debug, Clone, Copy)]
struct Travel {
    /// The last reading, radians (NaN before the first).
    last: f64,
    /// The travel from the first reading, radians, unwrapped.
    travel: f64,
    /// When and at which travel it first got [`MIN_TRAVEL_RAD`] from its first reading.
    moved: Option<(f64, f64)>,
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
            rows: 0,
            channels: Vec::new(),
            farthest: (0.0, 0.0),
        }
    }

    /// Adds a row's stamp, seconds, and its readings, radians (NaN where a channel has none).
    pub(crate) fn push(&mut self, t: f64, readings: &[f64]) {
        if self.steps.len() < KEPT_STEPS
            && let Some(prev) = self.prev
            && t > prev
        {
            self.steps.push(t - prev);
        }
        self.prev = Some(t);
        if self.rows < MOTION_ROWS {
            self.follow(t, readings);
        }
        self.rows += 1;
    }

    /// Follows each channel's travel (steps wrapped to ±180°: wrapped and accumulated readings
    /// alike).
    fn follow(&mut self, t: f64, readings: &[f64]) {
        if self.channels.len() < readings.len() {
            let still = Travel {
                last: f64::NAN,
                travel: 0.0,
                moved: None,
            };
            self.channels.resize(readings.len(), still);
        }
        for (c, &r) in self.channels.iter_mut().zip(readings) {
            if r.is_nan() {
                continue;
            }
            if !c.last.is_nan() {
                c.travel += calib_core::angle::wrap_pi(r - c.last);
                match c.moved {
                    None if c.travel.abs() >= MIN_TRAVEL_RAD => c.moved = Some((t, c.travel)),
                    Some((t0, travel0)) if (c.travel - travel0).abs() > self.farthest.0 => {
                        self.farthest = ((c.travel - travel0).abs(), t - t0);
                    }
                    _ => {}
                }
            }
            c.last = r;
        }
    }

    /// The readings' speed over the first rows, rad/s: the farthest a channel got from where it
    /// started moving over the time it took; `None` if none got [`MIN_TRAVEL_RAD`] from there.
    pub fn speed_rad_s(&self) -> Option<f64> {
        let (travel, elapsed) = self.farthest;
        (travel >= MIN_TRAVEL_RAD && elapsed > 0.0).then(|| travel / elapsed)
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
    /// ([`PLAUSIBLE_STEP_S`]) and its readings' speed one a shaft turns at ([`MAX_SPEED_RAD_S`])
    /// when they are not in the unit read, and what to say: "the time column `t` steps by 1
    /// (median of its first rows), read as seconds (the default …): 1 sample per 1 s, outside …;
    /// if it is in milliseconds, say `time_unit = ms`". `None` when both are plausible or no
    /// other unit makes them so.
    pub fn unit_hint(&self) -> Option<String> {
        let step_s = self.median_s()?;
        let speed = self.speed_rad_s();
        let plausible = |step: f64, speed: Option<f64>| {
            PLAUSIBLE_STEP_S.contains(&step) && speed.is_none_or(|v| v <= MAX_SPEED_RAD_S)
        };
        if plausible(step_s, speed) {
            return None;
        }
        let other = self.others().find(|&u| {
            let k = self.factor(u);
            plausible(step_s * k, speed.map(|v| v / k))
        })?;
        let k = self.factor(other);
        let head = format!(
            "the time column `{}` steps by {} (median of its first rows), read as {} ({}): {}",
            self.column,
            crate::limits::readable(step_s / self.unit.seconds()),
            name(self.unit),
            self.from(),
            rate(step_s)
        );
        Some(match speed {
            Some(v) if PLAUSIBLE_STEP_S.contains(&step_s) => format!(
                "{head}, and the readings turn at {} on average, faster than the {} encoders are \
                 rated for; if it is in {}, they turn at {} ({}): say `time_unit = {}`",
                rpm(v),
                rpm(MAX_SPEED_RAD_S),
                name(other),
                rpm(v / k),
                rate(step_s * k),
                suffix(other),
            ),
            _ => format!(
                "{head}, outside the 2 Hz to 500 kHz encoders are logged at; if it is in {}, say \
                 `time_unit = {}`",
                name(other),
                suffix(other),
            ),
        })
    }

    /// What to say when a method found the run too slow to count as moving (under `min_speed`,
    /// rad/s): [`unit_hint`](Self::unit_hint) where it has something to say, else, if the
    /// readings do move ([`speed_rad_s`](Self::speed_rad_s)) and would turn at `min_speed` or
    /// more in a smaller unit at a plausible rate and speed, that unit. The speed alone cannot
    /// tell a slow run from a column in the wrong unit: said only where a method needs the speed.
    pub fn unit_hint_when_still(&self, min_speed: f64) -> Option<String> {
        if let Some(hint) = self.unit_hint() {
            return Some(hint);
        }
        let step_s = self.median_s()?;
        let speed = self.speed_rad_s()?;
        if speed >= min_speed {
            return None;
        }
        let other = self.others().filter(|&u| self.factor(u) < 1.0).find(|&u| {
            let k = self.factor(u);
            PLAUSIBLE_STEP_S.contains(&(step_s * k))
                && (min_speed..=MAX_SPEED_RAD_S).contains(&(speed / k))
        })?;
        let k = self.factor(other);
        Some(format!(
            "the readings turn at {} on average by the time column `{}` read as {} ({}), {}; if \
             it is in {}, they turn at {} ({}): say `time_unit = {}`",
            deg_per_s(speed),
            self.column,
            name(self.unit),
            self.from(),
            rate(step_s),
            name(other),
            deg_per_s(speed / k),
            rate(step_s * k),
            suffix(other),
        ))
    }

    /// The units the column could be in instead, the nearest first.
    fn others(&self) -> impl Iterator<Item = TimeUnit> + '_ {
        let mut units = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us, TimeUnit::Ns];
        units.sort_by(|a, b| {
            let d = |u: &TimeUnit| self.factor(*u).log10().abs();
            d(a).total_cmp(&d(b))
        });
        units.into_iter().filter(move |&u| u != self.unit)
    }

    /// Seconds per second read: what the stamps' steps are multiplied by in `unit`.
    fn factor(&self, unit: TimeUnit) -> f64 {
        unit.seconds() / self.unit.seconds()
    }

    /// Where the unit read came from, in words.
    fn from(&self) -> &'static str {
        match self.from {
            UnitFrom::Option => "as the `time_unit` option says",
            UnitFrom::Name => "as its name says",
            UnitFrom::UnitsRow => "as the units row says",
            UnitFrom::Magnitude => "as its stamps' magnitude says: a date since 1970",
            UnitFrom::Default => "the default for a column without a unit",
        }
    }
}

/// A step between samples as a rate: "1 sample per 5 s", "200 samples per second".
fn rate(step_s: f64) -> String {
    if step_s >= 1.0 {
        format!("1 sample per {} s", crate::limits::readable(step_s))
    } else {
        format!(
            "{} samples per second",
            crate::limits::readable(1.0 / step_s)
        )
    }
}

/// A speed in r/min, rounded to 3 significant digits.
fn rpm(rad_s: f64) -> String {
    format!("{} r/min", round3(rad_s * 60.0 / std::f64::consts::TAU))
}

/// A speed in °/s, rounded to 3 significant digits.
fn deg_per_s(rad_s: f64) -> String {
    format!("{}°/s", round3(rad_s.to_degrees()))
}

/// `x` to 3 significant digits, written without an exponent.
fn round3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = 2 - x.abs().log10().floor() as i32;
    let scale = 10f64.powi(digits);
    crate::limits::readable((x * scale).round() / scale)
}

/// The unit's name in a sentence.
fn name(unit: TimeUnit) -> &'static str {
    unit.name()
}

/// The unit as the `time_unit` option takes it.
fn suffix(unit: TimeUnit) -> &'static str {
    unit.suffix()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stepped(unit: TimeUnit, from: UnitFrom, step: f64) -> TimeStep {
        let mut s = TimeStep::new("t", unit, from);
        for i in 0..2000 {
            s.push(i as f64 * step * unit.seconds(), &[]);
        }
        s
    }

    #[test]
    fn milliseconds_read_as_seconds_are_named() {
        let hint = stepped(TimeUnit::S, UnitFrom::Default, 1.0)
            .unit_hint()
            .unwrap();
        assert!(hint.contains("steps by 1 "), "{hint}");
        assert!(hint.contains("say `time_unit = ms`"), "{hint}");
        assert!(hint.contains("1 sample per 1 s"), "{hint}");
    }

    #[test]
    fn microseconds_read_as_seconds_skip_milliseconds() {
        // 1000 µs read as ms is 1 s: outside; as µs 1 ms.
        let hint = stepped(TimeUnit::S, UnitFrom::Default, 1000.0)
            .unit_hint()
            .unwrap();
        assert!(hint.contains("say `time_unit = us`"), "{hint}");
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
        assert!(hint.contains("say `time_unit = s`"), "{hint}");
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

    /// A run at `rpm` sampled at `hz`, its stamps written in `written` into a column `time`
    /// read in `read`: 3000 rows, a wrapped reading (radians) and a still one.
    fn run(written: TimeUnit, read: TimeUnit, hz: f64, rpm: f64) -> TimeStep {
        let mut s = TimeStep::new("time", read, UnitFrom::Name);
        for i in 0..3000 {
            let t = i as f64 / hz;
            let angle = (rpm / 60.0 * std::f64::consts::TAU * t).rem_euclid(std::f64::consts::TAU);
            // What the reader makes of the number written.
            s.push(t / written.seconds() * read.seconds(), &[angle, 0.25]);
        }
        s
    }

    #[test]
    fn seconds_read_as_milliseconds_are_named_at_any_rate() {
        // 20 Hz to 200 Hz in seconds under a `time_ms` name: 20 to 200 kHz, a rate encoders are
        // logged at, but 60 r/min reads as 60,000 r/min.
        for hz in [20.0, 200.0] {
            let hint = run(TimeUnit::S, TimeUnit::Ms, hz, 60.0)
                .unit_hint()
                .unwrap_or_else(|| panic!("{hz} Hz: no hint"));
            assert!(
                hint.contains(
                    "the readings turn at 60000 r/min on average, faster than the 30000 r/min"
                ),
                "{hint}"
            );
            assert!(
                hint.contains(&format!(
                    "if it is in seconds, they turn at 60 r/min ({hz} samples per second): say \
                     `time_unit = s`"
                )),
                "{hint}"
            );
        }
        // Turning 40 r/min: 40,000 r/min read, still named.
        assert!(
            run(TimeUnit::S, TimeUnit::Ms, 100.0, 40.0)
                .unit_hint()
                .is_some()
        );
    }

    #[test]
    fn fast_and_slow_runs_in_their_unit_give_no_hint() {
        for (unit, hz, rpm) in [
            (TimeUnit::S, 100_000.0, 10_000.0),
            (TimeUnit::S, 200.0, 60.0),
            (TimeUnit::Ms, 1000.0, 600.0),
            (TimeUnit::S, 10.0, 0.05),
        ] {
            let s = run(unit, unit, hz, rpm);
            assert_eq!(s.unit_hint(), None, "{hz} Hz {rpm} r/min");
            // Above a method's 1°/s threshold: nothing to say even when one fails. (0.05 r/min
            // is under it: a method finding it still is told what milliseconds would make it.)
            if rpm > 1.0 {
                assert_eq!(s.unit_hint_when_still(1f64.to_radians()), None);
            }
        }
    }

    #[test]
    fn milliseconds_read_as_seconds_are_named_where_a_method_finds_the_run_still() {
        // 10 kHz in ms read as seconds: steps of 0.1 s (10 Hz, plausible), 60 r/min reads as
        // 0.36°/s. Nothing to say by itself (a slow run looks the same), but under a method's
        // 1°/s threshold milliseconds make it 360°/s.
        let ms = run(TimeUnit::Ms, TimeUnit::S, 10_000.0, 60.0);
        assert_eq!(ms.unit_hint(), None);
        let hint = ms.unit_hint_when_still(1f64.to_radians()).unwrap();
        assert!(
            hint.contains(
                "the readings turn at 0.36°/s on average by the time column `time` read as seconds (as its \
                 name says), 10 samples per second; if it is in \
                 milliseconds, they turn at 360°/s (10000 samples per second): say \
                 `time_unit = ms`"
            ),
            "{hint}"
        );
        // Moving fast enough: nothing to say.
        let s = run(TimeUnit::S, TimeUnit::S, 10_000.0, 60.0);
        assert_eq!(s.unit_hint_when_still(1f64.to_radians()), None);
        // Still (noise of 0.1″ only): not the time's fault.
        let mut still = TimeStep::new("t", TimeUnit::S, UnitFrom::Default);
        for i in 0..3000 {
            let noise = if i % 2 == 0 { 5e-7 } else { -5e-7 };
            still.push(i as f64 * 0.1, &[1.0 + noise]);
        }
        assert_eq!(still.speed_rad_s(), None);
        assert_eq!(still.unit_hint_when_still(1f64.to_radians()), None);
    }

    #[test]
    fn the_median_ignores_a_pause() {
        let mut s = TimeStep::new("t", TimeUnit::S, UnitFrom::Default);
        for t in [0.0, 0.001, 0.002, 60.0, 60.001, 60.002] {
            s.push(t, &[]);
        }
        assert!((s.median_s().unwrap() - 0.001).abs() < 1e-12);
        assert_eq!(s.unit_hint(), None);
    }
}

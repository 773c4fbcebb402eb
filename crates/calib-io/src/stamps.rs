//! The clock's stamps must increase: one rule for every reader.
//!
//! Every method reads a log as a time series, so a sample whose stamp repeats or goes back is not
//! a reading at a new time. Three cases, told apart by [`StampOrder::check`]:
//!
//! - **an exact duplicate** ([`Step::Duplicate`]): the same stamp and the same values as the
//!   message before — a message recorded twice (a recorder or a bridge subscribed twice, a
//!   replayed segment, a log merged with itself). It carries nothing new: the reader drops it
//!   and counts it ([`StampOrder::duplicates`]), the count reaches `report.json`
//!   (`details.reading.duplicates_dropped`) and a warning naming the file. Passed on, copies
//!   double-weighted their angles: a `csrr` map from a log whose every message was recorded
//!   twice came out 254.9″ p-p instead of 68.9″, exit 0; refused, a log with 400 copies among
//!   its messages could not be calibrated at all.
//! - **a conflict** ([`Backward::conflict`]): the same stamp with other values — two readings
//!   claiming one instant. Which is right cannot be known: an error naming both messages (index,
//!   row id or line) and the values that differ.
//! - **a step back** ([`Backward`] without a conflict): neighbours swapped, publisher stamps
//!   running against the recorder's receive order. Passed on, it becomes a spurious velocity
//!   step: an error naming the message before, and the remedy (sort the log, or read the
//!   recorder's times).
//!
//! The CSV reader checks each row (each channel's cells in a sparse file, where two channels
//! may share a stamp on separate rows); the MCAP and bag readers check each topic's messages
//! and refuse a conflict or a step back only on the clock channel (the first selected, on whose
//! stamps every sample is taken). Other channels are interpolated onto the clock, and their own
//! out-of-order samples are left out and counted (the aligner's `out_of_order`).
//!
//! # Using it in a reader
//!
//! ```ignore
//! let mut order = StampOrder::default();          // one per series of stamps (a topic)
//! for (key, stamp_ns, values) in messages {       // key: the message's index, row id or line
//!     match order.check(stamp_ns, key, &values) {
//!         Ok(Step::New) => emit(stamp_ns, values),
//!         Ok(Step::Duplicate) => {}               // dropped; counted in `order.duplicates()`
//!         Err(back) => return Err(back.describe(clock, "message", time_source)),
//!     }
//! }
//! ```
//!
//! Stamps are `i64` nanoseconds by default; the CSV reader checks its `f64` seconds (a file's
//! stamps may be finer than a nanosecond). `calib inspect` passes conflicts and steps back on
//! ([`ReadOptions::allow_unordered_time`](crate::ReadOptions::allow_unordered_time)) and counts
//! them, so that what it reports is what the methods refuse; exact duplicates it drops too.

use crate::TimeSource;
use crate::ros2::decode::seconds;

/// Stamps from this many seconds on (2²¹ s, 24 days: seconds since 1970, ~1.7·10⁹ s, whose
/// doubles are 2.4·10⁻⁷ s apart) are counted from the whole second of the log's first stamp, so
/// that a sample's time, a double, keeps every nanosecond; below it doubles are at most
/// 4.7·10⁻¹⁰ s apart and stamps are kept as they are. Reports add the origin back
/// ([`crate::LogReader::time_origin_s`]).
pub(crate) const ORIGIN_FROM_S: i64 = 1 << 21;

/// The order of one series of stamps (a topic's, a CSV file's or one of its channels'): the
/// last stamp taken, the message that carried it and its values, and how many exact duplicates
/// of it were met.
#[derive(Debug, Clone, Default)]
pub(crate) struct StampOrder<T = i64> {
    last: Option<Last<T>>,
    duplicates: u64,
}

/// The last message a [`StampOrder`] took.
#[derive(Debug, Clone)]
struct Last<T> {
    stamp: T,
    message: i64,
    values: Vec<f64>,
}

/// What [`StampOrder::check`] makes of a message whose stamp does not go back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Step {
    /// A later stamp: a new reading, to be used.
    New,
    /// The previous message's stamp and values again: a copy, to be dropped (it is counted).
    Duplicate,
}

/// A stamp that repeats with other values or goes back, found by [`StampOrder::check`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Backward<T = i64> {
    /// The refused stamp.
    pub stamp: T,
    /// The previous stamp.
    pub previous: T,
    /// The message (index, row id or line key) that carried the previous stamp.
    pub previous_message: i64,
    /// For a repeated stamp, the values that differ: `(index, previous value, this value)` —
    /// the index into the values the reader passed. `None` for a stamp that goes back.
    pub conflict: Option<Vec<(usize, f64, f64)>>,
}

impl<T: PartialOrd + Copy> StampOrder<T> {
    /// Takes the stamp of `message` (its index in the file, its row id, or any number the
    /// reader finds it again by) and its `values` (NaN where it has none).
    ///
    /// [`Step::New`] if the stamp exceeds the previous one (or is the first); then it is the
    /// one the next is compared with. [`Step::Duplicate`] if it equals the previous one and so
    /// does every value (NaN equal to NaN, `-0.0` to `0.0`); counted, and the previous stays.
    /// Otherwise the [`Backward`]: a repeat with other values (`conflict`) or a step back; the
    /// previous stays, so the next increasing stamp passes.
    pub(crate) fn check(
        &mut self,
        stamp: T,
        message: i64,
        values: &[f64],
    ) -> Result<Step, Backward<T>> {
        let Some(last) = &mut self.last else {
            self.last = Some(Last {
                stamp,
                message,
                values: values.to_vec(),
            });
            return Ok(Step::New);
        };
        if stamp > last.stamp {
            last.stamp = stamp;
            last.message = message;
            last.values.clear();
            last.values.extend_from_slice(values);
            return Ok(Step::New);
        }
        let conflict = (stamp == last.stamp).then(|| differing(&last.values, values));
        if conflict.as_ref().is_some_and(Vec::is_empty) {
            self.duplicates += 1;
            return Ok(Step::Duplicate);
        }
        Err(Backward {
            stamp,
            previous: last.stamp,
            previous_message: last.message,
            conflict,
        })
    }

    /// Exact duplicates met so far ([`Step::Duplicate`]).
    pub(crate) fn duplicates(&self) -> u64 {
        self.duplicates
    }
}

/// The values that differ between `previous` and `values`, with their index; a value missing
/// from one (a shorter list) is NaN.
fn differing(previous: &[f64], values: &[f64]) -> Vec<(usize, f64, f64)> {
    let at = |v: &[f64], i: usize| v.get(i).copied().unwrap_or(f64::NAN);
    (0..previous.len().max(values.len()))
        .map(|i| (i, at(previous, i), at(values, i)))
        .filter(|&(_, a, b)| !(a == b || (a.is_nan() && b.is_nan())))
        .collect()
}

impl<T> Backward<T> {
    /// The differing values as a message lists them: "`a` 0.25 there, 0.5 here" (the first
    /// three, then how many more), each named by `name(index)` and shown by `show(value)`.
    pub(crate) fn differences(
        &self,
        name: impl Fn(usize) -> String,
        show: impl Fn(f64) -> String,
    ) -> String {
        let Some(conflict) = &self.conflict else {
            return String::new();
        };
        let shown = |v: f64| {
            if v.is_nan() {
                "none".to_string()
            } else {
                show(v)
            }
        };
        let mut text: Vec<String> = conflict
            .iter()
            .take(3)
            .map(|&(i, a, b)| format!("`{}` {} there, {} here", name(i), shown(a), shown(b)))
            .collect();
        if conflict.len() > 3 {
            text.push(format!("{} more", conflict.len() - 3));
        }
        text.join("; ")
    }
}

impl Backward<i64> {
    /// What is wrong and what to do, for the MCAP and bag readers: `clock` names the clock
    /// channel, `message` says how the previous message is called (`message 41`, `message id
    /// 42`), `time` where the stamps come from, `name` names the values' channels (raw indices),
    /// `show` writes a value.
    pub(crate) fn describe(
        &self,
        clock: &str,
        message: &str,
        time: TimeSource,
        name: impl Fn(usize) -> String,
        show: impl Fn(f64) -> String,
    ) -> String {
        let source = match time {
            TimeSource::Header => "header stamp",
            TimeSource::Log => "log time",
        };
        let head = format!(
            "the {source} {} s of clock channel `{clock}`",
            seconds(self.stamp)
        );
        if self.conflict.is_some() {
            return format!(
                "{head} repeats that of {message} {} with other readings ({}); a stamp's \
                 readings must be one message: two publishers (or a bridge) wrote this topic, \
                 or the clock is too coarse — keep one publisher, or record each on its own topic",
                self.previous_message,
                self.differences(name, show)
            );
        }
        let remedy = match time {
            TimeSource::Header => {
                "; if the recorder's receive times increase, read them with `time = log`"
            }
            TimeSource::Log => "",
        };
        format!(
            "{head} goes back before the previous one, {} s ({message} {}); a channel's stamps \
             must increase (messages out of order give this): sort the log by time{remedy}",
            seconds(self.previous),
            self.previous_message
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exact_copy_is_a_duplicate_and_other_values_a_conflict() {
        let mut order = StampOrder::default();
        assert_eq!(
            order.check(1_000_000_000, 0, &[1.0, f64::NAN]),
            Ok(Step::New)
        );
        assert_eq!(order.check(2_000_000_000, 1, &[2.0, 0.0]), Ok(Step::New));
        // The same stamp and values (-0.0 is 0.0): dropped and counted.
        assert_eq!(
            order.check(2_000_000_000, 2, &[2.0, -0.0]),
            Ok(Step::Duplicate)
        );
        assert_eq!(order.duplicates(), 1);
        let conflict = order.check(2_000_000_000, 3, &[2.5, 0.0]).unwrap_err();
        assert_eq!(
            (conflict.previous, conflict.previous_message),
            (2_000_000_000, 1)
        );
        assert_eq!(conflict.conflict.as_deref(), Some(&[(0, 2.0, 2.5)][..]));
        let text = conflict.describe(
            "a",
            "message",
            TimeSource::Header,
            |i| ["a", "b"][i].to_string(),
            |v| v.to_string(),
        );
        assert!(
            text.contains("repeats that of message 1 with other readings (`a` 2 there, 2.5 here)"),
            "{text}"
        );
        let back = order.check(1_500_000_000, 4, &[3.0, 0.0]).unwrap_err();
        assert!(back.conflict.is_none());
        let text = back.describe(
            "a",
            "message id",
            TimeSource::Log,
            |_| "a".into(),
            |v| v.to_string(),
        );
        assert!(
            text.contains("the log time 1.5 s of clock channel `a` goes back before the previous one, 2 s (message id 1)"),
            "{text}"
        );
        assert!(!text.contains("`time = log`"), "{text}");
        let text = back.describe(
            "a",
            "message",
            TimeSource::Header,
            |_| "a".into(),
            |v| v.to_string(),
        );
        assert!(text.contains("`time = log`"), "{text}");
        // A refused stamp does not move the order: the next increasing one passes.
        assert_eq!(order.check(3_000_000_000, 5, &[3.0, 0.0]), Ok(Step::New));
        assert_eq!(order.duplicates(), 1);
    }

    #[test]
    fn seconds_are_checked_as_well_as_nanoseconds() {
        let mut order: StampOrder<f64> = StampOrder::default();
        assert_eq!(order.check(0.5, 2, &[1.0]), Ok(Step::New));
        assert_eq!(order.check(0.5, 3, &[1.0]), Ok(Step::Duplicate));
        let back = order.check(0.25, 4, &[1.0]).unwrap_err();
        assert_eq!((back.stamp, back.previous), (0.25, 0.5));
    }
}

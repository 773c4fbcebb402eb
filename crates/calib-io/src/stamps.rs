//! The clock's stamps must increase: one rule for every reader.
//!
//! Every method reads a log as a time series, so a sample whose stamp repeats or goes back is not
//! a reading at a new time but a copy (a message recorded twice, a log merged with itself) or a
//! reading out of place (neighbours swapped, publisher stamps running against the recorder's
//! receive order). Passed on, copies double-weight their angles and swapped samples become
//! spurious velocity steps: a `csrr` map from a log whose every message was recorded twice came
//! out 254.9″ p-p instead of 68.9″, exit 0. The CSV reader refuses such a row naming its line;
//! the MCAP and bag readers refuse such a message of the clock channel (the first selected, on
//! whose stamps every sample is taken) naming its index or row id, its topic and the message
//! that came before, with [`StampOrder`]. Other channels are interpolated onto the clock, and
//! their own out-of-order samples are left out and counted (the aligner's `out_of_order`).
//!
//! `calib inspect` passes such stamps on
//! ([`ReadOptions::allow_unordered_time`](crate::ReadOptions::allow_unordered_time)) and counts
//! them, so that what it reports is what the methods refuse.

use crate::TimeSource;
use crate::ros2::decode::seconds;

/// Stamps from this many seconds on (2²¹ s, 24 days: seconds since 1970, ~1.7·10⁹ s, whose
/// doubles are 2.4·10⁻⁷ s apart) are counted from the whole second of the log's first stamp, so
/// that a sample's time, a double, keeps every nanosecond; below it doubles are at most
/// 4.7·10⁻¹⁰ s apart and stamps are kept as they are. Reports add the origin back
/// ([`crate::LogReader::time_origin_s`]).
pub(crate) const ORIGIN_FROM_S: i64 = 1 << 21;

/// The last stamp of the clock channel and the message that carried it.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct StampOrder {
    last: Option<(i64, i64)>,
}

/// A clock stamp that does not increase, found by [`StampOrder::check`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Backward {
    /// The refused stamp, ns.
    pub ns: i64,
    /// The previous clock stamp, ns.
    pub previous_ns: i64,
    /// The message (index or row id) that carried it.
    pub previous_message: i64,
}

impl StampOrder {
    /// Takes the clock stamp `ns` of `message` (its index in the file, or its row id); the
    /// [`Backward`] if it does not exceed the previous one.
    pub(crate) fn check(&mut self, ns: i64, message: i64) -> Result<(), Backward> {
        if let Some((previous_ns, previous_message)) = self.last
            && ns <= previous_ns
        {
            return Err(Backward {
                ns,
                previous_ns,
                previous_message,
            });
        }
        self.last = Some((ns, message));
        Ok(())
    }
}

impl Backward {
    /// What is wrong and what to do; `clock` names the clock channel, `message` says how the
    /// previous message is called (`message 41`, `message id 42`), `time` where the stamps come
    /// from.
    pub(crate) fn describe(&self, clock: &str, message: &str, time: TimeSource) -> String {
        let what = if self.ns == self.previous_ns {
            "repeats"
        } else {
            "goes back before"
        };
        let (source, remedy) = match time {
            TimeSource::Header => (
                "header stamp",
                "; if the recorder's receive times increase, read them with `time = log`",
            ),
            TimeSource::Log => ("log time", ""),
        };
        format!(
            "the {source} {} s of clock channel `{clock}` {what} the previous one, {} s \
             ({message} {}); a channel's stamps must strictly increase (every message recorded \
             twice, or messages out of order, give this): remove the duplicate messages or sort \
             the log by time{remedy}",
            seconds(self.ns),
            seconds(self.previous_ns),
            self.previous_message
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_repeated_or_earlier_stamp_is_refused_naming_the_previous_message() {
        let mut order = StampOrder::default();
        order.check(1_000, 0).unwrap();
        order.check(2_000, 1).unwrap();
        let repeat = order.check(2_000, 2).unwrap_err();
        assert_eq!((repeat.previous_ns, repeat.previous_message), (2_000, 1));
        let text = repeat.describe("a", "message", TimeSource::Header);
        assert!(text.contains("repeats the previous one"), "{text}");
        assert!(text.contains("(message 1)"), "{text}");
        assert!(text.contains("`time = log`"), "{text}");
        let back = order.check(1_500, 3).unwrap_err();
        let text = back.describe("a", "message id", TimeSource::Log);
        assert!(text.contains("goes back before"), "{text}");
        assert!(!text.contains("`time = log`"), "{text}");
        // A refused stamp does not move the clock: the next increasing one passes.
        order.check(3_000, 4).unwrap();
    }
}

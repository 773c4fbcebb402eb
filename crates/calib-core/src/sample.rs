//! Synchronized samples: a time stamp and one reading per channel.
//!
//! Readers (in `calib-io` or a caller's own DAQ code) turn logs into [`Sample`]s whose readings
//! are already in radians; the core never sees file formats or units. Channels are identified by
//! their index into the stream's [`Channel`] list, which is fixed for the whole stream.

use crate::angle::AngleUnit;

/// One channel of a log: a named angle sensor (or head, or reference encoder).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Channel {
    /// The channel's name as the log spells it (CSV header, JointState `name`, JSON field).
    pub name: String,
    /// The unit its readings were written in (they reach the core in radians).
    pub unit: AngleUnit,
}

/// One synchronized sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Time stamp, seconds.
    pub t: f64,
    /// One reading per channel, radians, in the order of the stream's channel list. Readings may be
    /// wrapped to one revolution or accumulate over revolutions.
    pub values: Vec<f64>,
    /// The CSRR session this sample belongs to, where the log marks it (`None`: not marked, or
    /// a negative mark meaning "not part of any session").
    pub session: Option<u32>,
}

/// Finds a channel by name, with an error that lists what the log has.
pub fn channel_index(channels: &[Channel], name: &str) -> Result<usize, UnknownChannel> {
    channels
        .iter()
        .position(|c| c.name == name)
        .ok_or_else(|| UnknownChannel {
            name: name.to_string(),
            available: channels.iter().map(|c| c.name.clone()).collect(),
        })
}

/// A channel name the log does not have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("no channel `{name}` in the log (it has: {}); pick one of those names", available.join(", "))]
pub struct UnknownChannel {
    /// The name asked for.
    pub name: String,
    /// The names the log has.
    pub available: Vec<String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_channel_lists_the_alternatives() {
        let ch = |n: &str| Channel {
            name: n.into(),
            unit: AngleUnit::Deg,
        };
        let channels = [ch("a"), ch("b")];
        assert_eq!(channel_index(&channels, "b"), Ok(1));
        let err = channel_index(&channels, "c").unwrap_err();
        assert!(err.to_string().contains("it has: a, b"), "{err}");
    }
}

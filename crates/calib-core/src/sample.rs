//! Synchronized samples: a time stamp and one reading per channel.

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
///
/// Readers (in `calib-io` or a caller's own DAQ code) turn logs into [`Sample`]s whose readings
/// are already in radians; the core never sees file formats or units. Channels are identified by
/// their index into the stream's [`Channel`] list, which is fixed for the whole stream.
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

/// One sample of a [`SampleBatch`], borrowed: the same fields as [`Sample`] without owning
/// its readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleRef<'a> {
    /// Time stamp, seconds.
    pub t: f64,
    /// One reading per channel, radians, in the order of the stream's channel list.
    pub values: &'a [f64],
    /// The CSRR session this sample belongs to, where the log marks it.
    pub session: Option<u32>,
}

impl SampleRef<'_> {
    /// The sample, owning its readings.
    pub fn to_sample(&self) -> Sample {
        Sample {
            t: self.t,
            values: self.values.to_vec(),
            session: self.session,
        }
    }
}

/// Samples read together: their time stamps, their readings one sample after the other
/// (`width` per sample, the stream's channels in order) and their session marks.
///
/// What readers hand over in place of one [`Sample`] each: a batch is filled, consumed and
/// filled again, so reading allocates nothing per sample.
///
/// ```
/// use calib_core::SampleBatch;
/// let mut batch = SampleBatch::new(2);
/// batch.push(0.0, &[0.1, 0.2], None);
/// batch.push(0.001, &[0.3, 0.4], Some(1));
/// let second = batch.get(1);
/// assert_eq!((second.t, second.values, second.session), (0.001, &[0.3, 0.4][..], Some(1)));
/// assert_eq!(batch.iter().map(|s| s.values[0]).sum::<f64>(), 0.4);
/// batch.clear();
/// assert!(batch.is_empty());
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SampleBatch {
    width: usize,
    t: Vec<f64>,
    values: Vec<f64>,
    sessions: Vec<Option<u32>>,
}

impl SampleBatch {
    /// An empty batch of samples of `width` readings each.
    pub fn new(width: usize) -> Self {
        SampleBatch {
            width,
            ..SampleBatch::default()
        }
    }

    /// An empty batch with room for `samples` samples of `width` readings.
    pub fn with_capacity(width: usize, samples: usize) -> Self {
        SampleBatch {
            width,
            t: Vec::with_capacity(samples),
            values: Vec::with_capacity(samples * width),
            sessions: Vec::with_capacity(samples),
        }
    }

    /// Readings per sample.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether the batch holds no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Forgets every sample, keeping the room they took.
    pub fn clear(&mut self) {
        self.t.clear();
        self.values.clear();
        self.sessions.clear();
    }

    /// Appends a sample; `values` holds one reading per channel.
    pub fn push(&mut self, t: f64, values: &[f64], session: Option<u32>) {
        debug_assert_eq!(values.len(), self.width, "a reading per channel");
        self.t.push(t);
        self.values.extend_from_slice(values);
        self.sessions.push(session);
    }

    /// Appends a sample whose readings are `row[i]` for each `i` of `pick`, in order.
    pub fn push_picked(&mut self, t: f64, row: &[f64], pick: &[usize], session: Option<u32>) {
        debug_assert_eq!(pick.len(), self.width, "a reading per channel");
        self.t.push(t);
        self.values.extend(pick.iter().map(|&i| row[i]));
        self.sessions.push(session);
    }

    /// The `i`-th sample.
    ///
    /// # Panics
    /// If `i` is not below [`len`](Self::len).
    pub fn get(&self, i: usize) -> SampleRef<'_> {
        SampleRef {
            t: self.t[i],
            values: &self.values[i * self.width..(i + 1) * self.width],
            session: self.sessions[i],
        }
    }

    /// The samples in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = SampleRef<'_>> {
        (0..self.len()).map(|i| self.get(i))
    }

    /// The time stamps, seconds.
    pub fn times(&self) -> &[f64] {
        &self.t
    }
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

//! [`McapWriter`]: samples as ROS 2 JointState messages.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use calib_core::{Channel, Sample};
use mcap::{Compression, McapError, WriteOptions, records::MessageHeader};
use tempfile::TempPath;

use super::cdr::JointStateEncoder;
use super::{JOINT_STATE_MSGDEF, JOINT_STATE_SCHEMA};
use crate::Error;

/// Writes [`Sample`]s to an MCAP file as `sensor_msgs/msg/JointState` messages on one topic:
/// `name` = the channel names, `position` = the readings in radians, `header.stamp` and log time
/// = the sample's time. Chunks are zstd-compressed and the profile is `ros2`, so ROS 2 tools
/// and Foxglove read the file, and so does [`McapReader`](super::McapReader).
///
/// The file is written under a temporary name in the target's directory and renamed into place by
/// [`finish`](Self::finish): a crash or an error never leaves a half-written file at the target
/// path, and dropping the writer without `finish` removes the temporary file.
///
/// ```no_run
/// use calib_core::{AngleUnit, Channel, Sample};
/// use calib_io::mcap_log::McapWriter;
///
/// let channels = [Channel { name: "a".into(), unit: AngleUnit::Rad }];
/// let mut writer = McapWriter::create("sim.mcap".as_ref(), &channels, "/joint_states")?;
/// writer.write(&Sample { t: 0.001, values: vec![0.5], session: None })?;
/// writer.finish()?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct McapWriter {
    // Declared before `temp`: fields drop in order, and the writer's drop flushes into the
    // temporary file, which must still exist then.
    writer: mcap::Writer<BufWriter<File>>,
    temp: TempPath,
    target: PathBuf,
    schema_id: u16,
    topics: Vec<TopicWriter>,
    written: u64,
}

/// One JointState topic of the file.
struct TopicWriter {
    channel_id: u16,
    encoder: JointStateEncoder,
    width: usize,
}

/// The topic `calib simulate` writes by default, as ROS 2 names joint states.
pub const DEFAULT_TOPIC: &str = "/joint_states";

impl McapWriter {
    /// Creates the writer for a file at `path` (which appears only on [`finish`](Self::finish)),
    /// with one JointState channel on `topic` naming `channels` (their units are ignored:
    /// positions are radians).
    ///
    /// Errors if the directory is not writable, or the channel names are empty or repeated.
    pub fn create(path: &Path, channels: &[Channel], topic: &str) -> Result<Self, Error> {
        let fail = |m: String| Error::Mcap {
            path: path.to_path_buf(),
            message_index: None,
            channel: None,
            message: m,
        };
        check_names(channels).map_err(fail)?;
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let (file, temp) = crate::atomic::temp_file_beside(path)
            .map_err(io)?
            .into_parts();
        let options = WriteOptions::new()
            .profile("ros2")
            .library(concat!("calib ", env!("CARGO_PKG_VERSION")))
            .compression(Some(Compression::Zstd));
        let mcap = |e: McapError| mcap_write_error(path, None, e);
        let mut writer = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(mcap)?;
        let schema_id = writer
            .add_schema(JOINT_STATE_SCHEMA, "ros2msg", JOINT_STATE_MSGDEF.as_bytes())
            .map_err(mcap)?;
        let mut this = McapWriter {
            writer,
            temp,
            target: path.to_path_buf(),
            schema_id,
            topics: Vec::new(),
            written: 0,
        };
        this.add_topic(topic, channels)?;
        Ok(this)
    }

    /// Adds another JointState topic naming `channels` (as a recording of sensors with a driver
    /// node each has); returns its index for [`write_to`](Self::write_to). The topic of
    /// [`create`](Self::create) is 0.
    pub fn add_topic(&mut self, topic: &str, channels: &[Channel]) -> Result<usize, Error> {
        check_names(channels).map_err(|m| Error::Mcap {
            path: self.target.clone(),
            message_index: None,
            channel: Some(topic.to_string()),
            message: m,
        })?;
        let channel_id = self
            .writer
            .add_channel(self.schema_id, topic, "cdr", &BTreeMap::new())
            .map_err(|e| mcap_write_error(&self.target, None, e))?;
        self.topics.push(TopicWriter {
            channel_id,
            encoder: JointStateEncoder::new(channels.iter().map(|c| c.name.as_str())),
            width: channels.len(),
        });
        Ok(self.topics.len() - 1)
    }

    /// Adds a metadata record (e.g. the simulation's parameters) to the file.
    pub fn metadata(
        &mut self,
        name: &str,
        entries: &BTreeMap<String, String>,
    ) -> Result<(), Error> {
        self.writer
            .write_metadata(&mcap::records::Metadata {
                name: name.to_string(),
                metadata: entries.clone(),
            })
            .map_err(|e| mcap_write_error(&self.target, None, e))
    }

    /// Writes one sample. Its time must be a non-negative number of seconds before 2038 (JointState
    /// stamps hold a 32-bit second), and it must have one value per channel.
    pub fn write(&mut self, sample: &Sample) -> Result<(), Error> {
        self.write_to(0, sample)
    }

    /// Writes one sample of the channels of topic `topic` (an index from
    /// [`add_topic`](Self::add_topic)), as [`write`](Self::write) does.
    pub fn write_to(&mut self, topic: usize, sample: &Sample) -> Result<(), Error> {
        let index = self.written;
        let fail = |m: String| Error::Mcap {
            path: self.target.clone(),
            message_index: Some(index),
            channel: None,
            message: m,
        };
        let Some(writer) = self.topics.get_mut(topic) else {
            return Err(fail(format!("there is no topic {topic}")));
        };
        if sample.values.len() != writer.width {
            return Err(fail(format!(
                "the sample has {} values for {} channels",
                sample.values.len(),
                writer.width
            )));
        }
        let (sec, nanosec) = stamp(sample.t).ok_or_else(|| {
            fail(format!(
                "time {} s cannot be a JointState stamp (it must be finite, non-negative and \
                 below 2^31 s)",
                sample.t
            ))
        })?;
        let header = MessageHeader {
            channel_id: writer.channel_id,
            // The sequence is a 32-bit counter; it wraps in logs of more than 4e9 messages.
            sequence: index as u32,
            log_time: sec as u64 * 1_000_000_000 + u64::from(nanosec),
            publish_time: sec as u64 * 1_000_000_000 + u64::from(nanosec),
        };
        let data = writer.encoder.encode(sec, nanosec, &sample.values);
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| mcap_write_error(&self.target, Some(index), e))?;
        self.written += 1;
        Ok(())
    }

    /// Writes the summary, flushes the file to disk and renames it into place.
    pub fn finish(mut self) -> Result<(), Error> {
        let target = self.target.clone();
        self.writer
            .finish()
            .map_err(|e| mcap_write_error(&target, None, e))?;
        let io = |source| Error::Io {
            path: target.clone(),
            source,
        };
        let McapWriter { writer, temp, .. } = self;
        let file = writer
            .into_inner()
            .into_inner()
            .map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        temp.persist(&target).map_err(|e| io(e.error))?;
        Ok(())
    }
}

/// Refuses an empty or repeated channel list.
fn check_names(channels: &[Channel]) -> Result<(), String> {
    if channels.is_empty() {
        return Err("no channels to write; give at least one".into());
    }
    for (i, c) in channels.iter().enumerate() {
        if channels[..i].iter().any(|d| d.name == c.name) {
            return Err(format!(
                "channel `{}` is named twice; JointState names must be unique",
                c.name
            ));
        }
    }
    Ok(())
}

/// `t` seconds as a JointState stamp (sec, nanosec), rounded to the nanosecond.
fn stamp(t: f64) -> Option<(i32, u32)> {
    if !(t >= 0.0 && t < f64::from(i32::MAX)) {
        return None;
    }
    let sec = t.floor();
    let nanosec = ((t - sec) * 1e9).round();
    // Rounding can carry into the next second.
    let (sec, nanosec) = if nanosec >= 1e9 {
        (sec + 1.0, 0.0)
    } else {
        (sec, nanosec)
    };
    let sec = i32::try_from(sec as i64).ok()?;
    Some((sec, nanosec as u32))
}

fn mcap_write_error(path: &Path, index: Option<u64>, e: McapError) -> Error {
    match e {
        McapError::Io(source) => Error::Io {
            path: path.to_path_buf(),
            source,
        },
        e => Error::Mcap {
            path: path.to_path_buf(),
            message_index: index,
            channel: None,
            message: format!("cannot write the MCAP file ({e})"),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_round_to_the_nanosecond_and_carry() {
        assert_eq!(stamp(0.0), Some((0, 0)));
        assert_eq!(stamp(12.5), Some((12, 500_000_000)));
        assert_eq!(stamp(1.000_000_000_4), Some((1, 0)));
        assert_eq!(stamp(1.999_999_999_9), Some((2, 0)));
        assert_eq!(stamp(-1.0), None);
        assert_eq!(stamp(f64::NAN), None);
        assert_eq!(stamp(3e9), None);
    }
}

//! Helpers shared by the fuzz targets: scratch files for the path-based readers, the checks every
//! yielded sample must pass, and wrapping message payloads into a well-formed MCAP file.

use calib_core::{AngleUnit, Sample};
use calib_io::{ReadOptions, TimeSource};
use mcap::records::MessageHeader;
use mcap::{WriteOptions, Writer};
use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::PathBuf;

/// Writes `data` to this process's scratch file with extension `ext` and returns its path.
/// The readers take paths (they reopen the file to name physical lines in errors), so the
/// targets fuzz them exactly as `calib` runs them.
pub fn scratch(ext: &str, data: &[u8]) -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let path = dir.join(format!("calib-fuzz-{}.{ext}", std::process::id()));
    std::fs::write(&path, data).expect("write the scratch file");
    path
}

/// Read options chosen by one input byte: every unit, with and without unordered time, skipping
/// damaged chunks or not, header or log time.
pub fn options(byte: u8) -> ReadOptions {
    let unit = match byte & 0x7 {
        0 => None,
        1 => Some(AngleUnit::Deg),
        2 => Some(AngleUnit::Rad),
        3 => Some(AngleUnit::Arcsec),
        4 => Some(AngleUnit::Rev),
        5 => Some(AngleUnit::Counts(1)),
        6 => Some(AngleUnit::Counts(1 << 24)),
        _ => Some(AngleUnit::Counts(u64::MAX)),
    };
    ReadOptions {
        unit,
        allow_unordered_time: byte & 0x8 != 0,
        skip_damaged: byte & 0x10 != 0,
        time: if byte & 0x20 != 0 {
            TimeSource::Log
        } else {
            TimeSource::Header
        },
        ..ReadOptions::default()
    }
}

/// What every sample a reader yields must satisfy: one finite value per channel and a finite
/// time stamp.
pub fn check_sample(sample: &Sample, channels: usize) {
    assert_eq!(sample.values.len(), channels, "one value per channel");
    assert!(
        sample.t.is_finite(),
        "time stamp {} is not finite",
        sample.t
    );
    for v in &sample.values {
        assert!(v.is_finite(), "reading {v} is not finite");
    }
}

/// What every row of a sparse CSV file must satisfy (its empty cells are NaN until
/// [`calib_io::LogReader`] aligns the channels): one value per channel, each finite or NaN, and a
/// finite time stamp.
pub fn check_sparse_row(sample: &Sample, channels: usize) {
    assert_eq!(sample.values.len(), channels, "one value per channel");
    assert!(
        sample.t.is_finite(),
        "time stamp {} is not finite",
        sample.t
    );
    for v in &sample.values {
        assert!(v.is_finite() || v.is_nan(), "reading {v} is infinite");
    }
}

/// How [`wrap_messages`] lays out the payloads.
pub struct Layout {
    /// The payloads are JSON messages (else JointState CDR).
    pub json: bool,
    /// Chunked file (else one record per message).
    pub chunked: bool,
    /// Every other payload goes to a second topic of the other encoding, to be joined.
    pub two_topics: bool,
}

impl Layout {
    /// The layout chosen by one input byte.
    pub fn from_byte(byte: u8) -> Self {
        Layout {
            json: byte & 1 != 0,
            chunked: byte & 2 != 0,
            two_topics: byte & 4 != 0,
        }
    }
}

/// The ROS 2 message definition of JointState, as rosbag2 stores it.
pub const JOINT_STATE: &str = calib_io::mcap_log::JOINT_STATE_MSGDEF;

/// A well-formed MCAP file holding `payloads` as messages 10 ms apart.
pub fn wrap_messages(layout: &Layout, payloads: &[&[u8]]) -> Vec<u8> {
    let options = WriteOptions::new()
        .profile("ros2")
        .compression(None)
        .use_chunks(layout.chunked);
    let mut writer: Writer<Cursor<Vec<u8>>> =
        options.create(Cursor::new(Vec::new())).expect("writer");
    let schema = writer
        .add_schema(
            "sensor_msgs/msg/JointState",
            "ros2msg",
            JOINT_STATE.as_bytes(),
        )
        .expect("schema");
    let cdr = writer
        .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
        .expect("channel");
    let json = writer
        .add_channel(0, "/reference", "json", &BTreeMap::new())
        .expect("channel");
    let (first, second) = if layout.json {
        (json, cdr)
    } else {
        (cdr, json)
    };
    for (i, payload) in payloads.iter().enumerate() {
        let channel_id = if layout.two_topics && i % 2 == 1 {
            second
        } else {
            first
        };
        let log_time = 1_700_000_000_000_000_000 + (i as u64 / 2) * 10_000_000;
        let header = MessageHeader {
            channel_id,
            sequence: i as u32,
            log_time,
            publish_time: log_time,
        };
        writer
            .write_to_known_channel(&header, payload)
            .expect("write");
    }
    writer.finish().expect("finish");
    writer.into_inner().into_inner()
}

/// The topic [`wrap_with_definition`] writes its messages on.
pub const PROBE_TOPIC: &str = "/probe";

/// A well-formed MCAP file holding `payloads` as CDR messages 10 ms apart on [`PROBE_TOPIC`],
/// of a type calib does not know, described by the `ros2msg` text `definition`.
pub fn wrap_with_definition(definition: &[u8], payloads: &[&[u8]]) -> Vec<u8> {
    let options = WriteOptions::new()
        .profile("ros2")
        .compression(None)
        .use_chunks(false);
    let mut writer: Writer<Cursor<Vec<u8>>> =
        options.create(Cursor::new(Vec::new())).expect("writer");
    let schema = writer
        .add_schema("fuzz_msgs/msg/Probe", "ros2msg", definition)
        .expect("schema");
    let channel = writer
        .add_channel(schema, PROBE_TOPIC, "cdr", &BTreeMap::new())
        .expect("channel");
    for (i, payload) in payloads.iter().enumerate() {
        let log_time = 1_700_000_000_000_000_000 + i as u64 * 10_000_000;
        let header = MessageHeader {
            channel_id: channel,
            sequence: i as u32,
            log_time,
            publish_time: log_time,
        };
        writer
            .write_to_known_channel(&header, payload)
            .expect("write");
    }
    writer.finish().expect("finish");
    writer.into_inner().into_inner()
}

/// Splits the rest of an input into payloads: each a 2-byte little-endian length and that many
/// bytes (the last one takes what is left).
pub fn payloads(mut rest: &[u8]) -> Vec<&[u8]> {
    let mut payloads = Vec::new();
    while let [lo, hi, tail @ ..] = rest {
        let n = usize::from(u16::from_le_bytes([*lo, *hi])).min(tail.len());
        let (payload, tail) = tail.split_at(n);
        payloads.push(payload);
        rest = tail;
    }
    payloads
}

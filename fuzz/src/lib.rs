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

/// How [`ros1_bag`] compresses its chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ros1Compression {
    None,
    Bz2,
    Lz4,
}

/// The topics of [`ros1_bag`]: name, type and message definition.
pub const ROS1_TOPICS: [(&str, &str, &str); 3] = [
    (
        "/joint_states",
        "sensor_msgs/JointState",
        "Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    ),
    ("/scalar", "std_msgs/Float64", "float64 data\n"),
    ("/other", "std_msgs/String", "string data\n"),
];

/// A record of a ROS 1 bag: `fields` as its header, then `data`, each with its length.
fn ros1_record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let header = ros1_fields(fields);
    let mut out = (header.len() as u32).to_le_bytes().to_vec();
    out.extend(header);
    out.extend((data.len() as u32).to_le_bytes());
    out.extend(data);
    out
}

/// Header fields as a ROS 1 bag holds them: each a `u32` length and `name=value`.
fn ros1_fields(fields: &[(&str, &[u8])]) -> Vec<u8> {
    let mut out = Vec::new();
    for (name, value) in fields {
        out.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
        out.extend(name.as_bytes());
        out.push(b'=');
        out.extend(*value);
    }
    out
}

fn ros1_time(ns: u64) -> [u8; 8] {
    let mut b = [0u8; 8];
    b[..4].copy_from_slice(&((ns / 1_000_000_000) as u32).to_le_bytes());
    b[4..].copy_from_slice(&((ns % 1_000_000_000) as u32).to_le_bytes());
    b
}

/// A ROS 1 bag (format 2.0) of `messages` (`(topic, time ns, payload)`, the topic an index into
/// [`ROS1_TOPICS`]), `per_chunk` messages a chunk, laid out as `rosbag record` writes it: the
/// bag header padded to 4096 bytes, each chunk (a connection record before a topic's first
/// message) followed by its index data, then the index (connections, chunk infos) unless
/// `indexed` is false (then `index_pos` is 0, as in a recording that did not close).
pub fn ros1_bag(
    messages: &[(usize, u64, &[u8])],
    per_chunk: usize,
    compression: Ros1Compression,
    indexed: bool,
) -> Vec<u8> {
    use std::io::Write;
    let connection = |k: usize| {
        let (topic, kind, definition) = ROS1_TOPICS[k];
        let id = (k as u32).to_le_bytes();
        let more = ros1_fields(&[
            ("topic", topic.as_bytes()),
            ("type", kind.as_bytes()),
            ("md5sum", b"*"),
            ("message_definition", definition.as_bytes()),
        ]);
        ros1_record(
            &[("op", &[7]), ("conn", &id), ("topic", topic.as_bytes())],
            &more,
        )
    };
    let mut out = b"#ROSBAG V2.0\n".to_vec();
    let header_at = out.len();
    out.extend(vec![0u8; 4096]);
    let mut infos = Vec::new();
    let mut known = [false; 3];
    for chunk in messages.chunks(per_chunk.max(1)) {
        let mut plain = Vec::new();
        let mut index: Vec<Vec<(u64, u32)>> = vec![Vec::new(); 3];
        for &(k, t, payload) in chunk {
            let k = k % 3;
            if !known[k] {
                known[k] = true;
                plain.extend(connection(k));
            }
            index[k].push((t, plain.len() as u32));
            let id = (k as u32).to_le_bytes();
            plain.extend(ros1_record(
                &[("op", &[2]), ("conn", &id), ("time", &ros1_time(t))],
                payload,
            ));
        }
        let (name, data): (&str, Vec<u8>) = match compression {
            Ros1Compression::None => ("none", plain.clone()),
            Ros1Compression::Bz2 => {
                let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
                e.write_all(&plain).expect("bz2");
                ("bz2", e.finish().expect("bz2"))
            }
            Ros1Compression::Lz4 => {
                let mut e = lz4::EncoderBuilder::new().build(Vec::new()).expect("lz4");
                e.write_all(&plain).expect("lz4");
                ("lz4", e.finish().0)
            }
        };
        let pos = out.len() as u64;
        out.extend(ros1_record(
            &[
                ("op", &[5]),
                ("compression", name.as_bytes()),
                ("size", &(plain.len() as u32).to_le_bytes()),
            ],
            &data,
        ));
        let mut counts = Vec::new();
        for (k, entries) in index.iter().enumerate().filter(|(_, e)| !e.is_empty()) {
            let mut data = Vec::new();
            for (t, offset) in entries {
                data.extend(ros1_time(*t));
                data.extend(offset.to_le_bytes());
            }
            out.extend(ros1_record(
                &[
                    ("op", &[4]),
                    ("ver", &1u32.to_le_bytes()),
                    ("conn", &(k as u32).to_le_bytes()),
                    ("count", &(entries.len() as u32).to_le_bytes()),
                ],
                &data,
            ));
            counts.extend((k as u32).to_le_bytes());
            counts.extend((entries.len() as u32).to_le_bytes());
        }
        let start = chunk.iter().map(|m| m.1).min().unwrap_or(0);
        let end = chunk.iter().map(|m| m.1).max().unwrap_or(0);
        infos.push(ros1_record(
            &[
                ("op", &[6]),
                ("ver", &1u32.to_le_bytes()),
                ("chunk_pos", &pos.to_le_bytes()),
                ("start_time", &ros1_time(start)),
                ("end_time", &ros1_time(end)),
                ("count", &((counts.len() / 8) as u32).to_le_bytes()),
            ],
            &counts,
        ));
    }
    let index_pos = out.len() as u64;
    let conns = known.iter().filter(|k| **k).count() as u32;
    if indexed {
        for (k, _) in known.iter().enumerate().filter(|(_, k)| **k) {
            out.extend(connection(k));
        }
        for info in &infos {
            out.extend(info);
        }
    }
    let (index_pos, conns, chunks) = if indexed {
        (index_pos, conns, infos.len() as u32)
    } else {
        (0, 0, 0)
    };
    let fields = ros1_fields(&[
        ("op", &[3]),
        ("index_pos", &index_pos.to_le_bytes()),
        ("conn_count", &conns.to_le_bytes()),
        ("chunk_count", &chunks.to_le_bytes()),
    ]);
    let pad = 4096 - 8 - fields.len();
    let mut header = (fields.len() as u32).to_le_bytes().to_vec();
    header.extend(&fields);
    header.extend((pad as u32).to_le_bytes());
    header.extend(vec![b' '; pad]);
    out[header_at..header_at + 4096].copy_from_slice(&header);
    out
}

/// A `sensor_msgs/JointState` in the ROS 1 wire format.
pub fn ros1_joint_state(seq: u32, stamp_ns: u64, names: &[&str], position: &[f64]) -> Vec<u8> {
    let mut out = seq.to_le_bytes().to_vec();
    out.extend(ros1_time(stamp_ns));
    out.extend(0u32.to_le_bytes());
    out.extend((names.len() as u32).to_le_bytes());
    for n in names {
        out.extend((n.len() as u32).to_le_bytes());
        out.extend(n.as_bytes());
    }
    out.extend((position.len() as u32).to_le_bytes());
    for p in position {
        out.extend(p.to_le_bytes());
    }
    out.extend(0u32.to_le_bytes());
    out.extend(0u32.to_le_bytes());
    out
}

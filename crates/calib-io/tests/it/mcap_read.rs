//! McapReader against the Python-written fixture and against files built here with `mcap::Writer`
//! (messages serialized with the `cdr-encoding` crate, an independent CDR implementation).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use byteorder::{BigEndian, LittleEndian};
use calib_core::{AngleUnit, Sample};
use calib_io::limits::ALIGN_QUEUE;
use calib_io::mcap_log::{IgnoredTopic, JOINT_STATE_MSGDEF, McapReader, PEEK_WINDOW};
use calib_io::{Error, ReadOptions};
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions};
use serde::Serialize;

const T0: u64 = 1_700_000_000_000_000_000;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/mcap/fixture.mcap")
}

fn read_all(path: &Path, opts: &ReadOptions) -> (McapReader, Vec<Sample>) {
    let mut reader = McapReader::open(path, opts).expect("open");
    let samples: Vec<Sample> = (&mut reader).collect::<Result<_, _>>().expect("read");
    (reader, samples)
}

fn names(reader: &McapReader) -> Vec<&str> {
    reader.channels().iter().map(|c| c.name.as_str()).collect()
}

/// The time a reader gives for a stamp in ns (exact: second and fraction converted apart):
/// stamps since 1970 (from `T0` on) counted from the second of the log's first, `T0` in these
/// files (see `LogReader::time_origin_s`).
fn secs(ns: u64) -> f64 {
    let ns = if ns >= T0 { ns - T0 } else { ns };
    (ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9
}

#[test]
fn python_fixture_joins_joint_states_with_json_reference() {
    let (reader, samples) = read_all(&fixture(), &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "b", "ref"]);
    assert_eq!(reader.time_origin_s(), (T0 / 1_000_000_000) as f64);
    let units: Vec<AngleUnit> = reader.channels().iter().map(|c| c.unit).collect();
    assert_eq!(units, [AngleUnit::Rad, AngleUnit::Rad, AngleUnit::Deg]);
    // See make_fixture.py: 300 JointStates, JSON missing for i = 100..=104, two stray JSONs.
    assert_eq!(samples.len(), 295);
    // Aligned on a's clock: b shares its messages, ref is exact where it has a message at a's
    // stamp and missing (a gap of 6 intervals, beyond 2.5) for i = 100..=104; the two stray
    // messages are nodes only.
    let alignment = reader.alignment();
    assert_eq!(
        (alignment.clock.as_str(), alignment.clock_samples),
        ("a", 300)
    );
    let counts: Vec<_> = alignment
        .channels
        .iter()
        .map(|c| (c.channel.as_str(), c.exact, c.interpolated, c.dropped))
        .collect();
    assert_eq!(counts, [("b", 295, 0, 0), ("ref", 295, 0, 5)]);
    assert_eq!(reader.diagnostics().truncated, None);
    assert_eq!(
        reader.ignored_topics(),
        [IgnoredTopic {
            topic: "/status".into(),
            schema: "std_msgs/msg/String".into(),
            message_encoding: "cdr".into(),
        }]
    );
    let expected = (0..300u64).filter(|i| !(100..=104).contains(i));
    for (s, i) in samples.iter().zip(expected) {
        let x = i as f64;
        assert_eq!(s.t, secs(T0 + i * 10_000_000), "sample {i}");
        assert_eq!(s.values[0], x / 64.0);
        assert_eq!(s.values[1], 1.0 - x / 32.0);
        assert_eq!(s.values[2], (x / 4.0).to_radians());
        assert_eq!(s.session, None);
    }
}

#[test]
fn unit_option_applies_to_json_only() {
    let opts = ReadOptions {
        unit: Some(AngleUnit::Rad),
        ..ReadOptions::default()
    };
    let (reader, samples) = read_all(&fixture(), &opts);
    assert_eq!(reader.channels()[0].unit, AngleUnit::Rad);
    assert_eq!(reader.channels()[2].unit, AngleUnit::Rad);
    assert_eq!(samples[3].values, [3.0 / 64.0, 1.0 - 3.0 / 32.0, 0.75]);
}

// ---- building MCAP files -----------------------------------------------------------------------

#[derive(Serialize, Clone)]
struct Time {
    sec: i32,
    nanosec: u32,
}
#[derive(Serialize, Clone)]
struct Header {
    stamp: Time,
    frame_id: String,
}
#[derive(Serialize, Clone)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

fn joint_state(ns: u64, names: &[&str], position: &[f64]) -> JointState {
    JointState {
        header: Header {
            stamp: Time {
                sec: (ns / 1_000_000_000) as i32,
                nanosec: (ns % 1_000_000_000) as u32,
            },
            // Three bytes plus NUL: the names start right after, testing alignment.
            frame_id: "enc".into(),
        },
        name: names.iter().map(|s| s.to_string()).collect(),
        position: position.to_vec(),
        velocity: vec![],
        effort: vec![0.5; names.len()],
    }
}

/// CDR with the encapsulation header, serialized by `cdr-encoding`.
fn cdr(msg: &JointState, big_endian: bool) -> Vec<u8> {
    let (mut out, body) = if big_endian {
        (vec![0, 0, 0, 0], cdr_encoding::to_vec::<_, BigEndian>(msg))
    } else {
        (
            vec![0, 1, 0, 0],
            cdr_encoding::to_vec::<_, LittleEndian>(msg),
        )
    };
    out.extend(body.expect("serialize"));
    out
}

struct Builder {
    writer: mcap::Writer<BufWriter<File>>,
    sequence: u32,
}

impl Builder {
    fn new(path: &Path, compression: Option<Compression>, chunked: bool) -> Self {
        let options = WriteOptions::new()
            .profile("ros2")
            .compression(compression)
            .use_chunks(chunked)
            // Small chunks, so truncation tests cut between and inside several of them.
            .chunk_size(Some(4096));
        Self::with_options(path, options)
    }
    fn with_options(path: &Path, options: WriteOptions) -> Self {
        let file = BufWriter::new(File::create(path).expect("create"));
        Builder {
            writer: options.create(file).expect("writer"),
            sequence: 0,
        }
    }
    fn joint_state_topic(&mut self, topic: &str) -> u16 {
        let schema = self
            .writer
            .add_schema(
                "sensor_msgs/msg/JointState",
                "ros2msg",
                JOINT_STATE_MSGDEF.as_bytes(),
            )
            .expect("schema");
        self.writer
            .add_channel(schema, topic, "cdr", &BTreeMap::new())
            .expect("channel")
    }
    fn json_topic(&mut self, topic: &str) -> u16 {
        self.writer
            .add_channel(0, topic, "json", &BTreeMap::new())
            .expect("channel")
    }
    fn other_topic(&mut self, topic: &str) -> u16 {
        let schema = self
            .writer
            .add_schema("foo.Bar", "protobuf", b"")
            .expect("schema");
        self.writer
            .add_channel(schema, topic, "protobuf", &BTreeMap::new())
            .expect("channel")
    }
    fn put(&mut self, channel: u16, log_time: u64, data: &[u8]) {
        let header = MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time,
            publish_time: log_time,
        };
        self.sequence += 1;
        self.writer
            .write_to_known_channel(&header, data)
            .expect("write");
    }
    /// A little-endian JointState on `channel`, stamped and logged at `ns`.
    fn put_joint_state(&mut self, channel: u16, ns: u64, names: &[&str], position: &[f64]) {
        self.put(channel, ns, &cdr(&joint_state(ns, names, position), false));
    }
    fn finish(mut self) {
        self.writer.finish().expect("finish");
    }
}

fn temp() -> tempfile::TempDir {
    tempfile::tempdir().expect("tempdir")
}

/// A JointState log of joints `a`, `b` with `n` messages at 1 kHz.
fn joint_state_log(path: &Path, n: u64, compression: Option<Compression>, chunked: bool, be: bool) {
    let mut b = Builder::new(path, compression, chunked);
    let ch = b.joint_state_topic("/joint_states");
    for i in 0..n {
        let ns = T0 + i * 1_000_000;
        let msg = joint_state(ns, &["a", "b"], &[i as f64 * 1e-3, -(i as f64)]);
        b.put(ch, ns, &cdr(&msg, be));
    }
    b.finish();
}

fn check_joint_state_log(path: &Path, n: u64) {
    let (reader, samples) = read_all(path, &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "b"]);
    assert_eq!(samples.len() as u64, n);
    for (i, s) in samples.iter().enumerate() {
        let i = i as u64;
        assert_eq!(s.t, secs(T0 + i * 1_000_000));
        assert_eq!(s.values, [i as f64 * 1e-3, -(i as f64)]);
    }
    assert!(reader.alignment().is_exact());
    assert_eq!(reader.diagnostics().truncated, None);
}

#[test]
fn every_compression_and_byte_order_reads_the_same() {
    let dir = temp();
    for (k, (compression, chunked, be)) in [
        (Some(Compression::Zstd), true, false),
        (Some(Compression::Lz4), true, false),
        (None, true, false),
        (None, false, false),
        (Some(Compression::Zstd), true, true),
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.path().join(format!("log{k}.mcap"));
        joint_state_log(&path, 500, compression, chunked, be);
        check_joint_state_log(&path, 500);
    }
}

#[test]
fn zero_stamp_falls_back_to_log_time() {
    let dir = temp();
    let path = dir.path().join("zero.mcap");
    let mut b = Builder::new(&path, None, true);
    let ch = b.joint_state_topic("/js");
    b.put(
        ch,
        42_000_000_123,
        &cdr(&joint_state(0, &["x"], &[1.0]), false),
    );
    b.put(
        ch,
        43,
        &cdr(&joint_state(75_000_000_000, &["x"], &[2.0]), false),
    );
    b.finish();
    // The second stamp after the first (its log time 43 ns is not used): stamps that go back
    // are refused (issue 33).
    let (_, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(samples.len(), 2);
    assert_eq!(samples[0].t, 42.000_000_123);
    assert_eq!(samples[1].t, 75.0);
}

#[test]
fn json_topic_alone_uses_log_time_and_unit() {
    let dir = temp();
    let path = dir.path().join("json.mcap");
    let mut b = Builder::new(&path, Some(Compression::Zstd), true);
    let ch = b.json_topic("/enc");
    let junk = b.other_topic("/camera");
    b.put(junk, 1, b"\x08\x01");
    for i in 0..10u64 {
        let msg = format!(
            r#"{{"note": "x", "h1": {}, "nested": {{"h9": 1}}, "h\u0032": {}, "flag": true}}"#,
            i * 90,
            i
        );
        b.put(ch, 1_000_000_000 * i, msg.as_bytes());
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(names(&reader), ["h1", "h2"]);
    assert_eq!(reader.channels()[0].unit, AngleUnit::Deg);
    assert_eq!(reader.ignored_topics()[0].topic, "/camera");
    assert_eq!(samples.len(), 10);
    assert_eq!(samples[3].t, 3.0);
    assert_eq!(samples[3].values, [270f64.to_radians(), 3f64.to_radians()]);

    let opts = ReadOptions {
        unit: Some(AngleUnit::Counts(4)),
        ..ReadOptions::default()
    };
    let (_, samples) = read_all(&path, &opts);
    assert_eq!(samples[1].values[1], std::f64::consts::FRAC_PI_2);
}

fn mcap_error(err: Error) -> (Option<u64>, Option<String>, String) {
    match err {
        Error::Mcap {
            message_index,
            channel,
            message,
            ..
        } => (message_index, channel, message),
        other => panic!("expected an MCAP error, got {other:?}"),
    }
}

fn open_error(path: &Path) -> (Option<u64>, Option<String>, String) {
    match McapReader::open(path, &ReadOptions::default()) {
        Ok(_) => panic!("{} opened", path.display()),
        Err(e) => mcap_error(e),
    }
}

/// Reads `path` to its first error.
fn first_error(path: &Path) -> (usize, Error) {
    let reader = McapReader::open(path, &ReadOptions::default()).expect("open");
    let mut n = 0;
    for item in reader {
        match item {
            Ok(_) => n += 1,
            Err(e) => return (n, e),
        }
    }
    panic!("no error in {}", path.display());
}

/// A log of good JointState messages of joints a, b with `bad` as message 2.
fn log_with_bad_message(path: &Path, bad: &[u8]) {
    let mut b = Builder::new(path, Some(Compression::Zstd), true);
    let ch = b.joint_state_topic("/joint_states");
    for i in 0..2 {
        b.put(
            ch,
            i,
            &cdr(&joint_state(T0 + i, &["a", "b"], &[0.0, 1.0]), false),
        );
    }
    b.put(ch, 2, bad);
    b.put(
        ch,
        3,
        &cdr(&joint_state(T0 + 3, &["a", "b"], &[0.0, 1.0]), false),
    );
    b.finish();
}

#[test]
fn a_joint_first_seen_after_the_peek_window_is_an_error() {
    let dir = temp();
    let path = dir.path().join("late.mcap");
    let mut b = Builder::new(&path, Some(Compression::Zstd), true);
    let ch = b.joint_state_topic("/joint_states");
    let n = PEEK_WINDOW + 10;
    for i in 0..n {
        let msg = joint_state(T0 + i, &["a", "b"], &[0.0, 1.0]);
        b.put(ch, i, &cdr(&msg, false));
    }
    b.put(
        ch,
        n,
        &cdr(&joint_state(T0 + n, &["a", "c"], &[0.0, 1.0]), false),
    );
    b.finish();
    let (read, err) = first_error(&path);
    assert_eq!(read as u64, n);
    let (index, channel, message) = mcap_error(err);
    assert_eq!(index, Some(n));
    assert_eq!(channel.as_deref(), Some("/joint_states"));
    assert!(message.contains("joint `c` is new"), "{message}");
}

#[test]
fn bad_messages_are_errors_naming_file_message_and_topic() {
    let dir = temp();
    let good = cdr(&joint_state(T0, &["a", "b"], &[0.0, 1.0]), false);
    let mut huge_count = good.clone();
    // The `name` count sits after the encapsulation (4), stamp (8) and frame_id (4 + 4) fields.
    huge_count[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "mismatch",
            cdr(&joint_state(T0, &["a", "b"], &[0.0]), false),
            "2 names but 1 positions",
        ),
        ("cut", good[..good.len() - 9].to_vec(), "truncated"),
        ("huge", huge_count, "claims 4294967295"),
        (
            "xcdr2",
            [&[0u8, 7, 0, 0][..], &good[4..]].concat(),
            "encapsulation",
        ),
    ];
    for (name, bad, expect) in cases {
        let path = dir.path().join(format!("{name}.mcap"));
        log_with_bad_message(&path, &bad);
        let (read, err) = first_error(&path);
        assert_eq!(read, 2, "{name}");
        let text = err.to_string();
        assert!(text.contains(&path.display().to_string()), "{text}");
        let (index, channel, message) = mcap_error(err);
        assert_eq!(index, Some(2), "{name}");
        assert_eq!(channel.as_deref(), Some("/joint_states"), "{name}");
        assert!(message.contains(expect), "{name}: {message}");
    }
}

#[test]
fn bad_json_messages_are_errors() {
    let dir = temp();
    for (name, bad, expect) in [
        ("missing", r#"{"a": 1}"#, "missing"),
        ("string", r#"{"a": 1, "b": "x"}"#, "not a number"),
        ("new", r#"{"a": 1, "b": 2, "c": 3}"#, "`c` is new"),
        ("syntax", r#"{"a": 1, "b": "#, "not valid JSON"),
    ] {
        let path = dir.path().join(format!("{name}.mcap"));
        let mut b = Builder::new(&path, None, true);
        let ch = b.json_topic("/enc");
        b.put(ch, 1, br#"{"a": 1, "b": 2}"#);
        b.put(ch, 2, bad.as_bytes());
        b.finish();
        let (read, err) = first_error(&path);
        assert_eq!(read, 1);
        let (index, channel, message) = mcap_error(err);
        assert_eq!(index, Some(1), "{name}");
        let channel = channel.expect("channel");
        assert!(channel == "/enc" || channel == "b", "{name}: {channel}");
        assert!(message.contains(expect), "{name}: {message}");
    }
}

#[test]
fn truncated_files_keep_every_message_before_the_break() {
    let dir = temp();
    let full = dir.path().join("full.mcap");
    joint_state_log(&full, 2000, Some(Compression::Zstd), true, false);
    let bytes = std::fs::read(&full).expect("read");
    let cut = dir.path().join("cut.mcap");
    let mut previous = 0;
    // Cuts inside the first chunk, in later chunks, and inside the summary.
    for keep in [
        100,
        bytes.len() / 3,
        bytes.len() / 2,
        bytes.len() * 9 / 10,
        bytes.len() - 30,
    ] {
        std::fs::write(&cut, &bytes[..keep]).expect("write");
        let result = McapReader::open(&cut, &ReadOptions::default());
        let Ok(mut reader) = result else {
            // Nothing before the break: an error saying the file is cut (issue 18: not "the
            // log holds no samples").
            let message = result.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(message.contains("cut short"), "keep {keep}: {message}");
            continue;
        };
        let samples: Vec<Sample> = (&mut reader).collect::<Result<_, _>>().expect("no error");
        assert!(samples.len() >= previous, "keep {keep}");
        previous = samples.len();
        for (i, s) in samples.iter().enumerate() {
            assert_eq!(s.values[1], -(i as f64));
        }
        match &reader.diagnostics().truncated {
            Some(t) => {
                assert_eq!(t.messages_read, samples.len() as u64);
                assert!(t.byte_offset < keep as u64, "keep {keep}");
                assert!(samples.len() < 2000);
            }
            // A cut inside the summary loses no message.
            None => assert_eq!(samples.len(), 2000, "keep {keep}"),
        }
    }
    assert_eq!(previous, 2000);
}

/// `Truncation::byte_offset` is where reading stopped: the bytes before it hold every message
/// read (the file cut there reads the same), and it lies within the file. Inside a compressed
/// chunk it is past the chunk's start, since the chunk streams up to the cut.
#[test]
fn truncation_offset_is_where_reading_stopped() {
    let dir = temp();
    for (k, (compression, chunked)) in [
        (Some(Compression::Zstd), true),
        (Some(Compression::Lz4), true),
        (None, true),
        (None, false),
    ]
    .into_iter()
    .enumerate()
    {
        let full = dir.path().join(format!("full{k}.mcap"));
        joint_state_log(&full, 2000, compression, chunked, false);
        let bytes = std::fs::read(&full).expect("read");
        let cut = dir.path().join("cut.mcap");
        let again = dir.path().join("again.mcap");
        for keep in [300, 4000, 9000, bytes.len() / 3, bytes.len() / 2 + 17] {
            std::fs::write(&cut, &bytes[..keep]).expect("write");
            let Ok(mut reader) = McapReader::open(&cut, &ReadOptions::default()) else {
                continue;
            };
            let n = (&mut reader)
                .collect::<Result<Vec<_>, _>>()
                .expect("samples")
                .len() as u64;
            let t = reader.diagnostics().truncated.clone().expect("truncated");
            assert_eq!(t.messages_read, n, "{k} keep {keep}");
            assert!(
                n > 0 && t.byte_offset <= keep as u64,
                "{k} keep {keep}: {t:?}"
            );
            std::fs::write(&again, &bytes[..t.byte_offset as usize]).expect("write");
            let mut reader = McapReader::open(&again, &ReadOptions::default()).expect("open");
            let m = (&mut reader)
                .collect::<Result<Vec<_>, _>>()
                .expect("samples")
                .len() as u64;
            assert_eq!(m, n, "{k} keep {keep}: cut at {t:?}");
            assert_eq!(
                reader
                    .diagnostics()
                    .truncated
                    .as_ref()
                    .map(|t| t.byte_offset),
                Some(t.byte_offset),
                "{k} keep {keep}"
            );
        }
    }
}

#[test]
fn empty_foreign_and_corrupt_files_are_clear_errors() {
    let dir = temp();
    let empty = dir.path().join("empty.mcap");
    std::fs::write(&empty, b"").expect("write");
    let (_, _, m) = open_error(&empty);
    assert!(m.contains("empty"), "{m}");

    let csv = dir.path().join("log.mcap");
    std::fs::write(&csv, b"t,a,b\n0,1,2\n").expect("write");
    let (_, _, m) = open_error(&csv);
    assert!(m.contains("not an MCAP file"), "{m}");

    let missing = dir.path().join("missing.mcap");
    assert!(matches!(
        McapReader::open(&missing, &ReadOptions::default()),
        Err(Error::Io { .. })
    ));

    // Random bytes overwritten in a valid file: each case must end in samples or an error, never
    // a panic.
    let full = dir.path().join("full.mcap");
    joint_state_log(&full, 300, None, true, false);
    let bytes = std::fs::read(&full).expect("read");
    let bad = dir.path().join("bad.mcap");
    for seed in 0..40u64 {
        let mut b = bytes.clone();
        let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        for _ in 0..8 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let at = 8 + (x as usize) % (b.len() - 8);
            b[at] = (x >> 32) as u8;
        }
        std::fs::write(&bad, &b).expect("write");
        if let Ok(reader) = McapReader::open(&bad, &ReadOptions::default()) {
            for item in reader {
                if item.is_err() {
                    break;
                }
            }
        }
    }
}

#[test]
fn stamps_off_the_clock_are_interpolated_never_extrapolated() {
    let dir = temp();
    let path = dir.path().join("disjoint.mcap");
    let mut b = Builder::new(&path, Some(Compression::Zstd), true);
    let a = b.joint_state_topic("/a");
    let r = b.json_topic("/ref");
    for i in 0..100u64 {
        let ns = T0 + i * 1_000_000;
        b.put_joint_state(a, ns, &["a"], &[1.0]);
        // Half a millisecond off: never equal. ref turns at 1°/ms.
        b.put(
            r,
            ns + 500_000,
            format!(r#"{{"ref": {}}}"#, i as f64 + 0.5).as_bytes(),
        );
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "ref"]);
    // The first stamp of a precedes ref's first sample: dropped, not extrapolated.
    assert_eq!(samples.len(), 99);
    for (s, i) in samples.iter().zip(1..) {
        // A straight line is interpolated exactly (to rounding).
        assert!(
            (s.values[1].to_degrees() - i as f64).abs() < 1e-9,
            "{i}: {:?}",
            s.values
        );
    }
    let c = &reader.alignment().channels[0];
    assert_eq!((c.interpolated, c.exact, c.dropped), (99, 0, 1));
    assert_eq!(c.median_offset_s.map(f64::abs), Some(0.5e-3));
}

#[test]
fn joints_published_in_separate_messages_are_separate_series() {
    // Two publishers share /joint_states: [a, b] on the even milliseconds, [c] on the odd.
    let dir = temp();
    let path = dir.path().join("subsets.mcap");
    let mut b = Builder::new(&path, Some(Compression::Zstd), true);
    let js = b.joint_state_topic("/joint_states");
    for i in 0..200u64 {
        let ns = T0 + i * 1_000_000;
        let x = i as f64 * 1e-3;
        let msg = if i % 2 == 0 {
            joint_state(ns, &["a", "b"], &[x, -x])
        } else {
            joint_state(ns, &["c"], &[2.0 * x])
        };
        b.put(js, ns, &cdr(&msg, false));
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "b", "c"]);
    // a's 100 stamps; c has no sample before the first.
    assert_eq!(samples.len(), 99);
    for s in &samples {
        assert!(
            (s.values[2] - 2.0 * s.values[0]).abs() < 1e-12,
            "{:?}",
            s.values
        );
        assert_eq!(s.values[1], -s.values[0]);
    }
}

#[test]
fn alignment_queues_stay_bounded_when_a_topic_lags() {
    let dir = temp();
    let path = dir.path().join("lag.mcap");
    let mut b = Builder::new(&path, Some(Compression::Zstd), true);
    let a = b.joint_state_topic("/a");
    let r = b.json_topic("/ref");
    let n = 2 * ALIGN_QUEUE as u64;
    // All of /a first, then all of /ref: only the last ALIGN_QUEUE of /a are still queued.
    for i in 0..n {
        let ns = T0 + i;
        b.put_joint_state(a, ns, &["a"], &[i as f64]);
    }
    for i in 0..n {
        b.put(r, T0 + i, format!(r#"{{"ref": {i}}}"#).as_bytes());
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(samples.len(), ALIGN_QUEUE);
    let first = n - ALIGN_QUEUE as u64;
    assert_eq!(
        samples[0].values,
        [first as f64, (first as f64).to_radians()]
    );
    assert_eq!(
        reader.alignment().channels[0].dropped,
        n - ALIGN_QUEUE as u64
    );
}

#[test]
fn files_without_usable_topics_or_with_repeated_joints_are_errors() {
    let dir = temp();
    let path = dir.path().join("none.mcap");
    let mut b = Builder::new(&path, None, true);
    let ch = b.other_topic("/camera");
    b.put(ch, 1, b"x");
    b.finish();
    let (_, _, m) = open_error(&path);
    assert!(m.contains("/camera (foo.Bar, protobuf)"), "{m}");

    let path = dir.path().join("nothing.mcap");
    Builder::new(&path, None, true).finish();
    assert!(matches!(
        McapReader::open(&path, &ReadOptions::default()),
        Err(Error::Empty { .. })
    ));

    let path = dir.path().join("twice.mcap");
    let mut b = Builder::new(&path, None, true);
    let one = b.joint_state_topic("/one");
    b.put_joint_state(one, 1, &["a", "a"], &[0.0, 0.0]);
    b.finish();
    let (_, channel, m) = open_error(&path);
    assert_eq!(channel.as_deref(), Some("/one"));
    assert!(m.contains("joint `a` appears twice in one message"), "{m}");
}

#[test]
fn names_shared_between_topics_are_qualified() {
    let dir = temp();
    let path = dir.path().join("shared.mcap");
    let mut b = Builder::new(&path, None, true);
    let one = b.joint_state_topic("/one");
    let two = b.json_topic("/two");
    for i in 1..=3 {
        b.put_joint_state(one, i, &["a", "b"], &[0.0, 0.0]);
        b.put(two, i, br#"{"b": 1}"#);
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "/one/b", "/two/b"]);
    assert_eq!(samples.len(), 3);
    let topics: Vec<(String, u64)> = reader
        .topics()
        .into_iter()
        .map(|t| (t.topic, t.messages))
        .collect();
    assert_eq!(topics, [("/one".to_string(), 3), ("/two".to_string(), 3)]);
}

#[test]
fn files_without_summary_are_scanned_for_their_topics() {
    let dir = temp();
    let path = dir.path().join("nosummary.mcap");
    let options = WriteOptions::new()
        .compression(Some(Compression::Lz4))
        .emit_summary_records(false)
        .emit_summary_offsets(false)
        .emit_statistics(false)
        .emit_chunk_indexes(false)
        .emit_message_indexes(false);
    let mut b = Builder::with_options(&path, options);
    let a = b.joint_state_topic("/a");
    let r = b.json_topic("/late");
    for i in 0..50u64 {
        b.put(a, i + 1, &cdr(&joint_state(0, &["a"], &[i as f64]), false));
    }
    // A topic whose first message comes late is still found.
    for i in 0..50u64 {
        b.put(r, i + 1, br#"{"r": 2}"#);
    }
    b.finish();
    let (reader, samples) = read_all(&path, &ReadOptions::default());
    assert_eq!(names(&reader), ["a", "r"]);
    assert_eq!(samples.len(), 50);
    assert_eq!(samples[49].values[0], 49.0);
}

#[test]
fn extreme_positions_and_stamps_are_errors_naming_the_joint() {
    let dir = temp();
    let mut wild_nanosec = joint_state(T0 + 2, &["a", "b"], &[0.0, 1.0]);
    wild_nanosec.header.stamp.nanosec = 4_000_000_000;
    let cases: Vec<(&str, Vec<u8>, &str, &str)> = vec![
        (
            "nan",
            cdr(&joint_state(T0 + 2, &["a", "b"], &[f64::NAN, 1.0]), false),
            "a",
            "not a finite number",
        ),
        (
            "inf",
            cdr(
                &joint_state(T0 + 2, &["a", "b"], &[0.0, f64::INFINITY]),
                true,
            ),
            "b",
            "not a finite number",
        ),
        (
            "billion_revolutions",
            cdr(
                &joint_state(T0 + 2, &["a", "b"], &[0.0, 1e9 * std::f64::consts::TAU]),
                false,
            ),
            "b",
            "revolutions from zero",
        ),
        (
            "nanosec",
            cdr(&wild_nanosec, false),
            "/joint_states",
            "nanosec is 4000000000",
        ),
    ];
    for (name, bad, channel, expect) in cases {
        let path = dir.path().join(format!("{name}.mcap"));
        log_with_bad_message(&path, &bad);
        let (read, err) = first_error(&path);
        assert_eq!(read, 2, "{name}");
        let (index, got, message) = mcap_error(err);
        assert_eq!(index, Some(2), "{name}");
        assert_eq!(got.as_deref(), Some(channel), "{name}");
        assert!(message.contains(expect), "{name}: {message}");
    }
}

#[test]
fn extreme_json_values_are_errors_naming_the_field() {
    let dir = temp();
    for (name, bad) in [
        ("degrees", r#"{"a": 1, "b": 1e12}"#),
        ("overflow", r#"{"a": 1, "b": 1e308}"#),
    ] {
        let path = dir.path().join(format!("{name}.mcap"));
        let mut b = Builder::new(&path, None, true);
        let ch = b.json_topic("/enc");
        b.put(ch, 1, br#"{"a": 1, "b": 2}"#);
        b.put(ch, 2, bad.as_bytes());
        b.finish();
        let opts = ReadOptions {
            unit: Some(AngleUnit::Rev),
            ..ReadOptions::default()
        };
        let reader = McapReader::open(&path, &opts).expect("open");
        let mut results: Vec<_> = reader.collect();
        assert_eq!(results.len(), 2, "{name}");
        assert!(results[0].is_ok(), "{name}");
        let (index, _, message) = mcap_error(results.pop().expect("two").unwrap_err());
        assert_eq!(index, Some(1), "{name}");
        assert!(message.contains("field `b`"), "{name}: {message}");
        assert!(
            message.contains("revolutions from zero"),
            "{name}: {message}"
        );
    }
}

#[test]
fn log_times_near_the_i64_limit_are_read_or_refused_never_wrapped() {
    let dir = temp();
    let path = dir.path().join("late.mcap");
    let mut b = Builder::new(&path, None, true);
    let ch = b.json_topic("/enc");
    let last_ok = i64::MAX as u64;
    b.put(ch, last_ok - 1, br#"{"a": 1}"#);
    b.put(ch, last_ok, br#"{"a": 2}"#);
    b.put(ch, last_ok + 1, br#"{"a": 3}"#);
    b.finish();
    let mut reader = McapReader::open(&path, &ReadOptions::default()).expect("open");
    let mut results: Vec<_> = (&mut reader).collect();
    assert_eq!(results.len(), 3);
    let t0 = results[0].as_ref().expect("first").t;
    let t1 = results[1].as_ref().expect("second").t;
    // Counted from the first stamp's second: 1 ns apart, exactly enough.
    let origin = reader.time_origin_s();
    assert_eq!(origin, (last_ok / 1_000_000_000) as f64);
    assert!((t1 - t0 - 1e-9).abs() < 1e-15, "{t0} {t1}");
    assert!((t1 + origin - last_ok as f64 * 1e-9).abs() < 1e-5, "{t1}");
    let (index, _, message) = mcap_error(results.pop().expect("three").unwrap_err());
    assert_eq!(index, Some(2));
    assert!(message.contains("beyond the year 2262"), "{message}");
}

/// The offsets and lengths of the top-level chunk records (opcode 0x06) of MCAP `bytes`.
fn chunk_records(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut at = 8;
    let mut found = Vec::new();
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        match bytes[at] {
            0x06 => found.push((at, 9 + len)),
            0x0F => break,
            _ => {}
        }
        at += 9 + len;
    }
    found
}

/// The message of the first error reading `path`, which must name the chunk at byte `at`.
#[track_caller]
fn chunk_error(path: &Path, at: usize) -> String {
    let (_, e) = first_error(path);
    let (_, _, message) = mcap_error(e);
    assert!(
        message.contains(&format!("the chunk at byte {at}")),
        "{message}"
    );
    message
}

/// One flipped bit in an uncompressed chunk (a position's last byte: the record still parses, the
/// reading changes) is caught by the chunk's CRC; with `skip_damaged` the chunk's messages are left
/// out, every other message is read, and the chunk is listed.
#[test]
fn a_flipped_bit_in_an_uncompressed_chunk_fails_its_crc_or_is_skipped() {
    let dir = temp();
    let path = dir.path().join("plain.mcap");
    joint_state_log(&path, 500, None, true, false);
    let mut bytes = std::fs::read(&path).unwrap();
    let chunks = chunk_records(&bytes);
    assert!(chunks.len() > 4, "{} chunks", chunks.len());
    let (at, len) = chunks[2];
    // The last byte of the chunk's last message is its last position's most significant byte.
    bytes[at + len - 1] ^= 1;
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, &bytes).unwrap();

    let message = chunk_error(&bad, at);
    assert!(message.contains("do not match its CRC"), "{message}");

    let opts = ReadOptions {
        skip_damaged: true,
        ..ReadOptions::default()
    };
    let (reader, samples) = read_all(&bad, &opts);
    let damaged = &reader.diagnostics().damaged_chunks;
    assert_eq!(damaged.len(), 1);
    assert_eq!(damaged[0].byte_offset, at as u64);
    let (good_reader, good) = read_all(&path, &ReadOptions::default());
    assert!(good_reader.diagnostics().damaged_chunks.is_empty());
    let lost = good.len() - samples.len();
    assert!(lost > 0 && lost < 100, "{lost} samples lost");
    // Every sample kept is one of the undamaged file's, unchanged.
    assert!(samples.iter().all(|s| good.contains(s)));

    // A record length inside the chunk that overruns it: the chunk cannot be decoded, and is
    // skipped by discarding the rest of it.
    let mut bytes = std::fs::read(&path).unwrap();
    // The chunk header of an uncompressed chunk is 40 bytes; then the first record's opcode and
    // length.
    let first_record = at + 9 + 40;
    bytes[first_record + 5] = 0x7f;
    std::fs::write(&bad, &bytes).unwrap();
    let message = chunk_error(&bad, at);
    assert!(message.contains("cannot be decoded"), "{message}");
    let (reader, samples) = read_all(&bad, &opts);
    assert_eq!(reader.diagnostics().damaged_chunks.len(), 1);
    assert_eq!(good.len() - samples.len(), lost);
}

/// In an unchunked file only the data section's CRC can catch a flipped bit: the read ends with
/// an error, so no calibration uses the changed reading.
#[test]
fn a_flipped_bit_in_an_unchunked_file_fails_the_data_section_crc() {
    let dir = temp();
    let path = dir.path().join("flat.mcap");
    joint_state_log(&path, 200, None, false, false);
    let mut bytes = std::fs::read(&path).unwrap();
    // The last message record before the data end: its last byte is the most significant byte
    // of its last position, so the message still decodes, to another finite reading.
    let mut at = 8;
    let mut last_message = 0;
    while bytes[at] != 0x0F {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if bytes[at] == 0x05 {
            last_message = at + 9 + len - 1;
        }
        at += 9 + len;
    }
    bytes[last_message] ^= 0x01;
    let bad = dir.path().join("bad.mcap");
    std::fs::write(&bad, &bytes).unwrap();
    let reader = McapReader::open(&bad, &ReadOptions::default());
    let error = match reader {
        Err(e) => e.to_string(),
        Ok(r) => r
            .filter_map(Result::err)
            .map(|e| e.to_string())
            .next()
            .expect("the flipped bit went unnoticed"),
    };
    assert!(
        error.contains("CRC") || error.contains("damaged"),
        "{error}"
    );
}

/// A message of the layout of the messages before it (the same bytes but its stamp and
/// positions) is read without a parse: its readings and stamp are still exactly its own, a
/// zero stamp still falls back to the log time, and a bad position or a `nanosec` past a second
/// is still the error it is; a message of another layout (the joints swapped, an effort added)
/// in between is parsed and read as such. Big- and little-endian.
#[test]
fn messages_of_one_layout_are_read_as_parsed() {
    let dir = temp();
    for be in [false, true] {
        let path = dir.path().join(format!("layouts-{be}.mcap"));
        let mut b = Builder::new(&path, Some(Compression::Zstd), true);
        let ch = b.joint_state_topic("/joint_states");
        let ns = |i: u64| T0 + i * 1_000_000;
        for i in 0..3000u64 {
            let (x, y) = (i as f64 * 1e-3, -(i as f64));
            let mut msg = match i {
                1000..1010 => joint_state(ns(i), &["b", "a"], &[y, x]),
                _ => joint_state(ns(i), &["a", "b"], &[x, y]),
            };
            if (2000..2010).contains(&i) {
                msg.effort = vec![0.5; 3];
            }
            if i == 2500 {
                msg.header.stamp.sec = 0;
                msg.header.stamp.nanosec = 0;
            }
            b.put(ch, ns(i) - 100, &cdr(&msg, be));
        }
        b.finish();
        let (_, samples) = read_all(&path, &ReadOptions::default());
        assert_eq!(samples.len(), 3000);
        for (i, s) in (0..3000u64).zip(&samples) {
            let t = if i == 2500 { ns(i) - 100 } else { ns(i) };
            assert_eq!(s.t, secs(t), "{be} {i}");
            assert_eq!(s.values, [i as f64 * 1e-3, -(i as f64)], "{be} {i}");
        }
    }
    // Errors after a thousand messages of the same layout.
    let good = |i: u64| cdr(&joint_state(T0 + i, &["a", "b"], &[0.0, 1.0]), false);
    let mut nan = good(1500);
    // Position `a` (0.0) comes right before position `b`, the message's only 1.0.
    let one = 1.0f64.to_le_bytes();
    let at = nan.windows(8).position(|w| w == one).unwrap() - 8;
    nan[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    let mut nanosec = good(1500);
    nanosec[8..12].copy_from_slice(&1_000_000_000u32.to_le_bytes());
    for (name, bad, expect) in [
        ("nan", nan, "not a finite number"),
        ("nanosec", nanosec, "not below 10⁹"),
    ] {
        let path = dir.path().join(format!("{name}.mcap"));
        let mut b = Builder::new(&path, Some(Compression::Zstd), true);
        let ch = b.joint_state_topic("/joint_states");
        for i in 0..1500 {
            b.put(ch, i, &good(i));
        }
        b.put(ch, 1500, &bad);
        b.finish();
        let (read, err) = first_error(&path);
        assert_eq!(read, 1500, "{name}");
        let (index, _, message) = mcap_error(err);
        assert_eq!(index, Some(1500), "{name}");
        assert!(message.contains(expect), "{name}: {message}");
    }
}

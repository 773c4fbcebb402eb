//! The bag reader through `LogReader`, as commands read bags: the committed fixture
//! (`testdata/rosbag/small_bag`, written by `cli/tests/it/rosbag_cli.rs`'s `make_fixture`) and
//! `.db3` files built here through rosbag2's SQLite tables, with payloads serialized by the
//! `cdr-encoding` crate (an independent CDR implementation). Each test checks the channels,
//! stamps and readings against the values written.

use std::path::{Path, PathBuf};

use byteorder::LittleEndian;
use calib_core::{AngleUnit, Sample};
use calib_io::AlignOptions;
use calib_io::{Error, LogReader, ReadOptions, TimeSource};
use rusqlite::{Connection, params};
use serde::Serialize;

const T0: i64 = 1_700_000_000_000_000_000;
const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

/// The SQL rosbag2's sqlite3 storage plugin (Humble) runs on a new `.db3` file.
const HUMBLE_SCHEMA: &str = "
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
INSERT INTO schema VALUES (3, 'humble');
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
    timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
";

#[derive(Serialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Serialize)]
struct Header {
    stamp: Time,
    frame_id: String,
}

#[derive(Serialize)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

/// A little-endian CDR payload with its encapsulation header, as rosbag2 stores it.
fn cdr<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    out.extend(cdr_encoding::to_vec::<_, LittleEndian>(msg).expect("serialize"));
    out
}

/// A `sensor_msgs/msg/JointState` stamped `stamp_ns`.
fn joint_state(stamp_ns: i64, names: &[&str], positions: &[f64]) -> Vec<u8> {
    cdr(&JointState {
        header: Header {
            stamp: Time {
                sec: (stamp_ns / 1_000_000_000) as i32,
                nanosec: (stamp_ns % 1_000_000_000) as u32,
            },
            frame_id: String::new(),
        },
        name: names.iter().map(|n| n.to_string()).collect(),
        position: positions.to_vec(),
        velocity: Vec::new(),
        effort: Vec::new(),
    })
}

/// A `.db3` file with rosbag2's tables and these topics `(name, type)`, ids from 1.
fn create_db3(path: &Path, topics: &[(&str, &str)]) -> Connection {
    let db = Connection::open(path).unwrap();
    db.execute_batch(HUMBLE_SCHEMA).unwrap();
    for (k, (name, kind)) in topics.iter().enumerate() {
        db.execute(
            "INSERT INTO topics VALUES (?1, ?2, ?3, 'cdr', '')",
            params![k as i64 + 1, name, kind],
        )
        .unwrap();
    }
    db
}

fn insert(db: &Connection, topic_id: i64, timestamp: i64, data: &[u8]) {
    db.execute(
        "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
        params![topic_id, timestamp, data],
    )
    .unwrap();
}

/// A bag of one JointState topic, joints `a` and `b`: message `i` stamped `T0 + i` ms
/// (received 0.1 ms later) with `a = i/1000`, `b = -2 a` radians.
fn one_topic(path: &Path, n: i64) {
    let db = create_db3(path, &[("/joint_states", JOINT_STATE)]);
    db.execute_batch("BEGIN").unwrap();
    for i in 0..n {
        let t = T0 + i * 1_000_000;
        let a = i as f64 * 1e-3;
        insert(
            &db,
            1,
            t + 100_000,
            &joint_state(t, &["a", "b"], &[a, -2.0 * a]),
        );
    }
    db.execute_batch("COMMIT").unwrap();
}

/// The time a reader gives for a stamp in ns (exact: second and fraction converted apart):
/// stamps since 1970 (from `T0` on) counted from the second of the bag's first, `T0` in these
/// bags (see `LogReader::time_origin_s`).
fn secs(ns: i64) -> f64 {
    let ns = if ns >= T0 { ns - T0 } else { ns };
    (ns / 1_000_000_000) as f64 + (ns % 1_000_000_000) as f64 * 1e-9
}

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/rosbag/small_bag")
}

fn read_all(reader: &mut LogReader) -> Vec<Sample> {
    reader.collect::<Result<_, _>>().expect("read")
}

fn display_names(reader: &LogReader) -> Vec<&str> {
    reader.names().iter().map(|n| n.display.as_str()).collect()
}

fn assert_close(got: &[f64], want: &[f64]) {
    assert_eq!(got.len(), want.len(), "{got:?} vs {want:?}");
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-9, "{got:?} vs {want:?}");
    }
}

/// The committed fixture: two splits of two arms sharing joint names (left at `T0 + i` × 10 ms
/// with `q = i/50`, `2q`; right 4 ms later with `-q`, `q`) and a `/rosout` topic calib skips.
#[test]
fn the_committed_bag_names_its_channels_and_aligns_both_arms_on_the_first() {
    let mut reader = LogReader::open(&fixture(), &ReadOptions::default()).expect("open");
    assert_eq!(
        display_names(&reader),
        [
            "/left/joint_states/shoulder",
            "/left/joint_states/elbow",
            "/right/joint_states/shoulder",
            "/right/joint_states/elbow",
        ]
    );
    assert!(reader.channels().iter().all(|c| c.unit == AngleUnit::Rad));
    let samples = read_all(&mut reader);
    // The right arm's first message comes after the left's: the left's first stamp cannot be
    // aligned (no extrapolation), every other one is, the right arm interpolated 4 ms back.
    assert_eq!(samples.len(), 199);
    for (k, s) in samples.iter().enumerate() {
        let i = k as i64 + 1;
        assert_eq!(s.t, secs(T0 + i * 10_000_000));
        let q = i as f64 * 0.02;
        let right = (i as f64 - 0.4) * 0.02;
        assert_close(&s.values, &[q, 2.0 * q, -right, right]);
    }
    let alignment = reader.alignment().expect("alignment");
    assert_eq!(
        (alignment.clock.as_str(), alignment.clock_samples),
        ("/left/joint_states/shoulder", 200)
    );
    let counts: Vec<_> = alignment
        .channels
        .iter()
        .map(|c| (c.channel.as_str(), c.exact, c.interpolated, c.dropped))
        .collect();
    // The left elbow shares its arm's messages: exact wherever a sample is kept, never the
    // cause of a drop.
    assert_eq!(
        counts,
        [
            ("/left/joint_states/elbow", 199, 0, 0),
            ("/right/joint_states/shoulder", 0, 199, 1),
            ("/right/joint_states/elbow", 0, 199, 1),
        ]
    );
    // Both splits read: 200 messages a topic, at 100 Hz of receive time; `/rosout` counted
    // from the bag's rows without being read.
    let topics: Vec<_> = reader
        .topics()
        .into_iter()
        .map(|t| (t.topic, t.schema, t.messages, t.rate_hz.map(f64::round)))
        .collect();
    let topic = |name: &str, schema: &str| (name.to_string(), schema.to_string(), 200, Some(100.0));
    assert_eq!(
        topics,
        [
            topic("/left/joint_states", JOINT_STATE),
            topic("/right/joint_states", JOINT_STATE),
            topic("/rosout", "rcl_interfaces/msg/Log"),
        ]
    );
    // `/rosout` is listed with the topics, but as ROS bookkeeping it is not noted (issue 31).
    assert!(reader.notes().is_empty(), "{:?}", reader.notes());
    // The one drop, once per right channel; nothing about how the bag was found.
    let warnings = reader.warnings(&fixture());
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(
        warnings
            .iter()
            .all(|w| w.contains("1 of 200 sample(s) of the clock")),
        "{warnings:?}"
    );
}

/// A selection in another order: the right arm's elbow sets the clock.
#[test]
fn a_selection_reads_its_channels_in_its_order_on_the_first_ones_clock() {
    let mut reader = LogReader::open(&fixture(), &ReadOptions::default()).expect("open");
    let channels = [
        reader.resolve("/right/joint_states/elbow").unwrap(),
        reader.resolve("/left/joint_states/shoulder").unwrap(),
    ];
    reader.select(&channels, AlignOptions::default());
    let names: Vec<&str> = reader.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        ["/right/joint_states/elbow", "/left/joint_states/shoulder"]
    );
    let samples = read_all(&mut reader);
    // The right arm's last stamp comes after the left's last message: it is dropped.
    assert_eq!(samples.len(), 199);
    for (i, s) in samples.iter().enumerate() {
        let t = T0 + i as i64 * 10_000_000 + 4_000_000;
        assert_eq!(s.t, secs(t));
        let q = i as f64 * 0.02;
        assert_close(&s.values, &[q, (i as f64 + 0.4) * 0.02]);
    }
}

/// One topic whose messages carry every joint: each message is a sample, at its header stamp,
/// or at its receive time with `TimeSource::Log`.
#[test]
fn one_topic_gives_a_sample_per_row_at_its_header_stamp_or_receive_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.db3");
    one_topic(&path, 500);
    for (time, offset) in [(TimeSource::Header, 0), (TimeSource::Log, 100_000)] {
        let opts = ReadOptions {
            time,
            ..ReadOptions::default()
        };
        let mut reader = LogReader::open(&path, &opts).expect("open");
        assert_eq!(display_names(&reader), ["a", "b"]);
        let samples = read_all(&mut reader);
        assert_eq!(samples.len(), 500);
        for (i, s) in samples.iter().enumerate() {
            assert_eq!(s.t, secs(T0 + i as i64 * 1_000_000 + offset));
            let a = i as f64 * 1e-3;
            assert_eq!(s.values, [a, -2.0 * a]);
        }
        let alignment = reader.alignment().expect("alignment");
        assert_eq!(alignment.clock_samples, 500);
        assert_eq!(alignment.channels[0].exact, 500);
    }
}

/// A `std_msgs/msg/Float64` topic is one channel named after it, in the unit asked for.
#[test]
fn a_scalar_topic_is_one_channel_in_the_unit_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scalar.db3");
    let db = create_db3(&path, &[("/encoder", "std_msgs/msg/Float64")]);
    for i in 0..10i64 {
        insert(&db, 1, T0 + i * 1_000_000, &cdr(&(i as f64 * 9.0)));
    }
    drop(db);
    let mut reader = LogReader::open(&path, &ReadOptions::default()).expect("open");
    assert_eq!(display_names(&reader), ["/encoder"]);
    assert_eq!(reader.channels()[0].unit, AngleUnit::Deg);
    let samples = read_all(&mut reader);
    assert_eq!(samples.len(), 10);
    for (i, s) in samples.iter().enumerate() {
        assert_eq!(s.t, secs(T0 + i as i64 * 1_000_000));
        assert_close(&s.values, &[(i as f64 * 9.0).to_radians()]);
    }
}

/// A damaged row: the samples before it are read, then an error naming the file, the table, the
/// row and the topic; the iteration ends there.
#[test]
fn a_damaged_row_ends_the_reading_naming_its_id_and_topic() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("damaged.db3");
    one_topic(&path, 100);
    let db = Connection::open(&path).unwrap();
    db.execute(
        "UPDATE messages SET data = X'00010000FFFF' WHERE id = 51",
        [],
    )
    .unwrap();
    drop(db);
    let mut reader = LogReader::open(&path, &ReadOptions::default()).expect("open");
    let mut read = Vec::new();
    let err = loop {
        match reader.next().expect("an error before the end") {
            Ok(s) => read.push(s),
            Err(e) => break e,
        }
    };
    assert_eq!(read.len(), 50);
    assert_close(&read[49].values, &[0.049, -0.098]);
    let Error::Bag {
        path: named,
        table,
        message_id,
        topic,
        ..
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(named, &path);
    assert_eq!(table.as_deref(), Some("messages"));
    assert_eq!(*message_id, Some(51));
    assert_eq!(topic.as_deref(), Some("/joint_states"));
    assert!(reader.next().is_none());
}

/// A row received before 1970 is refused, naming its id.
#[test]
fn a_receive_time_before_1970_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("clock.db3");
    one_topic(&path, 10);
    let db = Connection::open(&path).unwrap();
    db.execute("UPDATE messages SET timestamp = -5 WHERE id = 10", [])
        .unwrap();
    drop(db);
    // Rows come in receive-time order: the bad one first.
    let err = LogReader::open(&path, &ReadOptions::default())
        .expect("open")
        .next()
        .expect("a row")
        .unwrap_err();
    let Error::Bag {
        message_id,
        message,
        ..
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(*message_id, Some(10));
    assert!(message.contains("-5 ns is before 1970"), "{err}");
}

/// A file cut short is not read as a bag, and a SQLite file without rosbag2's tables is refused
/// naming the table missing.
#[test]
fn a_cut_or_foreign_db3_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole.db3");
    one_topic(&whole, 2000);
    let bytes = std::fs::read(&whole).unwrap();
    let cut = dir.path().join("cut.db3");
    std::fs::write(&cut, &bytes[..bytes.len() / 3]).unwrap();
    let outcome = LogReader::open(&cut, &ReadOptions::default())
        .and_then(|r| r.collect::<Result<Vec<_>, _>>());
    let err = outcome.expect_err("a cut bag");
    assert!(
        matches!(&err, Error::Bag { path, .. } if path == &cut),
        "{err}"
    );

    let foreign = dir.path().join("foreign.db3");
    let db = Connection::open(&foreign).unwrap();
    db.execute_batch("CREATE TABLE topics(id INTEGER PRIMARY KEY);")
        .unwrap();
    drop(db);
    let err = LogReader::open(&foreign, &ReadOptions::default())
        .err()
        .expect("refused");
    let Error::Bag { table, message, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(table.as_deref(), Some("messages"));
    assert!(message.contains("no `messages` table"), "{err}");
}

/// A topic without messages has no channel; a channel name of no topic is not found; a bag whose
/// only topic calib does not read is refused, listing it.
#[test]
fn missing_topics_have_no_channels_and_a_bag_of_none_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quiet.db3");
    let db = create_db3(
        &path,
        &[
            ("/joint_states", JOINT_STATE),
            ("/quiet/joint_states", JOINT_STATE),
        ],
    );
    insert(&db, 1, T0, &joint_state(T0, &["a"], &[0.5]));
    drop(db);
    let reader = LogReader::open(&path, &ReadOptions::default()).expect("open");
    assert_eq!(display_names(&reader), ["a"]);
    let topics: Vec<String> = reader.topics().into_iter().map(|t| t.topic).collect();
    assert_eq!(topics, ["/joint_states"]);
    assert!(reader.resolve("/quiet/joint_states/a").is_err());

    let path = dir.path().join("other.db3");
    let db = create_db3(&path, &[("/rosout", "rcl_interfaces/msg/Log")]);
    insert(&db, 1, T0, &[0, 1, 0, 0]);
    drop(db);
    let err = LogReader::open(&path, &ReadOptions::default())
        .err()
        .expect("refused");
    let Error::Bag { table, message, .. } = &err else {
        panic!("{err}")
    };
    assert_eq!(table.as_deref(), Some("topics"));
    assert!(
        message.contains("/rosout (rcl_interfaces/msg/Log)"),
        "{err}"
    );
}

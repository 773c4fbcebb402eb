//! Issue 33's reader findings, one test each: repeated or backward stamps in MCAP logs and bags,
//! MCAP integrity (chunk sizes, data end records inside chunks, definitions from the data
//! section), bounded work on small inputs, and valid inputs read. Every input is built here
//! (MCAP with `mcap::Writer` or byte by byte, bags through rosbag2's SQLite tables).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use calib_core::Sample;
use calib_io::mcap_log::JOINT_STATE_MSGDEF;
use calib_io::{Error, LogReader, ReadOptions, TimeSource};
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions};
use rusqlite::{Connection, params};

const T0: u64 = 1_700_000_000_000_000_000;
const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

/// A little-endian CDR `sensor_msgs/msg/JointState` with its encapsulation header, stamped
/// `stamp_ns`, `frame_id` empty, no velocity or effort.
fn joint_state(stamp_ns: u64, names: &[&str], positions: &[f64]) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    let align = |out: &mut Vec<u8>, n: usize| {
        while (out.len() - 4) % n != 0 {
            out.push(0);
        }
    };
    let string = |out: &mut Vec<u8>, s: &str| {
        align(out, 4);
        out.extend((s.len() as u32 + 1).to_le_bytes());
        out.extend(s.as_bytes());
        out.push(0);
    };
    out.extend(((stamp_ns / 1_000_000_000) as i32).to_le_bytes());
    out.extend(((stamp_ns % 1_000_000_000) as u32).to_le_bytes());
    string(&mut out, "");
    align(&mut out, 4);
    out.extend((names.len() as u32).to_le_bytes());
    for n in names {
        string(&mut out, n);
    }
    align(&mut out, 4);
    out.extend((positions.len() as u32).to_le_bytes());
    align(&mut out, 8);
    for p in positions {
        out.extend(p.to_le_bytes());
    }
    align(&mut out, 4);
    out.extend(0u32.to_le_bytes());
    out.extend(0u32.to_le_bytes());
    out
}

/// Writes an MCAP log of one JointState topic (`a`, `b`), a message per `(log ns, stamp ns)`.
fn mcap_log(path: &Path, messages: &[(u64, u64)], compression: Option<Compression>) {
    let file = BufWriter::new(File::create(path).unwrap());
    let mut w = WriteOptions::new()
        .profile("ros2")
        .compression(compression)
        .chunk_size(Some(4096))
        .create(file)
        .unwrap();
    let schema = w
        .add_schema(JOINT_STATE, "ros2msg", JOINT_STATE_MSGDEF.as_bytes())
        .unwrap();
    let ch = w
        .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
        .unwrap();
    for (i, &(log, stamp)) in messages.iter().enumerate() {
        let x = i as f64 * 1e-3;
        let header = MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: log,
            publish_time: log,
        };
        w.write_to_known_channel(&header, &joint_state(stamp, &["a", "b"], &[x, -x]))
            .unwrap();
    }
    w.finish().unwrap();
}

/// `n` messages at 1 kHz, stamped when logged.
fn regular(n: u64) -> Vec<(u64, u64)> {
    (0..n)
        .map(|i| (T0 + i * 1_000_000, T0 + i * 1_000_000))
        .collect()
}

fn read(path: &Path, opts: &ReadOptions) -> Result<Vec<Sample>, Error> {
    LogReader::open(path, opts)?.collect()
}

fn methods() -> ReadOptions {
    ReadOptions::default()
}

fn inspect() -> ReadOptions {
    ReadOptions {
        allow_unordered_time: true,
        ..ReadOptions::default()
    }
}

// ---------------------------------------------------------------------------------------------
// Item 2: stamps.

/// Every message recorded twice: before, `csrr` took 2 × n samples (map b 254.9″ p-p instead of
/// 68.9″ in the red-team run); now the second copy of the first message is refused, naming it
/// and the message before it.
#[test]
fn mcap_messages_recorded_twice_are_refused_naming_the_message() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twice.mcap");
    let twice: Vec<(u64, u64)> = regular(500).into_iter().flat_map(|m| [m, m]).collect();
    mcap_log(&path, &twice, Some(Compression::Zstd));
    let err = read(&path, &methods()).unwrap_err();
    let Error::Mcap {
        message_index,
        channel,
        message,
        ..
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(*message_index, Some(1), "{err}");
    assert_eq!(channel.as_deref(), Some("/joint_states"), "{err}");
    // Each copy's readings differ (`x` counts messages): a conflict, named with both readings.
    assert!(
        message.contains("clock channel `a` repeats that of message 0 with other readings")
            && message.contains("`a` 0 there, 0.001 here"),
        "{err}"
    );
    // `inspect` passes them on, to count them: all 1000.
    assert_eq!(read(&path, &inspect()).unwrap().len(), 1000);
}

/// Neighbours swapped: before, exit 0 and no warning; now refused at the later neighbour.
#[test]
fn mcap_neighbours_swapped_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("swapped.mcap");
    let mut messages = regular(300);
    messages.swap(100, 101);
    mcap_log(&path, &messages, None);
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("message 101: ")
            && err.contains("goes back before")
            && err.contains("(message 100)"),
        "{err}"
    );
    assert_eq!(read(&path, &inspect()).unwrap().len(), 300);
    messages.swap(100, 101);
    mcap_log(&path, &messages, None);
    assert_eq!(read(&path, &methods()).unwrap().len(), 300);
}

/// Header stamps running backwards while the log times increase: refused, pointing at
/// `--time log`, which reads the log.
#[test]
fn mcap_header_stamps_against_log_times_are_refused_with_the_remedy() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("backwards.mcap");
    let messages: Vec<(u64, u64)> = (0..200u64)
        .map(|i| (T0 + i * 1_000_000, T0 + (200 - i) * 1_000_000))
        .collect();
    mcap_log(&path, &messages, None);
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("message 1: ") && err.contains("`time = log`"),
        "{err}"
    );
    let log = ReadOptions {
        time: TimeSource::Log,
        ..ReadOptions::default()
    };
    assert_eq!(read(&path, &log).unwrap().len(), 200);
}

/// The SQL rosbag2's sqlite3 storage plugin (Humble) runs on a new `.db3` file.
const HUMBLE_SCHEMA: &str = "
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
INSERT INTO schema VALUES (3, 'humble');
CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
    timestamp INTEGER NOT NULL, data BLOB NOT NULL);
CREATE INDEX timestamp_idx ON messages (timestamp ASC);
";

/// A `.db3` file of one JointState topic (`a`, `b`), a row per `(receive ns, stamp ns)`.
fn db3(path: &Path, rows: &[(u64, u64)]) -> Connection {
    let db = Connection::open(path).unwrap();
    db.execute_batch(HUMBLE_SCHEMA).unwrap();
    db.execute(
        "INSERT INTO topics VALUES (1, '/joint_states', ?1, 'cdr', '')",
        params![JOINT_STATE],
    )
    .unwrap();
    let tx = db.unchecked_transaction().unwrap();
    for (i, &(receive, stamp)) in rows.iter().enumerate() {
        let x = i as f64 * 1e-3;
        tx.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            params![receive as i64, joint_state(stamp, &["a", "b"], &[x, -x])],
        )
        .unwrap();
    }
    tx.commit().unwrap();
    db
}

/// A bag whose receive timestamps run against its header stamps: before, `inspect` reported 1
/// sample of 46,400 and exit 0; now the methods refuse it at the second row (naming its id and
/// the remedy), `inspect` passes every row on to count them, and `--time log` reads them all.
#[test]
fn bag_receive_times_against_header_stamps_are_refused_or_read_by_log_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("against.db3");
    let rows: Vec<(u64, u64)> = (0..400u64)
        .map(|i| (T0 + i * 1_000_000, T0 + (400 - i) * 1_000_000))
        .collect();
    drop(db3(&path, &rows));
    let err = read(&path, &methods()).unwrap_err();
    let Error::Bag {
        message_id,
        topic,
        message,
        ..
    } = &err
    else {
        panic!("{err}")
    };
    assert_eq!(*message_id, Some(2), "{err}");
    assert_eq!(topic.as_deref(), Some("/joint_states"), "{err}");
    assert!(
        message.contains("goes back before")
            && message.contains("(message id 1)")
            && message.contains("`time = log`"),
        "{err}"
    );
    assert_eq!(read(&path, &inspect()).unwrap().len(), 400);
    let log = ReadOptions {
        time: TimeSource::Log,
        ..ReadOptions::default()
    };
    assert_eq!(read(&path, &log).unwrap().len(), 400);
}

/// A bag whose every message was recorded twice: refused at the copy.
#[test]
fn bag_rows_recorded_twice_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("twice.db3");
    let twice: Vec<(u64, u64)> = regular(100).into_iter().flat_map(|m| [m, m]).collect();
    drop(db3(&path, &twice));
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("message id 2: ") && err.contains("repeats"),
        "{err}"
    );
}

/// Writes a `.db3` bag of one JointState topic (`a`, `b`), a row per `(receive ns, stamp ns,
/// reading)`: `a` the reading, `b` its negative.
fn db3_readings(path: &Path, rows: &[(u64, u64, f64)]) {
    let db = Connection::open(path).unwrap();
    db.execute_batch(HUMBLE_SCHEMA).unwrap();
    db.execute(
        "INSERT INTO topics VALUES (1, '/joint_states', ?1, 'cdr', '')",
        params![JOINT_STATE],
    )
    .unwrap();
    let tx = db.unchecked_transaction().unwrap();
    for &(receive, stamp, x) in rows {
        tx.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            params![receive as i64, joint_state(stamp, &["a", "b"], &[x, -x])],
        )
        .unwrap();
    }
    tx.commit().unwrap();
}

/// Issue 50 item 2: a bag in which every 3rd row was recorded twice (a bridge subscribed
/// twice): before, refused at the first copy; now the copies are dropped and counted, and the
/// samples are those of the bag without them, exactly. A copy whose reading differs is still
/// refused, naming both rows' readings.
#[test]
fn bag_rows_recorded_twice_exactly_are_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<(u64, u64, f64)> = regular(300)
        .into_iter()
        .enumerate()
        .map(|(i, (r, st))| (r, st, i as f64 * 1e-3))
        .collect();
    let twice: Vec<(u64, u64, f64)> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, &row)| std::iter::repeat_n(row, 1 + usize::from(i % 3 == 0)))
        .collect();
    let (clean_path, twice_path) = (dir.path().join("clean.db3"), dir.path().join("twice.db3"));
    db3_readings(&clean_path, &rows);
    db3_readings(&twice_path, &twice);
    let mut reader = LogReader::open(&twice_path, &methods()).unwrap();
    let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
    assert_eq!(samples, read(&clean_path, &methods()).unwrap());
    assert_eq!(reader.diagnostics().duplicates_dropped, 100);
    assert_eq!(reader.reading().unwrap().duplicates_dropped, 100);
    let warnings = reader.warnings(&twice_path);
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("twice.db3: 100 duplicated message(s) dropped")),
        "{warnings:?}"
    );
    // The copy of row 4 (id 5) with another reading: refused at id 6, naming id 5's.
    let mut conflict = rows.clone();
    conflict.insert(4, (rows[3].0, rows[3].1, 0.5));
    let path = dir.path().join("conflict.db3");
    db3_readings(&path, &conflict);
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("message id 5: ")
            && err.contains("repeats that of message id 4 with other readings")
            && err.contains("`a` 0.003 there, 0.5 here; `b` -0.003 there, -0.5 here"),
        "{err}"
    );
}

/// The same for an MCAP file whose messages were each recorded twice, readings and all: the
/// copies dropped and counted, the samples those of the file without them.
#[test]
fn mcap_messages_recorded_twice_exactly_are_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let write = |path: &Path, copies: usize| {
        let file = BufWriter::new(File::create(path).unwrap());
        let mut w = WriteOptions::new()
            .profile("ros2")
            .chunk_size(Some(4096))
            .create(file)
            .unwrap();
        let schema = w
            .add_schema(JOINT_STATE, "ros2msg", JOINT_STATE_MSGDEF.as_bytes())
            .unwrap();
        let ch = w
            .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
            .unwrap();
        for (i, (log, stamp)) in regular(200).into_iter().enumerate() {
            let x = i as f64 * 1e-3;
            for _ in 0..copies {
                let header = MessageHeader {
                    channel_id: ch,
                    sequence: i as u32,
                    log_time: log,
                    publish_time: log,
                };
                w.write_to_known_channel(&header, &joint_state(stamp, &["a", "b"], &[x, -x]))
                    .unwrap();
            }
        }
        w.finish().unwrap();
    };
    let (once, twice) = (dir.path().join("once.mcap"), dir.path().join("twice.mcap"));
    write(&once, 1);
    write(&twice, 2);
    for opts in [methods(), inspect()] {
        let mut reader = LogReader::open(&twice, &opts).unwrap();
        let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
        assert_eq!(samples, read(&once, &opts).unwrap());
        assert_eq!(reader.diagnostics().duplicates_dropped, 200);
    }
}

// ---------------------------------------------------------------------------------------------
// Item 3: MCAP integrity.

/// An MCAP record: opcode, length, body.
fn record(out: &mut Vec<u8>, opcode: u8, body: &[u8]) {
    out.push(opcode);
    out.extend((body.len() as u64).to_le_bytes());
    out.extend(body);
}

fn string(out: &mut Vec<u8>, s: &str) {
    out.extend((s.len() as u32).to_le_bytes());
    out.extend(s.as_bytes());
}

/// Schema 1 (JointState) and channel 1 (`/joint_states`) records.
fn schema_and_channel() -> Vec<u8> {
    let mut out = Vec::new();
    let mut schema = 1u16.to_le_bytes().to_vec();
    string(&mut schema, JOINT_STATE);
    string(&mut schema, "ros2msg");
    string(&mut schema, JOINT_STATE_MSGDEF);
    record(&mut out, 0x03, &schema);
    let mut channel = 1u16.to_le_bytes().to_vec();
    channel.extend(1u16.to_le_bytes());
    string(&mut channel, "/joint_states");
    string(&mut channel, "cdr");
    channel.extend(0u32.to_le_bytes());
    record(&mut out, 0x04, &channel);
    out
}

/// Message records `range` of the regular 1 kHz log.
fn messages(range: std::ops::Range<u64>) -> Vec<u8> {
    let mut out = Vec::new();
    for i in range {
        let ns = T0 + i * 1_000_000;
        let mut body = 1u16.to_le_bytes().to_vec();
        body.extend((i as u32).to_le_bytes());
        body.extend(ns.to_le_bytes());
        body.extend(ns.to_le_bytes());
        let x = i as f64 * 1e-3;
        body.extend(joint_state(ns, &["a", "b"], &[x, -x]));
        record(&mut out, 0x05, &body);
    }
    out
}

/// A chunk record holding `records`, stored as `stored` (compressed with `compression`),
/// declaring `declared` uncompressed bytes and their CRC.
fn chunk(records: &[u8], stored: &[u8], compression: &str, declared: usize) -> Vec<u8> {
    let mut body = Vec::new();
    body.extend(T0.to_le_bytes());
    body.extend(T0.to_le_bytes());
    body.extend((declared as u64).to_le_bytes());
    body.extend(crc32fast::hash(&records[..declared]).to_le_bytes());
    string(&mut body, compression);
    body.extend((stored.len() as u64).to_le_bytes());
    body.extend(stored);
    let mut out = Vec::new();
    record(&mut out, 0x06, &body);
    out
}

/// A file of these data records: magic, header, the records, data end, an empty footer, magic.
fn mcap_file(data: &[u8]) -> Vec<u8> {
    let mut out = b"\x89MCAP0\r\n".to_vec();
    let mut header = Vec::new();
    string(&mut header, "ros2");
    string(&mut header, "test");
    record(&mut out, 0x01, &header);
    out.extend(data);
    record(&mut out, 0x0F, &0u32.to_le_bytes());
    record(&mut out, 0x02, &[0u8; 20]);
    out.extend(b"\x89MCAP0\r\n");
    out
}

/// A data end record inside a CRC-valid chunk: before, `inspect` and the methods stopped there
/// (2,927 of 46,400 samples in the red-team file) while `apply` read on; now the chunk is damaged
/// (an error, or left out and listed with `--skip-damaged`), the same for every reader.
#[test]
fn a_data_end_record_inside_a_chunk_is_a_damaged_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("data-end-in-chunk.mcap");
    let mut records = schema_and_channel();
    records.extend(messages(0..50));
    record(&mut records, 0x0F, &0u32.to_le_bytes());
    records.extend(messages(50..100));
    let mut data = chunk(&records, &records, "", records.len());
    // A second chunk, intact.
    let mut second = Vec::new();
    second.extend(messages(100..150));
    data.extend(chunk(&second, &second, "", second.len()));
    std::fs::write(&path, mcap_file(&data)).unwrap();
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("is damaged: it holds a data end record, which the MCAP format allows only outside chunks"),
        "{err}"
    );
    // Its channel is in the damaged chunk too: nothing is left to read.
    let skip = ReadOptions {
        skip_damaged: true,
        ..ReadOptions::default()
    };
    assert!(read(&path, &skip).is_err());
}

/// A zstd chunk whose header declares less than its frame holds: before, the rest of the frame
/// was taken for padding and 267 messages were dropped silently; now it is an error.
#[test]
fn a_chunk_decompressing_to_more_than_it_declares_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("short-declared.mcap");
    let mut records = schema_and_channel();
    let head = records.len() + messages(0..100).len();
    records.extend(messages(0..300));
    let frame = zstd::bulk::compress(&records, 3).unwrap();
    std::fs::write(&path, mcap_file(&chunk(&records, &frame, "zstd", head))).unwrap();
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(err.contains("decompresses to more than the"), "{err}");
    // Declared right, it reads whole.
    std::fs::write(
        &path,
        mcap_file(&chunk(&records, &frame, "zstd", records.len())),
    )
    .unwrap();
    assert_eq!(read(&path, &methods()).unwrap().len(), 300);
}

/// A record longer than the whole (small, compressed) file: before, "damaged chunk"; now read.
#[test]
fn a_small_file_with_one_large_compressible_record_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("large-record.mcap");
    let file = BufWriter::new(File::create(&path).unwrap());
    let mut w = WriteOptions::new()
        .compression(Some(Compression::Zstd))
        .create(file)
        .unwrap();
    let ch = w.add_channel(0, "/enc", "json", &BTreeMap::new()).unwrap();
    for i in 0..3u64 {
        let pad = if i == 0 {
            "x".repeat(2 << 20)
        } else {
            String::new()
        };
        let text = format!("{{\"note\": \"{pad}\", \"a\": {i}}}");
        let ns = T0 + i * 1_000_000;
        let header = MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: ns,
            publish_time: ns,
        };
        w.write_to_known_channel(&header, text.as_bytes()).unwrap();
    }
    w.finish().unwrap();
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len < 1 << 20, "the file is {len} bytes, the record 2 MiB");
    assert_eq!(read(&path, &methods()).unwrap().len(), 3);
}

/// Where the footer says the summary starts, and the offset of the footer's summary CRC.
fn summary_start(bytes: &[u8]) -> (usize, usize) {
    let footer = bytes.len() - 8 - 29;
    assert_eq!(bytes[footer], 0x02);
    let start = u64::from_le_bytes(bytes[footer + 9..footer + 17].try_into().unwrap());
    (start as usize, footer + 25)
}

/// A log of a topic calib reads only by field path (`/motor`, fields `a` then `b`), a = i,
/// b = 1000 + i degrees.
fn field_log(path: &Path) {
    let file = BufWriter::new(File::create(path).unwrap());
    let mut w = WriteOptions::new().profile("ros2").create(file).unwrap();
    let schema = w
        .add_schema("pkg/msg/Motor", "ros2msg", b"float64 a\nfloat64 b\n")
        .unwrap();
    let ch = w
        .add_channel(schema, "/motor", "cdr", &BTreeMap::new())
        .unwrap();
    for i in 0..100u64 {
        let ns = T0 + i * 1_000_000;
        let mut data = vec![0, 1, 0, 0];
        data.extend((i as f64).to_le_bytes());
        data.extend((1000.0 + i as f64).to_le_bytes());
        let header = MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: ns,
            publish_time: ns,
        };
        w.write_to_known_channel(&header, &data).unwrap();
    }
    w.finish().unwrap();
}

/// A damaged summary whose definition swaps `a` and `b`: before, the two maps were swapped,
/// exit 0; now the definition comes from the data section (and a summary that fails its CRC is
/// not used at all), whether the summary's CRC is kept or zeroed (not recorded).
#[test]
fn field_definitions_come_from_the_data_section_not_a_damaged_summary() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fields.mcap");
    field_log(&path);
    let mut bytes = std::fs::read(&path).unwrap();
    let (start, crc_at) = summary_start(&bytes);
    let text = b"float64 a\nfloat64 b\n";
    let at = start
        + bytes[start..]
            .windows(text.len())
            .position(|w| w == text)
            .expect("the summary's copy of the definition");
    bytes[at..at + text.len()].copy_from_slice(b"float64 b\nfloat64 a\n");
    let opts = ReadOptions {
        fields: vec!["/motor.a".into(), "/motor.b".into()],
        ..ReadOptions::default()
    };
    for zero_crc in [false, true] {
        if zero_crc {
            bytes[crc_at..crc_at + 4].copy_from_slice(&[0; 4]);
        }
        std::fs::write(&path, &bytes).unwrap();
        let mut reader = LogReader::open(&path, &opts).unwrap();
        let names: Vec<String> = reader.names().iter().map(|n| n.display.clone()).collect();
        let a = names.iter().position(|n| n == "/motor.a").unwrap();
        let b = names.iter().position(|n| n == "/motor.b").unwrap();
        reader.select(&[a, b], Default::default());
        let samples: Vec<Sample> = reader.collect::<Result<_, _>>().unwrap();
        assert_eq!(samples.len(), 100);
        for (i, s) in samples.iter().enumerate() {
            assert_eq!(s.values[0], (i as f64).to_radians(), "zero crc {zero_crc}");
            assert_eq!(
                s.values[1],
                (1000.0 + i as f64).to_radians(),
                "zero crc {zero_crc}"
            );
        }
    }
}

/// A summary whose statistics claim 0 messages (CRC not recorded): before, "holds no samples";
/// now the file is scanned as if it had no summary, and every message is read.
#[test]
fn a_summary_claiming_no_messages_does_not_hide_an_intact_log() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zero-count.mcap");
    mcap_log(&path, &regular(500), Some(Compression::Zstd));
    let mut bytes = std::fs::read(&path).unwrap();
    let (start, crc_at) = summary_start(&bytes);
    // Walk the summary to its statistics record and zero the message counts.
    let mut at = start;
    while bytes[at] != 0x0B {
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    let body = at + 9;
    bytes[body..body + 8].copy_from_slice(&[0; 8]);
    let map = body + 42;
    let map_len = u32::from_le_bytes(bytes[map..map + 4].try_into().unwrap()) as usize;
    let mut entry = map + 4;
    while entry < map + 4 + map_len {
        bytes[entry + 2..entry + 10].copy_from_slice(&[0; 8]);
        entry += 10;
    }
    bytes[crc_at..crc_at + 4].copy_from_slice(&[0; 4]);
    std::fs::write(&path, &bytes).unwrap();
    assert_eq!(read(&path, &methods()).unwrap().len(), 500);
}

// ---------------------------------------------------------------------------------------------
// Item 4: bounded work.

/// An MCAP log of `topics` JSON topics, one message each (`{"v": i}`), logged in turn.
fn json_topics_log(path: &Path, topics: usize) {
    let file = BufWriter::new(File::create(path).unwrap());
    let mut w = WriteOptions::new().create(file).unwrap();
    for k in 0..topics {
        let ch = w
            .add_channel(0, &format!("/t{k}"), "json", &BTreeMap::new())
            .unwrap();
        let ns = T0 + k as u64 * 1_000_000;
        let header = MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: ns,
            publish_time: ns,
        };
        w.write_to_known_channel(&header, format!("{{\"v{k}\": {k}}}").as_bytes())
            .unwrap();
    }
    w.finish().unwrap();
}

/// 5,000 JSON topics: before, 78 s to open (a check per message over every topic pair); now a
/// check per message that does not grow with them. The bound is loose (a debug build on a
/// shared machine); the figure is in the report.
#[test]
fn many_json_topics_open_in_near_linear_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("topics.mcap");
    json_topics_log(&path, 5_000);
    let started = std::time::Instant::now();
    let reader = LogReader::open(&path, &methods()).unwrap();
    let took = started.elapsed();
    eprintln!("5000 JSON topics: opened in {took:?}");
    assert_eq!(reader.names().len(), 5_000);
    assert!(took.as_secs_f64() < 20.0, "{took:?}");
}

/// Beyond the topic limit: refused before any message is read, naming the limit.
#[test]
fn more_topics_than_the_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("too-many-topics.mcap");
    json_topics_log(&path, calib_io::limits::MAX_TOPICS + 1);
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("more than 10000 topics"), "{err}");
}

/// 60,000 joints in one JointState: before, 48 s and 1.1 GB; now refused at the count.
#[test]
fn more_joints_than_the_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("joints.mcap");
    let names: Vec<String> = (0..60_000).map(|k| format!("j{k}")).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let file = BufWriter::new(File::create(&path).unwrap());
    let mut w = WriteOptions::new().profile("ros2").create(file).unwrap();
    let schema = w
        .add_schema(JOINT_STATE, "ros2msg", JOINT_STATE_MSGDEF.as_bytes())
        .unwrap();
    let ch = w
        .add_channel(schema, "/joint_states", "cdr", &BTreeMap::new())
        .unwrap();
    let header = MessageHeader {
        channel_id: ch,
        sequence: 0,
        log_time: T0,
        publish_time: T0,
    };
    w.write_to_known_channel(&header, &joint_state(T0, &names, &vec![0.0; names.len()]))
        .unwrap();
    w.finish().unwrap();
    let started = std::time::Instant::now();
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("names 60000 joints, more than the 10000"),
        "{err}"
    );
    assert!(started.elapsed().as_secs_f64() < 5.0);
}

/// 100,000 JSON keys: before, 62 s and a 789 KB one-line error; now refused at once, and a
/// message listing a topic's fields lists at most 20 of them.
#[test]
fn json_messages_with_more_fields_than_the_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("keys.mcap");
    let file = BufWriter::new(File::create(&path).unwrap());
    let mut w = WriteOptions::new().create(file).unwrap();
    let ch = w.add_channel(0, "/enc", "json", &BTreeMap::new()).unwrap();
    let many: Vec<String> = (0..100_000).map(|k| format!("\"k{k}\": {k}")).collect();
    let few: Vec<String> = (0..5_000).map(|k| format!("\"k{k}\": {k}")).collect();
    let messages = [
        format!("{{{}}}", few.join(", ")),
        format!("{{{}, \"new\": 1}}", few.join(", ")),
    ];
    for (i, text) in messages.iter().enumerate() {
        let ns = T0 + i as u64 * 1_000_000;
        let header = MessageHeader {
            channel_id: ch,
            sequence: i as u32,
            log_time: ns,
            publish_time: ns,
        };
        w.write_to_known_channel(&header, text.as_bytes()).unwrap();
    }
    w.finish().unwrap();
    let err = read(&path, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("numeric field `new` is new") && err.contains("(4980 more)"),
        "{err}"
    );
    assert!(err.len() < 1000, "{} bytes", err.len());

    let file = BufWriter::new(File::create(&path).unwrap());
    let mut w = WriteOptions::new().create(file).unwrap();
    let ch = w.add_channel(0, "/enc", "json", &BTreeMap::new()).unwrap();
    let header = MessageHeader {
        channel_id: ch,
        sequence: 0,
        log_time: T0,
        publish_time: T0,
    };
    w.write_to_known_channel(&header, format!("{{{}}}", many.join(", ")).as_bytes())
        .unwrap();
    w.finish().unwrap();
    let started = std::time::Instant::now();
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("more than 10000 fields"), "{err}");
    assert!(started.elapsed().as_secs_f64() < 5.0);
}

/// A `.db3` with more topics than the limit: refused before any message is read (before, 87 s
/// and then "no samples").
#[test]
fn a_bag_with_more_topics_than_the_limit_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("topics.db3");
    let db = db3(&path, &regular(10));
    let tx = db.unchecked_transaction().unwrap();
    for k in 0..calib_io::limits::MAX_TOPICS {
        tx.execute(
            "INSERT INTO topics VALUES (?1, ?2, 'std_msgs/msg/String', 'cdr', '')",
            params![k as i64 + 2, format!("/t{k}")],
        )
        .unwrap();
    }
    tx.commit().unwrap();
    drop(db);
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("table `topics`: the file has more than 10000 topics"),
        "{err}"
    );
}

/// `metadata.yaml` of a bag of `.db3` splits, compressed as `format` and `mode` say.
fn bag_metadata(files: &[&str], format: &str, mode: &str) -> String {
    let mut text = format!(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  \
         compression_format: {format}\n  compression_mode: {mode}\n  relative_file_paths:\n"
    );
    for f in files {
        text.push_str(&format!("    - {f}\n"));
    }
    text
}

/// One zstd payload that decompresses to 64 MiB of zeros: before, 1.59 GB of memory for a
/// 49 KB payload; now refused once 16 MiB are out. Read as a `.db3` alone, such a payload was
/// "unsupported CDR encapsulation 28 b5"; now it is named as a compressed payload.
#[test]
fn a_compressed_payload_is_bounded_while_decompressing_and_named_when_unexpected() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let db = db3(&bag.join("bag_0.db3"), &[]);
    for (i, &(receive, stamp)) in regular(3).iter().enumerate() {
        let payload = if i == 1 {
            zstd::bulk::compress(&vec![0u8; 64 << 20], 3).unwrap()
        } else {
            zstd::bulk::compress(&joint_state(stamp, &["a", "b"], &[0.0, 0.0]), 3).unwrap()
        };
        db.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            params![receive as i64, payload],
        )
        .unwrap();
    }
    drop(db);
    std::fs::write(
        bag.join("metadata.yaml"),
        bag_metadata(&["bag_0.db3"], "zstd", "MESSAGE"),
    )
    .unwrap();
    let err = read(&bag, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("message id 2: ") && err.contains("decompresses to more than 16777216 bytes"),
        "{err}"
    );
    let err = read(&bag.join("bag_0.db3"), &methods())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("zstd-compressed") && !err.contains("28 b5 ;"),
        "{err}"
    );
}

/// A split compressed whole that does not decompress to SQLite: refused before anything is
/// written (before, a 98 KB split wrote 3 GB to the temporary folder first).
#[test]
fn a_compressed_split_that_is_not_sqlite_is_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let zeros = zstd::bulk::compress(&vec![0u8; 32 << 20], 19).unwrap();
    std::fs::write(bag.join("bag_0.db3.zstd"), &zeros).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        bag_metadata(&["bag_0.db3.zstd"], "zstd", "FILE"),
    )
    .unwrap();
    let err = LogReader::open(&bag, &methods()).err().unwrap().to_string();
    assert!(
        err.contains("decompresses to something that is not SQLite"),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// Items 5 and 6: temporary files, valid inputs, messages.

fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A WAL-mode `.db3`: before, reading it left `-shm`/`-wal` files beside the recording (and a
/// read-only folder made it "not a rosbag2 bag"); now a checkpointed one is opened immutable and
/// nothing appears beside it, and one whose write-ahead log still holds rows is read from a
/// temporary copy of both, rows of the log included.
#[test]
fn a_wal_mode_bag_is_read_without_writing_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wal.db3");
    {
        let db = Connection::open(&path).unwrap();
        db.pragma_update(None, "journal_mode", "WAL").unwrap();
        drop(db);
    }
    drop(db3(&path, &regular(300)));
    assert_eq!(entries(dir.path()), ["wal.db3"]);
    assert_eq!(read(&path, &methods()).unwrap().len(), 300);
    assert_eq!(entries(dir.path()), ["wal.db3"]);

    // Rows still in the write-ahead log: a writer holds it open, checkpointing nothing.
    let writer = Connection::open(&path).unwrap();
    writer.pragma_update(None, "wal_autocheckpoint", 0).unwrap();
    let tx = writer.unchecked_transaction().unwrap();
    for (i, &(receive, stamp)) in regular(400).iter().enumerate().skip(300) {
        let x = i as f64 * 1e-3;
        tx.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, ?2)",
            params![receive as i64, joint_state(stamp, &["a", "b"], &[x, -x])],
        )
        .unwrap();
    }
    tx.commit().unwrap();
    let before = entries(dir.path());
    assert!(before.contains(&"wal.db3-wal".to_string()), "{before:?}");
    let modified = |name: &str| {
        std::fs::metadata(dir.path().join(name))
            .unwrap()
            .modified()
            .unwrap()
    };
    let wal_time = modified("wal.db3-wal");
    assert_eq!(read(&path, &methods()).unwrap().len(), 400);
    assert_eq!(entries(dir.path()), before);
    assert_eq!(modified("wal.db3-wal"), wal_time);
    drop(writer);
}

/// A bag whose metadata lists a split outside the bag folder: refused, naming the entry.
#[test]
fn bag_split_paths_outside_the_bag_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    drop(db3(&dir.path().join("outside.db3"), &regular(10)));
    for entry in ["../outside.db3", "/etc/hostname"] {
        std::fs::write(
            bag.join("metadata.yaml"),
            bag_metadata(&[entry], "\"\"", "\"\""),
        )
        .unwrap();
        let err = LogReader::open(&bag, &methods()).err().unwrap().to_string();
        assert!(err.contains("a path outside the bag directory"), "{err}");
    }
}

/// One file listing a topic twice with two types: before, "in an earlier split".
#[test]
fn a_topic_of_two_types_in_one_file_is_not_called_an_earlier_split() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two-types.db3");
    let db = db3(&path, &regular(10));
    db.execute(
        "INSERT INTO topics VALUES (2, '/joint_states', 'std_msgs/msg/Float64', 'cdr', '')",
        [],
    )
    .unwrap();
    drop(db);
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("in another row of this file's `topics` table"),
        "{err}"
    );
    assert!(!err.contains("earlier split"), "{err}");
}

/// A bag of two MCAP splits, the second cut short (a crashed recording): before, refused
/// while the same split alone was recovered; now the messages before the cut are read, with a
/// warning naming the split. A damaged chunk in a split is an error naming `--skip-damaged`,
/// which now leaves it out (before, ignored for split bags).
#[test]
fn a_split_mcap_bag_recovers_a_cut_last_split_and_skips_damaged_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let all = regular(2000);
    mcap_log(&bag.join("bag_0.mcap"), &all[..1000], None);
    mcap_log(&bag.join("bag_1.mcap"), &all[1000..], None);
    let second = std::fs::read(bag.join("bag_1.mcap")).unwrap();
    std::fs::write(bag.join("bag_1.mcap"), &second[..second.len() / 2]).unwrap();
    let meta =
        bag_metadata(&["bag_0.mcap", "bag_1.mcap"], "\"\"", "\"\"").replace("sqlite3", "mcap");
    std::fs::write(bag.join("metadata.yaml"), &meta).unwrap();
    let mut reader = LogReader::open(&bag, &methods()).unwrap();
    let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
    assert!(
        samples.len() > 1200 && samples.len() < 1600,
        "{}",
        samples.len()
    );
    let warnings = reader.warnings(&bag).join("\n");
    assert!(
        warnings.contains("bag_1.mcap: the last split ends early"),
        "{warnings}"
    );

    // A flipped byte in message 100's position of `a`, inside one chunk of the first split.
    let mut first = std::fs::read(bag.join("bag_0.mcap")).unwrap();
    let value = (100.0f64 * 1e-3).to_le_bytes();
    let at = first.windows(8).position(|w| w == value).unwrap();
    first[at] ^= 0x55;
    std::fs::write(bag.join("bag_0.mcap"), &first).unwrap();
    std::fs::write(bag.join("bag_1.mcap"), &second).unwrap();
    let err = read(&bag, &methods()).unwrap_err().to_string();
    assert!(
        err.contains("bag_0.mcap") && err.contains("the `skip_damaged` option"),
        "{err}"
    );
    let skip = ReadOptions {
        skip_damaged: true,
        ..ReadOptions::default()
    };
    let mut reader = LogReader::open(&bag, &skip).unwrap();
    let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
    assert!(
        samples.len() > 1500 && samples.len() < 2000,
        "{}",
        samples.len()
    );
    let warnings = reader.warnings(&bag).join("\n");
    assert!(
        warnings.contains("bag_0.mcap: skipped 1 damaged chunk(s)"),
        "{warnings}"
    );
}

/// A compressed bag (FILE mode) with a bad row: before, the error named the decompressed copy
/// in the temporary folder, gone once calib exits; now it names the split in the bag.
#[test]
fn errors_in_a_compressed_bag_name_the_split_not_its_temporary_copy() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let plain = dir.path().join("bag_0.db3");
    let db = db3(&plain, &regular(10));
    db.execute(
        "INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?1, x'00010000')",
        params![(T0 + 20_000_000) as i64],
    )
    .unwrap();
    drop(db);
    let packed = zstd::bulk::compress(&std::fs::read(&plain).unwrap(), 3).unwrap();
    std::fs::write(bag.join("bag_0.db3.zstd"), packed).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        bag_metadata(&["bag_0.db3.zstd"], "zstd", "FILE"),
    )
    .unwrap();
    let err = read(&bag, &methods()).unwrap_err().to_string();
    let split = bag.join("bag_0.db3.zstd");
    assert!(err.starts_with(&format!("{}: ", split.display())), "{err}");
}

/// `apply` on a `TOPIC.field.path` channel: before, it said the log has no such readings; now it
/// says that field paths are read but not rewritten.
#[test]
fn apply_on_a_field_path_says_field_paths_are_not_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("fields.mcap");
    field_log(&path);
    let map = calib_core::ErrorMap::new(vec![0.0; 360]).into();
    let opts = calib_io::apply::ApplyOptions {
        channel: "/motor.a".into(),
        unit: None,
        wrapping: None,
        skip_damaged: false,
        keep: false,
        one_thread: false,
    };
    let err = calib_io::apply::apply(&path, &dir.path().join("out.mcap"), &map, &opts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("names a field by path"), "{err}");
    assert!(!dir.path().join("out.mcap").exists());
}

/// A CSV log of 100,000 columns (1.5 MB): before, 24 s; now refused at its header.
#[test]
fn a_csv_log_with_more_columns_than_the_limit_is_refused_at_its_header() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wide.csv");
    let header: Vec<String> = std::iter::once("t".to_string())
        .chain((0..100_000).map(|k| format!("c{k}")))
        .collect();
    let row = vec!["0"; header.len()].join(",");
    std::fs::write(&path, format!("{}\n{row}\n", header.join(","))).unwrap();
    let started = std::time::Instant::now();
    let err = LogReader::open(&path, &methods())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("line 1: the header has 100001 columns, more than the 10000"),
        "{err}"
    );
    assert!(started.elapsed().as_secs_f64() < 5.0);
}

//! The rosbag2 bag reader (SQLite storage): rows built from the input into rosbag2's tables, so
//! every execution reaches the bag reader's topics, stamps, payload decoding and (with a flag)
//! payload decompression; or the input itself as the `.db3` file, or as a bag's
//! `metadata.yaml`.
//!
//! Layout: one byte of read options; one byte of layout (bits 0–1: rows, raw `.db3`, raw
//! `metadata.yaml`; bit 2: payloads zstd-compressed, `compression_mode: MESSAGE`); then, for
//! rows, each row a topic byte (of `/joint_states` JointState, `/scalar` Float64, `/dynamic`
//! DynamicJointState, `/other` String), an 8-byte little-endian receive time and a payload (a
//! 2-byte length and that many bytes).
#![no_main]

use calib_fuzz::{check_sample, options};
use calib_io::LogReader;
use libfuzzer_sys::fuzz_target;
use rusqlite::{Connection, params};
use std::path::{Path, PathBuf};

const SCHEMA: &str = "
CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
    serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
    timestamp INTEGER NOT NULL, data BLOB NOT NULL);
INSERT INTO topics VALUES (1, '/joint_states', 'sensor_msgs/msg/JointState', 'cdr', '');
INSERT INTO topics VALUES (2, '/scalar', 'std_msgs/msg/Float64', 'cdr', '');
INSERT INTO topics VALUES (3, '/dynamic', 'control_msgs/msg/DynamicJointState', 'cdr', '');
INSERT INTO topics VALUES (4, '/other', 'std_msgs/msg/String', 'cdr', '');
";

/// This process's scratch bag directory, emptied.
fn bag_dir() -> PathBuf {
    let root = if Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let dir = root.join(format!("calib-fuzz-bag-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch bag directory");
    dir
}

fn metadata(mode: &str) -> String {
    format!(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  \
         compression_format: {}\n  compression_mode: {mode}\n  relative_file_paths:\n  - \
         bag_0.db3\n",
        if mode.is_empty() { "\"\"" } else { "zstd" }
    )
}

/// Writes the rows of `rest` into `path`; whether any was written.
fn write_rows(path: &Path, mut rest: &[u8], compress: bool) -> bool {
    let Ok(db) = Connection::open(path) else {
        return false;
    };
    if db.execute_batch(SCHEMA).is_err() {
        return false;
    }
    let Ok(tx) = db.unchecked_transaction() else {
        return false;
    };
    while let [topic, t0, t1, t2, t3, t4, t5, t6, t7, lo, hi, tail @ ..] = rest {
        let n = usize::from(u16::from_le_bytes([*lo, *hi])).min(tail.len());
        let (payload, tail) = tail.split_at(n);
        rest = tail;
        let time = i64::from_le_bytes([*t0, *t1, *t2, *t3, *t4, *t5, *t6, *t7]);
        let data = if compress {
            zstd::bulk::compress(payload, 1).unwrap_or_default()
        } else {
            payload.to_vec()
        };
        let _ = tx.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
            params![i64::from(topic % 4) + 1, time, data],
        );
    }
    tx.commit().is_ok()
}

fuzz_target!(|data: &[u8]| {
    let [flags, layout, rest @ ..] = data else {
        return;
    };
    let dir = bag_dir();
    let db3 = dir.join("bag_0.db3");
    let compress = layout & 4 != 0;
    let path = match layout & 3 {
        // The input as the `.db3` file itself.
        1 => {
            std::fs::write(&db3, rest).expect("scratch");
            db3
        }
        // The input as `metadata.yaml` beside a small valid split.
        2 => {
            let rows: Vec<u8> = [0u8; 11].to_vec();
            if !write_rows(&db3, &rows, false) {
                return;
            }
            std::fs::write(dir.join("metadata.yaml"), rest).expect("scratch");
            dir.clone()
        }
        _ => {
            if !write_rows(&db3, rest, compress) {
                return;
            }
            std::fs::write(
                dir.join("metadata.yaml"),
                metadata(if compress { "MESSAGE" } else { "" }),
            )
            .expect("scratch");
            dir.clone()
        }
    };
    let Ok(reader) = LogReader::open(&path, &options(*flags)) else {
        return;
    };
    let channels = reader.channels().len();
    let unordered = options(*flags).allow_unordered_time;
    let mut last = f64::NEG_INFINITY;
    for sample in reader {
        let Ok(sample) = sample else { break };
        check_sample(&sample, channels);
        // The clock's stamps increase unless told to pass them on (issue 33).
        assert!(unordered || sample.t > last, "stamp {} after {last}", sample.t);
        last = sample.t;
    }
});

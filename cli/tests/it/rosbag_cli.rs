//! End-to-end tests of rosbag2 bags: bag directories with split `.db3` files, bare `.db3` files,
//! and their errors. The tests write the bags themselves, through the tables rosbag2 (Humble)
//! creates, with CDR payloads as `rmw` serializes them.

use crate::common::{self, inspect, json, ros};

use calib_core::{AngleUnit, Channel, Sample};
use calib_io::mcap_log::McapWriter;
use common::*;
use inspect::{inspect, inspect_json};
use json::read_json;
use ros::*;
use rusqlite::{Connection, params};
use std::path::{Path, PathBuf};

const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

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

/// A `sensor_msgs/msg/JointState` in little-endian CDR with its encapsulation header; alignment
/// is counted from the end of the header, `frame_id` is empty, velocity and effort are empty.
fn joint_state(stamp_ns: i64, names: &[&str], positions: &[f64]) -> Vec<u8> {
    let mut m = Cdr::message();
    m.stamp(stamp_ns as u64).string("").u32(names.len() as u32);
    for n in names {
        m.string(n);
    }
    m.u32(positions.len() as u32);
    for &p in positions {
        m.f64(p);
    }
    m.u32(0).u32(0).bytes()
}

/// `metadata.yaml` as `ros2 bag record` (Humble) writes it, listing these splits.
fn metadata(storage: &str, files: &[&str]) -> String {
    compressed_metadata(storage, files, "\"\"", "\"\"")
}

/// `metadata.yaml` of a bag recorded with `--compression-format FORMAT --compression-mode
/// MODE`.
fn compressed_metadata(storage: &str, files: &[&str], format: &str, mode: &str) -> String {
    let mut text = format!(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: {storage}\n  \
         duration:\n    nanoseconds: 0\n  starting_time:\n    nanoseconds_since_epoch: 0\n  \
         message_count: 0\n  topics_with_message_count: []\n  compression_format: {format}\n  \
         compression_mode: {mode}\n  relative_file_paths:\n"
    );
    for f in files {
        text.push_str(&format!("    - {f}\n"));
    }
    text.push_str("  files: []\n");
    text
}

/// Writes `quick.toml`'s run as a bag directory `dir/run_bag` of two split `.db3` files (the
/// second from the middle of the run on), A's joint `a` on `/enc_a/joint_states` and B's `b` on
/// `/enc_b/joint_states`, header stamps and log times the run's times (the run starts at 0 s,
/// and a zero header stamp means "use the log time", as in the MCAP file); and
/// the same run as `dir/run.mcap` as `calib simulate` writes it. Returns both.
fn write_run(dir: &Path) -> (PathBuf, PathBuf) {
    let mcap = simulate(&testdata("scenarios/quick.toml"), dir, "run.mcap");
    let sc = load_scenario("quick.toml");
    let samples: Vec<Sample> = sc.samples().unwrap().collect();
    let (ia, ib) = (0, 1);
    assert_eq!(sc.channels()[ia].name, "a");
    assert_eq!(sc.channels()[ib].name, "b");
    let bag = dir.join("run_bag");
    std::fs::create_dir(&bag).unwrap();
    let topics = [
        ("/enc_a/joint_states", JOINT_STATE),
        ("/enc_b/joint_states", JOINT_STATE),
    ];
    let half = samples.len() / 2;
    for (k, part) in [&samples[..half], &samples[half..]].into_iter().enumerate() {
        let db = create_db3(&bag.join(format!("run_bag_{k}.db3")), &topics);
        db.execute_batch("BEGIN").unwrap();
        // B's message first at each instant: the order of rows must not matter, only stamps.
        for s in part {
            let t = ns(s.t) as i64;
            insert(&db, 2, t, &joint_state(t, &["b"], &[s.values[ib]]));
            insert(&db, 1, t, &joint_state(t, &["a"], &[s.values[ia]]));
        }
        db.execute_batch("COMMIT").unwrap();
    }
    std::fs::write(
        bag.join("metadata.yaml"),
        metadata("sqlite3", &["run_bag_0.db3", "run_bag_1.db3"]),
    )
    .unwrap();
    (bag, mcap)
}

/// The same run read from a bag directory of two splits and from the MCAP file `calib simulate`
/// writes gives the same maps. The samples and their stamps (to the nanosecond) are the same
/// and A and B share their stamps, so alignment keeps every sample exactly: the maps can only
/// differ by floating-point rounding, far below 1e-6″.
#[test]
fn csrr_on_a_split_bag_matches_the_mcap_of_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let (bag, mcap) = write_run(dir.path());
    let out_mcap = dir.path().join("out_mcap");
    expect_exit(&calib(&["csrr", s(&mcap), "-o", s(&out_mcap)]), 0);
    let out_bag = dir.path().join("out_bag");
    let o = calib(&["csrr", s(&bag), "--a", "a", "--b", "b", "-o", s(&out_bag)]);
    expect_exit(&o, 0);
    for table in ["a.csv", "b.csv"] {
        let worst = table_difference(&out_mcap.join(table), &out_bag.join(table));
        assert!(worst < 1e-6, "{table}: max |bag − mcap| {worst}″");
    }
    // The same channels by their qualified names.
    let o = calib(&[
        "csrr",
        s(&bag),
        "--a",
        "/enc_a/joint_states/a",
        "--b",
        "/enc_b/joint_states/b",
        "-o",
        s(&dir.path().join("out_q")),
    ]);
    expect_exit(&o, 0);
    // Inspect reads every message of both splits, and the bag's .db3 split alone is a log too.
    let samples = inspect_json(&bag, &[]);
    let total = samples["topics"][0]["messages"].as_u64().unwrap();
    assert_eq!(samples["topics"].as_array().unwrap().len(), 2);
    assert_eq!(samples["topics"][1]["messages"].as_u64().unwrap(), total);
    assert_eq!(samples["alignment"]["samples"].as_u64().unwrap(), total);
    let first = inspect_json(&bag.join("run_bag_0.db3"), &[]);
    assert_eq!(
        first["topics"][0]["messages"].as_u64().unwrap(),
        total / 2,
        "{first}"
    );
}

/// A `.db3` file with a JointState topic and `/tf`, 200 messages each at 100 Hz from 1 s.
fn write_with_tf(path: &Path) {
    let db = create_db3(
        path,
        &[
            ("/joint_states", JOINT_STATE),
            ("/tf", "tf2_msgs/msg/TFMessage"),
        ],
    );
    db.execute_batch("BEGIN").unwrap();
    for i in 0..200i64 {
        let t = 1_000_000_000 + i * 10_000_000;
        let angle = i as f64 * 0.01;
        insert(
            &db,
            1,
            t,
            &joint_state(t, &["enc_a", "enc_b"], &[angle, angle + 0.5]),
        );
        // Not a JointState: never decoded.
        insert(&db, 2, t + 1000, &[0, 1, 0, 0, 7, 7, 7, 7]);
    }
    db.execute_batch("COMMIT").unwrap();
}

#[test]
fn inspect_lists_the_topics_calib_does_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let db3 = dir.path().join("robot.db3");
    write_with_tf(&db3);
    let out = inspect(&db3, &[]);
    assert!(out.contains("\ntopics: 1 read, 1 not read\n"), "{out}");
    let line = |topic: &str| {
        out.lines()
            .find(|l| l.trim_start().starts_with(topic))
            .unwrap_or_else(|| panic!("{topic} missing:\n{out}"))
            .to_string()
    };
    assert_mentions(
        &line("/joint_states"),
        &[JOINT_STATE, "cdr", "200 msg", "100.00 Hz"],
    );
    assert_mentions(
        &line("/tf"),
        &[
            "tf2_msgs/msg/TFMessage",
            "200 msg",
            "100.00 Hz",
            "(not read: ROS bookkeeping)",
        ],
    );
    assert!(!out.contains("warning: topic `/tf`"), "{out}");
    assert!(out.contains("      enc_a, enc_b\n"), "{out}");
    assert!(out.contains("  200 samples over "), "{out}");
    // The same file under another extension is recognised by SQLite's magic number.
    let renamed = dir.path().join("robot.bag2");
    std::fs::copy(&db3, &renamed).unwrap();
    expect_exit(&calib(&["inspect", s(&renamed)]), 0);
}

/// ROS 2 bookkeeping topics (`/rosout`, `/tf_static`, `/events/…`) are listed as not read
/// and not warned about; a topic of a type calib does not read that is not bookkeeping (it may
/// hold what the user meant to calibrate) is warned about by name (issue 31).
#[test]
fn bookkeeping_topics_are_listed_and_only_unknown_ones_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let db3 = dir.path().join("robot.db3");
    let db = create_db3(
        &db3,
        &[
            ("/joint_states", JOINT_STATE),
            ("/rosout", "rcl_interfaces/msg/Log"),
            ("/tf_static", "tf2_msgs/msg/TFMessage"),
            (
                "/events/write_split",
                "rosbag2_interfaces/msg/WriteSplitEvent",
            ),
            ("/motor/encoder_raw", "acme_msgs/msg/EncoderFrame"),
        ],
    );
    db.execute_batch("BEGIN").unwrap();
    for i in 0..200i64 {
        let t = 1_000_000_000 + i * 10_000_000;
        let angle = i as f64 * 0.01;
        insert(
            &db,
            1,
            t,
            &joint_state(t, &["enc_a", "enc_b"], &[angle, angle + 0.5]),
        );
        for topic in 2..=5 {
            insert(&db, topic, t + 1000, &[0, 1, 0, 0, 7, 7, 7, 7]);
        }
    }
    db.execute_batch("COMMIT").unwrap();
    drop(db);
    let out = inspect(&db3, &[]);
    assert!(out.contains("\ntopics: 1 read, 4 not read\n"), "{out}");
    for topic in ["/rosout", "/tf_static", "/events/write_split"] {
        let line = out
            .lines()
            .find(|l| l.trim_start().starts_with(topic))
            .unwrap_or_else(|| panic!("{topic} missing:\n{out}"));
        assert!(line.ends_with("(not read: ROS bookkeeping)"), "{line}");
        assert!(!out.contains(&format!("topic `{topic}`")), "{out}");
    }
    assert!(
        out.contains(
            "warning: topic `/motor/encoder_raw` (acme_msgs/msg/EncoderFrame, cdr) is not \
             JointState, a std_msgs scalar or JSON and was skipped"
        ),
        "{out}"
    );
    let json = inspect_json(&db3, &[]);
    let warnings = json["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{json}");
}

#[test]
fn a_bag_directory_without_metadata_is_read_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    write_with_tf(&bag.join("bag_0.db3"));
    let o = calib(&["inspect", s(&bag)]);
    expect_exit(&o, 0);
    // inspect lists warnings with its findings, on stdout.
    assert_mentions(
        &stdout(&o),
        &[
            "bag: the bag has no metadata.yaml",
            "1 .db3 file(s) found",
            "bag_0.db3",
        ],
    );
    assert!(stdout(&o).contains("  200 samples over "), "{}", stdout(&o));
}

#[test]
fn a_bag_directory_of_mcap_storage_is_read_by_the_mcap_reader() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    let channel = [Channel {
        name: "enc".into(),
        unit: AngleUnit::Rad,
    }];
    let mut writer =
        McapWriter::create(&bag.join("bag_0.mcap"), &channel, "/joint_states").unwrap();
    for i in 0..50 {
        let sample = Sample {
            t: 1.0 + f64::from(i) * 0.01,
            values: vec![f64::from(i) * 0.01],
            session: None,
        };
        writer.write(&sample).unwrap();
    }
    writer.finish().unwrap();
    std::fs::write(bag.join("metadata.yaml"), metadata("mcap", &["bag_0.mcap"])).unwrap();
    let o = calib(&["inspect", s(&bag)]);
    expect_exit(&o, 0);
    assert!(stdout(&o).contains("  50 samples over "), "{}", stdout(&o));
}

#[test]
fn bad_bags_are_errors_naming_the_file_table_and_message() {
    let dir = tempfile::tempdir().unwrap();
    // A SQLite file that is not a bag.
    let other = dir.path().join("other.db3");
    Connection::open(&other)
        .unwrap()
        .execute_batch("CREATE TABLE readings(t REAL, v REAL);")
        .unwrap();
    let err = expect_exit(&calib(&["inspect", s(&other)]), 1);
    assert_mentions(
        &err,
        &[
            "other.db3",
            "not a rosbag2 bag",
            "no `topics` table",
            "readings",
        ],
    );
    // A .db3 that is not SQLite at all.
    let text = write(dir.path(), "text.db3", "t,a\n0,1\n");
    let err = expect_exit(&calib(&["inspect", s(&text)]), 1);
    assert_mentions(&err, &["text.db3", "not a rosbag2 bag"]);
    // Metadata naming a split that is missing.
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    write_with_tf(&bag.join("bag_0.db3"));
    std::fs::write(
        bag.join("metadata.yaml"),
        metadata("sqlite3", &["bag_0.db3", "bag_1.db3"]),
    )
    .unwrap();
    let err = expect_exit(&calib(&["inspect", s(&bag)]), 1);
    assert_mentions(
        &err,
        &[
            "metadata.yaml",
            "relative_file_paths entry 2",
            "`bag_1.db3`",
        ],
    );
    // A JointState message cut short in the middle of the bag.
    let cut = dir.path().join("cut.db3");
    write_with_tf(&cut);
    let db = Connection::open(&cut).unwrap();
    db.execute(
        "UPDATE messages SET data = substr(data, 1, 20) WHERE id = 101",
        [],
    )
    .unwrap();
    drop(db);
    let err = expect_exit(&calib(&["inspect", s(&cut)]), 1);
    assert_mentions(
        &err,
        &[
            "cut.db3",
            "table `messages`",
            "message id 101",
            "topic `/joint_states`",
            "truncated",
        ],
    );
    // Only topics calib does not read.
    let tf = dir.path().join("tf.db3");
    let db = create_db3(&tf, &[("/tf", "tf2_msgs/msg/TFMessage")]);
    insert(&db, 1, 1, &[0, 1, 0, 0]);
    drop(db);
    let err = expect_exit(&calib(&["inspect", s(&tf)]), 1);
    assert_mentions(
        &err,
        &["tf.db3", JOINT_STATE, "/tf (tf2_msgs/msg/TFMessage)"],
    );
    // `apply` does not rewrite bags.
    write(
        dir.path(),
        "map.csv",
        "angle_deg,error_arcsec,correction_arcsec\n0,0,0\n",
    );
    let err = expect_exit(
        &calib(&[
            "apply",
            s(&dir.path().join("map.csv")),
            s(&cut),
            "-o",
            s(&dir.path().join("fixed.mcap")),
        ]),
        2,
    );
    assert_mentions(&err, &["cut.db3", "rosbag2 bag", "ros2 bag convert"]);
}

/// The committed fixture `testdata/rosbag/small_bag` (see [`make_fixture`]).
fn fixture() -> PathBuf {
    testdata("rosbag/small_bag")
}

#[test]
fn the_committed_bag_fixture_is_read() {
    let out = inspect(&fixture(), &[]);
    assert!(out.contains("\ntopics: 2 read, 1 not read\n"), "{out}");
    assert_mentions(
        &out,
        &[
            "/left/joint_states/shoulder, /left/joint_states/elbow",
            "/right/joint_states/shoulder, /right/joint_states/elbow",
            "/rosout",
            "aligned on the clock of `/left/joint_states/shoulder`: 199 of its 200 samples kept",
        ],
    );
}

/// Writes the committed fixture; run after changing it:
/// `cargo test -p calib-cli --test it rosbag_cli::make_fixture -- --ignored`.
///
/// `testdata/rosbag/small_bag`: a Humble bag directory of two splits, 2 s at 100 Hz of two arms
/// publishing the same joint names (`shoulder`, `elbow`) on `/left/joint_states` and
/// `/right/joint_states` (the right arm 4 ms after the left), and a `/rosout` topic calib does
/// not read: 600 messages. `testdata/rosbag/small_bag_zstd`: the same bag with both splits
/// compressed whole (zstd, `compression_mode: FILE`).
#[test]
#[ignore = "writes the committed fixture"]
fn make_fixture() {
    let bag = fixture();
    if bag.exists() {
        std::fs::remove_dir_all(&bag).unwrap();
    }
    std::fs::create_dir_all(&bag).unwrap();
    let topics = [
        ("/left/joint_states", JOINT_STATE),
        ("/right/joint_states", JOINT_STATE),
        ("/rosout", "rcl_interfaces/msg/Log"),
    ];
    for k in 0..2i64 {
        let db = create_db3(&bag.join(format!("small_bag_{k}.db3")), &topics);
        db.execute_batch("BEGIN").unwrap();
        for i in k * 100..(k + 1) * 100 {
            let t = 1_700_000_000_000_000_000 + i * 10_000_000;
            let q = i as f64 * 0.02;
            let names = ["shoulder", "elbow"];
            insert(&db, 1, t + 50_000, &joint_state(t, &names, &[q, 2.0 * q]));
            let t2 = t + 4_000_000;
            insert(&db, 2, t2 + 50_000, &joint_state(t2, &names, &[-q, q]));
            insert(&db, 3, t + 70_000, &[0, 1, 0, 0]);
        }
        db.execute_batch("COMMIT").unwrap();
    }
    std::fs::write(
        bag.join("metadata.yaml"),
        metadata("sqlite3", &["small_bag_0.db3", "small_bag_1.db3"]),
    )
    .unwrap();
    let zstd_bag = testdata("rosbag/small_bag_zstd");
    if zstd_bag.exists() {
        std::fs::remove_dir_all(&zstd_bag).unwrap();
    }
    compress_files(
        &bag,
        &zstd_bag,
        "sqlite3",
        &["small_bag_0.db3", "small_bag_1.db3"],
    );
}

/// A `std_msgs/msg/Float64` message in little-endian CDR.
fn float64(v: f64) -> Vec<u8> {
    Cdr::message().f64(v).bytes()
}

/// `quick.toml`'s run with A and B published as `std_msgs/msg/Float64` (radians) on
/// `/enc_a/angle` and `/enc_b/angle`, once in an MCAP file (`ros2msg` schemas, `cdr`) and once in
/// a `.db3` file; returns both and the MCAP of the same run that `calib simulate` writes.
fn write_scalar_run(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let reference = simulate(&testdata("scenarios/quick.toml"), dir, "run.mcap");
    let samples = scenario_samples("quick.toml");
    let topics = ["/enc_a/angle", "/enc_b/angle"];
    let mcap_path = dir.join("scalars.mcap");
    let mut writer = RawMcap::create(
        &mcap_path,
        "std_msgs/msg/Float64",
        "ros2msg",
        b"float64 data",
    );
    let ids: Vec<u16> = topics.iter().map(|t| writer.channel(t, "cdr")).collect();
    let db3 = dir.join("scalars.db3");
    let db = create_db3(
        &db3,
        &[
            (topics[0], "std_msgs/msg/Float64"),
            (topics[1], "std_msgs/msg/Float64"),
        ],
    );
    db.execute_batch("BEGIN").unwrap();
    for (n, s) in samples.iter().enumerate() {
        let t = ns(s.t);
        for (k, &id) in ids.iter().enumerate() {
            let data = float64(s.values[k]);
            writer.write(id, n as u32, t, &data);
            insert(&db, k as i64 + 1, t as i64, &data);
        }
    }
    db.execute_batch("COMMIT").unwrap();
    writer.finish();
    (mcap_path, db3, reference)
}

/// Scalar topics are channels named after the topic, in the unit `--unit` gives. The stamps
/// (the log time, to the nanosecond) and values are those of `calib simulate`'s MCAP, so the maps
/// agree to floating-point rounding (< 1e-6″).
#[test]
fn scalar_topics_in_mcap_and_bags_give_the_maps_of_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, db3, reference) = write_scalar_run(dir.path());
    let want = dir.path().join("want");
    expect_exit(&calib(&["csrr", s(&reference), "-o", s(&want)]), 0);
    for log in [&mcap, &db3] {
        let out = inspect(log, &[]);
        assert!(out.contains("\ntopics: 2 read, 0 not read\n"), "{out}");
        assert_mentions(&out, &["std_msgs/msg/Float64", "      /enc_a/angle\n"]);
        let out = dir.path().join(log.extension().unwrap());
        let o = calib(&[
            "csrr",
            s(log),
            "--a",
            "/enc_a/angle",
            "--b",
            "/enc_b/angle",
            "--unit",
            "rad",
            "-o",
            s(&out),
        ]);
        expect_exit(&o, 0);
        for (got, table) in [("enc_a_angle.csv", "a.csv"), ("enc_b_angle.csv", "b.csv")] {
            let worst = table_difference(&want.join(table), &out.join(got));
            assert!(
                worst < 1e-6,
                "{}: {table} differs by {worst}″",
                log.display()
            );
        }
    }
}

/// Raw counts: a `std_msgs/msg/UInt16` topic of a 4096-count encoder read with
/// `--unit counts:4096` (one count = 360/4096°).
#[test]
fn scalar_counts_are_read_with_a_counts_unit() {
    let dir = tempfile::tempdir().unwrap();
    let db3 = dir.path().join("counts.db3");
    let db = create_db3(&db3, &[("/encoder/count", "std_msgs/msg/UInt16")]);
    for i in 0..100i64 {
        let count = (i * 41 % 4096) as u16;
        let data = Cdr::message().primitive(count.to_le_bytes()).bytes();
        insert(&db, 1, 1_000_000_000 + i * 10_000_000, &data);
    }
    drop(db);
    let v = inspect_json(&db3, &["--unit", "counts:4096"]);
    assert_eq!(v["topics"][0]["channels"][0], "/encoder/count");
    let text = stdout(&calib(&["inspect", s(&db3), "--unit", "counts:4096"]));
    assert!(text.contains("  100 samples over "), "{text}");
    // The counts run 0, 41, … 4059 (99 × 41): 4059/4096 of a revolution.
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("/encoder/count ") && l.contains("counts:"))
        .unwrap_or_else(|| panic!("{text}"));
    assert_mentions(line, &["counts:4096", " 0.000000", "4059.000000", "0.991"]);
}

/// Reading speed: 10⁶ JointState messages (two joints, one topic, 100 Hz) in one `.db3` file,
/// timed through `calib inspect` (which reads every message). Prints the figure (measured
/// 2.7 s, 374k msg/s, on 2 shared cores under load); the bound is a tenth of that, so that only
/// a collapse fails it.
#[test]
#[ignore = "writes a 10⁶-message bag; run for the figure"]
fn reading_speed_of_a_large_bag() {
    const N: i64 = 1_000_000;
    let dir = tempfile::tempdir().unwrap();
    let db3 = dir.path().join("big.db3");
    let db = create_db3(&db3, &[("/joint_states", JOINT_STATE)]);
    db.execute_batch("BEGIN").unwrap();
    for i in 0..N {
        let t = 1_000_000_000 + i * 10_000_000;
        let q = (i as f64 * 0.001) % 6.0;
        insert(&db, 1, t, &joint_state(t, &["a", "b"], &[q, q + 0.1]));
    }
    db.execute_batch("COMMIT").unwrap();
    drop(db);
    let start = std::time::Instant::now();
    let o = calib(&["inspect", s(&db3)]);
    let seconds = start.elapsed().as_secs_f64();
    expect_exit(&o, 0);
    assert!(stdout(&o).contains(&format!("  {N} samples over ")));
    let rate = N as f64 / seconds;
    eprintln!("calib inspect on {N} bag messages: {seconds:.2} s, {rate:.0} msg/s");
    assert!(rate > 37_000.0, "{rate:.0} msg/s");
}

const DYNAMIC_JOINT_STATE: &str = "control_msgs/msg/DynamicJointState";

/// The `ros2msg` definition of `control_msgs/msg/DynamicJointState` as rosbag2 stores it in an
/// MCAP schema record.
const DYNAMIC_JOINT_STATE_MSGDEF: &str = "std_msgs/Header header
string[] joint_names
control_msgs/InterfaceValue[] interface_values

================================================================================
MSG: control_msgs/InterfaceValue
string[] interface_names
float64[] values

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// A `control_msgs/msg/DynamicJointState` in little-endian CDR: for each joint its name and
/// its interfaces `(name, value)`; `frame_id` is `base`.
fn dynamic_joint_state(stamp_ns: u64, joints: &[(&str, &[(&str, f64)])]) -> Vec<u8> {
    let mut m = Cdr::message();
    m.stamp(stamp_ns).string("base").u32(joints.len() as u32);
    for (name, _) in joints {
        m.string(name);
    }
    m.u32(joints.len() as u32);
    for (_, interfaces) in joints {
        m.u32(interfaces.len() as u32);
        for (name, _) in *interfaces {
            m.string(name);
        }
        m.u32(interfaces.len() as u32);
        for &(_, v) in *interfaces {
            m.f64(v);
        }
    }
    m.bytes()
}

/// The joints of one DynamicJointState as `ros2_control`'s broadcaster publishes them: `a` with
/// position and velocity, `b` with effort first and then position, and `gripper` with an
/// effort only (not a channel: it has no position).
fn dynamic_message(t: u64, a: f64, b: f64) -> Vec<u8> {
    dynamic_joint_state(
        t,
        &[
            ("a", &[("position", a), ("velocity", 1.0)]),
            ("b", &[("effort", 0.5), ("position", b)]),
            ("gripper", &[("effort", 2.0)]),
        ],
    )
}

/// `quick.toml`'s run as DynamicJointState messages on `/dynamic_joint_states` (see
/// [`dynamic_message`]), once in an MCAP file (`ros2msg` schema, `cdr`) and once in a `.db3`
/// file, header stamp and log time the sample's time; returns both.
fn write_dynamic_run(dir: &Path) -> (PathBuf, PathBuf) {
    let samples = scenario_samples("quick.toml");
    let mcap_path = dir.join("dynamic.mcap");
    let (mut writer, id) = dynamic_mcap(&mcap_path);
    let db3 = dir.join("dynamic.db3");
    let db = create_db3(&db3, &[("/dynamic_joint_states", DYNAMIC_JOINT_STATE)]);
    db.execute_batch("BEGIN").unwrap();
    for (n, s) in samples.iter().enumerate() {
        let t = ns(s.t);
        let data = dynamic_message(t, s.values[0], s.values[1]);
        writer.write(id, n as u32, t, &data);
        insert(&db, 1, t as i64, &data);
    }
    db.execute_batch("COMMIT").unwrap();
    writer.finish();
    (mcap_path, db3)
}

/// An MCAP file at `path` with the DynamicJointState schema (`ros2msg`) and the channel
/// `/dynamic_joint_states` (`cdr`), as rosbag2 writes it; the writer and the channel's id.
fn dynamic_mcap(path: &Path) -> (RawMcap, u16) {
    let mut writer = RawMcap::create(
        path,
        DYNAMIC_JOINT_STATE,
        "ros2msg",
        DYNAMIC_JOINT_STATE_MSGDEF.as_bytes(),
    );
    let id = writer.channel("/dynamic_joint_states", "cdr");
    (writer, id)
}

/// DynamicJointState in MCAP and in a bag: the `position` interface of each joint, wherever it
/// is among the joint's interfaces; a joint without one is no channel. The stamps and values
/// are those of `calib simulate`'s MCAP, so the maps agree to rounding (< 1e-6″; measured 0).
#[test]
fn dynamic_joint_states_in_mcap_and_bags_give_the_maps_of_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, db3) = write_dynamic_run(dir.path());
    let reference = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let want = dir.path().join("want");
    expect_exit(&calib(&["csrr", s(&reference), "-o", s(&want)]), 0);
    for log in [&mcap, &db3] {
        let out = inspect(log, &[]);
        assert_mentions(&out, &[DYNAMIC_JOINT_STATE, "3301 msg", "      a, b\n"]);
        assert!(!out.contains("gripper"), "{out}");
        let out = dir.path().join(log.extension().unwrap());
        let o = calib(&["csrr", s(log), "--a", "a", "--b", "b", "-o", s(&out)]);
        expect_exit(&o, 0);
        for table in ["a.csv", "b.csv"] {
            let worst = table_difference(&want.join(table), &out.join(table));
            eprintln!("{}: {table} max |difference| {worst:e}″", log.display());
            assert!(
                worst < 1e-6,
                "{}: {table} differs by {worst}″",
                log.display()
            );
        }
    }
}

/// The committed fixture `testdata/mcap/dynamic.mcap` (see [`make_dynamic_fixture`]).
fn dynamic_fixture() -> PathBuf {
    testdata("mcap/dynamic.mcap")
}

#[test]
fn the_committed_dynamic_joint_state_fixture_is_read() {
    let out = inspect(&dynamic_fixture(), &[]);
    assert_mentions(
        &out,
        &[
            "/dynamic_joint_states",
            DYNAMIC_JOINT_STATE,
            "200 msg",
            "100.00 Hz",
            "      a, b\n",
            "  200 samples over ",
        ],
    );
    // The readings: a = i·0.01 rad, b = −a, as written.
    let a = out
        .lines()
        .find(|l| l.trim_start().starts_with("a ") && l.contains("rad"))
        .unwrap_or_else(|| panic!("{out}"));
    assert_mentions(a, &[" 0.000000", "1.990000"]);
}

/// Writes `testdata/mcap/dynamic.mcap`: 2 s at 100 Hz of `/dynamic_joint_states` with joints
/// `a` (position `i·0.01` rad), `b` (position `−i·0.01` rad) and `gripper` (effort only), as
/// [`dynamic_message`] lays them out. Run after changing it:
/// `cargo test -p calib-cli --test it rosbag_cli::make_dynamic_fixture -- --ignored`.
#[test]
#[ignore = "writes the committed fixture"]
fn make_dynamic_fixture() {
    let (mut writer, id) = dynamic_mcap(&dynamic_fixture());
    for i in 0..200u64 {
        let t = 1_700_000_000_000_000_000 + i * 10_000_000;
        let q = i as f64 * 0.01;
        writer.write(id, i as u32, t, &dynamic_message(t, q, -q));
    }
    writer.finish();
}

/// The largest |difference| between the `a.csv` and `b.csv` maps of two output folders, arcsec.
fn worst_difference(want: &Path, got: &Path) -> f64 {
    ["a.csv", "b.csv"]
        .iter()
        .map(|table| table_difference(&want.join(table), &got.join(table)))
        .fold(0.0, f64::max)
}

/// Copies the bag directory `from` to `to` with every split compressed whole (zstd), as
/// `ros2 bag record --compression-mode file --compression-format zstd` leaves it.
fn compress_files(from: &Path, to: &Path, storage: &str, splits: &[&str]) {
    std::fs::create_dir(to).unwrap();
    let mut names = Vec::new();
    for split in splits {
        let name = format!("{split}.zstd");
        let input = std::fs::File::open(from.join(split)).unwrap();
        let output = std::fs::File::create(to.join(&name)).unwrap();
        zstd::stream::copy_encode(input, output, 3).unwrap();
        names.push(name);
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    std::fs::write(
        to.join("metadata.yaml"),
        compressed_metadata(storage, &names, "zstd", "FILE"),
    )
    .unwrap();
}

/// Writes `quick.toml`'s run as a bag directory `dir/NAME` of two `.mcap` splits (the second
/// from the middle of the run on), as `calib simulate` writes MCAP: joints `a` and `b` on
/// `/joint_states`.
fn write_mcap_split_run(dir: &Path, name: &str) -> PathBuf {
    let sc = load_scenario("quick.toml");
    let samples: Vec<Sample> = sc.samples().unwrap().collect();
    let channels: Vec<Channel> = sc.channels()[..2]
        .iter()
        .map(|c| Channel {
            name: c.name.clone(),
            unit: AngleUnit::Rad,
        })
        .collect();
    let bag = dir.join(name);
    std::fs::create_dir(&bag).unwrap();
    let half = samples.len() / 2;
    let mut splits = Vec::new();
    for (k, part) in [&samples[..half], &samples[half..]].into_iter().enumerate() {
        let split = format!("{name}_{k}.mcap");
        let mut writer = McapWriter::create(&bag.join(&split), &channels, "/joint_states").unwrap();
        for s in part {
            let sample = Sample {
                t: s.t,
                values: s.values[..2].to_vec(),
                session: None,
            };
            writer.write(&sample).unwrap();
        }
        writer.finish().unwrap();
        splits.push(split);
    }
    let splits: Vec<&str> = splits.iter().map(String::as_str).collect();
    std::fs::write(bag.join("metadata.yaml"), metadata("mcap", &splits)).unwrap();
    bag
}

/// Compressed bags and bags of several MCAP splits give the maps of the MCAP file of the same
/// run: zstd file mode (`.db3.zstd`, `.mcap.zstd`), zstd message mode (`.db3`), and two `.mcap`
/// splits. The stamps and values are the same, so the maps agree to rounding (< 1e-6″;
/// measured 0).
#[test]
fn compressed_bags_and_mcap_splits_give_the_maps_of_the_same_run() {
    let dir = tempfile::tempdir().unwrap();
    let (bag, mcap) = write_run(dir.path());
    let want = dir.path().join("want");
    expect_exit(&calib(&["csrr", s(&mcap), "-o", s(&want)]), 0);
    let splits = ["run_bag_0.db3", "run_bag_1.db3"];
    // File mode, SQLite storage.
    let db3_zstd = dir.path().join("db3_zstd");
    compress_files(&bag, &db3_zstd, "sqlite3", &splits);
    // Message mode, SQLite storage: each payload compressed.
    let db3_msg = dir.path().join("db3_msg");
    std::fs::create_dir(&db3_msg).unwrap();
    for split in splits {
        std::fs::copy(bag.join(split), db3_msg.join(split)).unwrap();
        let db = Connection::open(db3_msg.join(split)).unwrap();
        let rows: Vec<(i64, Vec<u8>)> = db
            .prepare("SELECT id, data FROM messages")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get(1)?)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        db.execute_batch("BEGIN").unwrap();
        for (id, data) in rows {
            let packed = zstd::bulk::compress(&data, 3).unwrap();
            db.execute(
                "UPDATE messages SET data = ?1 WHERE id = ?2",
                params![packed, id],
            )
            .unwrap();
        }
        db.execute_batch("COMMIT").unwrap();
    }
    std::fs::write(
        db3_msg.join("metadata.yaml"),
        compressed_metadata("sqlite3", &splits, "zstd", "MESSAGE"),
    )
    .unwrap();
    // Two MCAP splits, and the same compressed whole.
    let mcap_bag = write_mcap_split_run(dir.path(), "mcap_bag");
    let mcap_zstd = dir.path().join("mcap_zstd");
    compress_files(
        &mcap_bag,
        &mcap_zstd,
        "mcap",
        &["mcap_bag_0.mcap", "mcap_bag_1.mcap"],
    );
    for log in [&db3_zstd, &db3_msg, &mcap_bag, &mcap_zstd] {
        let out = dir.path().join(format!(
            "out_{}",
            log.file_name().unwrap().to_string_lossy()
        ));
        let o = calib(&["csrr", s(log), "--a", "a", "--b", "b", "-o", s(&out)]);
        expect_exit(&o, 0);
        let worst = worst_difference(&want, &out);
        eprintln!("{}: max |map − MCAP map| {worst:e}″", log.display());
        assert!(worst < 1e-6, "{}: {worst}″", log.display());
    }
    // A payload that is not zstd in a message-mode bag names the file, table and message.
    let db = Connection::open(db3_msg.join(splits[1])).unwrap();
    db.execute("UPDATE messages SET data = x'00010000' WHERE id = 7", [])
        .unwrap();
    drop(db);
    let err = expect_exit(&calib(&["inspect", s(&db3_msg)]), 1);
    assert_mentions(
        &err,
        &[
            "run_bag_1.db3",
            "table `messages`",
            "message id 7",
            "cannot be decompressed",
        ],
    );
}

/// The committed compressed bag: `small_bag`'s two splits compressed whole (see
/// [`make_fixture`]) read as the uncompressed bag is.
#[test]
fn the_committed_compressed_bag_fixture_is_read_as_the_uncompressed_one() {
    let zstd_bag = testdata("rosbag/small_bag_zstd");
    let (plain, packed) = (
        calib(&["inspect", s(&fixture())]),
        calib(&["inspect", s(&zstd_bag)]),
    );
    expect_exit(&plain, 0);
    expect_exit(&packed, 0);
    let strip = |o: &std::process::Output, name: &str| stdout(o).replace(name, "BAG");
    assert_eq!(strip(&plain, "small_bag"), strip(&packed, "small_bag_zstd"));
}

/// The temporary files and folders of calib's naming in `dir` (`.<name>.calib-<pid>.….tmp`).
fn calib_temps(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".calib-") && n.ends_with(".tmp"))
        .collect()
}

/// SIGTERM or SIGINT while a compressed bag is read: before, its decompressed copy (up to
/// 1.3 GB) stayed in the temporary folder although calib said it removed its temporary files;
/// now the copy goes, no output appears, and calib exits at once with 143 or 130 (128 + the
/// signal, as a shell reports a process killed by it).
#[test]
fn a_signal_while_a_compressed_bag_is_read_leaves_no_temporary_copy() {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    // 300,000 messages: a few hundred milliseconds of reading in a debug build, time enough to
    // signal the run while it reads.
    const N: i64 = 300_000;
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain");
    std::fs::create_dir(&plain).unwrap();
    let db = create_db3(
        &plain.join("run_bag_0.db3"),
        &[("/joint_states", JOINT_STATE)],
    );
    db.execute_batch("BEGIN").unwrap();
    for i in 0..N {
        let t = 1_000_000_000 + i * 1_000_000;
        let q = (i as f64 * 0.001) % 6.0;
        insert(&db, 1, t, &joint_state(t, &["a", "b"], &[q, q + 0.1]));
    }
    db.execute_batch("COMMIT").unwrap();
    drop(db);
    let bag = dir.path().join("run_bag");
    compress_files(&plain, &bag, "sqlite3", &["run_bag_0.db3"]);
    // How long a whole run lasts from the moment its temporary folder appears (however fast this
    // build reads), to signal the runs below halfway through it.
    let whole = {
        let tmp = dir.path().join("tmp-whole");
        std::fs::create_dir(&tmp).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_calib"))
            .args(["csrr", s(&bag), "-o", s(&dir.path().join("out-whole"))])
            .env("TMPDIR", &tmp)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        while calib_temps(&tmp).is_empty() && child.try_wait().unwrap().is_none() {
            std::thread::sleep(Duration::from_millis(1));
        }
        let appeared = Instant::now();
        child.wait().unwrap();
        appeared.elapsed()
    };
    let halfway = u64::try_from(whole.as_millis() / 2).unwrap();
    // Signalled as soon as the temporary folder appears (while decompressing), and halfway
    // through the run (while reading the messages).
    // A run can be faster than the measured one (a loaded machine slows the measurement): a
    // signal that would come after the run has ended is tried again sooner, at most 4 times.
    for (signal, status, halfway_or_not) in [
        ("TERM", 143, 0),
        ("INT", 130, 0),
        ("TERM", 143, halfway),
        ("INT", 130, halfway),
    ] {
        let signalled = (0..4).any(|attempt| {
            let after = halfway_or_not >> attempt;
            let signal_at = format!("{signal}-{after}-{attempt}");
            let tmp = dir.path().join(format!("tmp-{signal_at}"));
            std::fs::create_dir(&tmp).unwrap();
            let out = dir.path().join(format!("out-{signal_at}"));
            let mut child = Command::new(env!("CARGO_BIN_EXE_calib"))
                .args(["csrr", s(&bag), "-o", s(&out)])
                .env("TMPDIR", &tmp)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .unwrap();
            let started = Instant::now();
            let deadline = started + Duration::from_secs(60);
            while calib_temps(&tmp).is_empty() {
                assert!(Instant::now() < deadline, "no temporary folder appeared");
                assert!(child.try_wait().unwrap().is_none(), "finished too soon");
                std::thread::sleep(Duration::from_millis(1));
            }
            std::thread::sleep(Duration::from_millis(after));
            if child.try_wait().unwrap().is_some() {
                eprintln!("SIG{signal_at}: the run ended before the signal; sooner");
                return false;
            }
            Command::new("kill")
                .args([&format!("-{signal}"), &child.id().to_string()])
                .status()
                .unwrap();
            let sent = Instant::now();
            let exit = child.wait().unwrap();
            let took = sent.elapsed();
            eprintln!(
                "SIG{signal_at} ms: sent {:?} after the start, exit after {took:?}",
                sent - started
            );
            if exit.code() == Some(0) && after > 0 {
                // The run ended between the check and the signal.
                eprintln!("SIG{signal_at}: the run ended as the signal was sent; sooner");
                return false;
            }
            assert_eq!(exit.code(), Some(status), "SIG{signal_at}");
            assert!(took < Duration::from_secs(5), "SIG{signal_at}: {took:?}");
            assert!(
                calib_temps(&tmp).is_empty(),
                "SIG{signal}: {:?}",
                calib_temps(&tmp)
            );
            assert!(
                calib_temps(dir.path()).is_empty(),
                "{:?}",
                calib_temps(dir.path())
            );
            assert!(!out.exists());
            true
        });
        assert!(signalled, "SIG{signal} never reached a running calib");
    }
}

/// A WAL-mode `.db3` of 400 JointState rows at 1 kHz, written to `dir/wal.db3` with every row
/// still in its write-ahead log `wal.db3-wal` (copied while the writer held it open, as a
/// recorder that crashed leaves it).
fn wal_bag_with_rows_in_its_log(dir: &Path) -> PathBuf {
    let scratch = tempfile::tempdir().unwrap();
    let db3 = scratch.path().join("wal.db3");
    let db = create_db3(&db3, &[("/joint_states", JOINT_STATE)]);
    db.pragma_update(None, "journal_mode", "WAL").unwrap();
    db.pragma_update(None, "wal_autocheckpoint", 0).unwrap();
    db.execute_batch("BEGIN").unwrap();
    for i in 0..400 {
        let t = 1_000_000_000 + i * 1_000_000;
        let q = i as f64 * 1e-3;
        insert(&db, 1, t, &joint_state(t, &["a", "b"], &[q, -q]));
    }
    db.execute_batch("COMMIT").unwrap();
    let path = dir.join("wal.db3");
    for (from, to) in [("wal.db3", "wal.db3"), ("wal.db3-wal", "wal.db3-wal")] {
        std::fs::copy(scratch.path().join(from), dir.join(to)).unwrap();
    }
    drop(db);
    path
}

/// A WAL-mode bag in a folder calib cannot write: before, "not a rosbag2 bag"; now its rows
/// are read from a temporary copy of the file and its log, all 400. The folder is made
/// read-only by a read-only bind mount in a mount namespace of its own (`unshare -m`: the
/// tests run as root, whom permissions do not stop); where that cannot be made, by permissions
/// (not root), else the case is reported skipped.
#[test]
fn a_wal_bag_in_a_read_only_folder_is_read_from_a_temporary_copy() {
    use std::process::Command;
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("recording");
    std::fs::create_dir(&src).unwrap();
    wal_bag_with_rows_in_its_log(&src);
    let before = std::fs::read_dir(&src).unwrap().count();
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    let calib = env!("CARGO_BIN_EXE_calib");
    let script = format!(
        "mount --bind '{src}' '{ro}' && mount -o remount,bind,ro '{ro}' || exit 90; \
         touch '{ro}/probe' 2>/dev/null && exit 91; exec '{calib}' inspect '{ro}/wal.db3'",
        src = src.display(),
        ro = ro.display()
    );
    let o = Command::new("unshare")
        .args(["-m", "sh", "-c", &script])
        .output();
    let o = match o {
        Ok(o) if !matches!(o.status.code(), Some(90 | 91) | None) => o,
        _ => {
            use std::os::unix::fs::PermissionsExt;
            eprintln!("no read-only bind mount here: the folder is made read-only by permissions");
            std::fs::set_permissions(&src, std::fs::Permissions::from_mode(0o555)).unwrap();
            if std::fs::write(src.join("probe"), "").is_ok() {
                eprintln!(
                    "skipped: no read-only bind mount here, and permissions do not stop root"
                );
                return;
            }
            let o = Command::new(calib)
                .args(["inspect", s(&src.join("wal.db3"))])
                .output()
                .unwrap();
            std::fs::set_permissions(&src, std::fs::Permissions::from_mode(0o755)).unwrap();
            o
        }
    };
    expect_exit(&o, 0);
    assert!(stdout(&o).contains("  400 samples over "), "{}", stdout(&o));
    assert_eq!(std::fs::read_dir(&src).unwrap().count(), before);
}

/// The same bag where no temporary folder can be made (TMPDIR names a file): the error names
/// the split, its log, why a copy is needed and what to do — not the random name of a folder
/// that was never made — and nothing is written beside the recording.
#[test]
fn a_wal_bag_without_a_temporary_folder_says_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let db3 = wal_bag_with_rows_in_its_log(dir.path());
    let not_a_folder = write(dir.path(), "tmp-file", "");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(["inspect", s(&db3)])
        .env("TMPDIR", &not_a_folder)
        .output()
        .unwrap();
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            &format!("{}: cannot create a temporary folder in ", db3.display()),
            "tmp-file (",
            "wal.db3-wal: transactions not yet in the file",
            "set TMPDIR to a folder you can write",
            "or copy the bag to such a folder",
        ],
    );
    assert!(!err.contains(".bag.calib-"), "{err}");
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["tmp-file", "wal.db3", "wal.db3-wal"]);
}

/// `spindown.toml`'s coast as `/joint_states` JointStates (`enc`, `ref`) in an MCAP file, each
/// message stamped (header and log time) `origin_ns` plus its sample's time.
fn write_coast(path: &Path, origin_ns: u64) {
    let mut writer = RawMcap::create(
        path,
        JOINT_STATE,
        "ros2msg",
        calib_io::mcap_log::JOINT_STATE_MSGDEF.as_bytes(),
    );
    let id = writer.channel("/joint_states", "cdr");
    for (n, s) in scenario_samples("spindown.toml").iter().enumerate() {
        let t = origin_ns + ns(s.t);
        let data = joint_state(t as i64, &["enc", "ref"], &s.values);
        writer.write(id, n as u32, t, &data);
    }
    writer.finish();
}

/// A robot's log is stamped in nanoseconds since 1970, which a double of seconds (2.4·10⁻⁷ s
/// apart there) cannot hold: at 600 r/min such a step is 0.9″ of rotation, and a coast read that
/// way left 0.8″ of residual and a map 0.018″ off (0.06″ and 0.0014″ timed from 0). The reader
/// counts stamps from the first one's second, so the same run stamped since 1970 gives the same
/// bytes of map as stamped from 0, and report.json and `inspect` give the coast on the log's
/// clock.
#[test]
fn stamps_since_1970_give_the_map_of_stamps_from_0() {
    let dir = tempfile::tempdir().unwrap();
    let origin_ns = 1_700_000_000_000_000_000;
    let (from_0, since_1970) = (dir.path().join("zero.mcap"), dir.path().join("1970.mcap"));
    write_coast(&from_0, 0);
    write_coast(&since_1970, origin_ns);
    let (out_0, out_1970) = (dir.path().join("zero"), dir.path().join("1970"));
    for (log, out) in [(&from_0, &out_0), (&since_1970, &out_1970)] {
        expect_exit(
            &calib(&["tdr", s(log), "--channel", "enc", "-o", s(out)]),
            0,
        );
    }
    let table = |out: &Path| std::fs::read(out.join("enc.csv")).unwrap();
    assert!(table(&out_0) == table(&out_1970), "the maps differ");
    let coast = |out: &Path| {
        let report = read_json(&out.join("report.json"));
        let m = &report["details"]["motion"];
        (m["start_s"].as_f64().unwrap(), m["end_s"].as_f64().unwrap())
    };
    let (zero, since) = (coast(&out_0), coast(&out_1970));
    // On the log's clock: the stamps since 1970, to a double's step there.
    assert!(
        (since.0 - 1.7e9 - zero.0).abs() < 5e-7,
        "{since:?} {zero:?}"
    );
    assert!(
        (since.1 - 1.7e9 - zero.1).abs() < 5e-7,
        "{since:?} {zero:?}"
    );
    let inspection = inspect_json(&since_1970, &[]);
    let start = inspection["inspection"]["start_s"].as_f64().unwrap();
    assert!((start - 1.7e9).abs() < 1e-6, "{start}");
}

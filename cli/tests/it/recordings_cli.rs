//! End-to-end tests of recordings as robots and labs write them: channels named by topic,
//! sensors publishing on their own topics and clocks.

use crate::common::{self, inspect, ros};

use calib_core::simulate::Scenario;
use calib_core::{AngleUnit, Channel, ErrorMap, Sample};
use calib_io::mcap_log::McapWriter;
use common::*;
use inspect::{inspect, inspect_json};
use ros::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The simulator runs this many times faster than the sensors publish, so that each sensor can
/// be sampled at its own instants: offsets and jitter are whole 24ths of the sample period.
const OVERSAMPLE: u64 = 24;

/// The three topics of the run, each carrying one joint named `encoder`.
const TOPICS: [&str; 3] = [
    "/sensor_a/joint_states",
    "/sensor_b/joint_states",
    "/reference/joint_states",
];

fn scenario() -> Scenario {
    load_scenario("csrr72.toml")
}

/// An MCAP file at `path` with the three [`TOPICS`], each carrying one joint `encoder` (rad).
fn three_topics(path: &Path) -> McapWriter {
    let channel = [Channel {
        name: "encoder".into(),
        unit: AngleUnit::Rad,
    }];
    let mut writer = McapWriter::create(path, &channel, TOPICS[0]).unwrap();
    writer.add_topic(TOPICS[1], &channel).unwrap();
    writer.add_topic(TOPICS[2], &channel).unwrap();
    writer
}

/// Writes `testdata/scenarios/csrr72.toml`'s run (400 Hz) with A, B and the reference each on its
/// own topic: sample `k` of A at `k` periods, of B at `k + b_offset/24` and of the reference at
/// `k + ref_offset/24` periods, each of these two moved by a uniform draw from `−jitter..=jitter`
/// 24ths (a fixed pseudo-random sequence).
fn write_run(path: &Path, b_offset: u64, ref_offset: u64, jitter: u64) -> Scenario {
    let mut sc = scenario();
    let rate = sc.rate_hz;
    sc.rate_hz = rate * OVERSAMPLE as f64;
    let mut writer = three_topics(path);
    // A 64-bit LCG (Knuth's MMIX constants): deterministic jitter draws.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut draw = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 33) % (2 * jitter + 1)) as i64 - jitter as i64
    };
    let (mut at_b, mut at_ref) = (0, 0);
    let names = sc.channels();
    let index = |n: &str| names.iter().position(|c| c.name == n).unwrap();
    let (ia, ib, ir) = (index("a"), index("b"), index("ref"));
    for (n, s) in sc.samples().unwrap().enumerate() {
        let m = n as u64 % OVERSAMPLE;
        if m == 0 {
            at_b = (b_offset as i64 + draw()) as u64;
            at_ref = (ref_offset as i64 + draw()) as u64;
        }
        let one = |v: f64| Sample {
            t: s.t,
            values: vec![v],
            session: None,
        };
        if m == 0 {
            writer.write_to(0, &one(s.values[ia])).unwrap();
        }
        // B and the reference stay within the sample period that starts at A's sample k.
        if m == at_b {
            writer.write_to(1, &one(s.values[ib])).unwrap();
        }
        if m == at_ref {
            writer.write_to(2, &one(s.values[ir])).unwrap();
        }
    }
    writer.finish().unwrap();
    sc.rate_hz = rate;
    sc
}

fn truth(sc: &Scenario, name: &str) -> ErrorMap {
    sc.truth(36000)
        .unwrap()
        .into_iter()
        .find(|(n, _)| n == name)
        .unwrap()
        .1
}

/// `calib csrr` on the run with qualified channel names; the largest |map − truth| of A and B,
/// arcsec, and report.json.
fn csrr_error(log: &Path, sc: &Scenario, out: &Path) -> (f64, f64, Value) {
    let q = |t: &str| format!("{t}/encoder");
    let o = calib(&[
        "csrr",
        s(log),
        "--a",
        &q(TOPICS[0]),
        "--b",
        &q(TOPICS[1]),
        "--ref",
        &q(TOPICS[2]),
        "-o",
        s(out),
    ]);
    expect_exit(&o, 0);
    eprintln!("{}", stdout(&o));
    let read = |file: &str| {
        calib_io::table::read_turn_table(&out.join(file))
            .unwrap_or_else(|e| panic!("{e}"))
            .map
    };
    let ea = truth(sc, "a")
        .minus(&read("sensor_a_joint_states_encoder.csv"))
        .max_abs_arcsec();
    let eb = truth(sc, "b")
        .minus(&read("sensor_b_joint_states_encoder.csv"))
        .max_abs_arcsec();
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    (ea, eb, serde_json::from_str(&report).unwrap())
}

/// The bar: A, B and the reference on three topics, B 3/8 and the reference 5/8 of a
/// sample period after A, each ±1/8 jitter. Quintic interpolation of B errs by at most ~0.01″
/// at its orders 72, 216 and 432 (see `calib_io::align`), so the maps come out as accurate as
/// from the synchronized run: measured A 0.0764″, B 0.0736″ aligned, against A 0.0920″,
/// B 0.0760″ synchronized (`csrr_from_three_synchronized_topics`); the bar is 0.2″. With cubic
/// interpolation B was 0.130″; linear would err by up to 0.5″ at order 216.
#[test]
fn csrr_from_three_clocks_matches_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("clocks.mcap");
    let sc = write_run(&log, 9, 15, 3);
    let (ea, eb, report) = csrr_error(&log, &sc, &dir.path().join("out"));
    eprintln!("aligned: max |map − truth| A {ea:.4}″, B {eb:.4}″");
    assert!(ea < 0.2 && eb < 0.2, "A {ea:.4}″, B {eb:.4}″ (bar 0.2″)");
    // Nothing lost but A's first and last stamps: B and the reference have no sample before
    // the first (they publish later in each period) nor after the last (the run ends).
    let alignment = &report["details"]["alignment"];
    assert_eq!(alignment["clock"], "/sensor_a/joint_states/encoder");
    let clock = alignment["clock_samples"].as_u64().unwrap();
    assert_eq!(alignment["samples"].as_u64().unwrap(), clock - 2);
    for (c, offset) in alignment["channels"]
        .as_array()
        .unwrap()
        .iter()
        .zip([9.0, -9.0])
    {
        assert_eq!(c["dropped"], 2, "{c}");
        assert_eq!(c["interpolated"].as_u64().unwrap(), clock - 2, "{c}");
        // B's nearest sample is 9/24 period after A's stamp, the reference's 9/24 before.
        let want = offset / 24.0 / 400.0;
        let got = c["median_offset_s"].as_f64().unwrap();
        assert!((got - want).abs() < 1e-7, "{c}: want {want}");
    }
}

/// The same run synchronized (all three at A's stamps, on three topics): the exact path.
#[test]
#[ignore = "a second 5 s run, for the figure the aligned run is compared with"]
fn csrr_from_three_synchronized_topics() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("sync.mcap");
    let sc = write_run(&log, 0, 0, 0);
    let (ea, eb, report) = csrr_error(&log, &sc, &dir.path().join("out"));
    eprintln!("synchronized: max |map − truth| A {ea:.4}″, B {eb:.4}″");
    assert!(ea < 0.2 && eb < 0.2, "A {ea:.4}″, B {eb:.4}″");
    assert!(report["details"].get("alignment").is_none(), "{report}");
}

/// The committed three-clock fixture (see [`make_fixtures`]).
fn clocks() -> std::path::PathBuf {
    testdata("mcap/clocks.mcap")
}

/// The committed lab-export CSV fixture (see [`make_fixtures`]).
fn lab_export() -> std::path::PathBuf {
    testdata("csv/lab-export.csv")
}

#[test]
fn ambiguous_short_names_are_usage_errors_listing_the_topics() {
    let o = calib(&["csrr", s(&clocks()), "--a", "encoder", "--b", "x"]);
    let err = expect_exit(&o, 2);
    assert_mentions(
        &err,
        &[
            "clocks.mcap",
            "channel `encoder` is ambiguous",
            "/sensor_a/joint_states/encoder, /sensor_b/joint_states/encoder, /reference/joint_states/encoder",
            "TOPIC/encoder",
        ],
    );
}

#[test]
fn inspect_lists_topics_with_type_rate_and_qualified_channels() {
    let out = inspect(&clocks(), &[]);
    assert!(out.contains("\ntopics: 3 read, 0 not read\n"), "{out}");
    for t in TOPICS {
        let line = out
            .lines()
            .find(|l| l.trim_start().starts_with(t))
            .unwrap_or_else(|| panic!("{t} missing:\n{out}"));
        assert_mentions(
            line,
            &["sensor_msgs/msg/JointState", "cdr", "400 msg", "400.00 Hz"],
        );
        assert!(out.contains(&format!("      {t}/encoder\n")), "{out}");
    }
    // B and the reference are 0.9 and 1.6 ms after A: each interpolated at A's stamps but A's
    // first (before their first sample).
    assert!(out.contains("  399 samples over "), "{out}");
    assert_mentions(
        &out,
        &[
            "aligned on the clock of `/sensor_a/joint_states/encoder`: 399 of its 400 samples kept",
            "/sensor_b/joint_states/encoder: median offset +0.900 ms, 399 interpolated, 0 exact, 1 dropped",
            "/reference/joint_states/encoder: median offset -0.900 ms, 399 interpolated, 0 exact, 1 dropped",
        ],
    );
    let v = inspect_json(&clocks(), &[]);
    assert_eq!(v["topics"].as_array().unwrap().len(), 3);
    assert_eq!(
        v["topics"][1]["channels"][0],
        "/sensor_b/joint_states/encoder"
    );
    assert_eq!(v["alignment"]["samples"], 399);
}

#[test]
fn the_log_time_and_a_max_gap_are_options() {
    // With --time log the stamps are the same here (the writer sets both); a max gap shorter
    // than the interval drops every clock sample: refused as a log without samples.
    let o = calib(&["inspect", s(&clocks()), "--time", "log"]);
    expect_exit(&o, 0);
    let o = calib(&["inspect", s(&clocks()), "--max-gap", "0.001"]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["clocks.mcap", "no samples"]);
    let o = calib(&["inspect", s(&clocks()), "--max-gap", "-1"]);
    expect_exit(&o, 2);
}

#[test]
fn lab_csv_with_semicolons_metadata_and_a_time_unit_is_read() {
    let out = inspect(&lab_export(), &[]);
    // 400 rows 2.5 ms apart, the time in milliseconds.
    assert!(out.contains("  400 samples over "), "{out}");
    assert!(out.contains("400.00 Hz mean"), "{out}");
    let names: Vec<&str> = out
        .lines()
        .skip_while(|l| l.trim() != "channels")
        .skip(2)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(names, ["enc_a", "enc_b"]);
    // Naming the time column and its unit gives the same; a wrong name is an error naming the
    // header's columns, and a bad field names its line and column.
    let o = calib(&[
        "inspect",
        s(&lab_export()),
        "--time-column",
        "Time [ms]",
        "--time-unit",
        "ms",
    ]);
    expect_exit(&o, 0);
    assert!(stdout(&o).contains("400.00 Hz mean"));
    let o = calib(&["inspect", s(&lab_export()), "--time-column", "Zeit"]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "lab-export.csv: line 5",
            "no column `Zeit`",
            "Time [ms], enc_a, enc_b",
        ],
    );
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    let text = std::fs::read_to_string(lab_export()).unwrap();
    let text = text.replacen("0;0.000000;", "0;0.000000x;", 1);
    std::fs::write(&bad, text).unwrap();
    let err = expect_exit(&calib(&["inspect", s(&bad)]), 1);
    assert_mentions(&err, &["bad.csv: line 6, column `enc_a`", "0.000000x"]);
}

/// Writes the committed fixtures; run after changing them:
/// `cargo test -p calib-cli --test it recordings_cli::make_fixtures -- --ignored`.
/// - `testdata/mcap/clocks.mcap`: the first second (400 samples, at rest) of
///   `csrr72.toml` with A, B and the reference on three topics, each with one joint `encoder`,
///   B 0.9 ms and the reference 1.6 ms after A.
/// - `testdata/csv/lab-export.csv`: a TwinCAT-Scope-like export: three metadata lines and a blank
///   one, then `Time [ms];enc_a;enc_b` and 400 rows 2.5 ms apart, `;`-separated.
/// - `testdata/mcap/fields.mcap`: the first 200 samples of `quick.toml`'s run as
///   `my_robot/msg/MotorState` messages (see [`write_field_run`]).
/// - `testdata/mcap/ros1.mcap`: `quick.toml`'s run as `mcap convert` makes of a ROS 1 bag (see
///   [`write_ros1_run`]).
#[test]
#[ignore = "writes the committed fixtures"]
fn make_fixtures() {
    write_small_run(&clocks());
    write_ros1_run(&ros1());
    let samples = scenario_samples("quick.toml").into_iter().take(200);
    write_field_run(&fields(), samples);
    let mut csv = String::from(
        "Scope Project;calib fixture\nExported;2026-12-01 14:00:00\nSample time;2.5 ms\n\nTime [ms];enc_a;enc_b\n",
    );
    for i in 0..400 {
        let a = (i as f64 * 0.9) % 360.0;
        let b = (i as f64 * 0.9 + 30.0 + 0.01 * (i as f64 * 0.1).sin()) % 360.0;
        csv.push_str(&format!("{};{a:.6};{b:.6}\n", i as f64 * 2.5));
    }
    std::fs::write(lab_export(), csv).unwrap();
}

/// The first second of the scenario on three clocks (see [`make_fixtures`]).
fn write_small_run(path: &Path) {
    let sc = scenario();
    let mut writer = three_topics(path);
    for (n, s) in sc.samples().unwrap().take(400).enumerate() {
        for (k, shift) in [0.0, 0.9e-3, 1.6e-3].into_iter().enumerate() {
            let sample = Sample {
                t: 1.0 + n as f64 / 400.0 + shift,
                values: vec![s.values[k]],
                session: None,
            };
            writer.write_to(k, &sample).unwrap();
        }
    }
    writer.finish().unwrap();
}

/// The committed ROS 1 fixture (see [`write_ros1_run`]).
fn ros1() -> PathBuf {
    testdata("mcap/ros1.mcap")
}

/// The `ros1msg` schema `mcap convert` stores for `sensor_msgs/JointState`.
const ROS1_JOINT_STATE: &str = "Header header
string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
";

/// A ROS 1 `sensor_msgs/JointState` in the ROS 1 wire format: little-endian, no padding,
/// strings without NUL, the header `seq`, `stamp` (`uint32 secs, nsecs`) and `frame_id`
/// (`enc`, three bytes: everything after it is off any 4-byte boundary).
fn ros1_joint_state(seq: u32, stamp_ns: u64, names: &[&str], positions: &[f64]) -> Vec<u8> {
    let mut b = Vec::new();
    let string = |b: &mut Vec<u8>, s: &str| {
        b.extend_from_slice(&(s.len() as u32).to_le_bytes());
        b.extend_from_slice(s.as_bytes());
    };
    b.extend_from_slice(&seq.to_le_bytes());
    b.extend_from_slice(&((stamp_ns / 1_000_000_000) as u32).to_le_bytes());
    b.extend_from_slice(&((stamp_ns % 1_000_000_000) as u32).to_le_bytes());
    string(&mut b, "enc");
    b.extend_from_slice(&(names.len() as u32).to_le_bytes());
    for n in names {
        string(&mut b, n);
    }
    b.extend_from_slice(&(positions.len() as u32).to_le_bytes());
    for p in positions {
        b.extend_from_slice(&p.to_le_bytes());
    }
    b.extend_from_slice(&0u32.to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    b
}

/// Writes `quick.toml`'s run (3301 samples of `a` and `b`) to `path` as `mcap convert` makes of
/// a ROS 1 bag: schema `sensor_msgs/JointState` (`ros1msg`), message encoding `ros1`, one
/// message per sample on `/joint_states`, header stamp and log time the sample's time (whole
/// nanoseconds, as `calib simulate` writes them).
fn write_ros1_run(path: &Path) {
    let sc = load_scenario("quick.toml");
    let names = sc.channels();
    assert_eq!((names[0].name.as_str(), names[1].name.as_str()), ("a", "b"));
    let (mut writer, channel) = ros1_mcap(path);
    for (n, sample) in sc.samples().unwrap().enumerate() {
        let t = ns(sample.t);
        let data = ros1_joint_state(n as u32, t, &["a", "b"], &sample.values[..2]);
        writer.write(channel, n as u32, t, &data);
    }
    writer.finish();
}

/// An MCAP file at `path` as `mcap convert` makes of a ROS 1 bag, with the channel
/// `/joint_states` (`sensor_msgs/JointState`, `ros1`); the writer and the channel's id.
fn ros1_mcap(path: &Path) -> (RawMcap, u16) {
    let mut writer = RawMcap::create(
        path,
        "sensor_msgs/JointState",
        "ros1msg",
        ROS1_JOINT_STATE.as_bytes(),
    );
    let channel = writer.channel("/joint_states", "ros1");
    (writer, channel)
}

/// The committed ROS 1 fixture holds `quick.toml`'s run with the stamps and values `calib
/// simulate` writes to its CDR MCAP, so the maps agree to floating-point rounding (< 1e-6″;
/// measured 0).
#[test]
fn a_ros1_encoded_mcap_gives_the_maps_of_the_cdr_mcap() {
    let o = calib(&["inspect", s(&ros1())]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("/joint_states"))
        .unwrap_or_else(|| panic!("{out}"));
    assert_mentions(line, &["sensor_msgs/JointState", "ros1", "3301 msg"]);
    assert!(out.contains("      a, b\n"), "{out}");
    let dir = tempfile::tempdir().unwrap();
    let cdr = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let (want, got) = (dir.path().join("cdr"), dir.path().join("ros1"));
    expect_exit(&calib(&["csrr", s(&cdr), "-o", s(&want)]), 0);
    let o = calib(&["csrr", s(&ros1()), "--a", "a", "--b", "b", "-o", s(&got)]);
    expect_exit(&o, 0);
    for table in ["a.csv", "b.csv"] {
        let worst = table_difference(&want.join(table), &got.join(table));
        eprintln!("ros1 vs cdr MCAP, {table}: max |difference| {worst:e}″");
        assert!(worst < 1e-6, "{table}: {worst}″");
    }
    // A message cut short is an error naming the file, the message and the topic.
    let cut = dir.path().join("cut.mcap");
    let (mut writer, channel) = ros1_mcap(&cut);
    for n in 0..10u32 {
        let mut data = ros1_joint_state(n, 1_000_000_000 + u64::from(n), &["a"], &[0.1]);
        if n == 5 {
            data.truncate(30);
        }
        writer.write(channel, n, u64::from(n), &data);
    }
    writer.finish();
    let err = expect_exit(&calib(&["inspect", s(&cut)]), 1);
    assert_mentions(
        &err,
        &["cut.mcap", "message 5", "/joint_states", "truncated"],
    );
}

/// The committed field-path fixture (see [`write_field_run`]).
fn fields() -> PathBuf {
    testdata("mcap/fields.mcap")
}

/// The `ros2msg` definition of a motor driver's own message type: a header, a string, a fixed
/// array, the position, and a sequence of structures, so that a field path crosses every kind
/// of CDR field and padding.
const MOTOR_STATE: &str = "# State of one motor.
std_msgs/Header header
string name
float32[3] currents   # A
float64 position      # rad
Reading[] extra
uint8 MODE_IDLE=0

================================================================================
MSG: my_robot/Reading
uint8 id
float64 value

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// A `my_robot/msg/MotorState` in little-endian CDR, padding as `rmw` writes it: `frame_id`
/// `m`, `name` `motor`, `currents` 1, 2, 3, `position` A's reading and `extra` `[(1, 0.5),
/// (2, B's reading)]`.
fn motor_state(stamp_ns: u64, a: f64, b: f64) -> Vec<u8> {
    let mut m = Cdr::message();
    m.stamp(stamp_ns).string("m").string("motor");
    for c in [1.0f32, 2.0, 3.0] {
        m.primitive(c.to_le_bytes());
    }
    m.f64(a).u32(2);
    for (id, value) in [(1u8, 0.5), (2, b)] {
        m.primitive([id]).f64(value);
    }
    m.bytes()
}

/// Writes `samples` (of `a` and `b`, radians) to `path` as rosbag2 writes MCAP: one
/// `my_robot/msg/MotorState` message per sample on `/motor/state`, A in `position`, B in
/// `extra[1].value`, header stamp and log time the sample's time.
fn write_field_run(path: &Path, samples: impl IntoIterator<Item = Sample>) {
    let mut writer = RawMcap::create(
        path,
        "my_robot/msg/MotorState",
        "ros2msg",
        MOTOR_STATE.as_bytes(),
    );
    let channel = writer.channel("/motor/state", "cdr");
    for (n, sample) in samples.into_iter().enumerate() {
        let t = ns(sample.t);
        let data = motor_state(t, sample.values[0], sample.values[1]);
        writer.write(channel, n as u32, t, &data);
    }
    writer.finish();
}

/// Fields by path through the message definition the file carries: `TOPIC.position` and
/// `TOPIC.extra[1].value` of a message type calib does not know. The values and stamps are
/// those of `calib simulate`'s MCAP of the same run, so the maps agree to rounding (< 1e-6″;
/// measured 0).
#[test]
fn numeric_fields_are_read_by_path_through_the_schema() {
    // The committed fixture: the motor topic is listed as not read until a field is named.
    let o = calib(&["inspect", s(&fields())]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &["fields.mcap", "/motor/state (my_robot/msg/MotorState"],
    );
    let o = calib(&[
        "inspect",
        s(&fields()),
        "--a",
        "/motor/state.position",
        "--b",
        "/motor/state.extra[1].value",
        "--unit",
        "rad",
    ]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(
        &out,
        &[
            "my_robot/msg/MotorState",
            "200 msg",
            "      /motor/state.position, /motor/state.extra[1].value\n",
            "  200 samples over ",
        ],
    );
    // The whole run: the same maps as the CDR JointState MCAP of it.
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("motor.mcap");
    write_field_run(&log, scenario_samples("quick.toml"));
    let cdr = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let (want, got) = (dir.path().join("cdr"), dir.path().join("fields"));
    expect_exit(&calib(&["csrr", s(&cdr), "-o", s(&want)]), 0);
    let o = calib(&[
        "csrr",
        s(&log),
        "--a",
        "/motor/state.position",
        "--b",
        "/motor/state.extra[1].value",
        "--unit",
        "rad",
        "-o",
        s(&got),
    ]);
    expect_exit(&o, 0);
    for (table, field) in [
        ("a.csv", "motor_state.position.csv"),
        ("b.csv", "motor_state.extra_1_.value.csv"),
    ] {
        let worst = table_difference(&want.join(table), &got.join(field));
        eprintln!("field path vs JointState MCAP, {field}: max |difference| {worst:e}″");
        assert!(worst < 1e-6, "{field}: {worst}″");
    }
    // A path the type does not have, and a definition that does not parse, are errors naming
    // the topic and what is wrong.
    let o = calib(&["inspect", s(&fields()), "--a", "/motor/state.speed"]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "fields.mcap",
            "/motor/state",
            "no field `speed`",
            "currents, position",
        ],
    );
    let broken = dir.path().join("broken.mcap");
    let mut writer = RawMcap::create(
        &broken,
        "my_robot/msg/MotorState",
        "ros2msg",
        b"float64 position\nmy_robot/Gear gear\n",
    );
    let channel = writer.channel("/motor/state", "cdr");
    writer.write(channel, 0, 1, &[0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    writer.finish();
    let o = calib(&["inspect", s(&broken), "--a", "/motor/state.position"]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "broken.mcap",
            "/motor/state",
            "does not parse",
            "line 2",
            "`my_robot/Gear`",
        ],
    );
}

/// The readings of channel `name` of `log`, read on its own clock (no alignment).
fn channel_readings(log: &Path, name: &str) -> Vec<(f64, f64)> {
    let mut reader = calib_io::LogReader::open(log, &calib_io::ReadOptions::default()).unwrap();
    let i = reader.resolve(name).unwrap();
    reader.select(&[i], calib_io::AlignOptions::default());
    reader
        .map(|s| {
            let s = s.unwrap();
            (s.t, s.values[0])
        })
        .collect()
}

/// `calib apply` corrects a channel named `TOPIC/JOINT` (only that topic's joint, though two
/// other topics carry a joint of the same name), and a lab CSV export in its own dialect: the
/// output keeps its metadata lines, `;` separators and `Time [ms]` column byte for byte, and
/// only the channel's field changes. The map is +36″ at 0° and −36″ at 180°, linear between, so
/// every corrected reading is known in closed form (to rounding: 1e-12 rad, 1e-9°).
#[test]
fn apply_corrects_a_qualified_channel_and_keeps_a_csv_dialect() {
    let dir = tempfile::tempdir().unwrap();
    let table = write(
        dir.path(),
        "map.csv",
        "angle_deg,error_arcsec,correction_arcsec\n0,36,-36\n180,-36,36\n",
    );
    // The map's error at `deg`, in degrees.
    let e = |deg: f64| {
        let deg = deg.rem_euclid(360.0);
        36.0 * (1.0 - 2.0 * (deg.min(360.0 - deg) / 180.0)) / 3600.0
    };
    let fixed = dir.path().join("fixed.mcap");
    let b = "/sensor_b/joint_states/encoder";
    let o = calib(&[
        "apply",
        s(&table),
        s(&clocks()),
        "--channel",
        b,
        "-o",
        s(&fixed),
    ]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["400 readings"]);
    for (name, corrected) in [(b, true), (TOPICS[0], false), (TOPICS[2], false)] {
        let name = if name == b {
            name.to_string()
        } else {
            format!("{name}/encoder")
        };
        let (before, after) = (
            channel_readings(&clocks(), &name),
            channel_readings(&fixed, &name),
        );
        assert_eq!(before.len(), 400, "{name}");
        assert_eq!(before.len(), after.len(), "{name}");
        for (x, y) in before.iter().zip(&after) {
            assert_eq!(x.0, y.0, "{name}: stamps");
            let want = if corrected {
                x.1 - e(x.1.to_degrees()).to_radians()
            } else {
                x.1
            };
            let d = (want - y.1).abs();
            assert!(d < 1e-12, "{name}: {x:?} → {y:?}");
        }
    }
    // A lab CSV export: the same text but for enc_b's fields.
    let out = dir.path().join("fixed.csv");
    let o = calib(&[
        "apply",
        s(&table),
        s(&lab_export()),
        "--channel",
        "enc_b",
        "-o",
        s(&out),
    ]);
    expect_exit(&o, 0);
    let (input, output) = (
        std::fs::read_to_string(lab_export()).unwrap(),
        std::fs::read_to_string(&out).unwrap(),
    );
    let (input, output): (Vec<&str>, Vec<&str>) =
        (input.lines().collect(), output.lines().collect());
    assert_eq!(input.len(), output.len());
    assert_eq!(input[..5], output[..5], "metadata lines and header");
    for (a, b) in input[5..].iter().zip(&output[5..]) {
        let (a, b): (Vec<&str>, Vec<&str>) = (a.split(';').collect(), b.split(';').collect());
        assert_eq!((a.len(), a[0], a[1]), (3, b[0], b[1]), "{a:?} → {b:?}");
        let (x, y): (f64, f64) = (a[2].parse().unwrap(), b[2].parse().unwrap());
        // Written with at least enough decimals for 0.001″ (7 in degrees): within half of that.
        assert!((x - e(x) - y).abs() <= 0.5e-7, "{a:?} → {b:?}");
    }
    // The time column is not a channel to correct.
    let o = calib(&[
        "apply",
        s(&table),
        s(&lab_export()),
        "--channel",
        "Time [ms]",
        "-o",
        s(&dir.path().join("time.csv")),
    ]);
    assert_ne!(code(&o), 0);
}

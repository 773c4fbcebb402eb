//! ROS 1 bags (`.bag`, format 2.0) read as saved: the fixtures of `testdata/ros1/` (written by
//! the `rosbags` package from `testdata/examples/quick.mcap`, see its README) give the maps of the
//! MCAP of the same run; a bag without index, one cut short, and hostile bytes.

use crate::common::ros::table_difference;
use crate::common::*;
use calib_io::{LogReader, LogWriter, ReadOptions};
use std::path::{Path, PathBuf};

/// The bundled example run, as `calib simulate` wrote it (CDR JointState).
fn run_mcap() -> PathBuf {
    testdata("examples/quick.mcap")
}

fn bag(name: &str) -> PathBuf {
    testdata(&format!("ros1/{name}.bag"))
}

/// The offset of the first chunk record: after the 13-byte magic line and the bag header
/// record, which `rosbag record` (and `rosbags`) pad to 4096 bytes.
const FIRST_CHUNK: usize = 13 + 4096;

/// The value of the header field `name` of the record at `at` (whose header holds it).
fn field_at(bytes: &[u8], at: usize, name: &str) -> std::ops::Range<usize> {
    let len = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut k = at + 4;
    while k < at + 4 + len {
        let n = u32::from_le_bytes(bytes[k..k + 4].try_into().unwrap()) as usize;
        let field = &bytes[k + 4..k + 4 + n];
        if field.starts_with(format!("{name}=").as_bytes()) {
            return k + 4 + name.len() + 1..k + 4 + n;
        }
        k += 4 + n;
    }
    panic!("no field {name} in the record at {at}");
}

/// `run.mcap`'s samples, every `step`-th, written by calib's own MCAP writer to `out`.
fn every_nth(step: usize, out: &Path) -> PathBuf {
    let mut log = LogReader::open(&run_mcap(), &ReadOptions::default()).unwrap();
    let channels = log.channels().to_vec();
    let mut w = LogWriter::create(out, &channels, false).unwrap();
    for (n, sample) in log.by_ref().enumerate() {
        if n % step == 0 {
            w.write(&sample.unwrap()).unwrap();
        }
    }
    w.finish().unwrap();
    out.to_path_buf()
}

/// `calib csrr` of `log` into `out`, with `extra` options; asserts success.
fn csrr(log: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec!["csrr", s(log), "-o", s(out)];
    args.extend(extra);
    expect_exit(&calib(&args), 0);
}

/// The largest difference of `a.csv` and `b.csv` between two csrr outputs, arcsec.
fn maps_difference(want: &Path, got: &Path) -> f64 {
    ["a.csv", "b.csv"]
        .iter()
        .map(|t| table_difference(&want.join(t), &got.join(t)))
        .fold(0.0, f64::max)
}

/// The topic line of `topic` in `calib inspect`'s output.
fn topic_line<'a>(out: &'a str, topic: &str) -> &'a str {
    out.lines()
        .find(|l| l.trim_start().starts_with(&format!("{topic} ")))
        .unwrap_or_else(|| panic!("no {topic} in {out}"))
}

#[test]
fn inspect_lists_each_bags_topics_and_channels() {
    for (name, messages) in [
        ("quick-bz2", 3301),
        ("quick-lz4", 3301),
        ("quick-none", 1651),
    ] {
        let o = calib(&["inspect", s(&bag(name))]);
        expect_exit(&o, 0);
        let out = stdout(&o);
        let line = topic_line(&out, "/joint_states");
        assert_mentions(
            line,
            &["sensor_msgs/JointState", "ros1", &format!("{messages} msg")],
        );
        assert!(out.contains("      a, b\n"), "{name}: {out}");
        // The stamps are the MCAP's moved to 1.7e9 s: 16.5 s of them.
        assert!(
            out.contains("over 16.500 s (1700000000.000 … 1700000016.500 s)"),
            "{out}"
        );
        assert!(
            !out.contains("warning"),
            "{name}: a whole indexed bag: {out}"
        );
    }
    let o = calib(&["inspect", s(&bag("quick-scalars"))]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    for topic in ["/a", "/b"] {
        assert_mentions(
            topic_line(&out, topic),
            &["std_msgs/Float64", "ros1", "1651 msg", "100.00 Hz"],
        );
    }
}

/// The JointState bags hold the MCAP's values and stamps bit for bit (only moved by a whole
/// number of seconds, which calib's time origin takes off again), so the maps are the same
/// computation on the same numbers: a difference above 1e-9″ would be a reading error. (Measured:
/// 0.)
#[test]
fn csrr_on_each_bag_gives_the_maps_of_the_mcap_of_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let want = dir.path().join("mcap");
    csrr(&run_mcap(), &want, &[]);
    for name in ["quick-bz2", "quick-lz4"] {
        let got = dir.path().join(name);
        csrr(&bag(name), &got, &[]);
        let worst = maps_difference(&want, &got);
        eprintln!("{name} vs quick.mcap: max |difference| {worst:e}″");
        assert!(worst < 1e-9, "{name}: {worst}″");
    }
    // The 100 Hz bags against every other sample of the MCAP, written by calib itself.
    let half = every_nth(2, &dir.path().join("half.mcap"));
    let want = dir.path().join("half");
    csrr(&half, &want, &[]);
    let got = dir.path().join("none");
    csrr(&bag("quick-none"), &got, &[]);
    let worst = maps_difference(&want, &got);
    eprintln!("quick-none vs every other sample: max |difference| {worst:e}″");
    assert!(worst < 1e-9, "quick-none: {worst}″");
    // Float64 scalars carry radians and no header: timed by the record time, /b aligned on
    // /a's clock at the very same stamps.
    let got = dir.path().join("scalars");
    let scalars = bag("quick-scalars");
    csrr(&scalars, &got, &["--a", "/a", "--b", "/b", "--unit", "rad"]);
    let worst = maps_difference(&want, &got);
    eprintln!("quick-scalars vs every other sample: max |difference| {worst:e}″");
    assert!(worst < 1e-9, "quick-scalars: {worst}″");
}

/// A bag whose recording did not close: no index section, `index_pos` 0 in its header.
#[test]
fn a_bag_without_index_is_scanned_with_a_warning_and_reads_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = std::fs::read(bag("quick-lz4")).unwrap();
    let index_pos = field_at(&bytes, 13, "index_pos");
    let at = u64::from_le_bytes(bytes[index_pos.clone()].try_into().unwrap()) as usize;
    bytes.truncate(at);
    bytes[index_pos].fill(0);
    let crashed = dir.path().join("crashed.bag");
    std::fs::write(&crashed, &bytes).unwrap();
    let o = calib(&["inspect", s(&crashed)]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(topic_line(&out, "/joint_states"), &["3301 msg"]);
    assert_mentions(
        &out,
        &[
            "crashed.bag",
            "no index (index_pos 0",
            "11 chunk(s)",
            "rosbag reindex",
        ],
    );
    let (want, got) = (dir.path().join("indexed"), dir.path().join("scanned"));
    csrr(&bag("quick-lz4"), &want, &[]);
    csrr(&crashed, &got, &[]);
    assert_eq!(maps_difference(&want, &got), 0.0);
}

/// A bag cut inside a chunk (a partial copy): the messages before the cut, and a warning naming
/// the byte where the cut chunk starts.
#[test]
fn a_bag_cut_inside_a_chunk_gives_the_messages_before_the_break() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["quick-none", "quick-bz2", "quick-lz4"] {
        let bytes = std::fs::read(bag(name)).unwrap();
        let cut = &bytes[..bytes.len() / 2];
        let path = dir.path().join(format!("{name}-cut.bag"));
        std::fs::write(&path, cut).unwrap();
        let o = calib(&["inspect", s(&path)]);
        expect_exit(&o, 0);
        let out = stdout(&o);
        let err = out.clone();
        assert_mentions(
            &err,
            &[s(&path), "ends early at byte", "messages before the break"],
        );
        let at: usize = err
            .split("ends early at byte ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        // The byte named is where the cut chunk's record starts.
        assert!(at >= FIRST_CHUNK && at < cut.len(), "{name}: {at}");
        assert_eq!(
            &bytes[field_at(&bytes, at, "op")],
            &[5],
            "{name}: not a chunk"
        );
        let messages: u64 = topic_line(&out, "/joint_states")
            .split_whitespace()
            .find_map(|w| w.parse().ok())
            .unwrap();
        let whole = if name == "quick-none" { 1651 } else { 3301 };
        assert!(messages > 0 && messages < whole, "{name}: {messages}");
        // What was read is the run's start with nothing missing.
        assert_mentions(
            &out,
            &["(1700000000.000 …", "gaps (> 2× nominal interval): 0"],
        );
    }
}

#[test]
fn hostile_lengths_are_errors_naming_the_file_and_the_byte() {
    let dir = tempfile::tempdir().unwrap();
    let original = std::fs::read(bag("quick-none")).unwrap();
    let hostile = |name: &str, edit: &dyn Fn(&mut Vec<u8>)| {
        let mut bytes = original.clone();
        edit(&mut bytes);
        let path = dir.path().join(format!("{name}.bag"));
        std::fs::write(&path, &bytes).unwrap();
        let o = calib(&["inspect", s(&path)]);
        let err = expect_exit(&o, 1);
        assert!(!err.contains("panicked"), "{err}");
        err
    };
    // A chunk declaring 4 GiB uncompressed (the most its u32 `size` says).
    let err = hostile("huge-size", &|b| {
        let size = field_at(b, FIRST_CHUNK, "size");
        b[size].copy_from_slice(&u32::MAX.to_le_bytes());
    });
    assert_mentions(
        &err,
        &[
            "huge-size.bag: byte 4109: ",
            "declares 4294967295 bytes uncompressed",
            "the 268435456 calib holds",
        ],
    );
    // A chunk record whose header claims 4 GiB, whose data claims 4 GiB.
    let err = hostile("huge-header", &|b| {
        b[FIRST_CHUNK..FIRST_CHUNK + 4].copy_from_slice(&0xffff_fff0u32.to_le_bytes());
    });
    assert_mentions(
        &err,
        &["huge-header.bag: byte 4109: ", "claims 4294967280 bytes"],
    );
    let err = hostile("huge-data", &|b| {
        let len = u32::from_le_bytes(b[FIRST_CHUNK..FIRST_CHUNK + 4].try_into().unwrap());
        let at = FIRST_CHUNK + 4 + len as usize;
        b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    });
    assert_mentions(
        &err,
        &["huge-data.bag: byte 4109: ", "4294967295 bytes of data"],
    );
    // A message length running past its chunk.
    let err = hostile("bad-message", &|b| {
        let len = u32::from_le_bytes(b[FIRST_CHUNK..FIRST_CHUNK + 4].try_into().unwrap());
        let data = FIRST_CHUNK + 8 + len as usize;
        // The chunk starts with the connection record; its header length, made huge.
        b[data..data + 4].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    });
    assert_mentions(
        &err,
        &["bad-message.bag: byte 4109: ", "byte 0 of the chunk"],
    );
    // An index placed 1 TB in: the chunks are found by a scan, and the bag is read.
    let mut far = original.clone();
    let index_pos = field_at(&far, 13, "index_pos");
    far[index_pos].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let path = dir.path().join("far-index.bag");
    std::fs::write(&path, &far).unwrap();
    let o = calib(&["inspect", s(&path)]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(topic_line(&out, "/joint_states"), &["1651 msg"]);
    assert_mentions(&out, &["at byte 1099511627776, outside the file's records"]);
}

#[test]
fn other_versions_and_other_files_named_bag_are_refused_with_their_reason() {
    let dir = tempfile::tempdir().unwrap();
    let old = write(dir.path(), "old.bag", "#ROSBAG V1.2\n\0\0\0\0");
    let err = expect_exit(&calib(&["inspect", s(&old)]), 1);
    assert_mentions(
        &err,
        &[
            "old.bag",
            "format version 1.2",
            "calib reads format 2.0",
            "rosbag filter",
        ],
    );
    let text = write(dir.path(), "notes.bag", "hello\n");
    let err = expect_exit(&calib(&["inspect", s(&text)]), 1);
    assert_mentions(&err, &["notes.bag", "not a ROS 1 bag", "`hello\\n`"]);
    // Cut inside the bag header: nothing to read, said with the byte.
    let stub = dir.path().join("stub.bag");
    std::fs::write(&stub, b"#ROSBAG V2.0\n\x04\x00\x00\x00op=\x03").unwrap();
    let err = expect_exit(&calib(&["inspect", s(&stub)]), 1);
    assert_mentions(&err, &["stub.bag: byte 13: ", "ends inside the bag header"]);
    let out = dir.path().join("out");
    let err = expect_exit(&calib(&["csrr", s(&stub), "-o", s(&out)]), 1);
    assert_mentions(&err, &["stub.bag: byte 13: "]);
    assert_no_output(&out);
}

/// `calib apply` corrects CSV and MCAP logs; a ROS 1 bag is refused by name (exit 2), with the
/// conversion to run.
#[test]
fn apply_refuses_a_ros1_bag_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let table = write(
        dir.path(),
        "map.csv",
        "angle_deg,error_arcsec,correction_arcsec\n0,36,-36\n180,-36,36\n",
    );
    for out in ["fixed.mcap", "fixed.bag"] {
        let fixed = dir.path().join(out);
        let o = calib(&["apply", s(&table), s(&bag("quick-lz4")), "-o", s(&fixed)]);
        assert_mentions(
            &expect_exit(&o, 2),
            &["quick-lz4.bag", "ROS 1 bag", "mcap convert"],
        );
        assert!(!fixed.exists());
    }
}

//! McapWriter: round trip through McapReader, atomic output, and refused input.

use crate::common;

use std::collections::BTreeMap;

use calib_core::Sample;
use calib_io::mcap_log::{DEFAULT_TOPIC, McapReader, McapWriter};
use calib_io::{Error, ReadOptions};
use common::channels;

#[test]
fn samples_round_trip_with_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sim.mcap");
    let mut w = McapWriter::create(&path, &channels(&["a", "b", "ref"]), DEFAULT_TOPIC).unwrap();
    let mut meta = BTreeMap::new();
    meta.insert("seed".to_string(), "7".to_string());
    w.metadata("calib.simulate", &meta).unwrap();
    let n = 20_000;
    // Stamps hold whole nanoseconds: times come back rounded to the nearest one.
    let sample = |i: usize| Sample {
        t: 1.0 + i as f64 / 1024.0,
        values: vec![i as f64 * 1e-4, -(i as f64), std::f64::consts::PI],
        session: None,
    };
    for i in 0..n {
        w.write(&sample(i)).unwrap();
    }
    assert!(!path.exists(), "the file must appear only on finish");
    w.finish().unwrap();

    let mut reader = McapReader::open(&path, &ReadOptions::default()).unwrap();
    let names: Vec<&str> = reader.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["a", "b", "ref"]);
    let mut count = 0;
    for (i, s) in (&mut reader).enumerate() {
        let (s, want) = (s.unwrap(), sample(i));
        assert_eq!(s.values, want.values);
        assert!(
            (s.t - want.t).abs() <= 0.5e-9 + 4.0 * f64::EPSILON * want.t,
            "{} vs {}",
            s.t,
            want.t
        );
        count += 1;
    }
    assert_eq!(count, n);
    assert_eq!(reader.diagnostics().truncated, None);

    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::read::Summary::read(&bytes).unwrap().unwrap();
    let channel = summary.channels.values().next().unwrap();
    assert_eq!(channel.topic, "/joint_states");
    assert_eq!(channel.message_encoding, "cdr");
    let schema = channel.schema.as_ref().unwrap();
    assert_eq!(
        (schema.name.as_str(), schema.encoding.as_str()),
        ("sensor_msgs/msg/JointState", "ros2msg")
    );
    let index = &summary.metadata_indexes[0];
    let m = mcap::read::metadata(&bytes, index).unwrap();
    assert_eq!((m.name.as_str(), &m.metadata), ("calib.simulate", &meta));
    // Only the finished file is left in the directory.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn a_writer_dropped_before_finish_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("crash.mcap");
    let mut w = McapWriter::create(&path, &channels(&["a"]), "/js").unwrap();
    w.write(&Sample {
        t: 0.5,
        values: vec![1.0],
        session: None,
    })
    .unwrap();
    drop(w);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn bad_samples_and_channel_lists_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.mcap");
    let is_mcap = |r: Result<_, Error>| matches!(r, Err(Error::Mcap { .. }));
    assert!(is_mcap(
        McapWriter::create(&path, &channels(&["a", "a"]), "/js").map(|_| ())
    ));
    assert!(is_mcap(
        McapWriter::create(&path, &channels(&[]), "/js").map(|_| ())
    ));
    let mut w = McapWriter::create(&path, &channels(&["a", "b"]), "/js").unwrap();
    let bad = |t: f64, values: Vec<f64>| Sample {
        t,
        values,
        session: None,
    };
    assert!(is_mcap(w.write(&bad(1.0, vec![1.0]))));
    assert!(is_mcap(w.write(&bad(-1.0, vec![1.0, 2.0]))));
    assert!(is_mcap(w.write(&bad(f64::NAN, vec![1.0, 2.0]))));
    assert!(is_mcap(w.write(&bad(1e12, vec![1.0, 2.0]))));
    let missing_dir = dir.path().join("no/such/dir/x.mcap");
    assert!(matches!(
        McapWriter::create(&missing_dir, &channels(&["a"]), "/js"),
        Err(Error::Io { .. })
    ));
}

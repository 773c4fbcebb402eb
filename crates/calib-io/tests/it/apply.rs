//! `calib_io::apply`: logs rewritten with one channel corrected. The corrected values are checked
//! against a linear interpolation written here (not the library's), and everything else against
//! the input, byte for byte or record for record as read by the `mcap` crate.

use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::correction::Wrapping;
use calib_io::apply::{ApplyOptions, apply};
use calib_io::{Error, LogFormat, LogReader, ReadOptions};
use mcap::records::{MessageHeader, Record};
use mcap::{Compression, WriteOptions};
use std::collections::BTreeMap;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/mcap/fixture.mcap")
}

/// e(θ) = 30″ cos 3θ + 10″ sin θ on 360 points (zero mean by construction).
fn map() -> ErrorMap {
    ErrorMap::new(
        (0..360)
            .map(|i| {
                let th = TAU * i as f64 / 360.0;
                (30.0 * (3.0 * th).cos() + 10.0 * th.sin()) / ARCSEC_PER_RAD
            })
            .collect(),
    )
}

/// The map's error at `theta` (radians), interpolated linearly between its 1° grid points.
fn error_at(theta: f64) -> f64 {
    let m = map();
    let v = m.values();
    let u = theta.rem_euclid(TAU) / TAU * 360.0;
    let i = (u.floor() as usize).min(359);
    let f = u - i as f64;
    v[i] * (1.0 - f) + v[(i + 1) % 360] * f
}

fn opts(channel: &str) -> ApplyOptions {
    ApplyOptions {
        channel: channel.into(),
        unit: None,
        wrapping: None,
        skip_damaged: false,
        keep: false,
        one_thread: false,
    }
}

fn samples(path: &Path) -> (Vec<String>, Vec<calib_core::Sample>) {
    let reader = LogReader::open(path, &ReadOptions::default()).unwrap();
    let names = reader.channels().iter().map(|c| c.name.clone()).collect();
    (names, reader.map(Result::unwrap).collect())
}

/// Every record of an MCAP file but messages and the file's structure (chunks, indexes,
/// summary), in file order, schemas and channels once each, as the `mcap` crate reads them.
fn other_records(path: &Path) -> Vec<String> {
    let bytes = std::fs::read(path).unwrap();
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for record in mcap::read::LinearReader::new(&bytes).unwrap() {
        let text = match record.unwrap() {
            Record::Header(h) => format!("{h:?}"),
            Record::Schema { header, data } => format!("{header:?} {data:?}"),
            Record::Channel(c) => format!("{c:?}"),
            Record::Metadata(m) => format!("{m:?}"),
            Record::Attachment { header, data, .. } => format!("{header:?} {data:?}"),
            Record::Unknown { opcode, data } => format!("{opcode} {data:?}"),
            _ => continue,
        };
        if seen.insert(text.clone()) {
            out.push(text);
        }
    }
    out
}

/// Every message: (channel id, sequence, log time, publish time, data).
fn messages(path: &Path) -> Vec<(u16, u32, u64, u64, Vec<u8>)> {
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (
                m.channel.id,
                m.sequence,
                m.log_time,
                m.publish_time,
                m.data.into_owned(),
            )
        })
        .collect()
}

#[test]
fn joint_state_channel_is_corrected_and_every_other_record_kept() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let done = apply(&fixture(), &out, &map().into(), &opts("a")).unwrap();
    assert_eq!(done.format, LogFormat::Mcap);
    assert_eq!(done.readings, 300);
    // 300 JSON messages on /reference less 5 missing plus 2 stray, and 10 on /status.
    assert_eq!(done.copied, 297 + 10);
    // a = i/64 rad for i < 300: within [0, 2π), so kept there.
    assert_eq!(done.wrapping, Wrapping::Positive);
    assert_eq!(done.truncated, None);

    assert_eq!(other_records(&fixture()), other_records(&out));
    let (before, after) = (messages(&fixture()), messages(&out));
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert_eq!((b.0, b.1, b.2, b.3), (a.0, a.1, a.2, a.3));
        assert_eq!(b.4.len(), a.4.len());
        let changed: Vec<usize> = (0..b.4.len()).filter(|&i| b.4[i] != a.4[i]).collect();
        // Only the 8 bytes of one position may differ.
        assert!(
            changed.len() <= 8 && changed.last().unwrap_or(&0) - changed.first().unwrap_or(&0) < 8,
            "{changed:?}"
        );
    }

    let (names, input) = samples(&fixture());
    let (names_out, output) = samples(&out);
    assert_eq!(names, names_out);
    assert_eq!(names, ["a", "b", "ref"]);
    assert_eq!(input.len(), output.len());
    let mut wrapped = 0;
    for (i, o) in input.iter().zip(&output) {
        assert_eq!(i.t, o.t);
        // Other channels bit for bit.
        assert_eq!(i.values[1].to_bits(), o.values[1].to_bits());
        assert_eq!(i.values[2].to_bits(), o.values[2].to_bits());
        let r = i.values[0];
        let want = (r - error_at(r)).rem_euclid(TAU);
        // Interpolation and subtraction in f64: a few ulps of 2π.
        assert!(
            (o.values[0] - want).abs() < 1e-14,
            "{r}: {} vs {want}",
            o.values[0]
        );
        assert!((0.0..TAU).contains(&o.values[0]));
        wrapped += usize::from(o.values[0] > 6.0 && r < 1.0);
    }
    // The reading 0 (e = +30″) goes below zero and comes back just under 2π.
    assert_eq!(wrapped, 1);
}

#[test]
fn json_field_is_rewritten_in_its_unit_and_the_rest_of_the_text_kept() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let done = apply(&fixture(), &out, &map().into(), &opts("ref")).unwrap();
    // 295 joined messages plus 2 stray ones; ref from −1° to 74.75°: taken as [−180°, 180°).
    assert_eq!(done.readings, 297);
    assert_eq!(done.wrapping, Wrapping::Signed);
    assert_eq!(done.unit, calib_core::AngleUnit::Deg);
    let (before, after) = (messages(&fixture()), messages(&out));
    let mut json = 0;
    for (b, a) in before.iter().zip(&after) {
        let text = String::from_utf8_lossy(&b.4);
        if !text.starts_with("{\"ref\": ") {
            assert_eq!(b.4, a.4);
            continue;
        }
        json += 1;
        let new = String::from_utf8(a.4.clone()).unwrap();
        let (head, tail) = text.split_once(", \"status\"").unwrap();
        assert!(new.starts_with("{\"ref\": ") && new.ends_with(&format!(", \"status\"{tail}")));
        let deg: f64 = head["{\"ref\": ".len()..].parse().unwrap();
        let got: f64 = new["{\"ref\": ".len()..new.len() - tail.len() - 10]
            .parse()
            .unwrap();
        let want = deg - error_at(deg.to_radians()).to_degrees();
        assert!((got - want).abs() < 1e-12, "{deg}: {got} vs {want}");
    }
    assert_eq!(json, 297);
}

/// A log with what a real recording carries besides the encoders: metadata, an attachment, a
/// foreign topic, a private record, two channels on one schema; lz4 chunks.
fn rich_log(path: &Path) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = WriteOptions::new()
        .profile("x-lab")
        .library("rig recorder 2.1")
        .compression(Some(Compression::Lz4))
        .chunk_size(Some(2048))
        .create(file)
        .unwrap();
    let schema = w
        .add_schema_with_id(
            7,
            "sensor_msgs/msg/JointState",
            "ros2msg",
            calib_io::mcap_log::JOINT_STATE_MSGDEF.as_bytes(),
        )
        .unwrap();
    let meta = BTreeMap::from([("frame".to_string(), "rig".to_string())]);
    let js = w
        .add_channel_with_id(12, schema, "/encoders", "cdr", &meta)
        .unwrap();
    let other = w.add_schema("foo.Bar", "protobuf", b"\x01\x02").unwrap();
    let cam = w
        .add_channel_with_id(3, other, "/camera", "protobuf", &BTreeMap::new())
        .unwrap();
    w.write_metadata(&mcap::records::Metadata {
        name: "run".into(),
        metadata: BTreeMap::from([("operator".into(), "kim".into())]),
    })
    .unwrap();
    w.attach(&mcap::Attachment {
        log_time: 5,
        create_time: 6,
        name: "rig.urdf".into(),
        media_type: "text/xml".into(),
        data: std::borrow::Cow::Borrowed(b"<robot/>"),
    })
    .unwrap();
    w.write_private_record(0x90, b"vendor", Default::default())
        .unwrap();
    // Big-endian JointState, hand-serialized: stamp, frame_id "", names [x, enc], positions.
    for i in 0..500u32 {
        let mut m = vec![0u8, 0, 0, 0];
        m.extend((i + 1).to_be_bytes());
        m.extend(0u32.to_be_bytes());
        m.extend(1u32.to_be_bytes());
        m.extend([0, 0, 0, 0]); // "" + padding to 4
        m.extend(2u32.to_be_bytes());
        m.extend(2u32.to_be_bytes());
        m.extend([b'x', 0, 0, 0]);
        m.extend(4u32.to_be_bytes());
        m.extend(*b"enc\0");
        m.extend(2u32.to_be_bytes()); // ends 40 bytes after the origin: 8-aligned already
        m.extend(0.25f64.to_be_bytes());
        // Unwrapped: 0.02 rad per message from −1 rad, past 2π.
        m.extend((-1.0 + 0.02 * f64::from(i)).to_be_bytes());
        m.extend(0u32.to_be_bytes());
        m.extend(0u32.to_be_bytes());
        let h = |channel_id, sequence| MessageHeader {
            channel_id,
            sequence,
            log_time: 1_000 + u64::from(i),
            publish_time: 2_000 + u64::from(i),
        };
        w.write_to_known_channel(&h(js, 10 * i), &m).unwrap();
        if i % 50 == 0 {
            w.write_to_known_channel(&h(cam, i), b"\xffframe").unwrap();
        }
    }
    w.finish().unwrap();
}

#[test]
fn ids_metadata_attachments_private_records_and_compression_survive() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rich.mcap");
    rich_log(&log);
    let out = dir.path().join("out.mcap");
    let done = apply(&log, &out, &map().into(), &opts("enc")).unwrap();
    assert_eq!((done.readings, done.copied), (500, 10));
    assert_eq!(done.wrapping, Wrapping::Unwrapped);
    let records = other_records(&out);
    assert_eq!(other_records(&log), records);
    assert!(records.iter().any(|r| r.contains("rig.urdf")));
    assert!(records.iter().any(|r| r.starts_with("144 ")));
    let summary = mcap::Summary::read(&std::fs::read(&out).unwrap())
        .unwrap()
        .unwrap();
    assert!(summary.chunk_indexes.iter().all(|c| c.compression == "lz4"));
    let (before, after) = (messages(&log), messages(&out));
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert_eq!((b.0, b.1, b.2, b.3), (a.0, a.1, a.2, a.3));
        if b.0 == 3 {
            assert_eq!(b.4, a.4);
            continue;
        }
        // Big-endian position[1] at bytes 52..60; the rest unchanged.
        assert_eq!((&b.4[..52], &b.4[60..]), (&a.4[..52], &a.4[60..]));
        let r = f64::from_be_bytes(b.4[52..60].try_into().unwrap());
        let c = f64::from_be_bytes(a.4[52..60].try_into().unwrap());
        assert!((c - (r - error_at(r))).abs() < 1e-14, "{r} → {c}");
    }
}

#[test]
fn truncated_log_gives_a_complete_output_of_what_was_read() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rich.mcap");
    rich_log(&log);
    let bytes = std::fs::read(&log).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let out = dir.path().join("out.mcap");
    let done = apply(&cut, &out, &map().into(), &opts("enc")).unwrap();
    let t = done.truncated.clone().expect("truncated");
    assert!(done.readings > 100 && done.readings < 500, "{done:?}");
    assert!(t.messages_read >= done.readings);
    // The output is a complete file with every message read.
    assert_eq!(messages(&out).len() as u64, t.messages_read);
}

#[test]
fn csv_rewrites_the_channel_field_only() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let text = "\u{feff}t, \"a\" ,b,session\r\n\
                0.000, 0.0 ,359.99,0\r\n\
                \r\n\
                0.0010,\"90\",1.5e2,0\r\n\
                0.002,359.9999,7,-1\r\n\
                0.003,180,\"x\"\"y\",-1";
    std::fs::write(&log, text).unwrap();
    let out = dir.path().join("out.csv");
    let done = apply(&log, &out, &map().into(), &opts("a")).unwrap();
    assert_eq!((done.readings, done.wrapping), (4, Wrapping::Positive));
    let got = std::fs::read_to_string(&out).unwrap();
    let want_deg = |deg: f64| (deg - error_at(deg.to_radians()).to_degrees()).rem_euclid(360.0);
    let lines: Vec<&str> = got.split("\r\n").collect();
    assert_eq!(lines[0], "\u{feff}t, \"a\" ,b,session");
    assert_eq!(lines[2], "");
    let expect = [
        (1, "0.000,", ",359.99,0", 0.0),
        (3, "0.0010,", ",1.5e2,0", 90.0),
    ];
    // A corrected reading is written with its field's decimals, at least enough for 0.001″
    // (7 in degrees): within half of the last.
    const HALF_DECIMAL: f64 = 0.5e-7;
    for (k, head, tail, deg) in expect {
        let line = lines[k];
        assert!(line.starts_with(head) && line.ends_with(tail), "{line}");
        // A quoted field stays quoted (issue 52: the input's formatting is kept).
        let field = &line[head.len()..line.len() - tail.len()];
        let quoted = field.starts_with('"') && field.ends_with('"') && field.len() > 1;
        assert_eq!(quoted, k == 3, "{line}");
        let v: f64 = field.trim_matches('"').parse().unwrap();
        assert!((v - want_deg(deg)).abs() <= HALF_DECIMAL, "{line}");
    }
    // 0° reads 30″ high: corrected into [0, 360) from below.
    let v: f64 = lines[1][6..lines[1].len() - 9].parse().unwrap();
    assert!((v - (360.0 - 30.0 / 3600.0)).abs() <= HALF_DECIMAL, "{v}");
    let v: f64 = lines[4][6..lines[4].len() - 5].parse().unwrap();
    assert!((v - want_deg(359.9999)).abs() <= HALF_DECIMAL, "{v}");
    // No line end added where the input had none.
    assert!(lines[5].starts_with("0.003,") && lines[5].ends_with(",\"x\"\"y\",-1"));
    assert_eq!(lines.len(), 6);
}

#[test]
fn csv_units_are_kept_and_accumulated_readings_stay_unwrapped() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    // counts:4096 accumulating past a revolution, and below zero.
    std::fs::write(&log, "t,enc\n0,-3\n1,0\n2,4095\n3,4097\n4,9000\n").unwrap();
    let out = dir.path().join("out.csv");
    let o = ApplyOptions {
        unit: Some(calib_core::AngleUnit::Counts(4096)),
        ..opts("enc")
    };
    let done = apply(&log, &out, &map().into(), &o).unwrap();
    assert_eq!(done.wrapping, Wrapping::Unwrapped);
    let got = std::fs::read_to_string(&out).unwrap();
    let per_rad = 4096.0 / TAU;
    for (line, x) in got.lines().skip(1).zip([-3.0, 0.0, 4095.0, 4097.0, 9000.0]) {
        let v: f64 = line.split(',').nth(1).unwrap().parse().unwrap();
        let want = x - error_at(x / per_rad) * per_rad;
        // Integer counts are written with 6 decimals, enough for 0.001″ at 4096 a turn.
        assert!((v - want).abs() <= 0.5e-6, "{line}: want {want}");
    }
    // An explicit wrapping wins over the detected one.
    let o = ApplyOptions {
        wrapping: Some(Wrapping::Positive),
        ..o
    };
    apply(&log, &out, &map().into(), &o).unwrap();
    let got = std::fs::read_to_string(&out).unwrap();
    assert!(got.lines().skip(1).all(|l| {
        let v: f64 = l.split(',').nth(1).unwrap().parse().unwrap();
        (0.0..4096.0).contains(&v)
    }));
}

fn csv_error(text: &str, channel: &str) -> (u64, Option<String>, String) {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("bad.csv");
    std::fs::write(&log, text).unwrap();
    let out = dir.path().join("out.csv");
    let err = apply(&log, &out, &map().into(), &opts(channel)).unwrap_err();
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "temporary left behind"
    );
    assert!(err.to_string().contains("bad.csv"), "{err}");
    match err {
        Error::Csv {
            line,
            channel,
            message,
            ..
        } => (line, channel, message),
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_csv_logs_are_errors_naming_line_and_channel() {
    let (line, ch, m) = csv_error("t,a,b\n0,1,2\n", "c");
    assert_eq!((line, ch.as_deref()), (1, Some("c")));
    assert!(m.contains("it has: a, b"), "{m}");
    let (line, ch, m) = csv_error("t,a,b\n0,1,2\n\n1,x,2\n", "a");
    assert_eq!((line, ch.as_deref()), (4, Some("a")));
    assert!(m.contains("`x` is not a finite number"), "{m}");
    let (line, _, m) = csv_error("t,a,b\n0,1,2\n1,2\n", "a");
    assert_eq!(line, 3);
    assert!(m.contains("2 fields but the header has 3"), "{m}");
    let (line, _, m) = csv_error("t,a\n0,inf\n", "a");
    assert_eq!(line, 2);
    assert!(m.contains("not a finite number"), "{m}");
    let (_, _, m) = csv_error("", "a");
    assert!(m.contains("empty"), "{m}");
}

#[test]
fn formats_must_match_and_a_channel_without_readings_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.csv");
    let err = apply(&fixture(), &out, &map().into(), &opts("a")).unwrap_err();
    assert!(err.to_string().contains("same format"), "{err}");
    let out = dir.path().join("out.mcap");
    let err = apply(&fixture(), &out, &map().into(), &opts("zz")).unwrap_err();
    assert!(
        err.to_string().contains("no readings of channel `zz`"),
        "{err}"
    );
    // A JSON field of that name that is not a number.
    let err = apply(&fixture(), &out, &map().into(), &opts("status")).unwrap_err();
    assert!(
        err.to_string()
            .contains("message 1: channel `/reference`: field `status` is `\"ok\"`, not a number"),
        "{err}"
    );
    assert!(!out.exists());
}

/// `keep` (issue 31, `calib apply --keep`): a CSV keeps the channel's column as it was and gets
/// `a_corrected` right after it, header and rows, every other byte of each line as read.
#[test]
fn keep_adds_the_corrected_csv_column_beside_the_channel() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let readings = [0.0f64, 45.5, 123.25, 359.75];
    let mut text = String::from("t,a,b\n");
    for (i, x) in readings.iter().enumerate() {
        text += &format!("{i},{x:.6},{}\n", 7 + i);
    }
    std::fs::write(&log, &text).unwrap();
    let out = dir.path().join("out.csv");
    let o = ApplyOptions {
        keep: true,
        ..opts("a")
    };
    let done = apply(&log, &out, &map().into(), &o).unwrap();
    assert_eq!(done.readings, 4);
    assert_eq!(done.beside, ["a_corrected"]);
    let got = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = got.lines().collect();
    assert_eq!(lines[0], "t,a,a_corrected,b");
    for ((line, given), x) in lines[1..].iter().zip(text.lines().skip(1)).zip(readings) {
        let f: Vec<&str> = line.split(',').collect();
        let g: Vec<&str> = given.split(',').collect();
        // t, a and b exactly as given; a_corrected = a − e(a), in degrees, written with 7
        // decimals (0.001″ resolved): within half the last decimal.
        assert_eq!((f[0], f[1], f[3]), (g[0], g[1], g[2]), "{line}");
        let want = (x.to_radians() - error_at(x.to_radians())).to_degrees();
        let v: f64 = f[2].parse().unwrap();
        // Kept in [0, 360) as the readings are: compared modulo a turn.
        let off = (v - want).rem_euclid(360.0);
        assert!(off.min(360.0 - off) <= 0.5e-7, "{line}: want {want}");
    }
    // Read back, the two channels stand side by side.
    let (names, samples) = samples(&out);
    assert_eq!(names, ["a", "a_corrected", "b"]);
    assert_eq!(samples.len(), 4);
    // A header that has the column already is an error naming it; nothing is written.
    std::fs::write(&log, "t,a,a_corrected\n0,1,1\n").unwrap();
    let out2 = dir.path().join("out2.csv");
    let err = apply(&log, &out2, &map().into(), &o)
        .unwrap_err()
        .to_string();
    assert!(err.contains("`a_corrected` already"), "{err}");
    assert!(!out2.exists());
}

/// `keep` on an MCAP log: every original message is copied unchanged, and each message carrying
/// the channel is followed by a corrected copy on `<topic>/corrected` (same schema, times and
/// sequence), which calib reads as `/joint_states/corrected/a`.
#[test]
fn keep_copies_the_corrected_messages_onto_their_own_topic() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let o = ApplyOptions {
        keep: true,
        ..opts("a")
    };
    let done = apply(&fixture(), &out, &map().into(), &o).unwrap();
    assert_eq!(done.readings, 300);
    assert_eq!(done.beside, ["/joint_states/corrected"]);
    let (before, after) = (messages(&fixture()), messages(&out));
    assert_eq!(after.len(), before.len() + 300);
    let originals: Vec<_> = after.iter().filter(|m| m.0 != u16::MAX).cloned().collect();
    assert_eq!(
        originals, before,
        "the input's messages, unchanged and in order"
    );
    // Read back: the original and the corrected joint, at the same stamps.
    let reader = LogReader::open(&out, &ReadOptions::default()).unwrap();
    let names: Vec<String> = reader.names().iter().map(|n| n.qualified.clone()).collect();
    let raw = names.iter().position(|n| n == "/joint_states/a").unwrap();
    let fixed = names
        .iter()
        .position(|n| n == "/joint_states/corrected/a")
        .unwrap_or_else(|| panic!("{names:?}"));
    let mut reader = reader;
    reader.select(&[raw, fixed], Default::default());
    let mut n = 0;
    for s in reader {
        let s = s.unwrap();
        let (a, c) = (s.values[0], s.values[1]);
        // JointState positions are f64 radians: the correction exactly as computed.
        // Kept in [0, 2π) as the readings are: compared modulo a turn.
        let off = (c - (a - error_at(a))).rem_euclid(TAU);
        assert!(off.min(TAU - off) < 1e-12, "{a} {c}");
        n += 1;
    }
    assert_eq!(n, 300);
}

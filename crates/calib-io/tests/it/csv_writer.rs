//! CsvWriter: exact round trips through CsvReader, atomicity, and refusal of unreadable logs.

use crate::common;

use calib_core::{AngleUnit, Sample};
use calib_io::csv_log::{CsvReader, CsvWriter};
use calib_io::{Error, ReadOptions};
use common::channels;
use std::path::Path;

fn read(path: &Path, unit: AngleUnit) -> (Vec<String>, Vec<Sample>) {
    let r = CsvReader::open(
        path,
        &ReadOptions {
            unit: Some(unit),
            ..ReadOptions::default()
        },
    )
    .unwrap();
    let names = r.channels().iter().map(|c| c.name.clone()).collect();
    (names, r.collect::<Result<_, _>>().unwrap())
}

/// Samples with awkward numbers: non-terminating binary fractions, tiny and huge magnitudes,
/// wrapped and accumulated readings, sessions and gaps.
fn samples() -> Vec<Sample> {
    let mut state: u64 = 42;
    let mut rnd = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut t = 1.0e-3;
    (0..500)
        .map(|i| {
            t += 0.1 + 0.2 * rnd();
            Sample {
                t,
                values: vec![
                    rnd() * std::f64::consts::TAU,
                    (rnd() - 0.5) * 1e4,
                    if i % 7 == 0 { 1e-300 } else { -rnd() * 1e-9 },
                ],
                session: match i % 5 {
                    0 => None,
                    k => Some(k as u32 * 1_000_000),
                },
            }
        })
        .collect()
}

fn write_all(path: &Path, unit: AngleUnit, with_session: bool, samples: &[Sample]) {
    let mut w = CsvWriter::create(path, &channels(&["a", "b", "c"]), unit, with_session).unwrap();
    for s in samples {
        w.write(s).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn radians_round_trip_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rt.csv");
    let want = samples();
    write_all(&path, AngleUnit::Rad, true, &want);
    let (names, got) = read(&path, AngleUnit::Rad);
    assert_eq!(names, ["a", "b", "c"]);
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.t.to_bits(), w.t.to_bits());
        assert_eq!(g.session, w.session);
        for (x, y) in g.values.iter().zip(&w.values) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
    }
}

#[test]
fn other_units_round_trip_exactly_in_the_unit_and_to_an_ulp_in_radians() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rt.csv");
    let want = samples();
    for unit in [
        AngleUnit::Deg,
        AngleUnit::Arcsec,
        AngleUnit::Rev,
        AngleUnit::Counts(4096),
    ] {
        write_all(&path, unit, false, &want);
        // The text holds exactly the value in the unit: shortest round-trip formatting.
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("t,a,b,c\n"), "{text}");
        let first: Vec<f64> = text
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .map(|f| f.parse().unwrap())
            .collect();
        assert_eq!(first[0], want[0].t);
        assert_eq!(first[1], unit.from_rad(want[0].values[0]));
        // In radians, the conversion there and back costs at most a couple of ulps.
        let (_, got) = read(&path, unit);
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.t, w.t);
            assert_eq!(g.session, None);
            for (x, y) in g.values.iter().zip(&w.values) {
                assert!(
                    (x - y).abs() <= 4.0 * f64::EPSILON * y.abs(),
                    "{unit}: {x} vs {y}"
                );
            }
        }
    }
}

#[test]
fn degrees_by_default_format_and_quoted_names() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.csv");
    let mut w =
        CsvWriter::create(&path, &channels(&["x", "head, 2"]), AngleUnit::Deg, true).unwrap();
    w.write(&Sample {
        t: 0.0,
        values: vec![90f64.to_radians(), -std::f64::consts::PI],
        session: None,
    })
    .unwrap();
    w.write(&Sample {
        t: 0.001,
        values: vec![0.0, 1e-20],
        session: Some(7),
    })
    .unwrap();
    w.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let deg = 1e-20f64.to_degrees();
    assert_eq!(
        text,
        format!("t,x,\"head, 2\",session\n0.0,90.0,-180.0,-1\n0.001,0.0,{deg:e},7\n")
    );
    let (names, got) = read(&path, AngleUnit::Deg);
    assert_eq!(names, ["x", "head, 2"]);
    assert_eq!(got[1].session, Some(7));
}

#[test]
fn nothing_appears_before_finish_and_nothing_stays_without_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.csv");
    {
        let mut w = CsvWriter::create(&path, &channels(&["a"]), AngleUnit::Deg, false).unwrap();
        w.write(&Sample {
            t: 0.0,
            values: vec![1.0],
            session: None,
        })
        .unwrap();
        assert!(!path.exists());
    }
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[track_caller]
fn refused(path: &Path, err: Error, needle: &str) {
    let text = err.to_string();
    assert!(matches!(err, Error::Write { .. }), "{err:?}");
    assert!(text.contains(&path.display().to_string()), "{text}");
    assert!(text.contains(needle), "{text}");
}

#[test]
fn unreadable_logs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    let create = |names: &[&str]| CsvWriter::create(&path, &channels(names), AngleUnit::Deg, true);
    refused(&path, create(&[]).unwrap_err(), "no channels");
    refused(&path, create(&["a", "t"]).unwrap_err(), "reserved");
    refused(&path, create(&["session"]).unwrap_err(), "reserved");
    refused(&path, create(&["a", "a"]).unwrap_err(), "unique");
    refused(&path, create(&[" a"]).unwrap_err(), "whitespace");
    refused(&path, create(&[""]).unwrap_err(), "empty");

    let s = |t: f64, v: Vec<f64>| Sample {
        t,
        values: v,
        session: None,
    };
    let mut w = create(&["a", "b"]).unwrap();
    refused(
        &path,
        w.write(&s(0.0, vec![1.0])).unwrap_err(),
        "1 values for a log of 2 channels",
    );
    refused(
        &path,
        w.write(&s(f64::NAN, vec![1.0, 2.0])).unwrap_err(),
        "not finite",
    );
    refused(
        &path,
        w.write(&s(0.0, vec![1.0, f64::INFINITY])).unwrap_err(),
        "channel 2 is not finite",
    );
    w.write(&s(1.0, vec![1.0, 2.0])).unwrap();
    refused(
        &path,
        w.write(&s(1.0, vec![1.0, 2.0])).unwrap_err(),
        "sample for line 3: time 1 s is not after the previous sample's 1 s",
    );
    w.finish().unwrap();
    assert_eq!(read(&path, AngleUnit::Deg).1.len(), 1);

    let empty = dir.path().join("empty.csv");
    let w = CsvWriter::create(&empty, &channels(&["a"]), AngleUnit::Deg, false).unwrap();
    refused(&empty, w.finish().unwrap_err(), "no samples");
    assert!(!empty.exists());
}

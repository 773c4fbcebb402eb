//! CSV time stamps as loggers write them (issue 50 item 2, issue 52): rows recorded twice,
//! stamps since 1970 in a column that names no unit, sparse rows sharing a stamp, sparse rows
//! after the part of the file the dialect is found in, an empty column the command does not
//! read, and what a refusal names.

use calib_core::Sample;
use calib_io::csv_log::CsvReader;
use calib_io::{AlignOptions, LogReader, ReadOptions};
use std::path::{Path, PathBuf};

fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Every sample of `path` read with `LogReader`, `channels` selected (all if empty), and the
/// reader for its diagnostics.
fn read(path: &Path, channels: &[usize]) -> (Vec<Sample>, LogReader) {
    let mut reader = LogReader::open(path, &ReadOptions::default()).unwrap();
    if !channels.is_empty() {
        reader.select(channels, AlignOptions::default());
    }
    let samples = reader.by_ref().collect::<Result<Vec<_>, _>>().unwrap();
    (samples, reader)
}

/// Rows `t,a,b` at 100 Hz, `a` = 0.1·i°, `b` = −0.1·i°.
fn rows(n: usize) -> Vec<String> {
    (0..n)
        .map(|i| {
            format!(
                "{:.2},{:.1},{:.1}",
                i as f64 * 0.01,
                i as f64 * 0.1,
                -(i as f64) * 0.1
            )
        })
        .collect()
}

/// Rows repeated exactly are dropped and counted; the samples are those of the file without
/// them. Before: refused at the first copy ("repeats the previous row's … remove duplicate
/// rows").
#[test]
fn rows_repeated_exactly_are_dropped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let rows = rows(50);
    let doubled: Vec<&String> = rows
        .iter()
        .enumerate()
        .flat_map(|(i, r)| std::iter::repeat_n(r, 1 + usize::from(i % 5 == 2)))
        .collect();
    let text = |rows: &[&String]| {
        format!(
            "t,a,b\n{}\n",
            rows.iter()
                .map(|r| r.as_str())
                .collect::<Vec<_>>()
                .join("\n")
        )
    };
    let clean = write(&dir, "clean.csv", &text(&rows.iter().collect::<Vec<_>>()));
    let twice = write(&dir, "twice.csv", &text(&doubled));
    let mut reader = CsvReader::open(&twice, &ReadOptions::default()).unwrap();
    let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
    assert_eq!(samples, read(&clean, &[]).0);
    assert_eq!(reader.diagnostics().duplicates_dropped, 10);
}

/// A plain `timestamp` column of ms, µs or ns since 1970 is read in that unit, and the reader
/// says so; a unit the name gives, or the option, is kept. Before: refused ("time stamps must
/// be in seconds — convert milliseconds or nanoseconds").
#[test]
fn stamps_since_1970_are_read_in_the_unit_their_magnitude_says() {
    let dir = tempfile::tempdir().unwrap();
    // 2025-11-24 in each unit, 10 ms steps.
    for (unit, per_s, first) in [
        ("ms", 1e3, "1764000000000"),
        ("us", 1e6, "1764000000000000"),
        ("ns", 1e9, "1764000000000000000"),
    ] {
        let base: i64 = first.parse().unwrap();
        let body: String = (0..20)
            .map(|i| format!("{},{}\n", base + (i as f64 * 0.01 * per_s) as i64, i))
            .collect();
        let path = write(
            &dir,
            &format!("{unit}.csv"),
            &format!("timestamp,a\n{body}"),
        );
        let mut reader = CsvReader::open(&path, &ReadOptions::default()).unwrap();
        let samples: Vec<Sample> = reader.by_ref().collect::<Result<_, _>>().unwrap();
        // Times from 1764000000 s (or from the first row's for ns): steps of 10 ms.
        let step = samples[1].t - samples[0].t;
        assert!((step - 0.01).abs() < 1e-9, "{unit}: step {step}");
        let choice = reader.diagnostics().time_unit.clone().expect(unit);
        assert_eq!(
            (choice.column.as_str(), choice.unit.as_str()),
            ("timestamp", unit)
        );
        assert!(
            choice
                .reason
                .contains(&format!("its first stamp, {first}, is a date in 2025")),
            "{}",
            choice.reason
        );
    }
    // Seconds since 1970 and times from the start: nothing to choose.
    for body in ["1764000000.5,1\n1764000000.51,2\n", "0,1\n0.01,2\n"] {
        let path = write(&dir, "s.csv", &format!("timestamp,a\n{body}"));
        let mut reader = CsvReader::open(&path, &ReadOptions::default()).unwrap();
        reader.by_ref().for_each(drop);
        assert_eq!(reader.diagnostics().time_unit, None, "{body}");
    }
    // The name says seconds: refused, naming the unit the magnitude says and the option.
    let path = write(&dir, "named.csv", "time [s],a\n1764000000000000000,1\n");
    let err = CsvReader::open(&path, &ReadOptions::default())
        .unwrap()
        .next()
        .unwrap()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(
            "in nanoseconds, the column `time [s]`'s stamps are dates in 2025: say `time_unit = ns`"
        ),
        "{err}"
    );
}

/// `Zeit [s]` (LabVIEW in German), `temps (ms)`, `時間` are time columns.
#[test]
fn time_columns_in_other_languages_are_found() {
    let dir = tempfile::tempdir().unwrap();
    for (name, scale) in [
        ("Zeit [s]", 1.0),
        ("temps (ms)", 1e-3),
        ("時間", 1.0),
        ("czas_us", 1e-6),
    ] {
        let path = write(&dir, "lang.csv", &format!("{name};a;b\n0;1;2\n5;1,5;2,5\n"));
        let samples = read(&path, &[]).0;
        assert_eq!(samples.len(), 2, "{name}");
        assert_eq!(samples[1].t, 5.0 * scale, "{name}");
    }
}

/// A sparse file (each row one channel's sample, PlotJuggler's export) in which two channels
/// share a stamp on rows of their own: both samples are read. Before: "repeats the previous
/// row's … remove duplicate rows", whose removal deletes data. A channel's own sample repeated
/// exactly is dropped; one repeated with another reading is refused naming the channel.
#[test]
fn sparse_rows_of_two_channels_may_share_a_stamp() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("t,a,b\n");
    for i in 0..40 {
        let t = i as f64 * 0.01;
        text.push_str(&format!("{t:.2},{},\n{t:.2},,{}\n", i, 2 * i));
    }
    let path = write(&dir, "sparse.csv", &text);
    let (samples, reader) = read(&path, &[0, 1]);
    assert_eq!(samples.len(), 40);
    for (i, s) in samples.iter().enumerate() {
        assert!((s.values[0].to_degrees() - i as f64).abs() < 1e-9);
        assert!((s.values[1].to_degrees() - 2.0 * i as f64).abs() < 1e-9);
    }
    assert_eq!(reader.diagnostics().duplicates_dropped, 0);
    // Channel `b`'s row at 0.05 s twice: the copy dropped.
    let copy = text.replacen("0.05,,10\n", "0.05,,10\n0.05,,10\n", 1);
    let path = write(&dir, "copy.csv", &copy);
    let (samples, reader) = read(&path, &[0, 1]);
    assert_eq!(samples.len(), 40);
    assert_eq!(reader.diagnostics().duplicates_dropped, 1);
    let conflict = text.replacen("0.05,,10\n", "0.05,,10\n0.05,,11\n", 1);
    let path = write(&dir, "conflict.csv", &conflict);
    let err = LogReader::open(&path, &ReadOptions::default())
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("line 14")
            && err.contains("repeats channel `b`'s previous sample's 0.05 s (line 13)")
            && err.contains("`b` 10 there, 11 here"),
        "{err}"
    );
}

/// Full rows for more than the 64 KiB the dialect is found in, then sparse ones: read, the
/// sparse part aligned, and a warning naming the line it starts at. Before: "`` is not a
/// number" at the first empty cell.
#[test]
fn sparse_rows_after_the_first_64_kib_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let full = rows(4000);
    let mut text = format!("t,a,b\n{}\n", full.join("\n"));
    assert!(text.len() > 64 * 1024);
    for i in 4000..4100 {
        let t = i as f64 * 0.01;
        text.push_str(&format!(
            "{t:.2},{:.1},\n{:.3},,{:.1}\n",
            i as f64 * 0.1,
            t + 0.005,
            -(i as f64) * 0.1
        ));
    }
    let path = write(&dir, "late.csv", &text);
    let (samples, reader) = read(&path, &[0, 1]);
    // The 4000 full rows and about all 100 of `a`'s sparse ones (`b` interpolated half a step
    // away; the first of them may lack `b` before it).
    assert!((4098..=4100).contains(&samples.len()), "{}", samples.len());
    let last = samples.last().unwrap();
    assert!(
        (last.values[0].to_degrees() - 409.8).abs() < 0.2,
        "{last:?}"
    );
    assert!(
        (last.values[1].to_degrees() + last.values[0].to_degrees()).abs() < 0.1,
        "{last:?}"
    );
    let warnings = reader.warnings(&path);
    assert!(
        warnings.iter().any(|w| w.contains("from line 4002 on")),
        "{warnings:?}"
    );
}

/// An empty column the command does not read (a `notes` column left blank) does not refuse the
/// file. Before: "`` is not a number" at its first cell.
#[test]
fn an_empty_column_not_read_is_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let body: String = rows(30).iter().map(|r| format!("{r},\n")).collect();
    let path = write(&dir, "notes.csv", &format!("t,a,b,notes\n{body}"));
    let (samples, _) = read(&path, &[0, 1]);
    assert_eq!(samples.len(), 30);
    assert!(
        samples
            .iter()
            .all(|s| s.values.iter().all(|v| v.is_finite()))
    );
}

/// A FILETIME column out of order is to be sorted by its own name. Before: "sort the log by
/// `t`", a column the file does not have.
#[test]
fn a_step_back_names_the_time_column_to_sort_by() {
    let dir = tempfile::tempdir().unwrap();
    let text = "Name;Scope;\r\n\r\nName;pos;vel\r\nData-Type;REAL64;REAL64\r\nSampleTime;10;10\r\n\
        Unit;deg;deg/s\r\n\r\n132900081483350000;0;0\r\n132900081483250000;0,1;0\r\n";
    let path = write(&dir, "scope.csv", text);
    let err = LogReader::open(&path, &ReadOptions::default())
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap_err()
        .to_string();
    assert!(err.contains("sort the log by `FILETIME`"), "{err}");
}

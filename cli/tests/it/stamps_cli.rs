//! Time stamps as recorders write them (issue 50 item 2, issue 52): messages recorded twice,
//! stamps since 1970 in a plain `timestamp` column, time columns named in other languages.
//!
//! Each log is the quick scenario simulated, then edited as the recorder would have written it;
//! the maps of the edited log are compared with those of the clean one.

use crate::common::{calib, expect_exit, read_table, s, simulate, stderr, stdout, testdata};
use std::borrow::Cow;
use std::path::{Path, PathBuf};

/// Every 4th message of the first 1600 written twice (400 copies), every 13th message of the
/// rest left out up to 120 times (120 short gaps of two sample periods, 10 ms at 200 Hz).
fn edit_messages<T: Clone>(messages: &[T]) -> (Vec<T>, Vec<T>) {
    let mut clean = Vec::new();
    let mut doubled = Vec::new();
    let mut gaps = 0;
    for (i, m) in messages.iter().enumerate() {
        if i >= 1600 && i % 13 == 0 && gaps < 120 {
            gaps += 1;
            continue;
        }
        clean.push(m.clone());
        doubled.push(m.clone());
        if i < 1600 && i % 4 == 0 {
            doubled.push(m.clone());
        }
    }
    assert_eq!(gaps, 120);
    assert_eq!(doubled.len() - clean.len(), 400);
    (clean, doubled)
}

/// Writes `messages` as an MCAP file at `path` with the `mcap` crate.
fn write_mcap(path: &Path, messages: &[mcap::Message<'static>]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut writer = mcap::Writer::new(file).unwrap();
    for m in messages {
        writer.write(m).unwrap();
    }
    writer.finish().unwrap();
}

/// `calib csrr LOG -o OUT` (sessions from the marks); asserts success and returns what it
/// printed (its summary, whose `warning:` lines are the report's warnings).
fn csrr(log: &Path, out: &Path) -> String {
    let o = calib(&["csrr", s(log), "-o", s(out)]);
    expect_exit(&o, 0);
    stdout(&o)
}

/// The largest difference between two tables' errors, arcsec, asserting the same grid.
fn max_difference(a: &Path, b: &Path) -> f64 {
    let (a, b) = (read_table(a), read_table(b));
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(&b)
        .map(|(x, y)| {
            assert_eq!(x.0, y.0);
            (x.1 - y.1).abs()
        })
        .fold(0.0, f64::max)
}

/// The largest difference between a map and the truth's, arcsec, after removing their mean
/// difference (a map is known up to a constant).
fn against_truth(map: &Path, truth: &Path) -> f64 {
    let (m, t) = (read_table(map), read_table(truth));
    assert_eq!(m.len(), t.len());
    let mean = m.iter().zip(&t).map(|(a, b)| a.1 - b.1).sum::<f64>() / m.len() as f64;
    m.iter()
        .zip(&t)
        .map(|(a, b)| (a.1 - b.1 - mean).abs())
        .fold(0.0, f64::max)
}

fn report(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

/// The quick example with 400 duplicated messages and 120 short gaps: before, refused ("a
/// channel's stamps must strictly increase … remove the duplicate messages"); now the copies
/// are dropped with a warning naming their count and the file, `details.reading` counts them,
/// and the maps are those of the log without the copies — the same samples, so the same bytes
/// (tolerance 0). Against the scenario's truth both are within 0.3″ (the simulator's noise and
/// quantisation, 0.05″ and 0.09″, and the sessions' coverage).
#[test]
fn mcap_messages_recorded_twice_are_dropped_and_the_maps_are_the_clean_logs() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "quick.mcap");
    let bytes = std::fs::read(&log).unwrap();
    let messages: Vec<mcap::Message<'static>> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            mcap::Message {
                data: Cow::Owned(m.data.into_owned()),
                ..m
            }
        })
        .collect();
    let (clean, doubled) = edit_messages(&messages);
    let (clean_log, doubled_log) = (dir.path().join("clean.mcap"), dir.path().join("twice.mcap"));
    write_mcap(&clean_log, &clean);
    write_mcap(&doubled_log, &doubled);
    let (clean_out, doubled_out) = (dir.path().join("clean"), dir.path().join("twice"));
    let clean_printed = csrr(&clean_log, &clean_out);
    assert!(!clean_printed.contains("duplicated"), "{clean_printed}");
    let printed = csrr(&doubled_log, &doubled_out);
    assert!(
        printed.contains("twice.mcap: 400 duplicated message(s) dropped"),
        "{printed}"
    );
    assert_eq!(
        report(&doubled_out)["details"]["reading"]["duplicates_dropped"],
        400
    );
    assert!(report(&clean_out)["details"].get("reading").is_none());
    for channel in ["a", "b"] {
        let table = |out: &PathBuf| out.join(format!("{channel}.csv"));
        assert_eq!(
            std::fs::read(table(&clean_out)).unwrap(),
            std::fs::read(table(&doubled_out)).unwrap(),
            "{channel}"
        );
        let truth = testdata(&format!("examples/quick.truth/{channel}.csv"));
        let off = against_truth(&table(&doubled_out), &truth);
        eprintln!("map {channel} of the log with 400 copies vs truth: {off:.3}″ max");
        assert!(off < 0.3, "{channel}: {off}″ from the truth");
    }
}

/// The simulated quick CSV: its header and its rows.
fn quick_csv(dir: &Path) -> (String, Vec<String>) {
    let log = simulate(&testdata("scenarios/quick.toml"), dir, "quick.csv");
    let text = std::fs::read_to_string(log).unwrap();
    let mut lines = text.lines().map(str::to_string);
    let header = lines.next().unwrap();
    (header, lines.collect())
}

fn write_csv(path: &Path, header: &str, rows: &[String]) {
    std::fs::write(path, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
}

/// The same 400 copies and 120 gaps as rows of the CSV: the copies dropped and counted, the
/// maps those of the clean file byte for byte; a copy whose reading differs (the same stamp,
/// another angle) is refused naming both lines and both readings.
#[test]
fn csv_rows_recorded_twice_are_dropped_and_a_conflict_names_both_rows() {
    let dir = tempfile::tempdir().unwrap();
    let (header, rows) = quick_csv(dir.path());
    let (clean, doubled) = edit_messages(&rows);
    let (clean_log, doubled_log) = (dir.path().join("clean.csv"), dir.path().join("twice.csv"));
    write_csv(&clean_log, &header, &clean);
    write_csv(&doubled_log, &header, &doubled);
    let (clean_out, doubled_out) = (dir.path().join("clean"), dir.path().join("twice"));
    csrr(&clean_log, &clean_out);
    let printed = csrr(&doubled_log, &doubled_out);
    assert!(
        printed.contains("twice.csv: 400 duplicated row(s) dropped"),
        "{printed}"
    );
    assert!(
        report(&doubled_out)["warnings"][0]
            .as_str()
            .unwrap()
            .contains("400 duplicated row(s) dropped")
    );
    assert_eq!(
        report(&doubled_out)["details"]["reading"]["duplicates_dropped"],
        400
    );
    for channel in ["a.csv", "b.csv"] {
        assert_eq!(
            std::fs::read(clean_out.join(channel)).unwrap(),
            std::fs::read(doubled_out.join(channel)).unwrap(),
            "{channel}"
        );
    }
    // Row 11 (line 12) again on line 13, its `a` reading changed.
    let mut conflict = clean.clone();
    let copy = conflict[10].clone();
    let (t, rest) = copy.split_once(',').unwrap();
    let (a, rest) = rest.split_once(',').unwrap();
    // The reading changed by 0.5°.
    let other = format!("{t},{},{rest}", a.parse::<f64>().unwrap() + 0.5);
    conflict.insert(11, other);
    let conflict_log = dir.path().join("conflict.csv");
    write_csv(&conflict_log, &header, &conflict);
    let o = calib(&["csrr", s(&conflict_log), "-o", s(&dir.path().join("c"))]);
    let err = stderr(&o);
    assert_ne!(o.status.code(), Some(0), "{err}");
    let t = t.parse::<f64>().unwrap();
    assert!(
        err.contains("line 13")
            && err.contains(&format!("repeats the previous row's {t} s (line 12)"))
            && err.contains("with other readings (`a` ")
            && err.contains(" there, "),
        "{err}"
    );
}

/// A plain `timestamp` column of nanoseconds since 1970 (as ROS, pandas and most loggers write
/// them): before, refused ("time stamps must be in seconds — convert milliseconds or
/// nanoseconds"); now read in ns, said in `details.reading.time_unit` and by `inspect`, and
/// the maps are those of the file in seconds within 0.001″ (the stamps are the same to the
/// nanosecond; the difference is the doubles' rounding of times counted from another origin).
/// `--time-unit s` still overrides, and its refusal names the option.
#[test]
fn nanoseconds_since_1970_in_a_plain_timestamp_column_are_read_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let (header, rows) = quick_csv(dir.path());
    const T0_NS: i64 = 1_764_000_000_000_000_000;
    let ns_rows: Vec<String> = rows
        .iter()
        .map(|r| {
            let (t, rest) = r.split_once(',').unwrap();
            let ns = T0_NS + (t.parse::<f64>().unwrap() * 1e9).round() as i64;
            format!("{ns},{rest}")
        })
        .collect();
    let seconds_log = dir.path().join("seconds.csv");
    write_csv(&seconds_log, &header, &rows);
    let ns_log = dir.path().join("epoch.csv");
    write_csv(&ns_log, &header.replacen('t', "timestamp", 1), &ns_rows);
    let (seconds_out, ns_out) = (dir.path().join("s"), dir.path().join("ns"));
    csrr(&seconds_log, &seconds_out);
    csrr(&ns_log, &ns_out);
    let choice = &report(&ns_out)["details"]["reading"]["time_unit"];
    assert_eq!(choice["unit"], "ns", "{choice}");
    assert_eq!(choice["column"], "timestamp", "{choice}");
    assert!(
        choice["reason"]
            .as_str()
            .unwrap()
            .contains("is a date in 2025 counted in nanoseconds since 1970"),
        "{choice}"
    );
    for channel in ["a.csv", "b.csv"] {
        let d = max_difference(&seconds_out.join(channel), &ns_out.join(channel));
        assert!(d < 1e-3, "{channel}: {d}″");
    }
    let o = calib(&["inspect", s(&ns_log)]);
    let text = stdout(&o);
    assert!(
        text.contains("  time: column `timestamp` read in ns: the column names no unit"),
        "{text}"
    );
    // Told seconds: refused, naming the option and the unit that reads it.
    let o = calib(&[
        "csrr",
        s(&ns_log),
        "-o",
        s(&dir.path().join("x")),
        "--time-unit",
        "s",
    ]);
    let err = stderr(&o);
    assert!(
        err.contains("say `--time-unit ns`") && !err.contains("convert milliseconds"),
        "{err}"
    );
}

/// A German LabVIEW export's `Zeit [s]` is the time column; a header whose time column calib
/// does not take by itself (`Timestamp (UTC)`) is refused naming the option that reads it.
#[test]
fn a_time_column_in_another_language_is_found_and_a_likely_one_named() {
    let dir = tempfile::tempdir().unwrap();
    let (header, rows) = quick_csv(dir.path());
    let german = dir.path().join("zeit.csv");
    write_csv(&german, &header.replacen('t', "Zeit [s]", 1), &rows);
    let plain = dir.path().join("plain.csv");
    write_csv(&plain, &header, &rows);
    let (german_out, plain_out) = (dir.path().join("de"), dir.path().join("plain"));
    csrr(&german, &german_out);
    csrr(&plain, &plain_out);
    for channel in ["a.csv", "b.csv"] {
        assert_eq!(
            std::fs::read(german_out.join(channel)).unwrap(),
            std::fs::read(plain_out.join(channel)).unwrap()
        );
    }
    let utc = dir.path().join("utc.csv");
    write_csv(&utc, &header.replacen('t', "Timestamp (UTC)", 1), &rows);
    let o = calib(&["csrr", s(&utc), "-o", s(&dir.path().join("u"))]);
    let err = stderr(&o);
    assert_ne!(o.status.code(), Some(0));
    assert!(
        err.contains("column `Timestamp (UTC)` looks like one: read it with `--time-column 'Timestamp (UTC)'`"),
        "{err}"
    );
    let o = calib(&[
        "csrr",
        s(&utc),
        "-o",
        s(&dir.path().join("u")),
        "--time-column",
        "Timestamp (UTC)",
    ]);
    expect_exit(&o, 0);
}

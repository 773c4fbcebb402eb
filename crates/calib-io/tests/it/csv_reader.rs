//! CsvReader: what it accepts, and an error naming file, line and column for each bad input.

use calib_core::{AngleUnit, Sample};
use calib_io::csv_log::CsvReader;
use calib_io::{Error, ReadOptions};
use std::f64::consts::{PI, TAU};
use std::path::{Path, PathBuf};

fn write_tmp(dir: &tempfile::TempDir, content: &[u8]) -> PathBuf {
    let path = dir.path().join("log.csv");
    std::fs::write(&path, content).unwrap();
    path
}

fn read_with(path: &Path, unit: Option<AngleUnit>) -> Result<Vec<Sample>, Error> {
    CsvReader::open(
        path,
        &ReadOptions {
            unit,
            ..ReadOptions::default()
        },
    )?
    .collect()
}

fn read_str(content: &str) -> Result<Vec<Sample>, Error> {
    let dir = tempfile::tempdir().unwrap();
    read_with(&write_tmp(&dir, content.as_bytes()), None)
}

/// The error for `content`, checked to name the file and the given line (and column, if any);
/// returns its message for further checks.
#[track_caller]
fn error_of(content: impl AsRef<[u8]>, line: u64, column: Option<&str>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, content.as_ref());
    let err = read_with(&path, None).unwrap_err();
    let text = err.to_string();
    match &err {
        Error::Csv {
            path: p,
            line: l,
            channel,
            ..
        } => {
            assert_eq!(p, &path, "{text}");
            assert_eq!(*l, line, "{text}");
            assert_eq!(channel.as_deref(), column, "{text}");
        }
        other => panic!("expected a CSV error, got {other:?}"),
    }
    assert!(text.starts_with(&path.display().to_string()), "{text}");
    assert!(text.contains(&format!("line {line}")), "{text}");
    if let Some(c) = column {
        assert!(text.contains(&format!("column `{c}`")), "{text}");
    }
    text
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-15 * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn committed_fixture_reads_with_sessions_and_wrapped_readings_as_is() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../testdata/csv/small.csv");
    let reader = CsvReader::open(&path, &ReadOptions::default()).unwrap();
    let names: Vec<&str> = reader.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["a", "b"]);
    assert!(reader.channels().iter().all(|c| c.unit == AngleUnit::Deg));
    assert_eq!(reader.diagnostics(), &calib_io::ReadDiagnostics::default());
    let samples: Vec<Sample> = reader.collect::<Result<_, _>>().unwrap();
    assert_eq!(samples.len(), 4);
    let ts: Vec<f64> = samples.iter().map(|s| s.t).collect();
    assert_eq!(ts, [0.0, 0.1, 0.2, 0.3]);
    let sessions: Vec<Option<u32>> = samples.iter().map(|s| s.session).collect();
    assert_eq!(sessions, [Some(0), Some(0), Some(0), None]);
    // The wrap from 359.9° to 0.3° is left for the core's Unwrapper.
    let a: Vec<f64> = samples.iter().map(|s| s.values[0].to_degrees()).collect();
    for (got, want) in a.iter().zip([359.5, 359.9, 0.3, 0.7]) {
        assert!((got - want).abs() < 1e-12, "{a:?}");
    }
}

#[test]
fn accumulated_readings_pass_through() {
    let s = read_str("t,a\n0,719.5\n1,720.5\n2,-1000\n").unwrap();
    let a: Vec<f64> = s.iter().map(|s| s.values[0]).collect();
    assert!(close(a[0], 719.5_f64.to_radians()));
    assert!(close(a[1], 720.5_f64.to_radians()));
    assert!(close(a[2], (-1000.0_f64).to_radians()));
}

#[test]
fn every_unit_converts_to_radians() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, f64); 6] = [
        ("deg", "90", PI / 2.0),
        ("rad", "1.25", 1.25),
        ("arcsec", "3600", 1.0_f64.to_radians()),
        ("rev", "0.25", PI / 2.0),
        ("counts:4096", "1024", PI / 2.0),
        ("counts:1000", "-250", -TAU / 4.0),
    ];
    for (unit, text, want) in cases {
        let unit: AngleUnit = unit.parse().unwrap();
        let path = write_tmp(&dir, format!("t,x\n0,{text}\n").as_bytes());
        let reader = CsvReader::open(
            &path,
            &ReadOptions {
                unit: Some(unit),
                ..ReadOptions::default()
            },
        )
        .unwrap();
        assert_eq!(reader.channels()[0].unit, unit);
        let s: Vec<Sample> = reader.collect::<Result<_, _>>().unwrap();
        assert!(
            close(s[0].values[0], want),
            "{unit}: {} vs {want}",
            s[0].values[0]
        );
    }
}

#[test]
fn bom_whitespace_blank_lines_and_any_column_order() {
    let s = read_str("\u{feff}b , session,\tt \r\n 2.5 , 3 , 0.5\r\n\r\n1e1,-7,1.5\n").unwrap();
    assert_eq!(s.len(), 2);
    assert_eq!(s[0].t, 0.5);
    assert_eq!(s[0].session, Some(3));
    assert!(close(s[0].values[0], 2.5_f64.to_radians()));
    assert_eq!(s[1].t, 1.5);
    assert_eq!(s[1].session, None);
    assert!(close(s[1].values[0], 10.0_f64.to_radians()));
}

#[test]
fn quoted_names_and_fields_are_plain_csv() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, b"t,\"head, 1\"\n0,\"1.5\"\n");
    let r = CsvReader::open(&path, &ReadOptions::default()).unwrap();
    assert_eq!(r.channels()[0].name, "head, 1");
    assert_eq!(r.count(), 1);
}

#[test]
fn missing_file_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nope.csv");
    let err = CsvReader::open(&path, &ReadOptions::default()).unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("nope.csv"), "{err}");
}

#[test]
fn empty_files_and_bad_headers() {
    let m = error_of("", 1, None);
    assert!(m.contains("the file is empty"), "{m}");
    let m = error_of("\u{feff}", 1, None);
    assert!(m.contains("empty"), "{m}");
    let m = error_of("t,a\n", 2, None);
    assert!(m.contains("no data rows"), "{m}");
    let m = error_of("clock,a\n0,1\n", 1, None);
    assert!(m.contains("no time column (it has: clock, a)"), "{m}");
    assert!(m.contains("the `time_column` option"), "{m}");
    let m = error_of("t,session\n0,1\n", 1, None);
    assert!(m.contains("no channel columns"), "{m}");
    let m = error_of("t,a,b,a\n0,1,2,3\n", 1, Some("a"));
    assert!(m.contains("columns 2 and 4 are both named `a`"), "{m}");
    let m = error_of("t,,b\n0,1,2\n", 1, None);
    assert!(m.contains("header column 2 has no name"), "{m}");
    let m = error_of(b"t,a\xff\n", 1, None);
    assert!(m.contains("not valid UTF-8"), "{m}");
}

#[test]
fn rows_with_the_wrong_number_of_fields() {
    let m = error_of("t,a,b\n0,1,2\n1,2\n", 3, None);
    assert!(
        m.contains("the row has 2 fields but the header has 3 columns (t, a, b)"),
        "{m}"
    );
    let m = error_of("t,a\n0,1,2\n", 2, None);
    assert!(m.contains("3 fields"), "{m}");
}

#[test]
fn text_in_numbers() {
    let m = error_of("t,a,b\n0,1,2\n1,2,abc\n", 3, Some("b"));
    assert!(m.contains("`abc` is not a number"), "{m}");
    let m = error_of("t,a\n0,1\n1s,2\n", 3, Some("t"));
    assert!(m.contains("`1s` is not a number"), "{m}");
    let m = error_of("t,a\n0, \n", 2, Some("a"));
    assert!(m.contains("the field is empty"), "{m}");
    // Issue 33: a decimal comma is named as one.
    let m = error_of("t,a\n0,\"1,5\"\n", 2, Some("a"));
    assert!(m.contains("`1,5` is written with a decimal comma"), "{m}");
}

#[test]
fn non_finite_readings_and_times() {
    for bad in ["NaN", "inf", "-inf", "infinity"] {
        let m = error_of(format!("t,a\n0,1\n1,{bad}\n"), 3, Some("a"));
        assert!(
            m.contains(&format!("reading `{bad}` is not a finite number")),
            "{m}"
        );
        let m = error_of(format!("t,a\n{bad},1\n"), 2, Some("t"));
        assert!(
            m.contains(&format!("time `{bad}` is not a finite number")),
            "{m}"
        );
    }
}

#[test]
fn time_must_strictly_increase() {
    let m = error_of("t,a\n0,1\n1.5,2\n1.25,3\n", 4, Some("t"));
    assert!(
        m.contains("time stamp 1.25 s goes back before the previous row's 1.5 s (line 3)"),
        "{m}"
    );
    let m = error_of("t,a\n0,1\n2,2\n\n2,3\n", 5, Some("t"));
    assert!(
        m.contains("time stamp 2 s repeats the previous row's 2 s (line 3)"),
        "{m}"
    );
}

#[test]
fn line_numbers_count_blank_lines_and_crlf() {
    let m = error_of("t,a\r\n0,1\r\n\r\n\r\n0,3\r\n", 5, Some("t"));
    assert!(m.contains("previous row's 0 s (line 2)"), "{m}");
    error_of("\n\nt,a\n\n0,x\n", 5, Some("a"));
    error_of("t,a\n0,\"multi\nline\"\n", 2, Some("a"));
    error_of("t,\"a\nb\"\n0,1\n1,x\n", 4, Some("a\nb"));
}

#[test]
fn sessions_must_be_integers() {
    for bad in ["1.5", "x", "", "1e3"] {
        let m = error_of(format!("t,a,session\n0,1,{bad}\n"), 2, Some("session"));
        assert!(m.contains("is not an integer"), "{bad}: {m}");
    }
    let m = error_of("t,a,session\n0,1,4294967296\n", 2, Some("session"));
    assert!(m.contains("too large"), "{m}");
    let s = read_str("t,a,session\n0,1,4294967295\n1,1,-4294967296\n").unwrap();
    assert_eq!(s[0].session, Some(u32::MAX));
    assert_eq!(s[1].session, None);
}

#[test]
fn the_stream_ends_after_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, b"t,a\n0,1\n1,x\n2,3\n3,4\n");
    let mut r = CsvReader::open(&path, &ReadOptions::default()).unwrap();
    assert!(r.next().unwrap().is_ok());
    assert!(r.next().unwrap().is_err());
    assert!(r.next().is_none());
    assert!(r.next().is_none());
}

#[test]
fn arbitrary_bytes_never_panic() {
    // A cheap fuzz: deterministic pseudo-random mutations of a valid log.
    let base = b"\xEF\xBB\xBFt,a,session\n0,1.5,0\n0.5,2e1,1\n1,-3,-1\n".to_vec();
    let alphabet = b"t,a\n\r\" .e-+0123456789xN\xff";
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let dir = tempfile::tempdir().unwrap();
    for _ in 0..600 {
        let mut bytes = base.clone();
        for _ in 0..(next() % 4 + 1) {
            let pos = (next() % bytes.len() as u64) as usize;
            let c = alphabet[(next() % alphabet.len() as u64) as usize];
            match next() % 3 {
                0 => bytes[pos] = c,
                1 => bytes.insert(pos, c),
                _ => {
                    bytes.remove(pos);
                }
            }
        }
        let path = write_tmp(&dir, &bytes);
        if let Ok(r) = CsvReader::open(&path, &ReadOptions::default()) {
            // A sparse file's empty cells are NaN (no sample), never another non-finite value.
            let sparse = r.is_sparse();
            for s in r.flatten() {
                assert!(
                    s.t.is_finite()
                        && s.values
                            .iter()
                            .all(|v| v.is_finite() || (sparse && v.is_nan()))
                );
            }
        }
    }
}

#[test]
fn extreme_readings_and_times_are_errors_not_numbers() {
    // 1e12 degrees is 2.8e9 revolutions: beyond what an f64 holds to 0.002″.
    let m = error_of("t,a\n0,1\n1,1e12\n", 3, Some("a"));
    assert!(m.contains("revolutions from zero"), "{m}");
    // A billion revolutions, unwrapped.
    let m = error_of("t,a\n0,360000000000\n", 2, Some("a"));
    assert!(m.contains("revolutions from zero"), "{m}");
    // Nanoseconds in a column its name says is in seconds (a column that names no unit is read
    // in the unit its magnitude says: `csv_stamps`).
    let m = error_of("t [s],a\n1700000000000000000,1\n", 2, Some("t [s]"));
    assert!(m.contains("nanoseconds"), "{m}");
    let m = error_of("t,a\n-9.2e18,1\n", 2, Some("t"));
    assert!(m.contains("beyond"), "{m}");
    // Ten million revolutions and the year 2286 still pass.
    let samples = read_str("t,a\n9999999999,3600000000\n").unwrap();
    assert_eq!(samples[0].values, [3.6e9_f64.to_radians()]);
}

#[test]
fn finite_readings_that_overflow_in_radians_are_errors() {
    // 1e308 revolutions is a finite number whose conversion to radians is not.
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, b"t,a\n0,1e308\n");
    let err = read_with(&path, Some(AngleUnit::Rev)).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("revolutions from zero"), "{text}");
    assert!(text.contains("line 2"), "{text}");
}

#[test]
fn lab_dialects_semicolons_metadata_and_time_units() {
    let dir = tempfile::tempdir().unwrap();
    // Two metadata lines and a blank one, `;` separators, the time in milliseconds.
    let path = write_tmp(
        &dir,
        b"Instrument;Scope 3000\nRate;1 kHz\n\nTime [ms];a;b\n0;1;2\n1.5;3;4\n",
    );
    let r = CsvReader::open(&path, &ReadOptions::default()).unwrap();
    let names: Vec<&str> = r.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["a", "b"]);
    let s: Vec<_> = r.collect::<Result<_, _>>().unwrap();
    assert!((s[1].t - 1.5e-3).abs() < 1e-18);
    assert!(close(s[1].values[1], 4.0_f64.to_radians()));
    // Tabs, a `timestamp` column in microseconds by --time-unit.
    let path = write_tmp(&dir, b"a\ttimestamp\n1\t10\n2\t20\n");
    let opts = ReadOptions {
        time_unit: Some(calib_io::csv_log::dialect::TimeUnit::Us),
        ..ReadOptions::default()
    };
    let s: Vec<_> = CsvReader::open(&path, &opts)
        .unwrap()
        .collect::<Result<_, _>>()
        .unwrap();
    assert!((s[1].t - 20e-6).abs() < 1e-20);
    // A column named by --time-column; errors name the file's own line (metadata counted).
    let path = write_tmp(&dir, b"# exported\nstamp;a\n0;1\n1;x\n");
    let opts = ReadOptions {
        time_column: Some("stamp".into()),
        ..ReadOptions::default()
    };
    let err = CsvReader::open(&path, &opts)
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap_err()
        .to_string();
    assert!(err.contains("line 4, column `a`"), "{err}");
}

/// Seconds since 1970 with nine decimals (a Python `time.time()` log, a LabVIEW export): a
/// double of ~1.7·10⁹ s keeps steps of 2.4·10⁻⁷ s only, so the reader counts every stamp's
/// whole part from the first row's in integers and adds its fraction: each keeps its
/// nanoseconds, and the origin is the stamp's second, given back for reports.
#[test]
fn decimal_seconds_since_1970_keep_their_nanoseconds() {
    let mut text = String::from("t,a\n");
    let ns = |i: u64| 123_456_789 + i * 1_000_001;
    for i in 0..2000 {
        let t = ns(i);
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!(
                "{}.{:09},0.5\n",
                1_700_000_000 + t / 1_000_000_000,
                t % 1_000_000_000
            ),
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, text.as_bytes());
    let mut reader = CsvReader::open(&path, &ReadOptions::default()).unwrap();
    let samples: Vec<Sample> = (&mut reader).collect::<Result<_, _>>().unwrap();
    assert_eq!(samples.len(), 2000);
    assert_eq!(reader.time_origin_s(), 1_700_000_000.0);
    for (i, s) in samples.iter().enumerate() {
        // Within a double's rounding of a number below 3 s (4.4·10⁻¹⁶ s), not 2.4·10⁻⁷ s.
        let want = ns(i as u64) as f64 * 1e-9;
        assert!(
            (s.t - want).abs() < 1e-15,
            "row {i}: {} against {want}",
            s.t
        );
    }
    // Stamps a step of one nanosecond apart still increase; their error names them on the
    // file's clock.
    let m = error_of(
        "t,a\n1700000000.000000001,0\n1700000000.000000002,0\n1700000000.000000002,1\n",
        4,
        Some("t"),
    );
    assert!(m.contains("1700000000.000000002 s repeats"), "{m}");
}

/// A stamp with a decimal comma, a sign, or in milliseconds since 1970 keeps its digits as
/// well; stamps below 2²¹ s (24 days) are read as they are.
#[test]
fn other_stamps_since_1970_keep_their_digits() {
    let read = |text: &str, opts: ReadOptions| {
        let dir = tempfile::tempdir().unwrap();
        let path = write_tmp(&dir, text.as_bytes());
        let mut reader = CsvReader::open(&path, &opts).unwrap();
        let samples: Vec<Sample> = (&mut reader).collect::<Result<_, _>>().unwrap();
        (
            reader.time_origin_s(),
            samples.iter().map(|s| s.t).collect::<Vec<_>>(),
        )
    };
    let (origin, t) = read(
        "t;a\n1700000000,000000100;0,5\n1700000000,000000300;0,5\n",
        ReadOptions::default(),
    );
    assert_eq!(origin, 1_700_000_000.0);
    assert!(
        (t[0] - 1e-7).abs() < 1e-20 && (t[1] - 3e-7).abs() < 1e-20,
        "{t:?}"
    );
    let (origin, t) = read(
        "time [ms],a\n1700000000123.5,0\n1700000000124.25,0\n",
        ReadOptions::default(),
    );
    assert!((origin - 1_700_000_000.123).abs() < 1e-6, "{origin}");
    assert!(
        (t[0] - 0.5e-3).abs() < 1e-18 && (t[1] - 1.25e-3).abs() < 1e-18,
        "{t:?}"
    );
    let (origin, t) = read("t,a\n-2097152.25,0\n-2097152.0,0\n", ReadOptions::default());
    assert_eq!(origin, -2_097_152.0);
    assert_eq!(t, [-0.25, 0.0]);
    let (origin, t) = read("t,a\n2097151.5,0\n2097152.5,0\n", ReadOptions::default());
    assert_eq!((origin, t), (0.0, vec![2_097_151.5, 2_097_152.5]));
}

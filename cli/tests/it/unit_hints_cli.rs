//! Units the data contradicts (issue 33): a CSV time column in milliseconds read as seconds
//! ("sensor A never moves"), named with the `--time-unit` that fits; and `calib apply`'s
//! readings checked against the default unit as the methods check them, before anything is
//! written.

use crate::common::{self, inspect};

use common::*;
use inspect::inspect;
use std::path::{Path, PathBuf};

/// `log` (quick.toml's `t,a,b,session`, 5 ms apart) as a lab DAQ exports it: three metadata
/// lines, `;` separators, the time in milliseconds under a header `Time` that does not say so,
/// no session column. Returns the export.
fn lab_export_in_ms(log: &Path, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(log).unwrap();
    let mut o = String::from("Device;DAQ-4\nOperator;lab\nSample rate;200 Hz\n\nTime;a;b\n");
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let ms = (f[0].parse::<f64>().unwrap() * 1e3).round() as i64;
        o.push_str(&format!("{ms};{};{}\n", f[1], f[2]));
    }
    write(dir, "export.csv", &o)
}

/// The run in ms read as seconds turns at 1/1000 of its speed, under `--min-speed` (1°/s):
/// before, "sensor A never moves" and nothing else; now the error ends with the column's step
/// and `--time-unit ms`, `reference` says the same, `inspect` warns; with `--time-unit ms` the
/// maps are those of the same run in seconds.
#[test]
fn a_time_column_in_milliseconds_read_as_seconds_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "run.csv", &[]);
    let export = lab_export_in_ms(&log, dir.path());

    let o = calib(&["csrr", s(&export), "-o", s(&dir.path().join("out"))]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "export.csv: channels `a` and `b`: channel `a`",
            "sensor A never moves",
            "the time column `Time` steps by 5 (median of its first rows), read as seconds \
             (the default for a column without a unit): 1 sample per 5 s",
            "if it is in milliseconds, say `--time-unit ms`",
        ],
    );
    assert_no_output(&dir.path().join("out"));

    let o = reference_run(&export, dir.path().join("ref"), &[]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "export.csv: DUT `a`, reference `b`",
            "while moving",
            "the time column `Time` steps by 5",
            "say `--time-unit ms`",
        ],
    );

    let report = inspect(&export, &[]);
    assert!(
        report.contains("warning: ") && report.contains("say `--time-unit ms`"),
        "{report}"
    );

    // Told the unit: the maps of the same run in seconds. Stamps k·5·10⁻³ and k·0.005 differ
    // in their last bit, which can move a session's edge over the speed threshold by a sample:
    // the maps then agree within their standard uncertainty u (0.0067″ here), not bit for bit.
    let plain = write(
        dir.path(),
        "plain.csv",
        &std::fs::read_to_string(&log)
            .unwrap()
            .lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
            .collect::<String>(),
    );
    let (ms_out, s_out) = (dir.path().join("ms"), dir.path().join("s"));
    let o = calib(&["csrr", s(&export), "--time-unit", "ms", "-o", s(&ms_out)]);
    expect_exit(&o, 0);
    assert!(!stderr(&o).contains("--time-unit"), "{}", stderr(&o));
    expect_exit(&calib(&["csrr", s(&plain), "-o", s(&s_out)]), 0);
    for name in ["a.csv", "b.csv"] {
        let (got, want) = (
            table_rows(&ms_out.join(name)),
            table_rows(&s_out.join(name)),
        );
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g[1] - w[1]).abs() <= w[3],
                "{name} at {}°: {g:?} {w:?}",
                w[0]
            );
        }
    }
}

/// The rows of a table with its `u_arcsec` column: `[angle, error, correction, u]`.
fn table_rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.starts_with("angle_deg,error_arcsec,correction_arcsec,u_arcsec\n"));
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

fn reference_run(log: &Path, out: PathBuf, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "reference",
        s(log),
        "--dut",
        "a",
        "--ref",
        "b",
        "-o",
        s(&out),
    ];
    args.extend_from_slice(extra);
    calib(&args)
}

/// The reverse: a `time_ms` column that holds seconds, 1 ms apart, reads as 1 µs apart (1 MHz):
/// `inspect` names `--time-unit s`. A column in ms that says so, 2.5 ms apart, gets no warning.
#[test]
fn seconds_under_a_millisecond_name_are_named_and_a_true_one_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("time_ms,a,b\n");
    for k in 0..2000 {
        let x = k as f64 * 0.36;
        text.push_str(&format!("{:.3},{x:.4},{:.4}\n", k as f64 * 1e-3, x + 30.0));
    }
    let log = write(dir.path(), "seconds.csv", &text);
    let report = inspect(&log, &[]);
    assert_mentions(
        &report,
        &[
            "warning: ",
            "seconds.csv: the time column `time_ms` steps by 0.001 (median of its first rows), \
             read as milliseconds (as its name says): 1000000 samples per second",
            "if it is in seconds, say `--time-unit s`",
        ],
    );
    let report = inspect(&testdata("csv/lab-export.csv"), &[]);
    assert!(!report.contains("--time-unit"), "{report}");
}

/// `log` (`t,a,b,session` in seconds) rewritten with its time in `scale` units per second under
/// the header `time`, without the session column.
fn retimed(log: &Path, dir: &Path, name: &str, time: &str, scale: f64) -> PathBuf {
    let text = std::fs::read_to_string(log).unwrap();
    let mut o = format!("{time},a,b\n");
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let t = f[0].parse::<f64>().unwrap() * scale;
        o.push_str(&format!("{t},{},{}\n", f[1], f[2]));
    }
    write(dir, name, &o)
}

/// The reverse below 500 Hz: quick.toml's 200 Hz run in seconds under `time_ms` reads as
/// 200 kHz (a rate encoders are logged at, so the step says nothing) turning at ~44,000 r/min on
/// average.
/// Before: "found 0 session(s)" and nothing else; now the error and `inspect` name the speed and
/// `--time-unit s`, which gives the maps of the run read in seconds.
#[test]
fn seconds_under_a_millisecond_name_are_named_below_500_hz() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "run.csv", &[]);
    let reversed = retimed(&log, dir.path(), "reversed.csv", "time_ms", 1.0);
    let hint = [
        "the time column `time_ms` steps by 0.005 (median of its first rows), read as \
         milliseconds (as its name says): 200000 samples per second, and the readings turn at",
        "faster than the 30000 r/min encoders are rated for; if it is in seconds, they turn at",
        "(200 samples per second): say `--time-unit s`",
    ];
    let o = calib(&["csrr", s(&reversed), "-o", s(&dir.path().join("out"))]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &hint);
    assert_no_output(&dir.path().join("out"));
    let o = reference_run(&reversed, dir.path().join("ref"), &[]);
    assert_mentions(&expect_exit(&o, 1), &hint);
    let report = inspect(&reversed, &[]);
    assert_mentions(&report, &hint);

    let plain = retimed(&log, dir.path(), "plain.csv", "t", 1.0);
    let (told, s_out) = (dir.path().join("told"), dir.path().join("s"));
    let o = calib(&["csrr", s(&reversed), "--time-unit", "s", "-o", s(&told)]);
    expect_exit(&o, 0);
    assert!(!stderr(&o).contains("--time-unit"), "{}", stderr(&o));
    expect_exit(&calib(&["csrr", s(&plain), "-o", s(&s_out)]), 0);
    for name in ["a.csv", "b.csv"] {
        // The same numbers read in the same unit: the same bytes.
        assert_eq!(
            std::fs::read(told.join(name)).unwrap(),
            std::fs::read(s_out.join(name)).unwrap(),
            "{name}"
        );
    }
}

/// Milliseconds read as seconds where the step is a plausible one: quick.toml at 4 kHz, its
/// stamps in ms under `t`, steps by 0.25 (4 Hz read as seconds) and turns at 0.36°/s at most. By itself
/// that is a slow run (no warning from `inspect`), but where csrr finds sensor A still the error
/// says milliseconds would make it 360°/s at 4 kHz; told so, csrr calibrates.
#[test]
fn milliseconds_at_a_plausible_step_are_named_where_a_method_finds_the_run_still() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "run.csv", &[("rate_hz", "rate_hz = 4000.0")]);
    let ms = retimed(&log, dir.path(), "ms.csv", "t", 1e3);
    let o = calib(&["csrr", s(&ms), "-o", s(&dir.path().join("out"))]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "sensor A never moves",
            "on average by the time column `t` read as seconds (the default for a column \
             without a unit), 4 samples per second; if it is in milliseconds, they turn at ",
            "(4000 samples per second): say `--time-unit ms`",
        ],
    );
    // The average from the first move over the first 20,000 rows (5 s): 360°/s turning, less
    // over the pauses between sessions (0.2 s each of every ~2.7 s), more than half of it.
    let said: f64 = err
        .split("they turn at ")
        .nth(1)
        .and_then(|r| r.split('°').next())
        .and_then(|v| v.parse().ok())
        .unwrap();
    assert!((180.0..=360.0).contains(&said), "{said}°/s");
    let report = inspect(&ms, &[]);
    assert!(!report.contains("--time-unit"), "{report}");
    let o = calib(&[
        "csrr",
        s(&ms),
        "--time-unit",
        "ms",
        "-o",
        s(&dir.path().join("ok")),
    ]);
    expect_exit(&o, 0);
}

/// A log in radians or encoder counts read as degrees: before, `apply` corrected it with the
/// degree map and exit 0 (a correction 57× off, at the wrong angles); now exit 1 (a data
/// error, as degrees read as radians are) naming the unit, and no output, as the methods refuse
/// it. With `--unit` it is corrected as told.
#[test]
fn apply_checks_the_default_unit_against_the_readings() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "run.csv", &[]);
    let tables = dir.path().join("cal");
    expect_exit(&calib(&["csrr", s(&log), "-o", s(&tables)]), 0);
    let text = std::fs::read_to_string(&log).unwrap();
    let convert = |f: &dyn Fn(f64) -> String| {
        let mut o = String::from("t,a,b\n");
        for line in text.lines().skip(1) {
            let v: Vec<&str> = line.split(',').collect();
            let (a, b) = (v[1].parse().unwrap(), v[2].parse().unwrap());
            o.push_str(&format!("{},{},{}\n", v[0], f(a), f(b)));
        }
        o
    };
    let rad = write(
        dir.path(),
        "rad.csv",
        &convert(&|deg: f64| format!("{:.9}", deg.to_radians())),
    );
    let counts = write(
        dir.path(),
        "counts.csv",
        &convert(&|deg: f64| format!("{}", (deg / 360.0 * 16384.0).floor())),
    );
    let table = tables.join("a.csv");
    let out = dir.path().join("corrected.csv");
    for (log, unit, named) in [
        (&rad, "rad", "--unit rad"),
        (&counts, "counts:16384", "(counts:16384 if they wrap there)"),
    ] {
        let o = calib(&["apply", s(&table), s(log), "-o", s(&out)]);
        let err = expect_exit(&o, 1);
        let name = log.file_name().unwrap().to_string_lossy();
        assert_mentions(&err, &[&format!("{name}: the readings of `a`"), named]);
        assert!(!out.exists());
        let o = calib(&["apply", s(&table), s(log), "-o", s(&out), "--unit", unit]);
        expect_exit(&o, 0);
        assert!(stdout(&o).contains("corrected 3301 readings of `a`"));
        std::fs::remove_file(&out).unwrap();
    }
    // Degrees, as the default says: corrected.
    expect_exit(&calib(&["apply", s(&table), s(&log), "-o", s(&out)]), 0);
}

/// Degrees read as radians (issue 52), the mirror of a log in radians read as degrees: quick's
/// wrapped degrees given `--unit rad` were taken as 229 revolutions (each wrap at 360 a jump of
/// 57 turns) and gave a map of the wrong orders, exit 0; a CSV units row saying `rad` over the
/// same degrees did the same. Now exit 1 naming `--unit deg`, nothing written; with
/// `--unit deg` the log calibrates. `apply --unit rad` refuses the same log before writing.
#[test]
fn degrees_read_as_radians_are_refused_naming_unit_deg() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "run.csv", &[]);
    let out = dir.path().join("out");
    let run = |log: &Path, extra: &[&str]| {
        let mut args = vec!["csrr", s(log), "-o", s(&out)];
        args.extend_from_slice(extra);
        calib(&args)
    };
    let err = expect_exit(&run(&log, &["--unit", "rad"]), 1);
    assert_mentions(
        &err,
        &[
            "run.csv",
            "`a`",
            "read in radians",
            "wrap at 360",
            "--unit deg",
        ],
    );
    assert_no_output(&out);
    // A units row saying `rad` over the same degrees.
    let text = std::fs::read_to_string(&log).unwrap();
    let (header, rows) = text.split_once('\n').unwrap();
    let row: Vec<&str> = header
        .split(',')
        .map(|c| match c {
            "t" => "s",
            "session" => "",
            _ => "rad",
        })
        .collect();
    let units = write(
        dir.path(),
        "units.csv",
        &format!("{header}\n{}\n{rows}", row.join(",")),
    );
    let err = expect_exit(&run(&units, &[]), 1);
    assert_mentions(&err, &["units.csv", "--unit deg"]);
    assert_no_output(&out);
    expect_exit(&run(&log, &["--unit", "deg"]), 0);

    let table = out.join("a.csv");
    let corrected = dir.path().join("corrected.csv");
    let o = calib(&[
        "apply",
        s(&table),
        s(&log),
        "-o",
        s(&corrected),
        "--unit",
        "rad",
    ]);
    assert_mentions(&expect_exit(&o, 1), &["`a`", "--unit deg"]);
    assert!(!corrected.exists());
}

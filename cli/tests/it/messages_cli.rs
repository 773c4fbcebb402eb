//! Issue 52: messages that say what was found and what fixes it, and `calib apply` on every CSV
//! dialect the methods read. Each test failed before the fix it names.

use crate::common::*;
use std::path::{Path, PathBuf};

/// A whole-turn table of 360 points, error `10″·sin θ + 3″·cos 5θ`.
fn table(dir: &Path) -> PathBuf {
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..360 {
        let a = f64::from(i).to_radians();
        let e = 10.0 * a.sin() + 3.0 * (5.0 * a).cos();
        text += &format!("{i}.000000,{e:.6},{:.6}\n", -e);
    }
    write(dir, "a.csv", &text)
}

/// A log of 200 rows: `t,a,b`, `a` turning through 0–359°, in `,` and `.` (the plain dialect).
fn plain_log() -> String {
    let mut text = String::from("t,a,b\n");
    for k in 0..200 {
        let t = f64::from(k) * 0.01;
        text += &format!(
            "{t:.2},{:.4},{:.4}\n",
            f64::from(k) * 1.8,
            10.0 + f64::from(k)
        );
    }
    text
}

fn apply(dir: &Path, log: &Path, out: &str, extra: &[&str]) -> (std::process::Output, PathBuf) {
    let out = dir.join(out);
    let t = table(dir);
    let mut args = vec!["apply", s(&t), s(log), "--channel", "a", "-o", s(&out)];
    args.extend_from_slice(extra);
    (calib(&args), out)
}

/// A log whose lines end with `\r` alone (old Mac files, which the methods read) is corrected
/// and keeps its line ends; it was "holds no readings of channel `a`".
#[test]
fn apply_keeps_old_mac_line_ends() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let lf = write(d, "lf.csv", &plain_log());
    let cr = write(d, "cr.csv", &plain_log().replace('\n', "\r"));
    let (o, out_lf) = apply(d, &lf, "lf-out.csv", &[]);
    expect_exit(&o, 0);
    let (o, out_cr) = apply(d, &cr, "cr-out.csv", &[]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["corrected 200 readings"]);
    let (lf, cr) = (
        std::fs::read_to_string(out_lf).unwrap(),
        std::fs::read_to_string(out_cr).unwrap(),
    );
    assert_ne!(lf, plain_log());
    assert_eq!(cr, lf.replace('\n', "\r"));
}

/// A `.tsv` or `.txt` log is written back under its own extension (or `.csv`); it was
/// refused with "name the output with the same extension (e.g. -o corrected.csv)".
#[test]
fn apply_writes_tsv_and_txt_logs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tabs = plain_log().replace(',', "\t");
    let tsv = write(d, "log.tsv", &tabs);
    let txt = write(d, "log.txt", &tabs);
    let (o, as_csv) = apply(d, &tsv, "out.csv", &[]);
    expect_exit(&o, 0);
    let expected = std::fs::read(as_csv).unwrap();
    for (log, out) in [(&tsv, "out.tsv"), (&txt, "out.txt"), (&tsv, "out.txt")] {
        let (o, out) = apply(d, log, out, &[]);
        expect_exit(&o, 0);
        assert_eq!(std::fs::read(out).unwrap(), expected);
    }
    // An MCAP output of a CSV log is still refused, saying which extensions fit.
    let (o, _) = apply(d, &tsv, "out.mcap", &[]);
    assert_mentions(
        &expect_exit(&o, 2),
        &["log.tsv", ".csv, .tsv, .txt or .dat"],
    );
}

/// Decimal commas and a units row (as docs/recordings.md says `apply` keeps them): the output
/// keeps both, and its readings are those of the plain dialect's output; with --keep the units
/// row gets the channel's unit for the new column. It was refused ("apply rewrites only CSV
/// logs with one header row").
#[test]
fn apply_keeps_decimal_commas_and_a_units_row() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let plain = write(d, "plain.csv", &plain_log());
    let european = plain_log()
        .replacen("t,a,b\n", "t,a,b\ns,deg,deg\n", 1)
        .replace(',', ";")
        .replace('.', ",");
    let comma = write(d, "comma.csv", &european);
    let (o, out_plain) = apply(d, &plain, "plain-out.csv", &[]);
    expect_exit(&o, 0);
    let (o, out_comma) = apply(d, &comma, "comma-out.csv", &[]);
    expect_exit(&o, 0);
    let plain_text = std::fs::read_to_string(out_plain).unwrap();
    let comma_text = std::fs::read_to_string(out_comma).unwrap();
    assert!(comma_text.starts_with("t;a;b\ns;deg;deg\n"), "{comma_text}");
    let back = comma_text
        .replace(',', ".")
        .replace(';', ",")
        .replacen("s,deg,deg\n", "", 1);
    assert_eq!(back, plain_text);
    // --keep: the units row names the corrected column's unit too.
    let (o, kept) = apply(d, &comma, "kept.csv", &["--keep"]);
    expect_exit(&o, 0);
    let kept = std::fs::read_to_string(kept).unwrap();
    assert!(
        kept.starts_with("t;a;a_corrected;b\ns;deg;deg;deg\n0,00;0,0000;"),
        "{kept}"
    );
}

/// TwinCAT Scope's export (property block, FILETIME stamps, `EOF` line) is corrected in place:
/// every line but the channel's fields is copied, and calib reads the output as it reads the
/// input. --keep, which has no header row to add to, is refused saying so.
#[test]
fn apply_corrects_a_twincat_scope_export() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = testdata("csv/twincat-scope.csv");
    let t = table(d);
    let out = d.join("tc-out.csv");
    let channel = "fActPosition (Resolver)";
    let o = calib(&["apply", s(&t), s(&log), "--channel", channel, "-o", s(&out)]);
    expect_exit(&o, 0);
    let (input, output) = (
        std::fs::read_to_string(&log).unwrap(),
        std::fs::read_to_string(&out).unwrap(),
    );
    let (lines_in, lines_out): (Vec<&str>, Vec<&str>) =
        (input.lines().collect(), output.lines().collect());
    assert_eq!(lines_in.len(), lines_out.len());
    let mut changed = 0;
    for (a, b) in lines_in.iter().zip(&lines_out) {
        let (fa, fb): (Vec<&str>, Vec<&str>) = (a.split(';').collect(), b.split(';').collect());
        // Only the channel's field (the last of a data row) may differ.
        assert_eq!(fa.len(), fb.len());
        assert_eq!(fa[..fa.len() - 1], fb[..fb.len() - 1], "{a} → {b}");
        changed += usize::from(a != b);
    }
    // Every data row of the fixture (100, each with the channel's reading) is corrected.
    let rows = lines_in.iter().filter(|l| l.starts_with("1329")).count();
    assert_eq!((rows, changed), (100, 100));
    let o = calib(&["inspect", s(&out)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &[channel]);
    let o = calib(&[
        "apply",
        s(&t),
        s(&log),
        "--channel",
        channel,
        "-o",
        s(&d.join("k.csv")),
        "--keep",
    ]);
    assert_mentions(&expect_exit(&o, 1), &["TwinCAT", "leave --keep out"]);
}

/// A named pipe given as a table or a log is refused at once, saying it can be read only once
/// (it was "Illegal seek", or a table read from its second line on).
#[cfg(unix)]
#[test]
fn a_pipe_is_refused_saying_it_cannot_be_read_twice() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let pipe = d.join("pipe.csv");
    let made = std::process::Command::new("mkfifo")
        .arg(&pipe)
        .status()
        .unwrap();
    assert!(made.success());
    let log = write(d, "log.csv", &plain_log());
    let t = table(d);
    // No writer: calib must not wait for one.
    let o = calib(&[
        "apply",
        s(&pipe),
        s(&log),
        "--channel",
        "a",
        "-o",
        s(&d.join("o.csv")),
    ]);
    assert_mentions(
        &stderr(&o),
        &[
            "pipe.csv",
            "named pipe",
            "read only once",
            "save it to a file",
        ],
    );
    let o = calib(&["inspect", s(&pipe)]);
    assert_mentions(&expect_exit(&o, 1), &["named pipe", "save it to a file"]);
    let o = calib(&[
        "apply",
        s(&t),
        s(&pipe),
        "--channel",
        "a",
        "-o",
        s(&d.join("o.csv")),
    ]);
    assert_mentions(&stderr(&o), &["named pipe"]);
}

/// `--plots` naming a file is said of `--plots` (it was "-o FILE: this is a file"), and
/// `--plots` naming a file of the -o folder is refused before anything is written.
#[test]
fn plots_paths_are_checked_as_plots() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulate_quick(d, "run.csv", &[]);
    let file = write(d, "notes.txt", "x");
    let out = d.join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--plots", s(&file)]);
    let err = expect_exit(&o, 2);
    assert_mentions(
        &err,
        &["--plots", "notes.txt", "this is a file", "plot files"],
    );
    assert!(!err.contains("-o "), "{err}");
    let o = calib(&[
        "csrr",
        s(&log),
        "-o",
        s(&out),
        "--plots",
        s(&out.join("report.html")),
    ]);
    assert_mentions(
        &expect_exit(&o, 2),
        &["--plots", "names a file in the -o folder", "plots"],
    );
    assert!(!out.join("report.html").exists());
}

/// Numbers far out of range are refused with the range, in a short line (they were printed
/// with their hundreds of digits, or accepted).
#[test]
fn out_of_range_numbers_are_refused_with_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let t = table(d);
    for scale in ["1e-300", "1e300"] {
        let o = calib(&["export", s(&t), "--format", "lut-i16", "--scale", scale]);
        let err = expect_exit(&o, 2);
        assert_mentions(&err, &["--scale", "1e-6 to 1.296e6"]);
        assert!(err.len() < 400, "{err}");
    }
    let o = calib(&[
        "import",
        s(&t),
        "--format",
        "lut-i16",
        "--scale",
        "1e-300",
        "-o",
        s(&d.join("i.csv")),
    ]);
    assert_mentions(
        &expect_exit(&o, 2),
        &["--scale 1.0000e-300", "1e-6 to 1.296e6"],
    );
    let o = calib(&["plan", "reference", "--rate", "1e-300"]);
    let err = expect_exit(&o, 2);
    assert_mentions(
        &err,
        &["--rate 1.0000e-300 Hz", "below 30 Hz", "--speed 30"],
    );
    assert!(err.len() < 400, "{err}");
    let o = calib(&["plan", "reference", "--rate", "30"]);
    expect_exit(&o, 0);
}

/// A SimpleFOC table that cannot hold a small error blames the format's fixed 19.78″ code, not
/// `--scale` (which the format refuses) or `--points`.
#[test]
fn simplefoc_blames_its_fixed_code() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 4″ at order 1: a fifth of a code.
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..360 {
        let e = 4.0 * f64::from(i).to_radians().sin();
        text += &format!("{i}.000000,{e:.6},{:.6}\n", -e);
    }
    let small = write(d, "small.csv", &text);
    let o = calib(&["export", s(&small), "--format", "simplefoc"]);
    let err = stderr(&o);
    assert_mentions(
        &err,
        &[
            "the format's quantum",
            "19.78 arcsec",
            "--points cannot change",
            "--format simplefoc-float",
        ],
    );
    assert!(!err.contains("(--scale) or its size"), "{err}");
}

/// More sessions or heads than a plan takes are refused naming the option and the limit (a
/// plan of 1,000 took over a minute, and more ran on unbounded).
#[test]
fn plans_refuse_more_angles_than_the_limit() {
    for args in [
        ["plan", "csrr", "--max-order", "10", "--sessions", "1001"],
        ["plan", "multihead", "--max-order", "10", "--heads", "1001"],
    ] {
        let o = calib(&args);
        assert_mentions(&expect_exit(&o, 2), &[args[4], "1001", "at most 1000"]);
    }
}

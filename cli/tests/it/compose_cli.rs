//! End-to-end tests of `calib compose`: the composed table against the two tables applied in
//! turn with `calib apply`, on a simulated log with errors of hundreds of arcseconds; the
//! uncertainty column; bad usage.

use crate::common;

use calib_core::angle::{ARCSEC_PER_RAD, wrap_pi};
use calib_io::{LogReader, ReadOptions};
use common::*;
use std::path::{Path, PathBuf};

/// A table `dir/name` on `points` points of the error Σ A·cos(h·θ + φ) (arcsec, degrees), with a
/// constant `u_arcsec` column if `u` is given.
fn table_file(
    dir: &Path,
    name: &str,
    harmonics: &[(f64, f64, f64)],
    points: usize,
    u: Option<f64>,
) -> PathBuf {
    std::fs::create_dir_all(dir.join(name).parent().unwrap()).unwrap();
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec");
    text.push_str(if u.is_some() { ",u_arcsec\n" } else { "\n" });
    for i in 0..points {
        let deg = 360.0 * i as f64 / points as f64;
        let e: f64 = harmonics
            .iter()
            .map(|&(h, a, p)| a * (h * deg + p).to_radians().cos())
            .sum();
        let e = if e.abs() < 5e-7 { 0.0 } else { e };
        text.push_str(&format!("{deg:.6},{e:.6},{:.6}", -e));
        match u {
            Some(u) => text.push_str(&format!(",{u:.6}\n")),
            None => text.push('\n'),
        }
    }
    write(dir, name, &text)
}

/// Channel `a` of a log, radians.
fn channel_a(log: &Path) -> Vec<f64> {
    let reader = LogReader::open(log, &ReadOptions::default()).unwrap();
    let k = reader
        .channels()
        .iter()
        .position(|c| c.name == "a")
        .unwrap();
    reader.map(|s| s.unwrap().values[k]).collect()
}

/// `calib apply TABLE LOG -o OUT` (channel `a`, from the table's name).
fn apply(table: &Path, log: &Path, out: &Path) {
    let o = calib(&["apply", s(table), s(log), "-o", s(out)]);
    expect_exit(&o, 0);
}

/// Largest |x − y − c| over the two logs' channel `a` (arcsec), `c` the mean difference (arcsec).
fn apart(x: &[f64], y: &[f64]) -> (f64, f64) {
    assert_eq!(x.len(), y.len());
    let d: Vec<f64> = x
        .iter()
        .zip(y)
        .map(|(a, b)| wrap_pi(a - b) * ARCSEC_PER_RAD)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|v| (v - mean).abs()).fold(0.0, f64::max), mean)
}

/// The bar of the issue: the composed table corrects a log as T1 and then the residual do, to
/// 0.01″. The log's sensor `a` errs by 400″, 300″ and 80″ at orders 1, 8 and 16; T1 holds most of
/// it, the residual (a function of the corrected reading) the rest and an order 72. Measured:
/// within 0.0048″ (after the constant the composition's mean removal leaves, 0.0001″); adding
/// the two tables instead leaves 0.56″.
#[test]
fn the_composed_table_corrects_as_the_two_applied_in_turn() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = simulate_quick(
        d,
        "run.csv",
        &[
            (
                "  { order = 8,",
                "  { order = 8, amplitude_arcsec = 300.0, phase_deg = 30.0 },",
            ),
            (
                "  { order = 16,",
                "  { order = 16, amplitude_arcsec = 80.0, phase_deg = -45.0 },",
            ),
            (
                "  { order = 1,",
                "  { order = 1, amplitude_arcsec = 400.0, phase_deg = 100.0 },",
            ),
        ],
    );
    let first = table_file(
        d,
        "t1/a.csv",
        &[(1.0, 400.0, 100.0), (8.0, 290.0, 30.0), (16.0, 74.0, -45.0)],
        3600,
        None,
    );
    let residual = table_file(
        d,
        "r/a.csv",
        &[(8.0, 10.0, 30.0), (16.0, 6.0, -45.0), (72.0, 1.0, 0.0)],
        3600,
        None,
    );
    let (once, twice) = (d.join("once.csv"), d.join("twice.csv"));
    apply(&first, &log, &once);
    apply(&residual, &once, &twice);

    std::fs::create_dir_all(d.join("t2")).unwrap();
    let composed = d.join("t2/a.csv");
    let o = calib(&["compose", s(&first), s(&residual), "-o", s(&composed)]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(&summary, &["e₂(r) = e₁(r) + F·e_R(r − e₁(r))", "wrote"]);
    let in_one = d.join("in-one.csv");
    apply(&composed, &log, &in_one);

    let (sequence, one) = (channel_a(&twice), channel_a(&in_one));
    let (worst, constant) = apart(&one, &sequence);
    // Between grid points the composed table departs from the sequence by at most the residual's
    // own interpolation error, Σ A·h²·Δ²/4 = 0.0056″ here on 0.1° steps (core::compose docs).
    assert!(worst <= 0.01, "composed vs in turn: {worst}″");
    // The constant is the one compose printed.
    let printed: f64 = summary
        .split("readings ")
        .nth(1)
        .unwrap()
        .split('″')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    // (The log's mean difference adds what is left at its samples, at most `worst`; the summary
    // rounds to 4 decimals.)
    assert!(
        (constant - printed).abs() <= worst + 1e-4,
        "{constant} vs {printed}"
    );
    // Adding the two tables is not the same: the residual is read at the wrong angle.
    let added = table_file(
        d,
        "sum/a.csv",
        &[
            (1.0, 400.0, 100.0),
            (8.0, 300.0, 30.0),
            (16.0, 80.0, -45.0),
            (72.0, 1.0, 0.0),
        ],
        3600,
        None,
    );
    let by_sum = d.join("by-sum.csv");
    apply(&added, &log, &by_sum);
    let (off, _) = apart(&channel_a(&by_sum), &sequence);
    assert!(off > 0.05, "adding the tables: {off}″");
    println!("composed vs in turn {worst}″ (constant {constant}″); added vs in turn {off}″");
}

#[test]
fn uncertainties_combine_where_both_tables_have_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = table_file(d, "t1.csv", &[(1.0, 200.0, 0.0)], 360, Some(0.3));
    let residual = table_file(d, "r.csv", &[(2.0, 5.0, 0.0)], 360, Some(0.4));
    let plain = table_file(d, "p.csv", &[(2.0, 5.0, 0.0)], 720, None);
    let out = d.join("t2.csv");
    let o = calib(&["compose", s(&first), s(&residual), "-o", s(&out)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["root-sum-square"]);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("angle_deg,error_arcsec,correction_arcsec,u_arcsec\n"));
    // √(0.3² + 0.4²) everywhere, the residual's uncertainty being constant.
    for line in text.lines().skip(1) {
        let u: f64 = line.rsplit(',').next().unwrap().parse().unwrap();
        assert!((u - 0.5).abs() < 1e-6, "{line}");
    }
    // With --factor 0.5 the residual's part is halved: √(0.3² + 0.2²).
    let o = calib(&[
        "compose",
        s(&first),
        s(&residual),
        "-o",
        s(&out),
        "--factor",
        "0.5",
    ]);
    expect_exit(&o, 0);
    let text = std::fs::read_to_string(&out).unwrap();
    let u: f64 = text
        .lines()
        .nth(1)
        .unwrap()
        .rsplit(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((u - 0.13f64.sqrt()).abs() < 1e-6, "{u}");
    // Only one table with u: dropped, and said; the finer grid is kept.
    let o = calib(&["compose", s(&first), s(&plain), "-o", s(&out)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["u_arcsec: dropped", "720 points"]);
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("angle_deg,error_arcsec,correction_arcsec\n"));
    assert_eq!(text.lines().count(), 721);
}

#[test]
fn bad_usage_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let first = table_file(d, "t1.csv", &[(1.0, 200.0, 0.0)], 360, None);
    let out = d.join("t2.csv");
    for factor in ["0", "-1", "3", "nan"] {
        let factor = format!("--factor={factor}");
        let o = calib(&["compose", s(&first), s(&first), "-o", s(&out), &factor]);
        assert_mentions(&expect_exit(&o, 2), &["--factor"]);
    }
    // A factor far out of range is shown as a number, not its 309 digits, beside the range.
    let o = calib(&[
        "compose",
        s(&first),
        s(&first),
        "-o",
        s(&out),
        "--factor=1e308",
    ]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["--factor 1.0000e308", "(0, 2]"]);
    assert!(err.len() < 200, "{err}");
    let o = calib(&["compose", s(&first), s(&d.join("none.csv")), "-o", s(&out)]);
    assert_mentions(&expect_exit(&o, 2), &["none.csv", "no such table"]);
    let broken = write(
        d,
        "broken.csv",
        "angle_deg,error_arcsec,correction_arcsec\n0,1,-1\n",
    );
    let o = calib(&["compose", s(&first), s(&broken), "-o", s(&out)]);
    assert_mentions(
        &expect_exit(&o, 1),
        &["broken.csv", "at least 2 grid points"],
    );
    assert!(!out.exists());
}

//! End-to-end tests of `calib export`: every format read back and compared with the table within
//! its quantization step; saturation refused; the harmonic form's kept and dropped terms.

mod common;

use common::*;
use std::path::Path;

/// The table's error, arcsec: 10″·cos(3θ + 20°) + 2″·cos 7θ + 0.05″·cos 11θ (zero mean).
fn error_of(deg: f64) -> f64 {
    let th = deg.to_radians();
    10.0 * (3.0 * th + 20f64.to_radians()).cos() + 2.0 * (7.0 * th).cos() + 0.05 * (11.0 * th).cos()
}

/// A 720-point table file.
fn table(dir: &Path) -> std::path::PathBuf {
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..720 {
        let a = i as f64 * 0.5;
        let e = error_of(a);
        text.push_str(&format!("{a:.6},{e:.6},{:.6}\n", -e));
    }
    write(dir, "t.csv", &text)
}

/// Runs an export to a file; returns (comment lines, data lines).
fn export(dir: &Path, args: &[&str]) -> (Vec<String>, Vec<String>) {
    let t = table(dir);
    let out = dir.join("out.txt");
    let mut all = vec!["export", s(&t), "-o", s(&out)];
    all.extend_from_slice(args);
    expect_exit(&calib(&all), 0);
    let text = std::fs::read_to_string(&out).unwrap();
    let (c, d): (Vec<_>, Vec<_>) = text
        .lines()
        .map(str::to_string)
        .partition(|l| l.starts_with("# ") || l.starts_with("// "));
    let head = c.join("\n");
    assert_mentions(
        &head,
        &[
            "correction = -error",
            "reading + correction(reading)",
            "i*360/",
        ],
    );
    (c, d)
}

fn scale_of(comments: &[String]) -> f64 {
    let l = comments.iter().find(|l| l.contains("scale:")).unwrap();
    l.rsplit(' ').next().unwrap().parse().unwrap()
}

#[track_caller]
fn check(values: &[f64], tol: f64) {
    assert_eq!(values.len(), 720);
    for (i, v) in values.iter().enumerate() {
        let want = -error_of(i as f64 * 0.5);
        assert!(
            (v - want).abs() <= tol,
            "point {i}: {v} vs {want} (tol {tol})"
        );
    }
}

/// The table's own rounding: 6 decimals, 5e-7″.
const TABLE: f64 = 1e-6;

#[test]
fn float_formats_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let (_, d) = export(dir.path(), &["--format", "lut-f32-rad"]);
    let v: Vec<f64> = d
        .iter()
        .map(|l| l.parse::<f64>().unwrap() * 206264.80624709636)
        .collect();
    // f32: 2⁻²⁴ relative of ≤ 12.05″.
    check(&v, TABLE + 12.05 * 6e-8);

    let (_, d) = export(dir.path(), &["--format", "csv"]);
    assert_eq!(d[0], "angle_deg,correction_arcsec");
    let v: Vec<f64> = d[1..]
        .iter()
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    check(&v, TABLE + 5e-7);

    // Resampled on 360 points (every other point of the table): the same values there.
    let (_, d) = export(dir.path(), &["--format", "csv", "--points", "360"]);
    assert_eq!(d.len(), 361);
    assert_eq!(d[2].split(',').next().unwrap(), "1.000000");
    let table_2 = -error_of(2.0);
    let got: f64 = d[3].split(',').nth(1).unwrap().parse().unwrap();
    assert!((got - table_2).abs() < TABLE + 5e-7, "{got} vs {table_2}");

    let (c, d) = export(dir.path(), &["--format", "c-array"]);
    assert!(c.iter().all(|l| l.starts_with("//")));
    assert!(
        d.iter()
            .any(|l| l.contains("#define CALIB_CORRECTION_POINTS 720"))
    );
    let v: Vec<f64> = d
        .iter()
        .filter(|l| l.starts_with("    "))
        .flat_map(|l| {
            l.split(',')
                .filter_map(|x| x.trim().trim_end_matches('f').parse::<f64>().ok())
                .collect::<Vec<_>>()
        })
        .collect();
    check(&v, TABLE + 5e-7);
}

#[test]
fn integer_formats_round_trip_within_half_an_lsb() {
    let dir = tempfile::tempdir().unwrap();
    for (format, offset) in [("lut-i16", 0.0), ("lut-u16", 32768.0), ("lut-i8", 0.0)] {
        let (c, d) = export(dir.path(), &["--format", format]);
        let scale = scale_of(&c);
        let v: Vec<f64> = d
            .iter()
            .map(|l| (l.parse::<f64>().unwrap() - offset) * scale)
            .collect();
        check(&v, scale / 2.0 + TABLE);
        // A given scale is used as given.
        let (c, d) = export(dir.path(), &["--format", format, "--scale", "0.5"]);
        assert_eq!(scale_of(&c), 0.5);
        let v: Vec<f64> = d
            .iter()
            .map(|l| (l.parse::<f64>().unwrap() - offset) * 0.5)
            .collect();
        check(&v, 0.25 + TABLE);
    }
}

#[test]
fn a_scale_too_small_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path());
    let out = dir.path().join("out.txt");
    // |correction| ≤ ~12″: at 0.01″/LSB that needs code ~1200, beyond int8's 127.
    let o = calib(&[
        "export",
        s(&t),
        "--format",
        "lut-i8",
        "--scale",
        "0.01",
        "-o",
        s(&out),
    ]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["t.csv", "--scale", "127"]);
    assert!(!out.exists());
    let o = calib(&["export", s(&t), "--format", "lut-i16", "--scale", "-1"]);
    expect_exit(&o, 2);
}

#[test]
fn harmonic_form_keeps_the_largest_and_names_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let (c, d) = export(dir.path(), &["--format", "harmonic", "--orders", "2"]);
    assert_eq!(d[0], "order,amplitude_arcsec,phase_deg");
    let rows: Vec<(usize, f64, f64)> = d[1..]
        .iter()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(rows.len(), 2);
    // The correction is −error: 10″ at phase 20° − 180° = −160°, 2″ at 180°.
    assert_eq!(rows[0].0, 3);
    assert!(
        (rows[0].1 - 10.0).abs() < 1e-5 && (rows[0].2 + 160.0).abs() < 1e-4,
        "{rows:?}"
    );
    assert_eq!(rows[1].0, 7);
    assert!(
        (rows[1].1 - 2.0).abs() < 1e-5 && (rows[1].2.abs() - 180.0).abs() < 1e-4,
        "{rows:?}"
    );
    // Dropped: the 0.05″ order 11, RMS 0.05/√2.
    let dropped = c.iter().find(|l| l.contains("dropped")).unwrap();
    assert!(dropped.contains("RMS 0.0353"), "{dropped}");
    // By threshold: 0.01″ keeps all three.
    let (_, d) = export(dir.path(), &["--format", "harmonic"]);
    assert_eq!(d.len(), 4, "{d:?}");
}

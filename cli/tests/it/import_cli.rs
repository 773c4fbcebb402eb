//! End-to-end tests of `calib import`: a table as a controller holds it (moteus settings,
//! SimpleFOC printLUT() output, calib's look-up tables) read back into a calib table that
//! `compose`, `compare` and `export` take; errors name the file and line.

use crate::common;

use common::*;
use std::path::Path;

/// The table's error, arcsec: 10″·cos(3θ + 20°) + 2″·cos 7θ (zero mean).
fn error_of(deg: f64) -> f64 {
    let th = deg.to_radians();
    10.0 * (3.0 * th + 20f64.to_radians()).cos() + 2.0 * (7.0 * th).cos()
}

/// A table of `n` points.
fn table(dir: &Path, n: usize) -> std::path::PathBuf {
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..n {
        let a = i as f64 * 360.0 / n as f64;
        let e = error_of(a);
        text.push_str(&format!("{a:.6},{e:.6},{:.6}\n", -e));
    }
    write(dir, &format!("t{n}.csv"), &text)
}

/// Every controller format exported at its own size, imported, and compared with the table
/// within half a code (the grid is the export's, so the table is written as it is).
#[test]
fn exports_read_back_within_half_a_code() {
    let dir = tempfile::tempdir().unwrap();
    // moteus: 256 entries, 127 codes for the largest |correction| (11.9″): 0.047″ half a code.
    // simplefoc: half of 2π/65535 rad, 9.89″. The others: their own quantum or 6 decimals.
    for (format, points, half_code) in [
        ("moteus", 256, 12.0 / 127.0 / 2.0),
        ("moteus-config", 256, 12.0 / 127.0 / 2.0),
        ("simplefoc", 200, 9.8879),
        ("simplefoc-float", 200, 1e-5),
        ("lut-i16", 200, 12.0 / 32767.0 / 2.0),
        ("lut-f32-rad", 200, 1e-5),
        ("csv", 200, 1e-6),
    ] {
        let t = table(dir.path(), points);
        let exported = dir.path().join(format!("t.{format}"));
        let p = points.to_string();
        let mut args = vec!["export", s(&t), "--format", format, "-o", s(&exported)];
        if format != "moteus" && format != "moteus-config" {
            args.extend(["--points", &p]);
        }
        expect_exit(&calib(&args), 0);
        let imported = dir.path().join(format!("{format}.csv"));
        let o = calib(&[
            "import",
            s(&exported),
            "--format",
            format,
            "-o",
            s(&imported),
        ]);
        let out = {
            expect_exit(&o, 0);
            stdout(&o)
        };
        assert_mentions(&out, &[&format!("{points} points"), "peak-to-peak"]);
        let rows = read_table(&imported);
        assert_eq!(rows.len(), points, "{format}");
        // The imported table has its mean removed (a constant, at most half a code): compare
        // after removing the mean of the difference, as no calibration observes it.
        let diff: Vec<f64> = rows.iter().map(|(a, e)| e - error_of(*a)).collect();
        let mean = diff.iter().sum::<f64>() / diff.len() as f64;
        assert!(mean.abs() <= half_code, "{format}: mean {mean}");
        for (d, (a, _)) in diff.iter().zip(&rows) {
            // Half a code, and the 6 decimals of both tables.
            assert!(
                (d - mean).abs() <= half_code + 2e-6,
                "{format} at {a}°: {d} (mean {mean})"
            );
        }
    }
}

/// printLUT() output of a current SimpleFOC sketch, composed with a residual and compared.
#[test]
fn print_lut_output_feeds_compose_and_compare() {
    let dir = tempfile::tempdir().unwrap();
    let codes: Vec<String> = (0..200)
        .map(|i| {
            let e = error_of(i as f64 * 1.8) / 206264.80624709636;
            ((e * 10430.2191955 + 32767.0) as u16).to_string()
        })
        .collect();
    let printed = format!(
        "\n// Calibrated Sensor LUT\nuint16_t calibrationLut[200] = {{\n{}\n}};\nfloat \
         zero_electric_angle = 4.12;\nDirection sensor_direction = Direction::CCW;\n\n",
        codes.join(", ")
    );
    let lut = write(dir.path(), "serial.txt", &printed);
    let in_use = dir.path().join("in-use.csv");
    let o = calib(&["import", s(&lut), "--format", "simplefoc", "-o", s(&in_use)]);
    assert_mentions(
        &{
            expect_exit(&o, 0);
            stdout(&o)
        },
        &["zero_electric_angle = 4.12", "Direction::CCW", "200 points"],
    );
    let next = dir.path().join("next.csv");
    let t = table(dir.path(), 720);
    expect_exit(&calib(&["compose", s(&in_use), s(&t), "-o", s(&next)]), 0);
    // The imported table is within one code (19.8″, the driver's truncation) of the table: as
    // an expanded uncertainty of 20″ against the table's 6 decimals, every point agrees.
    let cmp = dir.path().join("compare");
    let o = calib(&[
        "compare",
        s(&in_use),
        s(&t),
        "--U1",
        "20",
        "--U2",
        "0.001",
        "-o",
        s(&cmp),
    ]);
    expect_exit(&o, 0);
}

#[test]
fn bad_files_are_named_with_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let bad = write(
        dir.path(),
        "bad.txt",
        "uint16_t calibrationLut[3] = {\n32767,\n32767x,\n32767\n};\n",
    );
    let out = dir.path().join("t.csv");
    let o = calib(&["import", s(&bad), "--format", "simplefoc", "-o", s(&out)]);
    assert_mentions(&expect_exit(&o, 1), &["bad.txt", "line 3", "`32767x`"]);
    assert!(!out.exists());
    let o = calib(&["import", s(&bad), "--format", "moteus", "-o", s(&out)]);
    assert_mentions(&expect_exit(&o, 1), &["bad.txt", "no motor_position"]);
    let missing = dir.path().join("none.txt");
    let o = calib(&["import", s(&missing), "--format", "moteus", "-o", s(&out)]);
    expect_exit(&o, 2);
    let o = calib(&["import", s(&bad), "--format", "harmonic", "-o", s(&out)]);
    expect_exit(&o, 2);
}

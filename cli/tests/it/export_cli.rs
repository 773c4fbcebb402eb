//! End-to-end tests of `calib export`: every format read back and compared with the table within
//! its quantization step; saturation refused; the harmonic form's kept and dropped terms; the
//! controller formats (moteus, SimpleFOC) decoded as their firmware does (the exact firmware
//! arithmetic is re-implemented in `calib_io::export`'s unit tests); orders chosen before
//! resampling.

use crate::common;

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

/// Issue 33: a --scale above twice the largest correction (~12″) made every code 0, exit 0.
#[test]
fn a_scale_that_zeroes_every_code_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path());
    let out = dir.path().join("out.txt");
    for format in ["lut-i16", "lut-i8", "lut-u16", "moteus"] {
        let o = calib(&[
            "export",
            s(&t),
            "--format",
            format,
            "--scale",
            "100",
            "-o",
            s(&out),
        ]);
        let err = expect_exit(&o, 2);
        assert_mentions(
            &err,
            &[
                "largest |correction| is 11.7",
                "every code would be 0",
                "--scale",
            ],
        );
        assert!(!out.exists(), "{format}");
    }
}

/// Issue 30: a table whose error is mostly in orders the controller's table cannot hold is
/// written with a warning naming them (the refusal of one that would leave all of its error is
/// tested in `calib_io::export`).
#[test]
fn tables_that_leave_much_of_their_error_are_written_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    // 4″ at order 1 and 20″ at order 150 on 3600 points: 256 entries hold order 1 only.
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..3600 {
        let th = (i as f64 * 0.1).to_radians();
        let e = 4.0 * th.cos() + 20.0 * (150.0 * th).cos();
        text.push_str(&format!("{:.6},{e:.6},{:.6}\n", i as f64 * 0.1, -e));
    }
    let t = write(dir.path(), "high.csv", &text);
    let out = dir.path().join("high.moteus");
    let o = calib(&["export", s(&t), "--format", "moteus", "-o", s(&out)]);
    assert_mentions(
        &{
            expect_exit(&o, 0);
            stdout(&o)
        },
        &[
            "warning: as the controller uses it, this table leaves",
            "order 150 40.0000",
            "cannot correct them",
        ],
    );
}

#[test]
fn harmonic_form_keeps_the_largest_and_names_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let (c, d) = export(dir.path(), &["--format", "harmonic", "--harmonics", "2"]);
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

/// `--format harmonic` says what it leaves, as every format does (issue 52): before, a
/// `--min-amplitude` above every order wrote a header and no row (exit 0), and one that left
/// half of the RMS said nothing. The table: 20″ at order 8, 12″ at order 16 on 3600 points.
#[test]
fn harmonic_form_says_what_it_leaves_and_refuses_an_empty_listing() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for i in 0..3600 {
        let a = i as f64 * 0.1;
        let th = a.to_radians();
        let e = 20.0 * (8.0 * th).cos() + 12.0 * (16.0 * th + 0.5).cos();
        text.push_str(&format!("{a:.6},{e:.6},{:.6}\n", -e));
    }
    let t = write(dir.path(), "t8.csv", &text);
    let out = dir.path().join("h.txt");
    let run = |extra: &[&str]| {
        let mut args = vec!["export", s(&t), "--format", "harmonic", "-o", s(&out)];
        args.extend_from_slice(extra);
        calib(&args)
    };
    let err = expect_exit(&run(&["--min-amplitude", "50"]), 1);
    assert_mentions(
        &err,
        &[
            "t8.csv",
            "order 8, is 20.0000",
            "--min-amplitude",
            "not written",
        ],
    );
    assert!(!out.exists());
    // Order 16 left out: 12/√2 = 8.485″ RMS of √((20² + 12²)/2) = 16.492″, 51.4 %; p-p 24″
    // less what the 0.1° grid misses of cos(16θ + 0.5)'s peaks (23.99919″). The table's 6
    // decimals move these by < 10⁻⁵″.
    let o = run(&["--min-amplitude", "15"]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(
        &summary,
        &[
            "leave 23.99919",
            "8.4852",
            "16.4924",
            "(51.45 % of its RMS)",
            "warning:",
            "--min-amplitude",
        ],
    );
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(written.contains("# warning: "), "{written}");
    // Both orders: nothing left, no warning.
    let o = run(&["--min-amplitude", "1"]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert!(summary.contains("(0.00 % of its RMS)"), "{summary}");
    assert!(!summary.contains("warning"), "{summary}");
}

/// The numbers between the first `= {` and the next `};` of a C snippet.
fn c_numbers(text: &str) -> Vec<String> {
    let open = text.find("= {").unwrap() + 3;
    let close = open + text[open..].find("};").unwrap();
    text[open..close]
        .split([',', '\n', ' '])
        .filter(|t| !t.is_empty())
        .map(|t| t.trim_end_matches('f').to_string())
        .collect()
}

/// Linear interpolation of the 720-point table at `deg`: what a resampled table holds there.
fn table_at(deg: f64) -> f64 {
    let x = deg / 0.5;
    let i = x.floor();
    let f = x - i;
    error_of(i * 0.5) * (1.0 - f) + error_of((i + 1.0) * 0.5) * f
}

#[test]
fn help_lists_every_format_and_where_it_is_loaded() {
    let o = calib(&["export", "--help"]);
    expect_exit(&o, 0);
    let help = stdout(&o);
    for name in [
        "lut-f32-rad",
        "lut-i16",
        "lut-u16",
        "lut-i8",
        "c-array",
        "csv",
        "harmonic",
        "moteus",
        "moteus-config",
        "simplefoc",
        "simplefoc-float",
    ] {
        assert!(help.contains(&format!("{name}:")), "{name} in:\n{help}");
    }
    assert_mentions(
        &help,
        &[
            "--write-config",
            "--restore-config",
            "CalibratedSensor(sensor, N, lut)",
            "PR #75",
            "commit 06a3d52",
            "--harmonics",
            "--orders",
            "Not established from the source",
        ],
    );
}

#[test]
fn moteus_lines_decode_to_the_table_and_their_header_goes_to_the_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path());
    let o = calib(&["export", s(&t), "--format", "moteus", "--source", "1"]);
    let err = expect_exit(&o, 0);
    assert_mentions(
        &err,
        &["# calib", "correction = -error", "--write-config", "fit: "],
    );
    let text = stdout(&o);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 256 + 3);
    assert_eq!(lines[258], "conf write");
    let prefix = "conf set motor_position.sources.1.compensation_";
    let mut codes = vec![0i64; 256];
    let mut scale = f64::NAN;
    for line in &lines[1..258] {
        let (key, value) = line.strip_prefix(prefix).unwrap().split_once(' ').unwrap();
        match key.strip_prefix("table.") {
            Some(i) => codes[i.parse::<usize>().unwrap()] = value.parse().unwrap(),
            None => scale = value.parse().unwrap(),
        }
    }
    // moteus adds code·scale/127 revolutions: the correction, −error, at i/256 of a turn.
    // The scale is the largest |correction| (between 10″ and 12.05″ here): 127 codes span it.
    let quantum = scale / 127.0 * 1_296_000.0;
    assert!(
        (10.0 / 127.0..=12.05 / 127.0).contains(&quantum),
        "{quantum}″"
    );
    for (i, &k) in codes.iter().enumerate() {
        let got = k as f64 * quantum;
        let want = -table_at(i as f64 * 360.0 / 256.0);
        // Half a code, and the table's 6-decimal rounding.
        assert!(
            (got - want).abs() <= quantum / 2.0 + TABLE,
            "{i}: {got} vs {want}"
        );
    }
    // To a file: the same lines; standard output says where, and shows the header.
    let out = dir.path().join("a.moteus");
    let o = calib(&[
        "export",
        s(&t),
        "--format",
        "moteus",
        "--source",
        "1",
        "-o",
        s(&out),
    ]);
    expect_exit(&o, 0);
    assert_eq!(std::fs::read_to_string(&out).unwrap(), text);
    assert_mentions(&stdout(&o), &["wrote", "compensation_scale", "fit: "]);
    // The restore-config form: the same settings, a `#` header, no `conf`.
    let (c, d) = export(dir.path(), &["--format", "moteus-config"]);
    assert!(c.iter().any(|l| l.contains("--restore-config")));
    assert_eq!(d.len(), 258);
    assert!(
        d.iter()
            .all(|l| l.starts_with("motor_position.sources.0.compensation_"))
    );
    // moteus holds 256 entries, no other size; a scale too small is refused.
    let o = calib(&["export", s(&t), "--format", "moteus", "--points", "512"]);
    assert_mentions(&expect_exit(&o, 2), &["t.csv", "256", "not 512"]);
    let o = calib(&["export", s(&t), "--format", "moteus", "--scale", "0.01"]);
    assert_mentions(&expect_exit(&o, 2), &["--scale", "127"]);
    let o = calib(&["export", s(&t), "--format", "moteus", "--source", "3"]);
    expect_exit(&o, 2);
}

/// `--format simplefoc`: current SimpleFOC's uint16_t codes, decoded as `decodeOffsetU16` does;
/// `--format simplefoc-float`: the float table of releases before PR #75. 200 entries of the
/// 720-point table hold its orders 3, 7 and 11 exactly: each entry is the error there.
#[test]
fn simplefoc_tables_hold_the_error_in_radians() {
    let dir = tempfile::tempdir().unwrap();
    let (c, d) = export(dir.path(), &["--format", "simplefoc", "--points", "200"]);
    assert!(c.iter().any(|l| l.contains("returns raw - lut(raw)")));
    let body = d.join("\n");
    assert_mentions(&body, &["uint16_t calibrationLut[200] = {"]);
    assert!(
        c.iter()
            .any(|l| l.contains("CalibratedSensor(sensor, 200, calibrationLut)"))
    );
    let codes: Vec<u16> = c_numbers(&body)
        .iter()
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(codes.len(), 200);
    // Half a code of 2π/65535 rad (9.89″), and f32 decoding (2⁻²⁴ of 12″).
    let half_code = std::f64::consts::TAU / 65535.0 / 2.0 * 206264.80624709636;
    for (i, &k) in codes.iter().enumerate() {
        let got = f64::from((f32::from(k) - 32767.0) / 10430.219) * 206264.80624709636;
        let want = error_of(i as f64 * 1.8);
        assert!(
            (got - want).abs() <= half_code + TABLE,
            "{i}: {got} vs {want}"
        );
    }
    let (c, d) = export(
        dir.path(),
        &["--format", "simplefoc-float", "--points", "200"],
    );
    assert!(c.iter().any(|l| l.contains("before PR #75")));
    let body = d.join("\n");
    assert_mentions(
        &body,
        &[
            "#define CALIB_LUT_SIZE 200",
            "float calib_lut[CALIB_LUT_SIZE] = {",
        ],
    );
    let values: Vec<f64> = c_numbers(&body)
        .iter()
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(values.len(), 200);
    for (i, v) in values.iter().enumerate() {
        let want = error_of(i as f64 * 1.8);
        assert!(
            (v * 206264.80624709636 - want).abs() <= TABLE + 12.05 * 6e-8,
            "{i}"
        );
    }
    // Without --points: the driver's default 200 entries (this table has no order above 99).
    let t = table(dir.path());
    let o = calib(&["export", s(&t), "--format", "simplefoc"]);
    assert_mentions(
        &{
            expect_exit(&o, 0);
            stdout(&o)
        },
        &["calibrationLut[200]"],
    );
    // The code is the driver's: no --scale.
    let o = calib(&["export", s(&t), "--format", "simplefoc", "--scale", "1"]);
    assert_mentions(&expect_exit(&o, 2), &["takes no --scale", "LUT_SCALE"]);
}

#[test]
fn chosen_orders_are_resynthesized_before_resampling() {
    let dir = tempfile::tempdir().unwrap();
    let (c, d) = export(
        dir.path(),
        &["--format", "csv", "--points", "64", "--orders", "3,7"],
    );
    let harmonics = c.iter().find(|l| l.contains("harmonics: ")).unwrap();
    assert!(harmonics.contains("kept orders 3, 7"), "{harmonics}");
    // Left out: the 0.05″ of order 11, 0.1″ peak to peak (0.09998″ on the 0.5° grid).
    let pp: f64 = harmonics
        .split(" arcsec peak-to-peak")
        .next()
        .unwrap()
        .rsplit(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((pp - 0.1).abs() < 1e-3, "{harmonics}");
    assert!(c.iter().any(|l| l.contains("fit: ")));
    // Each of the 64 rows is the kept series exactly (6 decimals in the table and the output).
    for row in &d[1..] {
        let (a, v) = row.split_once(',').unwrap();
        let th = a.parse::<f64>().unwrap().to_radians();
        let kept = 10.0 * (3.0 * th + 20f64.to_radians()).cos() + 2.0 * (7.0 * th).cos();
        assert!((v.parse::<f64>().unwrap() + kept).abs() < 1e-5, "{row}");
    }
    // --harmonics 2 chooses the same two orders.
    let (c, _) = export(
        dir.path(),
        &["--format", "csv", "--points", "64", "--harmonics", "2"],
    );
    assert!(
        c.iter()
            .any(|l| l.contains("kept the 2 largest orders, 3, 7"))
    );
    // An order the output grid cannot hold is refused, as are both options at once.
    let t = table(dir.path());
    let o = calib(&["export", s(&t), "--format", "moteus", "--orders", "3,200"]);
    assert_mentions(
        &expect_exit(&o, 2),
        &["order 200", "256 points", "--points"],
    );
    let o = calib(&[
        "export",
        s(&t),
        "--format",
        "csv",
        "--orders",
        "3",
        "--harmonics",
        "2",
    ]);
    expect_exit(&o, 2);
    let o = calib(&["export", s(&t), "--format", "csv", "--orders", "0"]);
    expect_exit(&o, 2);
}

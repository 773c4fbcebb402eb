//! End-to-end tests of lab files as they are saved (issue 25): TwinCAT Scope exports with their
//! property block and FILETIME column, point lists without time (MagAlpha-like, an arm joint's
//! encoder file paired with a protractor file), and the dialects — whitespace, decimal commas,
//! integer time, a units row, CR line ends — each against a known truth or against the same
//! data in the plain dialect (byte-identical tables).

use crate::common::{self, compare, json, reference};

use common::*;
use compare::max_diff_zero_mean;
use json::read_json;
use reference::reference;
use serde_json::Value;
use std::f64::consts::PI;
use std::path::Path;

/// The DUT's error in the TwinCAT-like export, degrees: order 4 at 0.5°.
fn resolver_error(deg: f64) -> f64 {
    0.5 * (4.0 * deg.to_radians() + 0.3).sin()
}

/// A TwinCAT Scope export as Beckhoff's tool saves it: `;`, CRLF, the `Name`/`File`/`Starttime`
/// lines, a property block (`Name`, `SymbolComment`, `Data-Type`, `SampleTime`, …, `Unit`),
/// blank lines, then rows `FILETIME;counter;velocity;resolver` at 10 ms and an `EOF` line. The motion: `still`
/// rows at rest, one turn forward in `turn` rows, 10 rows of pause, one turn back, `still` rows
/// at rest.
fn twincat_export(still: usize, turn: usize) -> String {
    let start: u64 = 132_900_081_483_250_000;
    let step = 360.0 / turn as f64;
    let mut angles = Vec::new();
    angles.extend(std::iter::repeat_n(0.0, still));
    angles.extend((0..turn).map(|k| k as f64 * step));
    angles.extend(std::iter::repeat_n(360.0, 10));
    angles.extend((0..turn).map(|k| 360.0 - k as f64 * step));
    angles.extend(std::iter::repeat_n(0.0, still));
    let end = start + 100_000 * (angles.len() as u64 - 1);
    let mut o = String::new();
    for line in [
        "Name;Encoder test;".to_string(),
        "File;C:\\Users\\lab\\Documents\\Scope\\encoder test.csv;".to_string(),
        format!("Starttime of export;{start};Tuesday, February 22, 2022;13:55:48.325"),
        format!("Endtime of export;{end};Tuesday, February 22, 2022;13:56:11.325"),
        String::new(),
        String::new(),
        "TriggerGroup;Count;ReleaseTime;Comment;".to_string(),
        String::new(),
        "Name;fActPosition (Internal Counter);fActVelocity;fActPosition (Resolver)".to_string(),
        "SymbolComment;Actual position value;Actual velocity;Actual position value".to_string(),
        "Data-Type;REAL64;REAL64;REAL64".to_string(),
        "SampleTime;10;10;10".to_string(),
        "VariableSize;8;8;8".to_string(),
        "SymbolBased;True;True;True".to_string(),
        "IndexGroup;61462;61462;16448".to_string(),
        "IndexOffset;0;0;1740840".to_string(),
        "SymbolName;MAIN.axis.fActPosition;MAIN.axis.fActVelocity;GVL.resolver.fActPosition"
            .to_string(),
        "NetID;5.1.2.3.1.1;5.1.2.3.1.1;5.1.2.3.1.1".to_string(),
        "Port;852;852;852".to_string(),
        "Offset;0;0;0".to_string(),
        "ScaleFactor;1;1;1".to_string(),
        "BitMask;0xffffffffffffffff;0xffffffffffffffff;0xffffffffffffffff".to_string(),
        "Unit;(None);(None);(None)".to_string(),
        "Unit ScaleFactor;1;1;1".to_string(),
        "Unit Offset;0;0;0".to_string(),
        String::new(),
        String::new(),
    ] {
        o.push_str(&line);
        o.push_str("\r\n");
    }
    for (k, &a) in angles.iter().enumerate() {
        let v = if k > 0 {
            (a - angles[k - 1]) * 100.0
        } else {
            0.0
        };
        let r = a + resolver_error(a);
        o.push_str(&format!("{};{a};{v};{r}\r\n", start + 100_000 * k as u64));
    }
    o.push_str("EOF\r\n");
    o
}

/// The committed fixture is what [`twincat_export`] writes for a short record: 100 rows, a turn
/// in 40 rows each way. `CALIB_WRITE_FIXTURES=1 cargo test -p calib-cli --test it labfiles_cli::
/// committed` rewrites it.
#[test]
fn committed_twincat_fixture_is_what_the_generator_writes() {
    let path = testdata("csv/twincat-scope.csv");
    if std::env::var_os("CALIB_WRITE_FIXTURES").is_some() {
        std::fs::write(&path, twincat_export(5, 40)).unwrap();
    }
    let committed = std::fs::read_to_string(&path).unwrap();
    assert!(
        committed == twincat_export(5, 40),
        "{} is not the generator's",
        path.display()
    );
}

#[test]
fn twincat_export_is_inspected_by_its_property_names() {
    let o = calib(&["inspect", s(&testdata("csv/twincat-scope.csv"))]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    // 5 + 40 + 10 + 40 + 5 rows 10 ms apart: 99 intervals, 0.99 s.
    assert_mentions(
        &out,
        &[
            "read as: `;`-separated, TwinCAT Scope's property block, FILETIME time stamps",
            "100 samples over 0.990 s",
            "100.00 Hz",
            "fActPosition (Internal Counter)",
            "fActVelocity",
            "fActPosition (Resolver)",
        ],
    );
}

#[test]
fn twincat_export_calibrates_the_resolver_against_the_counter() {
    // A turn each way at 36°/s, 0.5 s at rest before and after: 2110 rows.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let log = write(dir.path(), "Scope export.csv", &twincat_export(50, 1000));
    let o = reference(
        &log,
        "fActPosition (Resolver)",
        "fActPosition (Internal Counter)",
        &out,
        &[],
    );
    expect_exit(&o, 0);
    let report = read_json(&out.join("report.json"));
    let ch = &report["channels"]["fActPosition (Resolver)"];
    let table = read_map(&out.join(ch["table"].as_str().unwrap()));
    // The map is e(reading) with the reading θ + e(θ): against e(θ) at θ = reading it differs by
    // e·e′ ≤ 4·(0.5°)²·π/180 = 0.0175° = 63″ (order 8). Order 4 itself changes only at third
    // order: ≈ (4·0.0087)²/8 of 1800″ = 0.3″; the cubic between samples 0.36° apart costs < 0.01″.
    let order4 = harmonic(ch, 4);
    assert!((order4 - 1800.0).abs() < 2.0, "order 4: {order4}″");
    let worst = max_diff_zero_mean(&table, |a| resolver_error(a) * 3600.0);
    assert!(worst < 70.0, "map − truth: {worst}″");
}

/// A TwinCAT Scope export of the channels `names` (with their `SymbolName`s), the title line
/// first if `title`, a FILETIME column if `filetime`, and `rows` of readings (one per channel),
/// 10 ms apart.
fn twincat_channels(
    title: bool,
    names: &[&str],
    symbols: &[&str],
    filetime: bool,
    rows: &[Vec<f64>],
) -> String {
    let row = |key: &str, v: &str| format!("{key}{}\r\n", format!(";{v}").repeat(names.len()));
    let mut o = String::new();
    if title {
        o.push_str("Name;Encoder test;\r\nFile;C:\\Scope\\encoder test.csv;\r\n");
        o.push_str("Starttime of export;132900081483250000;Tuesday;13:55:48.325\r\n\r\n");
        o.push_str("TriggerGroup;Count;ReleaseTime;Comment;\r\n\r\n");
    }
    o.push_str(&format!("Name;{}\r\n", names.join(";")));
    o.push_str(&row("Data-Type", "REAL64"));
    o.push_str(&row("SampleTime", "10"));
    o.push_str(&format!("SymbolName;{}\r\n", symbols.join(";")));
    o.push_str(&row("Unit", "(None)"));
    o.push_str("\r\n\r\n");
    for (k, r) in rows.iter().enumerate() {
        let mut fields: Vec<String> = r.iter().map(f64::to_string).collect();
        if filetime {
            fields.insert(
                0,
                (132_900_081_483_250_000u64 + 100_000 * k as u64).to_string(),
            );
        }
        o.push_str(&fields.join(";"));
        o.push_str("\r\n");
    }
    o.push_str("EOF\r\n");
    o
}

/// A single channel without a time column: before, its first 57 rows (52 with the title
/// line) were taken for properties, whatever the file's length; now every row is a sample.
#[test]
fn twincat_single_channel_without_time_keeps_every_row() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<Vec<f64>> = (0..300).map(|k| vec![k as f64 * 1.2]).collect();
    for title in [false, true] {
        let text = twincat_channels(title, &["fActPosition"], &["MAIN.x"], false, &rows);
        let log = write(dir.path(), "one.csv", &text);
        let o = calib(&["inspect", s(&log)]);
        expect_exit(&o, 0);
        // 300 rows 10 ms apart: 299 intervals.
        assert_mentions(
            &stdout(&o),
            &[
                "300 samples over 2.990 s",
                "fActPosition",
                "time from SampleTime",
            ],
        );
    }
}

/// A 2-channel export without time whose file starts with the title line: before, the title
/// was taken for the `Name` row (one channel `Encoder test`) and the second channel for a
/// FILETIME column; now the channels are `ref` and `dut`, timed by SampleTime.
#[test]
fn twincat_title_line_is_not_taken_for_the_channel_names() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<Vec<f64>> = (0..200).map(|k| vec![k as f64, k as f64 + 0.5]).collect();
    let text = twincat_channels(true, &["ref", "dut"], &["MAIN.r", "MAIN.d"], false, &rows);
    let log = write(dir.path(), "two.csv", &text);
    let o = calib(&["inspect", s(&log)]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(
        &out,
        &[
            "200 samples over 1.990 s",
            "ref",
            "dut",
            "time from SampleTime",
        ],
    );
    assert!(!out.contains("Encoder test"), "{out}");
}

/// Two channels of one name (two axes' `fActPosition`): before, accepted and the first used
/// for the name; now refused as a header row of two columns of one name is, naming both
/// columns, their SymbolNames and the `Name` row's line.
#[test]
fn twincat_channels_of_one_name_are_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<Vec<f64>> = (0..50).map(|k| vec![k as f64, k as f64]).collect();
    let text = twincat_channels(
        true,
        &["fActPosition", "fActPosition"],
        &["MAIN.axis1.fActPosition", "MAIN.axis2.fActPosition"],
        true,
        &rows,
    );
    let log = write(dir.path(), "same.csv", &text);
    {
        let err = expect_exit(&calib(&["inspect", s(&log)]), 1);
        assert_mentions(
            &err,
            &[
                "same.csv",
                "line 7",
                "(columns 2 and 3) are both named `fActPosition`",
                "MAIN.axis1.fActPosition",
                "MAIN.axis2.fActPosition",
                "Name property",
            ],
        );
    }
}

/// Data rows of neither width (here a time column per channel): before, "columns 2 and 3 are
/// both named REAL64" (the `Data-Type` row taken for a header); now what was found and what
/// to do.
#[test]
fn twincat_layout_not_read_says_what_it_found() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<Vec<f64>> = (0..50)
        .map(|k| vec![k as f64 * 0.01, k as f64, k as f64 * 0.01, k as f64 + 0.5])
        .collect();
    let text = twincat_channels(true, &["ref", "dut"], &["MAIN.r", "MAIN.d"], false, &rows);
    let log = write(dir.path(), "pairs.csv", &text);
    let err = expect_exit(&calib(&["inspect", s(&log)]), 1);
    assert_mentions(
        &err,
        &[
            "pairs.csv",
            "line 7",
            "names 2 channels but whose data rows hold 4 fields",
            "single time column",
        ],
    );
    assert!(!err.contains("REAL64"), "{err}");
}

/// The amplitude, arcsec, of order `order` in a channel of report.json.
fn harmonic(ch: &Value, order: u64) -> f64 {
    ch["harmonics"]
        .as_array()
        .unwrap()
        .iter()
        .find(|h| h["order"].as_u64() == Some(order))
        .map_or(0.0, |h| h["amplitude_arcsec"].as_f64().unwrap())
}

/// The rows `(angle°, error″)` of a table, whole-turn or range (its `# range_deg` line skipped).
fn read_map(path: &Path) -> Vec<(f64, f64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("angle_deg"))
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (f[0], f[1])
        })
        .collect()
}

/// Rounds to a multiple of `q`.
fn quantize(x: f64, q: f64) -> f64 {
    (x / q).round() * q
}

/// The MagAlpha-like error, degrees, at the measured angle: orders 2, 4 and 1.
fn magalpha_error(deg: f64) -> f64 {
    let r = deg.to_radians();
    3.51 * (2.0 * r + 0.4).cos() + 1.47 * (4.0 * r - 1.1).cos() + 0.77 * (r + 2.0).cos()
}

#[test]
fn magalpha_like_point_list_gives_its_orders() {
    // 200 points over a turn as the MPS tool's input: `Reference Angle [degree],Measured Angle
    // [degree]`, both quantized to 360/512°, the reference starting at 258°.
    let q = 360.0 / 512.0;
    let mut text = String::from("Reference Angle [degree],Measured Angle [degree]\n");
    for k in 0..200 {
        let measured = quantize(0.7 + k as f64 * 1.8, q);
        let reference = quantize(
            (measured - magalpha_error(measured) + 257.3).rem_euclid(360.0),
            q,
        );
        text.push_str(&format!("{reference},{measured}\n"));
    }
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "magalpha.csv", &text);
    let out = dir.path().join("out");

    let o = calib(&["inspect", s(&log)]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["a list of 200 stationary points", "Measured Angle [degree]"],
    );

    let o = reference(
        &log,
        "Measured Angle [degree]",
        "Reference Angle [degree]",
        &out,
        &[],
    );
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["measured twice"]);
    assert_mentions(&stdout(&o), &["200 stationary points at 200 targets"]);
    let report = read_json(&out.join("report.json"));
    let ch = &report["channels"]["Measured Angle [degree]"];
    // The reference's quantization (σ = 0.703°/√12 = 0.20°) on 200 points leaves each
    // amplitude uncertain by σ·√(2/200) ≈ 0.02° (0.03° with the uneven spacing of the
    // quantized measured angles); 0.1° is 3–5σ. The chords between points 1.8° apart lose
    // (4·1.8°)²/8 = 0.2 % of order 4.
    for (order, deg) in [(2, 3.51), (4, 1.47), (1, 0.77)] {
        let got = harmonic(ch, order) / 3600.0;
        assert!((got - deg).abs() < 0.1, "order {order}: {got}° vs {deg}°");
    }
}

/// The arm joint's true error, degrees.
fn joint_error(deg: f64) -> f64 {
    2.0 * (2.0 * deg.to_radians()).sin() + (deg.to_radians() + 0.5).cos()
}

#[test]
fn arm_joint_encoder_file_pairs_with_a_protractor_file() {
    // As the arm's files: `enc.txt` holds 7 whitespace-separated joint readings per line
    // (quantum 360/4096°), `prot.txt` one protractor reading per line (0.1° steps), the same
    // stops in the same order; the protractor reads 180° − angle. Swept 100° → −86° in 3° steps,
    // then back from −84.5° in 3° steps.
    let q = 360.0 / 4096.0;
    let mut angles: Vec<f64> = (0..63).map(|k| 100.0 - 3.0 * k as f64).collect();
    angles.extend((0..62).map(|k| -84.5 + 3.0 * k as f64));
    let (mut enc, mut prot) = (String::new(), String::new());
    for &a in &angles {
        let joint = quantize(a + joint_error(a), q);
        enc.push_str(&format!(
            "{joint} -65.91796875 336.533203125 9.4921875 -2.78481561068692 19.248046875 -81.650390625\n"
        ));
        prot.push_str(&format!("{:.1}\n", 180.0 - a));
    }
    prot.push('\n');
    let dir = tempfile::tempdir().unwrap();
    let enc = write(dir.path(), "enc.txt", &enc);
    let prot = write(dir.path(), "prot.txt", &prot);
    let out = dir.path().join("out");
    let o = reference(
        &enc,
        "1",
        "1",
        &out,
        &["--ref-file", s(&prot), "--ref-reversed"],
    );
    expect_exit(&o, 0);
    let table_path = out.join("1.csv");
    let text = std::fs::read_to_string(&table_path).unwrap();
    assert!(text.starts_with("# range_deg:"), "{}", &text[..80]);
    let table = read_map(&table_path);
    // The table is a function of the reading m = a + e(a): find a by fixed point.
    let truth = |m: f64| {
        let m = if m > 180.0 { m - 360.0 } else { m };
        let mut a = m;
        for _ in 0..50 {
            a = m - joint_error(a);
        }
        joint_error(a) * 3600.0
    };
    // Per point: encoder quantum 0.088°/√12 = 0.025° ⊕ protractor 0.1°/√12 = 0.029° → 0.038°;
    // the worst of ~125 targets is below 4σ = 0.15°; the chords between points 3° apart sag by
    // at most (3°)²/8·|e″| < 0.01°. 0.2° = 720″.
    let worst = max_diff_zero_mean(&table, truth);
    assert!(worst < 720.0, "map − truth: {worst}″");

    // The same without --ref-reversed: the reference runs the other way round, and the
    // difference changes by twice the encoder's step from point to point.
    let o = reference(
        &enc,
        "1",
        "1",
        &dir.path().join("out2"),
        &["--ref-file", s(&prot)],
    );
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["does not follow the DUT"]);

    // A protractor file with a point more than the encoder's is refused, naming both counts.
    std::fs::write(
        &prot,
        format!("{}80.0\n", std::fs::read_to_string(&prot).unwrap()),
    )
    .unwrap();
    let o = reference(
        &enc,
        "1",
        "1",
        &dir.path().join("out3"),
        &["--ref-file", s(&prot), "--ref-reversed"],
    );
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["holds 125 point(s)", "holds 126"]);
}

#[test]
fn iso_230_2_of_a_point_list_by_hand() {
    // The data set of `reference_points`' unit test, through the CLI: targets 10°, 20°, 30°,
    // two cycles each way in ISO 230-2's order (up 10, 20, 30, down 30, 20, 10), errors (″):
    //   target   ↑ cycle 1, 2   ↓ cycle 1, 2
    //   10°         2, 4          0, 0
    //   20°         6, 6          2, 4
    //   30°         1, 3          5, 5
    // x̄↑ = 3, 6, 2; x̄↓ = 0, 3, 5; s↑ = √2, 0, √2; s↓ = 0, √2, 0; B_i = 3, 3, −3 → B = 3;
    // x̄_i = 1.5, 4.5, 3.5 → M = 3; E = 6 − 0 = 6; R_i = 2√2 + 3 everywhere → R = 3 + 2√2;
    // A = 6 (20° ↑) − (2 − 2√2) (30° ↑) = 4 + 2√2.
    let e = [
        [2.0, 4.0, 0.0, 0.0],
        [6.0, 6.0, 2.0, 4.0],
        [1.0, 3.0, 5.0, 5.0],
    ];
    let mut text = String::from("target;measured\n");
    for c in 0..2 {
        for (i, t) in [10.0, 20.0, 30.0].into_iter().enumerate() {
            text.push_str(&format!("{t};{}\n", t - e[i][c] / 3600.0));
        }
        for (i, t) in [10.0, 20.0, 30.0].into_iter().enumerate().rev() {
            text.push_str(&format!("{t};{}\n", t - e[i][2 + c] / 3600.0));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "iso.csv", &text);
    let out = dir.path().join("out");
    let o = reference(&log, "target", "measured", &out, &[]);
    expect_exit(&o, 0);
    let iso = &read_json(&out.join("report.json"))["details"]["iso230_2"];
    let r2 = 2f64.sqrt();
    for (k, v) in [
        ("reversal_arcsec", 3.0),
        ("mean_bidirectional_arcsec", 3.0),
        ("systematic_arcsec", 6.0),
        ("repeatability_arcsec", 3.0 + 2.0 * r2),
        ("accuracy_arcsec", 4.0 + 2.0 * r2),
    ] {
        // The readings are decimal degrees (17 digits): the figures are exact to ~1e-9″.
        let got = iso[k].as_f64().unwrap();
        assert!((got - v).abs() < 1e-6, "{k}: {got} vs {v}");
    }
}

/// A timed log of `a` (DUT) and `b` (reference), two turns up and two down at 720 samples per
/// turn: `(t s, a°, b°)` per row.
fn timed_rows() -> Vec<(f64, f64, f64)> {
    let mut rows = Vec::new();
    let mut theta = 0.0f64;
    for k in 0..2880u32 {
        let step = if k < 1440 { 0.5 } else { -0.5 };
        let a = (theta + 0.01 * (3.0 * theta.to_radians()).sin()).rem_euclid(360.0);
        rows.push((f64::from(k) * 2.5 * 1e-3, a, theta.rem_euclid(360.0)));
        theta += step;
    }
    rows
}

/// The same rows in another dialect: `header`, each row by `row`, lines ended by `end`.
fn dialect(header: &str, end: &str, row: impl Fn(u32, f64, f64, f64) -> String) -> String {
    let mut o = String::from(header);
    o.push_str(end);
    for (k, &(t, a, b)) in timed_rows().iter().enumerate() {
        o.push_str(&row(k as u32, t, a, b));
        o.push_str(end);
    }
    o
}

#[test]
fn dialects_read_as_the_plain_csv() {
    let dir = tempfile::tempdir().unwrap();
    let comma = |x: f64| format!("{x}").replace('.', ",");
    let files: Vec<(&str, String)> = vec![
        (
            "plain.csv",
            dialect("t,a,b", "\n", |_, t, a, b| format!("{t},{a},{b}")),
        ),
        (
            "semicolon-comma.csv",
            dialect("Time [ms];a;b", "\r\n", |k, _, a, b| {
                format!("{};{};{}", comma(f64::from(k) * 2.5), comma(a), comma(b))
            }),
        ),
        (
            "tab-comma.txt",
            dialect("time\ta\tb", "\n", |_, t, a, b| {
                format!("{}\t{}\t{}", comma(t), comma(a), comma(b))
            }),
        ),
        (
            "spaces.txt",
            dialect("  t    a    b", "\n", |_, t, a, b| {
                format!("  {t}   {a}  {b}  ")
            }),
        ),
        (
            "units-row.csv",
            dialect("t,a,b\nms,deg,deg", "\n", |k, _, a, b| {
                format!("{},{a},{b}", f64::from(k) * 2.5)
            }),
        ),
        (
            "integer-ns.csv",
            dialect("time_ns,a,b", "\n", |k, _, a, b| {
                format!(
                    "{},{a},{b}",
                    1_764_000_000_000_000_000u64 + u64::from(k) * 2_500_000
                )
            }),
        ),
        (
            "cr-only.csv",
            dialect("t,a,b", "\r", |_, t, a, b| format!("{t},{a},{b}")),
        ),
    ];
    let mut tables: Vec<(String, Vec<u8>)> = Vec::new();
    for (name, text) in &files {
        let log = write(dir.path(), name, text);
        let out = dir.path().join(format!("out-{name}"));
        let o = reference(&log, "a", "b", &out, &[]);
        expect_exit(&o, 0);
        tables.push((name.to_string(), std::fs::read(out.join("a.csv")).unwrap()));
    }
    // The tables are the plain file's, byte for byte: the readings are the same numbers, and so
    // are the times (k·2.5 ms; the integer ns ones to an ulp, and the map depends on time only
    // through the speed threshold).
    for (name, table) in &tables[1..] {
        assert!(
            table == &tables[0].1,
            "{name}: table differs from the plain file's"
        );
    }
}

#[test]
fn bad_lab_files_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    // A point list given to a method that needs time.
    let points = write(dir.path(), "points.csv", "dut,ref\n1,2\n3,4\n5,6\n");
    let o = calib(&["csrr", s(&points), "-o", s(&dir.path().join("o1"))]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &["no time column", "stationary points", "calib reference"],
    );
    // A decimal comma in a `,`-separated file (quoted): said so.
    let late = write(dir.path(), "late.csv", "t,a,b\n0,1,2\n1,\"3,5\",4\n");
    let o = calib(&["inspect", s(&late)]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["line 3", "column `a`", "decimal comma"]);
    // Integer stamps beyond 2^53 that turn into decimals.
    let mixed = write(
        dir.path(),
        "mixed.csv",
        "t_ns,a,b\n1764000000000000000,1,2\n1764000000000000000.5,2,3\n",
    );
    let o = calib(&["inspect", s(&mixed)]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["line 3", "whole number"]);
    // --ref-file with a timed log is a usage error.
    let timed = write(dir.path(), "timed.csv", "t,a,b\n0,1,2\n1,2,3\n");
    let o = reference(
        &timed,
        "a",
        "b",
        &dir.path().join("o2"),
        &["--ref-file", s(&points)],
    );
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["--ref-file", "has a time column"]);
}

#[test]
fn integer_time_keeps_its_precision() {
    // ns stamps since 1970 (1.76e18) are not exact in an f64 (256 ns apart there; as seconds,
    // 2.4e-7 s apart): counted from the first row in integers, 1 µs steps are 1 µs apart to
    // the f64's last digit (jitter < 1e-15 s where the stamps through an f64 would give ~1e-7 s).
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("time_ns,a,b\n");
    for k in 0..50u64 {
        text.push_str(&format!(
            "{},{},{}\n",
            1_764_000_000_000_000_001u64 + k * 1_000,
            (k as f64 * 7.2 * PI).sin(),
            k
        ));
    }
    let log = write(dir.path(), "ns.csv", &text);
    let o = calib(&["inspect", s(&log), "--json"]);
    expect_exit(&o, 0);
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    let i = &v["inspection"];
    assert_eq!(i["start_s"].as_f64(), Some(0.0));
    assert!((i["end_s"].as_f64().unwrap() - 49e-6).abs() < 1e-15, "{i}");
    // Through f64 seconds of the absolute stamps the 1 µs intervals would be multiples of
    // 2.4e-7 s (jitter ~1e-7 s); counted in integers they are equal to rounding (~1e-14 s).
    assert!(i["interval_jitter_s"].as_f64().unwrap() < 1e-12, "{i}");
}

#[test]
fn sparse_rows_are_aligned_as_topics() {
    // A plotting tool's export (PlotJuggler: `__time`, one column per topic, a cell empty where
    // the topic has no message): `/enc/a` at 200 Hz on k·5 ms, `/enc/b` at 200 Hz 2.5 ms later,
    // three turns at 180°/s. a = θ + e(θ) with e of order 3 at 180″, b = θ.
    let e = |deg: f64| 0.05 * (3.0 * deg.to_radians() + 0.7).sin();
    let mut text = String::from("__time,/enc/a,/enc/b\n");
    for k in 0..1200u32 {
        let t = f64::from(k) * 0.005;
        let th = 180.0 * t;
        text.push_str(&format!("{t},{},\n", (th + e(th)).rem_euclid(360.0)));
        let t = t + 0.0025;
        text.push_str(&format!("{t},,{}\n", (180.0 * t).rem_euclid(360.0)));
    }
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "plotjuggler.csv", &text);
    let out = dir.path().join("out");
    let o = reference(&log, "/enc/a", "/enc/b", &out, &[]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["aligned on the clock of `/enc/a`"]);
    let report = read_json(&out.join("report.json"));
    let table = read_map(&out.join(report["channels"]["/enc/a"]["table"].as_str().unwrap()));
    // b is linear in time between its samples, so the quintic at a's stamps is exact to
    // rounding; the map's only error is the cubic between a's samples 0.9° apart (order 3:
    // (9/384)·(3·0.0157)⁴ of 180″ < 0.001″) and e's warp of the reading (e·e′ ≤ 3·(0.05°)²
    // ·π/180 = 0.47″). 1″.
    let worst = max_diff_zero_mean(&table, |a| e(a) * 3600.0);
    assert!(worst < 1.0, "map − truth: {worst}″");
}

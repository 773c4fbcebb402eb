//! End-to-end tests of `calib reference`: a simulated run against its truth, a hand-made run
//! turning both ways (reversal value), and bad inputs (exit code, message, nothing written).

use crate::common::{self, compare, json, reference};

use common::*;
use compare::max_diff_zero_mean;
use json::read_json;
use reference::reference;
use serde_json::Value;

/// A DUT `b` and a reference `ref` on the driven shaft: 5 revolutions at 60 r/min, 1000 Hz
/// (0.36° between samples: interpolating between samples costs < 0.004″ on order 12).
const SCENARIO: &str = r#"
seed = 3
rate_hz = 1000.0
speed_rpm = 60.0
wrap = true

[speed]
variation_percent = 0.5

[[sensor]]
name = "b"
mount = "b"
harmonics = [
  { order = 6, amplitude_arcsec = 15.0, phase_deg = -120.0 },
  { order = 12, amplitude_arcsec = 5.0, phase_deg = 10.0 },
  { order = 2, amplitude_arcsec = 2.0, phase_deg = 60.0 },
]
quantization_arcsec = 0.09
noise_arcsec = 0.05

[[sensor]]
name = "ref"
mount = "b"
harmonics = [
  { order = 1, amplitude_arcsec = 0.45, phase_deg = 30.0 },
  { order = 2, amplitude_arcsec = 0.30, phase_deg = -50.0 },
]
quantization_arcsec = 0.001
noise_arcsec = 0.01

[procedure]
relative_deg = [0.0]
revolutions = 5.0
ramp_s = 0.25
pause_s = 0.2
turn_s = 0.5
"#;

/// Bound on |map − (truth b − truth ref)|. Measured: 0.089″. Per reading the difference carries
/// noise 0.05″ ⊕ 0.09″/√12 quantization ⊕ 0.01″ ≈ 0.058″; a point's mean over 5 passes has
/// σ ≈ 0.026″ and the worst of 3600 points is ~4σ ≈ 0.1″; interpolation between samples and
/// reading-vs-true angle add < 0.015″. 0.2″ leaves 2× margin; a lost harmonic (the smallest,
/// the reference's 0.3″ order 2 or 0.45″ order 1) or a sign error would exceed it.
const TOL_ARCSEC: f64 = 0.2;

#[test]
fn simulated_run_matches_the_truth_difference() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = write(dir.path(), "run.toml", SCENARIO);
    let log = simulate(&scenario, dir.path(), "run.csv");
    let out = dir.path().join("out");
    // ISO 230-2 at every grid point (the default is 20 targets), so E↑ is the map's p-p.
    let o = reference(&log, "b", "ref", &out, &["--targets", "3600"]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &[
            "`b` against `ref`",
            "accuracy",
            "report.json",
            "3600 targets",
        ],
    );

    let got = read_table(&out.join("b.csv"));
    assert_eq!(got.len(), 3600);
    let header = std::fs::read_to_string(out.join("b.csv")).unwrap();
    assert!(header.starts_with("angle_deg,error_arcsec,correction_arcsec,u_arcsec\n"));
    let truth_b = read_table(&dir.path().join("run.truth/b.csv"));
    let truth_r = read_table(&dir.path().join("run.truth/ref.csv"));
    let e = max_diff_zero_mean(&got, |a| {
        interpolate(&truth_b, a) - interpolate(&truth_r, a)
    });
    println!("simulated_run_matches_the_truth_difference: max |map − truth| = {e:.4}″");
    assert!(e < TOL_ARCSEC, "max |map − (b − ref)| = {e}″");

    let report = read_json(&out.join("report.json"));
    assert_eq!(report["method"], "reference");
    assert_eq!(report["channels"]["b"]["table"], "b.csv");
    let h = &report["channels"]["b"]["harmonics"][0];
    assert_eq!(h["order"], 6);
    assert!((h["amplitude_arcsec"].as_f64().unwrap() - 15.0).abs() < 0.05);
    let iso = &report["details"]["iso230_2"];
    // One direction only: no reversal; E↑ is the map's p-p (truth b − ref: about 39″).
    assert!(iso["reversal_arcsec"].is_null());
    let e_up = iso["systematic_up_arcsec"].as_f64().unwrap();
    assert!((38.0..41.0).contains(&e_up), "E↑ = {e_up}″");
    let a = iso["accuracy_arcsec"].as_f64().unwrap();
    assert!(a > e_up && a < e_up + 1.0, "A = {a}″");
}

/// The CSRR paper's rig (csrr72.toml): sensor b (72-pole-pair, up to order 432, 78″ p-p)
/// against the RON-886-like `ref` on its shaft, 15 revolutions at 400 Hz, 10 r/min (0.15°
/// between samples). Measured: 0.100″. Bound 0.2″: a point's mean over 15 passes has σ ≈ 0.015″
/// (0.057″ per reading), the worst of 3600 ~0.06″; the cubic between samples costs up to
/// (9/384)·(432·0.0026)⁴·1.12″ ≈ 0.04″ on order 432 (a straight line would cost ~0.9″ there,
/// which this bound catches).
#[test]
fn csrr72_sensor_b_against_its_reference() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/csrr72.toml"), dir.path(), "c72.csv");
    let out = dir.path().join("out");
    let o = reference(&log, "b", "ref", &out, &[]);
    expect_exit(&o, 0);
    let got = read_table(&out.join("b.csv"));
    let truth_b = read_table(&dir.path().join("c72.truth/b.csv"));
    let truth_r = read_table(&dir.path().join("c72.truth/ref.csv"));
    let e = max_diff_zero_mean(&got, |a| {
        interpolate(&truth_b, a) - interpolate(&truth_r, a)
    });
    println!("csrr72_sensor_b_against_its_reference: max |map − truth| = {e:.4}″");
    assert!(e < 0.2, "max |map − (b − ref)| = {e}″");
}

/// `t,dut,ref` at 1000 Hz: 5 revolutions up at 1 r/s, a pause, 5 down; the DUT reads
/// `θ + 10″·cos 3θ ± backlash/2` (+ going up), the reference `θ`.
fn back_and_forth(backlash: f64) -> String {
    let e = |th: f64| 10.0 / 3600.0 * (3.0 * th.to_radians()).cos();
    let mut text = String::from("t,dut,ref\n");
    let mut t = 0.0;
    let mut row = |text: &mut String, th: f64, sign: f64| {
        let dut = th + e(th) + sign * backlash / 7200.0;
        text.push_str(&format!(
            "{t:.3},{:.9},{:.9}\n",
            dut.rem_euclid(360.0),
            th.rem_euclid(360.0)
        ));
        t += 0.001;
    };
    for k in 0..=5000 {
        row(&mut text, 0.36 * k as f64, 1.0);
    }
    for _ in 0..100 {
        row(&mut text, 1800.0, 1.0);
    }
    for k in 1..=5000 {
        row(&mut text, 1800.0 - 0.36 * k as f64, -1.0);
    }
    text
}

#[test]
fn both_directions_give_the_reversal_value() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "run.csv", &back_and_forth(3.0));
    let out = dir.path().join("out");
    let o = reference(
        &log,
        "dut",
        "ref",
        &out,
        &["--ref-u", "0.2", "--json", "--targets", "3600"],
    );
    expect_exit(&o, 0);
    let report: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(report, read_json(&out.join("report.json")));
    let iso = &report["details"]["iso230_2"];
    let f = |k: &str| iso[k].as_f64().unwrap_or_else(|| panic!("{k}: {iso}"));
    // Noise-free, so exact to the 1e-9° of the CSV's numbers: B = B̄ = 3″ (calib's sign: the
    // DUT reads higher going up), R↑ = R↓ = 0, E = p-p of the cosine (20″) + 3″, A = E.
    assert!((f("mean_reversal_arcsec") - 3.0).abs() < 1e-3, "{iso}");
    assert!((f("reversal_arcsec") - 3.0).abs() < 1e-3, "{iso}");
    assert!(f("repeatability_up_arcsec") < 1e-3, "{iso}");
    assert!(f("repeatability_down_arcsec") < 1e-3, "{iso}");
    // ISO 230-2's bidirectional R_i = 2s↑ + 2s↓ + |B_i| holds the reversal.
    assert!((f("repeatability_arcsec") - 3.0).abs() < 1e-3, "{iso}");
    assert!((f("systematic_arcsec") - 23.0).abs() < 0.01, "{iso}");
    assert!(
        (f("accuracy_arcsec") - f("systematic_arcsec")).abs() < 1e-3,
        "{iso}"
    );
    // The map is the bidirectional mean: the cosine without the backlash. Linear interpolation
    // at 0.36° spacing costs ≤ 9·0.0063²/8·10″ ≈ 0.0005″.
    let got = read_table(&out.join("dut.csv"));
    let e = max_diff_zero_mean(&got, |a| 10.0 * (3.0 * a.to_radians()).cos());
    assert!(e < 0.002, "{e}″");
    // u is the reference's alone (the passes agree exactly).
    let text = std::fs::read_to_string(out.join("dut.csv")).unwrap();
    let u: f64 = text
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(3)
        .unwrap()
        .parse()
        .unwrap();
    assert!((u - 0.2).abs() < 1e-3, "{u}");
}

/// The back-and-forth run with the reference column replaced by `f(reference reading)`.
fn with_reference(f: impl Fn(f64) -> f64) -> String {
    back_and_forth(0.0)
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                let c: Vec<&str> = l.split(',').collect();
                format!("{},{},{}\n", c[0], c[1], f(c[2].parse().unwrap()))
            }
        })
        .collect()
}

#[test]
fn bad_inputs_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let good = write(dir.path(), "run.csv", &back_and_forth(0.0));

    // Unknown channel: bad usage.
    let o = reference(&good, "dut", "enc2", &out, &[]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["enc2", "run.csv"]);
    assert_no_output(&out);

    // Same channel twice: bad usage.
    let o = reference(&good, "dut", "dut", &out, &[]);
    expect_exit(&o, 2);
    let o = calib(&[
        "reference",
        s(&good),
        "--dut",
        "dut",
        "--ref",
        "ref",
        "--points",
        "1",
    ]);
    expect_exit(&o, 2);

    // A reference that never moves.
    let still = with_reference(|_| 12.5);
    let log = write(dir.path(), "still.csv", &still);
    let err = expect_exit(&reference(&log, "dut", "ref", &out, &[]), 1);
    assert_mentions(&err, &["still.csv", "`ref`", "does not move"]);
    assert_no_output(&out);

    // A reference on another shaft (turning the other way).
    let reversed = with_reference(|r| (-r).rem_euclid(360.0));
    let log = write(dir.path(), "reversed.csv", &reversed);
    let err = expect_exit(&reference(&log, "dut", "ref", &out, &[]), 1);
    assert_mentions(&err, &["reversed.csv", "does not follow"]);
    assert_no_output(&out);

    // Less than a revolution (the first 800 samples, 799 steps of 0.36° = 287.64°, one way): a
    // range table from the end of the 1° approach to the last reading.
    let short: String = back_and_forth(0.0)
        .lines()
        .take(801)
        .map(|l| format!("{l}\n"))
        .collect();
    let log = write(dir.path(), "short.csv", &short);
    let short_out = dir.path().join("short-out");
    expect_exit(&reference(&log, "dut", "ref", &short_out, &[]), 0);
    let table = std::fs::read_to_string(short_out.join("dut.csv")).unwrap();
    assert!(
        table.starts_with("# range_deg: 1.100000 to 287.600000 "),
        "{}",
        table.lines().next().unwrap()
    );

    // A motion that crosses no grid point (0.72° on a 1° grid) gives nothing to map.
    let tiny: String = back_and_forth(0.0)
        .lines()
        .take(3)
        .map(|l| format!("{l}\n"))
        .collect();
    let log = write(dir.path(), "tiny.csv", &tiny);
    let err = expect_exit(
        &reference(&log, "dut", "ref", &out, &["--points", "360"]),
        1,
    );
    assert_mentions(&err, &["tiny.csv", "crossed 0 grid point", "at least 2"]);
    assert_no_output(&out);
}

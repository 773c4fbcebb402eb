//! End-to-end tests of `calib tdr`: the simulated air-bearing and rolling-bearing coasts against
//! their truth, and logs with no spin-down (exit code, message, nothing written).

use crate::common::{self, coast, json};

use coast::{coast_log, tdr_with_reference};
use common::*;
use json::read_json;
use serde_json::Value;

/// Largest |table − truth table| on the table's grid, the truth interpolated linearly on its
/// own (finer) grid, both zero mean.
fn max_diff(got: &[(f64, f64)], truth: &[(f64, f64)]) -> f64 {
    got.iter()
        .map(|(a, g)| (g - interpolate(truth, *a)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn air_bearing_coast_matches_the_truth_and_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let log = coast_log(dir.path());
    let out = dir.path().join("out");
    let o = tdr_with_reference(&log, &out);
    expect_exit(&o, 0);
    let text = stdout(&o);
    assert_mentions(
        &text,
        &["`enc`", "revolutions", "check against `ref`", "report.json"],
    );
    assert!(!text.contains("warning"), "{text}");
    let got = read_table(&out.join("enc.csv"));
    let truth = read_table(&dir.path().join("coast.truth/enc.csv"));
    let e = max_diff(&got, &truth);
    println!("air bearing: max |map − truth| = {e:.4}″");
    // As in calib-core's tests/it/tdr.rs: σ ≈ 0.057″ per sample over 60 000 samples and the ~13
    // orders kept give a map rms ≈ 1e-3″, its worst point ~4× that; the table's 6-decimal
    // rounding adds nothing. Measured 0.0056″.
    assert!(e < 0.02, "max |map − truth| = {e}″");

    let report = read_json(&out.join("report.json"));
    assert_eq!(report["method"], "tdr");
    assert_eq!(report["channels"]["enc"]["table"], "enc.csv");
    let h = &report["channels"]["enc"]["harmonics"][0];
    assert_eq!(h["order"], 2);
    assert!((h["amplitude_arcsec"].as_f64().unwrap() - 25.0).abs() < 0.01);
    let d = &report["details"];
    assert!(d["drag"]["ambiguity"].as_str().unwrap().contains("bearing"));
    assert_eq!(d["drag"]["speed_dependent_orders"], serde_json::json!([]));
    assert_eq!(d["drag"]["terms"], serde_json::json!([]));
    // ~322 r/min at the slow end (its slowest window's mean speed), 2 kHz: ≈ 372 samples per
    // revolution, orders to 0.4 × that tested.
    assert_eq!(d["orders"]["max_order_tested"], 148);
    assert!(text.contains("orders: "), "{text}");
    let rpm0 = d["motion"]["speed_start_rpm"].as_f64().unwrap();
    assert!((595.0..600.0).contains(&rpm0), "{rpm0}");
    // The reference's own error is 0.05″ (order 3).
    let check = d["reference"]["max_difference_arcsec"].as_f64().unwrap();
    assert!(check < 0.07, "{check}");

    // --json prints the same report.
    let out2 = dir.path().join("out2");
    let o = calib(&["tdr", s(&log), "--channel", "enc", "-o", s(&out2), "--json"]);
    expect_exit(&o, 0);
    let printed: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(printed, read_json(&out2.join("report.json")));
    assert!(printed["details"]["reference"].is_null());

    // Every point has its standard uncertainty, summarized in the report and on stdout.
    let table = std::fs::read_to_string(out.join("enc.csv")).unwrap();
    assert!(
        table.starts_with("angle_deg,error_arcsec,correction_arcsec,u_arcsec"),
        "{}",
        &table[..80]
    );
    let u = &report["details"]["uncertainty"]["enc"];
    let u_max = u["u_max_arcsec"].as_f64().unwrap();
    // σ·√(2K/N) for ~13 orders over 60 000 samples ≈ 0.0015″, more where orders correlate.
    assert!((0.0005..0.01).contains(&u_max), "{u}");
    assert_eq!(u["components"][0]["type"], "A");
    assert_mentions(&text, &["standard uncertainty u of the table"]);
    // `calib compare` takes u_arcsec from both tables: the same log twice gives En = 0.
    let cmp = dir.path().join("cmp");
    let o = calib(&[
        "compare",
        s(&out.join("enc.csv")),
        s(&out2.join("enc.csv")),
        "-o",
        s(&cmp),
    ]);
    expect_exit(&o, 0);
}

#[test]
fn rolling_bearing_drag_is_separated_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(
        &testdata("scenarios/spindown-bearing.toml"),
        dir.path(),
        "coast.csv",
    );
    let out = dir.path().join("out");
    let o = calib(&["tdr", s(&log), "--channel", "enc", "-o", s(&out)]);
    expect_exit(&o, 0);
    let text = stdout(&o);
    assert_mentions(&text, &["drag separated", "order 2: 0.15", "order 4: 0.29"]);
    assert!(!text.contains("warning"), "{text}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_mentions(
        &html,
        &[
            "fig-map-enc",
            "fig-spectrum",
            "drag separated here",
            "imprint",
        ],
    );
    let got = read_table(&out.join("enc.csv"));
    let truth = read_table(&dir.path().join("coast.truth/enc.csv"));
    let e = max_diff(&got, &truth);
    println!("rolling bearing: max |map − truth| = {e:.4}″");
    // Unseparated, the drag of orders 2 and 4 shifted the map by 3.94″ and 1.97″. Separated
    // (calib-core's tests/it/tdr.rs derives the tolerance): measured 0.024″.
    assert!(e < 0.05, "max |map − truth| = {e}″");
    let report = read_json(&out.join("report.json"));
    let drag = &report["details"]["drag"];
    assert_eq!(drag["separated"], true);
    let orders: Vec<u64> = drag["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["order"].as_u64().unwrap())
        .collect();
    assert_eq!(orders, [2, 4]);
    let a2 = drag["terms"][0]["deceleration_rad_s2"].as_f64().unwrap();
    assert!((a2 / 0.15 - 1.0).abs() < 0.005, "{a2}");
    assert_eq!(drag["speed_dependent_orders"], serde_json::json!([]));
    let kept = report["details"]["orders"]["kept"].as_array().unwrap();
    assert!(kept.len() < 20, "{kept:?}");
}

#[test]
fn a_log_without_spin_down_is_refused_naming_file_and_channel() {
    let dir = tempfile::tempdir().unwrap();
    // The CSRR quick run: constant-speed sessions with short ramps, no coast.
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "quick.csv");
    let out = dir.path().join("out");
    let o = calib(&["tdr", s(&log), "--channel", "a", "-o", s(&out)]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["quick.csv", "channel `a`", "spin-down"]);
    assert_no_output(&out);

    // Driven at a constant 1 r/s for 20 s.
    let mut text = String::from("t,enc\n");
    for n in 0..2000 {
        let t = n as f64 / 100.0;
        text.push_str(&format!("{t:.2},{:.6}\n", (360.0 * t).rem_euclid(360.0)));
    }
    let log = write(dir.path(), "driven.csv", &text);
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--run",
        "coast",
        "-o",
        s(&out),
    ]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &[
            "driven.csv",
            "channel `enc`",
            "speed stays",
            "release the drive",
        ],
    );
    assert_no_output(&out);

    // At rest.
    let text: String = std::iter::once("t,enc\n".to_string())
        .chain((0..500).map(|n| format!("{:.2},12.5\n", n as f64 / 100.0)))
        .collect();
    let log = write(dir.path(), "still.csv", &text);
    let o = calib(&["tdr", s(&log), "--channel", "enc", "-o", s(&out)]);
    assert_mentions(&expect_exit(&o, 1), &["still.csv", "stands still"]);
    assert_no_output(&out);
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "x.csv", "t,enc\n0,0\n0.1,1\n");
    let out = dir.path().join("out");
    for (args, says) in [
        (vec!["--channel", "enc", "--ref", "enc"], "both name"),
        (vec!["--channel", "nope"], "nope"),
        (vec!["--channel", "enc", "--max-order", "0"], "--max-order"),
        (
            vec!["--channel", "enc", "--max-drag-order", "101"],
            "--max-drag-order",
        ),
        (vec!["--channel", "enc", "--points", "1"], "--points"),
        (
            vec!["--channel", "enc", "--motion-degree", "0"],
            "--motion-degree",
        ),
        (
            vec!["--channel", "enc", "--pole-pairs", "0"],
            "--pole-pairs",
        ),
        (
            vec!["--channel", "enc", "--cogging-orders", "42,0"],
            "--cogging-orders",
        ),
        (
            vec![
                "--channel",
                "enc",
                "--pole-pairs",
                "7",
                "--cogging-orders",
                "42",
            ],
            "--cogging-orders",
        ),
        (vec!["--channel", "enc", "--run", "spin"], "--run"),
    ] {
        let mut all = vec!["tdr", s(&log), "-o", s(&out)];
        all.extend(args);
        let err = expect_exit(&calib(&all), 2);
        assert!(err.contains(says), "{all:?}: {err}");
    }
    assert_no_output(&out);
}

/// A CSV log timed in seconds since 1970 with every digit (a Python `time.time()` log) gives
/// the map of the same run timed from 0, byte for byte: the reader counts the stamps' whole
/// seconds from the first row's in integers and adds their fractions, where a double of
/// ~1.7·10⁹ s would have kept steps of 2.4·10⁻⁷ s only (0.9″ of rotation at 600 r/min). The
/// summary and report.json give the coast on the file's clock.
#[test]
fn seconds_since_1970_give_the_map_of_seconds_from_0() {
    let dir = tempfile::tempdir().unwrap();
    let from_0 = simulate(&testdata("scenarios/spindown.toml"), dir.path(), "zero.csv");
    let text = std::fs::read_to_string(&from_0).unwrap();
    let shifted: String = text
        .lines()
        .map(|line| match line.split_once('.') {
            Some((whole, rest)) if whole.bytes().all(|b| b.is_ascii_digit()) => {
                let whole: u64 = whole.parse().unwrap();
                format!("{}.{rest}\n", whole + 1_700_000_000)
            }
            _ => format!("{line}\n"),
        })
        .collect();
    assert!(
        shifted.contains("\n1700000000.0005,"),
        "{}",
        &shifted[..200]
    );
    let since_1970 = write(dir.path(), "1970.csv", &shifted);
    let (out_0, out_1970) = (dir.path().join("zero"), dir.path().join("1970"));
    let mut printed = Vec::new();
    for (log, out) in [(&from_0, &out_0), (&since_1970, &out_1970)] {
        let o = calib(&["tdr", s(log), "--channel", "enc", "-o", s(out)]);
        expect_exit(&o, 0);
        printed.push(stdout(&o));
    }
    let table = |out: &std::path::Path| std::fs::read(out.join("enc.csv")).unwrap();
    assert!(table(&out_0) == table(&out_1970), "the maps differ");
    let start = |out: &std::path::Path| {
        read_json(&out.join("report.json"))["details"]["motion"]["start_s"]
            .as_f64()
            .unwrap()
    };
    let (zero, since) = (start(&out_0), start(&out_1970));
    assert!((since - 1.7e9 - zero).abs() < 5e-7, "{since} {zero}");
    assert_mentions(&printed[1], &["coast 1700000000."]);
}

/// `table` less its harmonics at `orders`, from its values on its uniform grid (exact there).
fn without_orders(table: &[(f64, f64)], orders: &[usize]) -> Vec<(f64, f64)> {
    let n = table.len() as f64;
    let mut out = table.to_vec();
    for &k in orders {
        let (mut a, mut b) = (0.0, 0.0);
        for (deg, v) in table {
            let (sn, cs) = (k as f64 * deg.to_radians()).sin_cos();
            a += 2.0 * v * cs / n;
            b += 2.0 * v * sn / n;
        }
        for (deg, v) in out.iter_mut() {
            let (sn, cs) = (k as f64 * deg.to_radians()).sin_cos();
            *v -= a * cs + b * sn;
        }
    }
    out
}

/// The committed driven run `testdata/driven/motor.csv` (`testdata/driven/README.md` says how
/// it was made): a 7-pole-pair motor at constant voltage, ~297 r/min for 5 s, its cogging
/// shaking the shaft at orders 42 and 84, read by a 14-bit encoder erring by up to 600″.
#[test]
fn a_driven_run_names_the_motor_orders_and_matches_the_truth_off_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let log = testdata("driven/motor.csv");
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--pole-pairs",
        "7",
        "-o",
        s(&out),
    ]);
    expect_exit(&o, 0);
    let text = stdout(&o);
    assert_mentions(
        &text,
        &[
            "Driven-run (TDR) self-calibration of `enc` — 1 pass",
            "order 42: ",
            "order 84: ",
            "order 126: ",
            "(left out of the map)",
        ],
    );
    let report = read_json(&out.join("report.json"));
    let d = &report["details"]["driven"];
    let orders: Vec<u64> = d["motor_orders"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            assert_eq!(m["in_map"], false);
            m["order"].as_u64().unwrap()
        })
        .collect();
    assert_eq!(orders, [42, 84, 126]);
    assert_eq!(d["passes"].as_array().unwrap().len(), 1);
    assert!(
        report["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("left out of the map"))
    );
    let got = read_table(&out.join("enc.csv"));
    let truth = without_orders(
        &read_table(&testdata("driven/motor.truth/enc.csv")),
        &[42, 84, 126],
    );
    let e = max_diff(&got, &truth);
    println!("driven run, one speed: max |map − truth off orders 42, 84, 126| = {e:.3}″");
    // σ ≈ 23.6″ per sample (79.1″ counts, 5″ noise) over the 7744 samples of the pass (the
    // spin-up's first 0.6 s left out): each coefficient ±0.38″, an order kept above ≈ 1.7″.
    // The encoder's eight orders are kept; what the map lacks is the truth's cross terms e·e′
    // (≤ 0.65″ each, ~20 orders) and the cogging's sidebands at 41, 43, 85 (~1″): measured
    // 7.7″ at the worst point (calib-core's 20 s run: 6.6″).
    assert!(e < 10.0, "max |map − truth off the motor's orders| = {e}″");
    for (order, amplitude) in [(1, 600.0), (2, 250.0)] {
        let h = &report["channels"]["enc"]["harmonics"][order - 1];
        assert_eq!(h["order"], order);
        let a = h["amplitude_arcsec"].as_f64().unwrap();
        assert!((a - amplitude).abs() < 1.5, "order {order}: {a}″");
    }

    // Without the motor named, the run is calibrated all the same and the warning says how
    // to name it; --run coast refuses the log.
    let out2 = dir.path().join("out2");
    let o = calib(&["tdr", s(&log), "--channel", "enc", "-o", s(&out2)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["pole_pairs", "none named"]);
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--run",
        "coast",
        "-o",
        s(&out2),
        "--force",
    ]);
    assert_mentions(&expect_exit(&o, 1), &["release the drive"]);
}

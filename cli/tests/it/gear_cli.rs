//! End-to-end tests of a reference through a gear (issue 48): an actuator's output encoder
//! calibrated against its motor encoder, both maps from one run, against the simulator's truth
//! (`testdata/scenarios/actuator.toml`, `actuator-turns.toml`, `capstan.toml`).
//!
//! The DUT maps are compared with the truth smoothed over 2.1° (21 grid points): point by point
//! they carry the 14-bit DUT's quantization (79.1″ quantum, 15″ of noise: a bias of up to
//! `(Δ/√12)·exp(−2π²σ²/Δ²)` ≈ 11″ that changes from grid point to grid point, 0.1° being 4.55
//! quanta) and the pass noise, which the map's u holds; the smoothing lowers those by √21 to
//! ~2.5″, so what is left is what the method itself gets wrong — the motor's error leaking
//! into the map, which is what these tests are about. Each test also runs the run with the
//! motor's readings divided by the ratio by hand (what a user had to do before), to show the
//! leak the gear fit removes.

use crate::common::{self, json, reference};

use common::*;
use json::read_json;
use reference::reference;
use std::path::{Path, PathBuf};

/// `(angle°, error″, u″)` of a table, range or whole turn.
fn rows(path: &Path) -> Vec<(f64, f64, f64)> {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let u = header.iter().position(|h| *h == "u_arcsec");
    lines
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            (f[0], f[1], u.map_or(0.0, |j| f[j]))
        })
        .collect()
}

/// A truth table linearly interpolated at `deg`: periodic for a whole turn (first angle 0),
/// else inside its range (`None` outside).
fn truth_at(truth: &[(f64, f64, f64)], deg: f64) -> Option<f64> {
    let (lo, hi) = (truth[0].0, truth[truth.len() - 1].0);
    let x = if lo == 0.0 && hi < 360.0 && truth.len() > 1000 {
        deg.rem_euclid(360.0)
    } else if (lo..=hi).contains(&deg) {
        deg
    } else {
        return None;
    };
    let i = truth.partition_point(|r| r.0 <= x).clamp(1, truth.len());
    let (a, b) = (truth[i - 1], truth[i % truth.len()]);
    let b0 = if i == truth.len() { b.0 + 360.0 } else { b.0 };
    Some(a.1 + (b.1 - a.1) * (x - a.0) / (b0 - a.0))
}

/// The map's difference from the truth at its points (both zero-mean over them).
fn differences(map: &[(f64, f64, f64)], truth: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
    let pairs: Vec<(f64, f64, f64)> = map
        .iter()
        .filter_map(|&(a, e, u)| truth_at(truth, a).map(|t| (e - t, u, a)))
        .collect();
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len() as f64;
    pairs.iter().map(|p| (p.0 - mean, p.1)).collect()
}

/// Largest |difference| after a moving mean over `width` points (circular for a whole turn).
fn smoothed_max(d: &[(f64, f64)], width: usize, turn: bool) -> f64 {
    let n = d.len() as isize;
    let h = (width / 2) as isize;
    (0..n)
        .map(|i| {
            let window: Vec<f64> = (i - h..=i + h)
                .filter_map(|j| match (turn, j) {
                    (true, j) => Some(d[j.rem_euclid(n) as usize].0),
                    (false, j) if (0..n).contains(&j) => Some(d[j as usize].0),
                    _ => None,
                })
                .collect();
            (window.iter().sum::<f64>() / window.len() as f64).abs()
        })
        .fold(0.0, f64::max)
}

/// The simulated log of a scenario of `testdata/scenarios/`, and the same log with the motor's
/// readings accumulated and divided by `ratio` by hand.
fn logs(dir: &Path, scenario: &str, ratio: f64) -> (PathBuf, PathBuf) {
    let log = simulate(
        &testdata(&format!("scenarios/{scenario}.toml")),
        dir,
        &format!("{scenario}.csv"),
    );
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines = text.lines();
    let mut divided = format!("{}\n", lines.next().unwrap());
    let (mut previous, mut total) = (None::<f64>, 0.0);
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        let m: f64 = f[2].parse().unwrap();
        total = match previous {
            None => m,
            Some(p) => total + (m - p) - 360.0 * ((m - p) / 360.0).round(),
        };
        previous = Some(m);
        divided += &format!("{},{},{}\n", f[0], f[1], total / ratio);
    }
    (
        log,
        write(dir, &format!("{scenario}-divided.csv"), &divided),
    )
}

/// What one scenario gives through the gear and by hand.
struct Figures {
    /// Smoothed max |DUT map − truth| through the gear and by hand, arcsec.
    dut: f64,
    by_hand: f64,
    /// Max |motor map − truth|, arcsec of the motor's angle, and the largest |diff|/u.
    motor: f64,
    motor_worst_in_u: f64,
    report: serde_json::Value,
}

fn run(dir: &Path, scenario: &str, ratio: f64, ratio_arg: &str, turn: bool) -> Figures {
    let (log, divided) = logs(dir, scenario, ratio);
    let out = dir.join("out");
    let o = reference(&log, "out", "motor", &out, &["--ref-ratio", ratio_arg]);
    expect_exit(&o, 0);
    println!("{}", stdout(&o));
    let truth = dir.join(format!("{scenario}.truth"));
    let d = differences(&rows(&out.join("out.csv")), &rows(&truth.join("out.csv")));
    let dut = smoothed_max(&d, 21, turn);
    let motor_d = differences(
        &rows(&out.join("motor.csv")),
        &rows(&truth.join("motor.csv")),
    );
    let motor = motor_d.iter().map(|p| p.0.abs()).fold(0.0, f64::max);
    let motor_worst_in_u = motor_d.iter().map(|p| p.0.abs() / p.1).fold(0.0, f64::max);
    let by_hand_out = dir.join("by-hand");
    expect_exit(&reference(&divided, "out", "motor", &by_hand_out, &[]), 0);
    let by_hand = smoothed_max(
        &differences(
            &rows(&by_hand_out.join("out.csv")),
            &rows(&truth.join("out.csv")),
        ),
        21,
        turn,
    );
    println!(
        "{scenario}: DUT map smoothed max |map − truth| {dut:.3}″ (by hand {by_hand:.3}″); motor map max {motor:.3}″ \
         (worst {motor_worst_in_u:.2} u)"
    );
    Figures {
        dut,
        by_hand,
        motor,
        motor_worst_in_u,
        report: read_json(&out.join("report.json")),
    }
}

/// A 50:1 actuator over −60…120° (`actuator.toml`), the ratio given: the motor encoder's
/// 900″/400″ at its orders 1 and 2 (18″ and 8″ at the output) is fitted and taken out.
///
/// The bars: the DUT's map within 8″ of the truth smoothed (by hand the motor's 18″ + 8″ land in
/// it: 22″), and the motor's map within 75″ of its truth (1.5″ at the output, against its 2118″
/// peak to peak) and within 2.5 u everywhere. Why achievable: the motor's two orders, fitted on
/// ~40,000 samples with ~27″ of residual each (DUT quantization ⊕ noise at the output), carry
/// ~12″ (motor) of noise per order, 0.25″ at the output; the 14 orders that fail the
/// significance test are left out, their variance kept in u.
#[test]
fn an_actuator_over_a_range_gives_both_maps() {
    let dir = tempfile::tempdir().unwrap();
    let f = run(dir.path(), "actuator", 50.0, "50", false);
    assert!(f.dut < 8.0, "DUT map {:.3}″ off (bar 8″)", f.dut);
    assert!(f.by_hand > 2.0 * f.dut, "by hand {:.3}″", f.by_hand);
    assert!(f.motor < 75.0, "motor map {:.3}″ off (bar 75″)", f.motor);
    assert!(f.motor_worst_in_u < 2.5, "{}", f.motor_worst_in_u);
    let details = &f.report["details"];
    assert_eq!(details["ratio"], 50.0);
    assert!(details["ratio_u"].is_null());
    let gear = &details["gear"];
    assert_eq!(gear["ratio_source"], "given");
    assert_eq!(gear["reference_table"], "motor.csv");
    let kept: Vec<u64> = gear["reference_terms"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kept"] == true)
        .map(|t| t["order"].as_u64().unwrap())
        .collect();
    assert_eq!(kept, [1, 2], "{gear}");
    let said = gear["not_separable"].to_string();
    assert_mentions(&said, &["over a range", "reference's map"]);
    assert!(f.report["channels"]["motor"].is_object());
}

/// The same actuator with `--ref-ratio auto`: over a range a scale error of the DUT is the
/// ratio's, so the map holds no straight line (its least-squares slope below 0.01″ per degree,
/// against the truth's ~4″/° over the range) and the report and summary say so; the ratio
/// found is 50 to within the DUT's own straight-line part (its error's slope over the range,
/// ~4″/°, a relative 1.2·10⁻³ of the output's angle).
#[test]
fn over_a_range_an_estimated_ratio_holds_the_straight_line() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = logs(dir.path(), "actuator", 50.0);
    let out = dir.path().join("out");
    let o = reference(&log, "out", "motor", &out, &["--ref-ratio", "auto"]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["(estimated)", "straight-line part is in the ratio"],
    );
    let map = rows(&out.join("out.csv"));
    let n = map.len() as f64;
    let (xm, ym) = map
        .iter()
        .fold((0.0, 0.0), |a, r| (a.0 + r.0 / n, a.1 + r.1 / n));
    let slope = map.iter().map(|r| (r.0 - xm) * (r.1 - ym)).sum::<f64>()
        / map.iter().map(|r| (r.0 - xm).powi(2)).sum::<f64>();
    println!("slope of the map {slope:.5}″/°");
    assert!(slope.abs() < 0.01, "slope {slope}″/°");
    let ratio = read_json(&out.join("report.json"))["details"]["ratio"]
        .as_f64()
        .unwrap();
    assert!((ratio / 50.0 - 1.0).abs() < 5e-3, "ratio {ratio}");
}

/// A non-integer ratio, 11.35:1, over two whole output turns each way (`actuator-turns.toml`),
/// the ratio estimated. The motor's error (1200″/500″/120″ at its orders 1, 2, 4: 106″ at
/// 11.35 cycles per output turn) is no harmonic of the output: by hand it stays in the map.
///
/// The bars: the ratio within 3 of its u and 2·10⁻⁵ of 11.35 (the fit's line column over
/// 61,500 samples spanning 720°); the DUT's map within 8″ of the truth smoothed (by hand: tens of
/// arcseconds), the motor's within 17″ of its truth (1.5″ at the output) and 2.5 u; the DUT's
/// order 34, one beat of 11.35·3 = 34.05 over the 2 turns' span from the motor's order 3, named
/// as not separable.
#[test]
fn a_non_integer_ratio_over_whole_turns_is_estimated_with_both_maps() {
    let dir = tempfile::tempdir().unwrap();
    let f = run(dir.path(), "actuator-turns", 11.35, "auto", true);
    let details = &f.report["details"];
    let (ratio, u) = (
        details["ratio"].as_f64().unwrap(),
        details["ratio_u"].as_f64().unwrap(),
    );
    println!("ratio {ratio:.7} ± {u:.7}");
    assert!((ratio - 11.35).abs() < (3.0 * u).max(1e-7), "{ratio} ± {u}");
    assert!((ratio - 11.35).abs() < 2e-5, "{ratio}");
    assert!(f.dut < 8.0, "DUT map {:.3}″ off (bar 8″)", f.dut);
    assert!(f.by_hand > 4.0 * f.dut, "by hand {:.3}″", f.by_hand);
    assert!(f.motor < 17.0, "motor map {:.3}″ off (bar 17″)", f.motor);
    assert!(f.motor_worst_in_u < 2.5, "{}", f.motor_worst_in_u);
    let coincident = details["gear"]["coincident"].as_array().unwrap();
    assert!(
        coincident
            .iter()
            .any(|c| c["dut_order"] == 34 && c["reference_order"] == 3),
        "{coincident:?}"
    );
}

/// A capstan joint moved by hand (`capstan.toml`: twelve strokes reversing at random points,
/// 60–500°/s, random rests): ratio 7.3 estimated, the output lagging by 1 ms and 600″ of lost
/// motion in the cable. The lag is found within 0.05 ms (it moves the difference by 0.5″ per ms
/// at 500°/s, at many speeds), the reversal within 30″ of the 600″ of play, the ratio within
/// 3 u and 2·10⁻⁵, the DUT's map within 12″ smoothed (the motor's 4096-count quantum is 43″ at
/// the output, ~4″ per point over its passes), and the motor's within 2.5 u everywhere and 22″
/// (3″ at the output): its 4096-count quantum, 12.5″ RMS per sample at the output over ~19,000
/// samples unevenly spread by the hand's motion, leaves each of its terms a few arcseconds (its
/// own angle) of noise, which the u of its table holds.
#[test]
fn a_capstan_with_lag_and_lost_motion_gives_ratio_lag_and_both_maps() {
    let dir = tempfile::tempdir().unwrap();
    let f = run(dir.path(), "capstan", 7.3, "auto", true);
    let details = &f.report["details"];
    let (ratio, u) = (
        details["ratio"].as_f64().unwrap(),
        details["ratio_u"].as_f64().unwrap(),
    );
    assert!((ratio - 7.3).abs() < (3.0 * u).max(1e-7), "{ratio} ± {u}");
    assert!((ratio - 7.3).abs() < 2e-5, "{ratio}");
    let lag = details["latency_s"].as_f64().unwrap();
    assert!((lag - 1e-3).abs() < 5e-5, "lag {lag} s");
    let reversal = details["iso230_2"]["mean_reversal_arcsec"]
        .as_f64()
        .unwrap();
    assert!(
        (reversal.abs() - 600.0).abs() < 30.0,
        "reversal {reversal}″"
    );
    assert!(f.dut < 12.0, "DUT map {:.3}″ off (bar 12″)", f.dut);
    assert!(f.by_hand > 3.0 * f.dut, "by hand {:.3}″", f.by_hand);
    assert!(f.motor < 22.0, "motor map {:.3}″ off (bar 22″)", f.motor);
    assert!(f.motor_worst_in_u < 2.5, "{}", f.motor_worst_in_u);
}

/// A ratio that is not the run's is refused with exit 1, naming the option and the ratio the
/// run shows; a ratio of 0 or text is a usage error (exit 2) before anything is read.
#[test]
fn a_wrong_ratio_is_refused_with_the_ratio_the_run_shows() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = logs(dir.path(), "actuator", 50.0);
    let o = reference(
        &log,
        "out",
        "motor",
        &dir.path().join("a"),
        &["--ref-ratio", "40"],
    );
    let e = expect_exit(&o, 1);
    assert_mentions(&e, &["--ref-ratio", "turned 50.1", "says 40", "auto"]);
    let o = reference(
        &log,
        "out",
        "motor",
        &dir.path().join("b"),
        &["--ref-ratio", "-50"],
    );
    expect_exit(&o, 1);
    for bad in ["0", "fifty", "inf"] {
        let o = reference(
            &log,
            "out",
            "motor",
            &dir.path().join("c"),
            &["--ref-ratio", bad],
        );
        let e = expect_exit(&o, 2);
        assert_mentions(&e, &["--ref-ratio", "auto"]);
    }
    let o = reference(
        &log,
        "out",
        "motor",
        &dir.path().join("d"),
        &["--ref-orders", "4"],
    );
    expect_exit(&o, 2);
}

/// `calib inspect` on an actuator's log says what it is — one channel travels about R times
/// the other — and proposes `calib reference … --ref-ratio auto` with the slower channel as
/// the DUT (and no spin-down against the other channel as a reference).
#[test]
fn inspect_recognises_an_actuator() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = logs(dir.path(), "actuator-turns", 11.35);
    let o = calib(&["inspect", s(&log)]);
    expect_exit(&o, 0);
    let text = stdout(&o);
    assert_mentions(
        &text,
        &[
            "--dut out --ref motor --ref-ratio auto",
            "an actuator",
            "gear of about 11.",
        ],
    );
    assert!(!text.contains("--channel out --ref motor"), "{text}");
}

/// A stepper driven open loop before a 5:1 gear (`commanded-gear.toml`): the reference is the
/// drive's commanded motor angle, whose "error" is the motor's ripple at its orders 3 and 6
/// (400″ and 100″ of its angle; the output's orders 15 and 30). With `--ref-kind commanded
/// --pole-pairs 3` the ripple is the reference's map, found within 5″ (1″ at the output: the
/// output encoder's 1″ noise and 2″ quantum over 38,000 samples leave its two terms ~0.1″ of
/// noise at the output), and the output's map is within 2.5″ of its truth (a point's 4
/// crossings of ~1.15″ each: σ ≈ 0.6″, the worst of 3600 points ~4σ), its orders 15 and 30
/// named as the reference's.
#[test]
fn a_commanded_reference_through_a_gear_gives_the_ripple_as_its_map() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(
        &testdata("scenarios/commanded-gear.toml"),
        dir.path(),
        "cg.csv",
    );
    let out = dir.path().join("out");
    let o = reference(
        &log,
        "out",
        "commanded",
        &out,
        &[
            "--ref-ratio",
            "5",
            "--ref-kind",
            "commanded",
            "--pole-pairs",
            "3",
        ],
    );
    expect_exit(&o, 0);
    let report = read_json(&out.join("report.json"));
    let gear = &report["details"]["gear"];
    let kept: Vec<(u64, f64)> = gear["reference_terms"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kept"] == true)
        .map(|t| {
            (
                t["order"].as_u64().unwrap(),
                t["amplitude_arcsec"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(kept.len(), 2, "{kept:?}");
    assert_eq!((kept[0].0, kept[1].0), (3, 6));
    assert!(
        (kept[0].1 - 400.0).abs() < 5.0 && (kept[1].1 - 100.0).abs() < 5.0,
        "{kept:?}"
    );
    let coincident = gear["coincident"].to_string();
    assert_mentions(&coincident, &["\"dut_order\":15", "\"dut_order\":30"]);
    let d = differences(
        &rows(&out.join("out.csv")),
        &rows(&dir.path().join("cg.truth/out.csv")),
    );
    let worst = d.iter().map(|p| p.0.abs()).fold(0.0, f64::max);
    println!("commanded through a gear: max |map − truth| {worst:.3}″");
    assert!(worst < 2.5, "{worst}″ (bar 2.5″)");
}

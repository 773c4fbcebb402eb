//! End-to-end tests of issue 24's real reference set-ups and issue 29's moteus dump, on the
//! committed scenarios `testdata/scenarios/{latency,backlash,commanded}.toml` (simulated with a
//! known truth) and a moteus dump written here: a lag between the channels estimated and
//! removed, backlash at the ends of a range across 0°, an open-loop (commanded) reference whose
//! ripple is taken out, and `calib moteus-dump`.

use crate::common::{self, json, reference};

use common::*;
use json::read_json;
use reference::reference;
use std::f64::consts::TAU;
use std::path::Path;

/// A table's rows `(angle_deg, error_arcsec, u_arcsec)`.
type Rows = Vec<(f64, f64, f64)>;

/// A table's `(range, rows)`: the `# range_deg:` line's `(lo, hi)` if any, and its rows.
fn table(path: &Path) -> (Option<(f64, f64)>, Rows) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut range = None;
    let mut rows = Vec::new();
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("# range_deg:") {
            let w: Vec<&str> = rest.split_whitespace().collect();
            range = Some((w[0].parse().unwrap(), w[2].parse().unwrap()));
        } else if !line.starts_with('#') && !line.starts_with("angle_deg") {
            let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            rows.push((f[0], f[1], f.get(3).copied().unwrap_or(0.0)));
        }
    }
    (range, rows)
}

/// Linear interpolation of rows `(angle, value, _)` at `deg`, brought into their span by whole
/// turns (periodic if `periodic`); `None` outside.
fn at(rows: &[(f64, f64, f64)], deg: f64, periodic: bool) -> Option<f64> {
    let lo = rows[0].0;
    let x = lo + (deg - lo).rem_euclid(360.0);
    let last = rows[rows.len() - 1];
    if x > last.0 {
        if !periodic {
            return (x - last.0 < 1e-9).then_some(last.1);
        }
        let f = (x - last.0) / (360.0 + lo - last.0);
        return Some(last.1 + f * (rows[0].1 - last.1));
    }
    let i = rows.partition_point(|r| r.0 <= x).clamp(1, rows.len() - 1);
    let (a, b) = (rows[i - 1], rows[i]);
    Some(a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0))
}

/// `(max |map − truth|, rms, fraction within 2u)` over the map's points, the common constant
/// removed, arcsec.
fn against_truth(
    got: &[(f64, f64, f64)],
    truth: &[(f64, f64, f64)],
    periodic: bool,
) -> (f64, f64, f64) {
    let pairs: Vec<(f64, f64)> = got
        .iter()
        .filter_map(|&(a, e, u)| at(truth, a, periodic).map(|t| (e - t, u)))
        .collect();
    let n = pairs.len() as f64;
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / n;
    let d: Vec<(f64, f64)> = pairs.iter().map(|&(d, u)| (d - mean, u)).collect();
    let max = d.iter().map(|p| p.0.abs()).fold(0.0, f64::max);
    let rms = (d.iter().map(|p| p.0 * p.0).sum::<f64>() / n).sqrt();
    let covered = d.iter().filter(|p| p.0.abs() <= 2.0 * p.1).count() as f64 / n;
    (max, rms, covered)
}

/// The DUT 20 ms late, swept over a turn both ways at four speeds (20–90°/s).
///
/// The bars: τ within 5 % (the issue's; measured 20.0000 ms ± 0.06 µs: with four speeds the fit
/// sees the lag through 6480″ of difference at 90°/s, against 0.5″ of noise per sample); the
/// map within 1.5″ of the truth (measured 0.59″, rms 0.18″: the DUT's 1″ quantum and 0.5″ noise
/// over 4 passes a direction, ~0.2″ per point, the worst of 3600 ~3σ); ≥ 85 % of the points
/// within 2u (measured 91 %; a standard u gives 95 % for Gaussian errors, the quantization's
/// are not). With the lag ignored (`--latency 0`) the same map is more than 100″ off.
#[test]
fn latency_is_estimated_and_removed() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(
        &testdata("scenarios/latency.toml"),
        dir.path(),
        "latency.csv",
    );
    let out = dir.path().join("out");
    let o = reference(&log, "dut", "ref", &out, &[]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(&summary, &["latency", "estimated, removed"]);
    let report = read_json(&out.join("report.json"));
    let d = &report["details"];
    let tau = d["latency_s"].as_f64().unwrap();
    println!("τ = {tau} s, u {}", d["latency"]["u_s"]);
    assert!((tau - 0.02).abs() < 0.05 * 0.02, "τ = {tau}");
    assert_eq!(d["latency"]["source"], "estimated");
    let truth = table(&dir.path().join("latency.truth/dut.csv")).1;
    let (max, rms, covered) = against_truth(&table(&out.join("dut.csv")).1, &truth, true);
    println!(
        "map − truth: max {max:.3}″, rms {rms:.3}″, {:.1} % within 2u",
        100.0 * covered
    );
    assert!(max < 1.5 && covered >= 0.85, "{max} {covered}");

    let out0 = dir.path().join("out0");
    expect_exit(
        &reference(&log, "dut", "ref", &out0, &["--latency", "0"]),
        0,
    );
    let (max0, _, _) = against_truth(&table(&out0.join("dut.csv")).1, &truth, true);
    println!("with --latency 0: max {max0:.1}″");
    assert!(max0 > 100.0, "{max0}");
    let given = dir.path().join("given");
    expect_exit(
        &reference(&log, "dut", "ref", &given, &["--latency", "0.02"]),
        0,
    );
    let (max_given, _, _) = against_truth(&table(&given.join("dut.csv")).1, &truth, true);
    assert!(max_given < 1.5, "{max_given}");
}

/// −40…95° through a coupling with 30″ of play, readings wrapped: the range crosses 0.
///
/// The bars (the issue's): |map − truth| ≤ 2u at ≥ 90 % of the points (measured 91 %), and
/// the ends within the noise, not 15″ off: max 0.5″ (measured 0.11″; the DUT's 0.2″ quantum and
/// 0.1″ noise over 5 passes a direction, the ends' half reversal from the 20 points next to them
/// known to ~0.03″). The table runs from −39.8° to 94.9°, never above 360°.
#[test]
fn backlash_at_the_ends_of_a_range_across_zero() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(
        &testdata("scenarios/backlash.toml"),
        dir.path(),
        "backlash.csv",
    );
    let out = dir.path().join("out");
    let o = reference(&log, "dut", "ref", &out, &[]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(
        &summary,
        &["one direction", "half the reversal", "across 0°"],
    );
    let (range, got) = table(&out.join("dut.csv"));
    let (lo, hi) = range.unwrap();
    println!("range {lo}° to {hi}°");
    assert!(
        lo < -39.0 && lo > -41.0 && hi > 94.0 && hi < 96.0,
        "{lo} {hi}"
    );
    assert!(got.iter().all(|r| r.0 < 360.0));
    let truth = table(&dir.path().join("backlash.truth/dut.csv")).1;
    let (max, rms, covered) = against_truth(&got, &truth, false);
    println!(
        "map − truth: max {max:.3}″, rms {rms:.3}″, {:.1} % within 2u",
        100.0 * covered
    );
    assert!(max < 0.5 && covered >= 0.9, "{max} {covered}");
    let report = read_json(&out.join("report.json"));
    let ends = &report["details"]["one_direction_points"];
    assert!(
        (ends["max_correction_arcsec"].as_f64().unwrap() - 15.0).abs() < 1.0,
        "{ends}"
    );
    assert!(report["details"]["range"]["start_deg"].as_f64().unwrap() < 0.0);
}

/// An open-loop reference, 21 pole pairs, ripple 700″ at order 126 and 150″ at 252.
///
/// The bars: the ripple found within 1 % (measured 700.0″, 150.0″: a least-squares fit over
/// 3600 points of a term 700× the noise per point); the encoder's orders 1 and 2 within 2″ of
/// 800″ and 650″ and nothing above 5″ at order 126 (measured: map within 1.3″ of the truth);
/// without --ref-kind commanded order 126 stays in the map at ~700″.
#[test]
fn a_commanded_reference_has_its_ripple_taken_out() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(
        &testdata("scenarios/commanded.toml"),
        dir.path(),
        "commanded.csv",
    );
    let out = dir.path().join("out");
    let extra = ["--ref-kind", "commanded", "--pole-pairs", "21"];
    let o = reference(&log, "encoder", "commanded", &out, &extra);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(&summary, &["motor ripple", "order 126"]);
    let report = read_json(&out.join("report.json"));
    let terms = report["details"]["ripple"]["terms"]
        .as_array()
        .unwrap()
        .clone();
    let amp = |k: u64| {
        terms.iter().find(|t| t["harmonic"] == k).unwrap()["amplitude_arcsec"]
            .as_f64()
            .unwrap()
    };
    println!("ripple k=6: {}″, k=12: {}″", amp(6), amp(12));
    assert!((amp(6) - 700.0).abs() < 7.0 && (amp(12) - 150.0).abs() < 1.5);
    let orders = report["channels"]["encoder"]["harmonics"]
        .as_array()
        .unwrap()
        .clone();
    let order = |h: u64| {
        orders
            .iter()
            .find(|o| o["order"] == h)
            .map_or(0.0, |o| o["amplitude_arcsec"].as_f64().unwrap())
    };
    println!(
        "orders 1, 2, 126: {}″ {}″ {}″",
        order(1),
        order(2),
        order(126)
    );
    assert!((order(1) - 800.0).abs() < 2.0 && (order(2) - 650.0).abs() < 2.0);
    assert!(order(126) < 5.0);
    let truth = table(&dir.path().join("commanded.truth/encoder.csv")).1;
    let (max, rms, covered) = against_truth(&table(&out.join("encoder.csv")).1, &truth, true);
    println!(
        "map − truth: max {max:.3}″, rms {rms:.3}″, {:.1} % within 2u",
        100.0 * covered
    );
    assert!(max < 3.0, "{max}");

    let plain = dir.path().join("plain");
    expect_exit(&reference(&log, "encoder", "commanded", &plain, &[]), 0);
    let report = read_json(&plain.join("report.json"));
    let o126 = report["channels"]["encoder"]["harmonics"]
        .as_array()
        .unwrap()
        .iter()
        .find(|o| o["order"] == 126)
        .map_or(0.0, |o| o["amplitude_arcsec"].as_f64().unwrap());
    // The ripple stays in a map against the commanded angle taken as an encoder (599.5″ at
    // order 126 in the reading's spectrum: the encoder's error modulates its phase).
    assert!(o126 > 400.0, "{o126}");
}

#[test]
fn reference_kind_and_latency_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "x.csv", "t,a,b\n0,0,0\n");
    let out = dir.path().join("out");
    for (extra, says) in [
        (&["--pole-pairs", "7"][..], "--ref-kind commanded"),
        (&["--ref-kind", "commanded"][..], "--pole-pairs"),
        (&["--latency", "soon"][..], "auto"),
    ] {
        let o = reference(&log, "a", "b", &out, extra);
        let err = expect_exit(&o, 2);
        assert_mentions(&err, &[says]);
    }
}

/// A moteus dump simulated with a known truth: 21 pole pairs, the rotor pulled by a ripple of
/// 6 per electrical turn (0.15°), an encoder erring by 0.2° at order 1 and 0.15° at order 2,
/// read as raw uint16 (19.8″ quantum); 1060 samples a turn each way, as moteus records.
///
/// The bar: the table within 25″ of the truth, rms 7″ (measured 17.1″, rms 5.3″). Why: each
/// point is the mean of 2 passes interpolated between samples 0.34° apart whose readings carry
/// the quantum's ±9.9″ (σ 5.7″ per reading), ~4–5″ per point; the worst of 3600 points (about
/// 1000 independent) ~3.5σ. The ripple (540″ at order 126) is found within 1 %.
///
/// u is honest: ≥ 90 % of the points within 2u (issue 24 item 4's bar). Both passes read the
/// same codes and no noise dithers them, so the quantum's error does not average: u holds its
/// whole `Δ/√12` = 5.709″ at every point (found from the readings: Δ = 360°/65536 = 19.775″).
/// Without that term u came from the passes' scatter alone and 34.6 % of the points were
/// within 2u.
#[test]
fn moteus_dump_is_calibrated_within_its_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let p = 21.0;
    let e = |th: f64| {
        0.2f64.to_radians() * (th + 0.5).cos() + 0.15f64.to_radians() * (2.0 * th - 1.0).cos()
    };
    let rho = |phi: f64| 0.15f64.to_radians() * (6.0 * phi + 0.3).cos();
    let mut text = String::from("CAL start\n");
    let n = 1060usize;
    let line = |dir: u8, k: usize| {
        let phase = k as f64 * p * 65536.0 / n as f64; // electrical phase, counts
        let c = phase / 65536.0 * TAU / p + 1.0; // commanded shaft angle
        let theta = c + rho(p * (c - 1.0));
        let enc = ((theta + e(theta)) / TAU * 65536.0)
            .round()
            .rem_euclid(65536.0) as u32;
        format!("{dir} {} {enc}\n", (phase.round() as u64 % 65536))
    };
    for k in 0..n + 4 {
        text += &line(1, k);
    }
    for k in (0..n + 4).rev() {
        text += &line(2, k);
    }
    text += "CAL done\n";
    let dump = write(dir.path(), "dump.txt", &text);
    let out = dir.path().join("out");
    let o = calib(&["moteus-dump", s(&dump), "-o", s(&out)]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    println!("{summary}");
    assert_mentions(&summary, &["21 pole pairs", "order 126"]);
    let moteus = std::fs::read_to_string(out.join("moteus.txt")).unwrap();
    assert_eq!(moteus.lines().count(), 259);
    // The truth at reading r: r − θ with θ + e(θ) = r.
    let truth: Vec<(f64, f64, f64)> = (0..3600)
        .map(|i| {
            let r = (i as f64 * 0.1).to_radians();
            let mut th = r;
            for _ in 0..50 {
                th = r - e(th);
            }
            (i as f64 * 0.1, (r - th).to_degrees() * 3600.0, 0.0)
        })
        .collect();
    let (max, rms, covered) = against_truth(&table(&out.join("encoder.csv")).1, &truth, true);
    println!(
        "map − truth: max {max:.3}″, rms {rms:.3}″, {:.1} % within 2u",
        100.0 * covered
    );
    assert!(max < 25.0 && rms < 7.0, "{max} {rms}");
    assert!(covered >= 0.9, "{covered}");
    let report = read_json(&out.join("report.json"));
    let q = &report["details"]["quantization"];
    let quantum = 360.0 * 3600.0 / 65536.0;
    assert!(
        (q["quantum_arcsec"].as_f64().unwrap() - quantum).abs() < 1e-6,
        "{q}"
    );
    assert!(
        (q["u_arcsec"].as_f64().unwrap() - quantum / 12f64.sqrt()).abs() < 1e-6,
        "{q}"
    );
    assert!(q["noise_arcsec"].is_null(), "{q}");
}

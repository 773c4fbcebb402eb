//! End-to-end tests of `calib apply`: simulated runs corrected with their true error tables and
//! with tables from `calib csrr`, compared sample by sample with the simulator's true angles;
//! bad usage and bad tables refused with clear errors and no output.

use crate::common;

use calib_core::Sample;
use calib_core::angle::{ARCSEC_PER_RAD, wrap_pi};
use calib_core::simulate::Scenario;
use calib_io::{LogReader, ReadOptions};
use common::*;
use std::path::Path;

/// quick.toml without reading noise: what is left after a perfect correction is quantization.
fn noiseless_quick() -> String {
    let text = std::fs::read_to_string(testdata("scenarios/quick.toml")).unwrap();
    assert_eq!(text.matches("noise_arcsec = 0.05").count(), 2);
    text.replace("noise_arcsec = 0.05", "noise_arcsec = 0.0")
}

fn read_samples(log: &Path) -> Vec<Sample> {
    let opts = ReadOptions::default();
    let reader = LogReader::open(log, &opts).unwrap();
    let names: Vec<&str> = reader.channels().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["a", "b"]);
    reader.map(Result::unwrap).collect()
}

/// Per channel, the largest and the RMS |reading − true angle| of `log` (arcsec), against the
/// simulator's true angles for `scenario` (the log's samples in order).
fn deviation(log: &Path, scenario: &str) -> [(f64, f64); 2] {
    let scenario: Scenario = toml::from_str(scenario).unwrap();
    let truth: Vec<_> = scenario.samples().unwrap().with_truth().collect();
    let samples = read_samples(log);
    assert_eq!(samples.len(), truth.len());
    let mut out = [(0.0f64, 0.0f64); 2];
    for (s, t) in samples.iter().zip(&truth) {
        for k in 0..2 {
            let d = wrap_pi(s.values[k] - t.true_angles[k]).abs() * ARCSEC_PER_RAD;
            out[k].0 = out[k].0.max(d);
            out[k].1 += d * d;
        }
    }
    out.map(|(max, ss)| (max, (ss / samples.len() as f64).sqrt()))
}

/// Corrects `a` then `b` of `log` with the tables in `dir` (channels named by the tables' file
/// names); returns the doubly corrected log.
fn apply_both(log: &Path, tables: &Path, ext: &str) -> std::path::PathBuf {
    let dir = log.parent().unwrap();
    let once = dir.join(format!("a-corrected.{ext}"));
    let twice = dir.join(format!("ab-corrected.{ext}"));
    let o = calib(&["apply", s(&tables.join("a.csv")), s(log), "-o", s(&once)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["readings of `a`", "kept in [0, ", "wrote"]);
    let o = calib(&["apply", s(&tables.join("b.csv")), s(&once), "-o", s(&twice)]);
    expect_exit(&o, 0);
    twice
}

/// The true error table applied to a noise-free run gives back the true angle up to the
/// readings' quantization. Tolerance 0.0451″: half the 0.09″ quantum, times 1 + |e′| (≤ 1 + 10⁻³:
/// a rounding step δ in the reading moves the inverse θ(r) by δ/(1 + e′)), plus the linear
/// interpolation of the 36000-point truth table (A·(hΔ)²/8 ≤ 6·10⁻⁶″ for 20″ at order 8, 6″ at
/// order 16) and its 6-decimal rounding (5·10⁻⁷″). The RMS must be the quantum's 0.09/√12 = 0.026″:
/// the correction removed 51″ and 38″ peak-to-peak errors down to the resolution. Measured:
/// max 0.04504″ / 0.04501″, RMS 0.0260″ / 0.0242″ (a / b; MCAP and CSV alike), from 26.6″ / 20.2″.
#[test]
fn the_true_table_gives_back_the_true_angle_within_quantization() {
    for ext in ["mcap", "csv"] {
        let dir = tempfile::tempdir().unwrap();
        let text = noiseless_quick();
        let scenario = write(dir.path(), "quick.toml", &text);
        let log = simulate(&scenario, dir.path(), &format!("run.{ext}"));
        let raw = deviation(&log, &text);
        assert!(raw[0].0 > 20.0 && raw[1].0 > 15.0, "{raw:?}");
        let fixed = deviation(&apply_both(&log, &dir.path().join("run.truth"), ext), &text);
        for (k, (max, rms)) in fixed.into_iter().enumerate() {
            assert!(max <= 0.0451, "{ext} channel {k}: {max}″");
            assert!(
                (0.022..0.030).contains(&rms),
                "{ext} channel {k}: RMS {rms}″"
            );
        }
    }
}

/// `--keep` (issue 31): the raw channel stays as it was and the corrected one is beside it — a
/// CSV column `a_corrected`, an MCAP topic `/joint_states/corrected` — named in the summary and
/// `--json`. Against the simulator's truth the corrected channel is what `apply` without --keep
/// writes (the same bound, half the 0.09″ quantum: see above) and the raw one is untouched
/// (its 26.6″ error).
#[test]
fn keep_adds_the_corrected_channel_beside_the_raw_one() {
    for (ext, raw, corrected, added) in [
        ("csv", "a", "a_corrected", "a_corrected"),
        (
            "mcap",
            "/joint_states/a",
            "/joint_states/corrected/a",
            "/joint_states/corrected",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let text = noiseless_quick();
        let scenario = write(dir.path(), "quick.toml", &text);
        let log = simulate(&scenario, dir.path(), &format!("run.{ext}"));
        let table = dir.path().join("run.truth/a.csv");
        let out = dir.path().join(format!("kept.{ext}"));
        let o = calib(&["apply", s(&table), s(&log), "-o", s(&out), "--keep"]);
        expect_exit(&o, 0);
        assert_mentions(
            &stdout(&o),
            &[
                "`a` kept as it was (--keep)",
                &format!("`{added}`"),
                "wrote",
            ],
        );
        let o = calib(&[
            "apply",
            s(&table),
            s(&log),
            "-o",
            s(&out),
            "--keep",
            "--json",
        ]);
        expect_exit(&o, 0);
        let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        assert_eq!(json["beside"], serde_json::json!([added]), "{json}");

        let mut reader = LogReader::open(&out, &ReadOptions::default()).unwrap();
        let names: Vec<String> = reader.names().iter().map(|n| n.qualified.clone()).collect();
        let find = |name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .unwrap_or_else(|| panic!("{name} not in {names:?}"))
        };
        reader.select(&[find(raw), find(corrected)], Default::default());
        let scenario: Scenario = toml::from_str(&text).unwrap();
        let truth: Vec<_> = scenario.samples().unwrap().with_truth().collect();
        let (mut worst_raw, mut worst_fixed, mut n) = (0.0f64, 0.0f64, 0);
        for (sample, t) in reader.zip(&truth) {
            let v = sample.unwrap().values;
            let off = |x: f64| wrap_pi(x - t.true_angles[0]).abs() * ARCSEC_PER_RAD;
            worst_raw = worst_raw.max(off(v[0]));
            worst_fixed = worst_fixed.max(off(v[1]));
            n += 1;
        }
        assert_eq!(n, truth.len(), "{ext}");
        assert!(
            worst_raw > 20.0,
            "{ext}: the raw channel is kept: {worst_raw}″"
        );
        assert!(worst_fixed <= 0.0451, "{ext}: {worst_fixed}″");
    }
}

/// Tables from `calib csrr` on the standard quick.toml run (noise 0.05″) correct both sensors to
/// the method's accuracy. Per sample, corrected − true = the map's error at the reading (≤ 0.25″,
/// csrr_cli.rs's bound for this run) + noise (σ 0.05″, ≤ 0.25″ at 5σ over ~3300 samples) +
/// quantization (≤ 0.045″): ≤ 0.55″. The RMS, ≈ 0.08″ expected (0.074″ per-sample residual and the
/// map's own error), must stay under 0.15″, against ~15″ before correction. Measured: max
/// 0.197″ / 0.230″, RMS 0.058″ / 0.060″ (a / b), from RMS 15.4″ / 10.4″.
#[test]
fn csrr_tables_correct_both_sensors_to_the_methods_accuracy() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(testdata("scenarios/quick.toml")).unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let cal = dir.path().join("cal");
    expect_exit(&calib(&["csrr", s(&log), "-o", s(&cal)]), 0);
    let raw = deviation(&log, &text);
    let fixed = deviation(&apply_both(&log, &cal, "mcap"), &text);
    for k in 0..2 {
        assert!(raw[k].1 > 10.0, "{raw:?}");
        assert!(fixed[k].0 <= 0.55, "channel {k}: {:?}", fixed[k]);
        assert!(fixed[k].1 <= 0.15, "channel {k}: {:?}", fixed[k]);
    }
}

fn table_text(rows: &[(f64, f64)]) -> String {
    let mut t = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for (a, e) in rows {
        t.push_str(&format!("{a},{e},{}\n", -e));
    }
    t
}

#[test]
fn usage_errors_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "run.csv", "t,a,b\n0,10,20\n1,11,21\n");
    let table = write(
        dir.path(),
        "c.csv",
        &table_text(&[(0.0, 1.0), (180.0, -1.0)]),
    );
    // The default channel is the table's stem, `c`: not in the log.
    let out = dir.path().join("out.csv");
    let err = expect_exit(&calib(&["apply", s(&table), s(&log), "-o", s(&out)]), 2);
    assert_mentions(&err, &["no channel `c`", "it has: a, b", "--channel"]);
    assert!(!out.exists());
    // The input itself, even by another path.
    let same = dir.path().join(".").join("run.csv");
    let err = expect_exit(
        &calib(&[
            "apply",
            s(&table),
            s(&log),
            "-o",
            s(&same),
            "--channel",
            "a",
        ]),
        2,
    );
    assert_mentions(&err, &["would replace the log", "an input of this run"]);
    assert_eq!(
        std::fs::read_to_string(&log).unwrap(),
        "t,a,b\n0,10,20\n1,11,21\n"
    );
    // Another format.
    let err = expect_exit(
        &calib(&[
            "apply",
            s(&table),
            s(&log),
            "-o",
            s(&dir.path().join("out.mcap")),
            "--channel",
            "a",
        ]),
        2,
    );
    assert_mentions(&err, &["is a .csv log", "-o corrected.csv"]);
    // Missing files.
    let err = expect_exit(&calib(&["apply", "nope.csv", s(&log), "-o", s(&out)]), 2);
    assert_mentions(&err, &["nope.csv", "no such table"]);
    let err = expect_exit(&calib(&["apply", s(&table), "nope.mcap", "-o", s(&out)]), 2);
    assert_mentions(&err, &["nope.mcap", "no such file"]);
    assert!(!out.exists());
}

#[test]
fn a_csv_log_is_corrected_in_its_unit_and_named_by_the_table() {
    let dir = tempfile::tempdir().unwrap();
    // 4096 counts per revolution; `a` accumulates, `b` is untouched.
    let log = write(
        dir.path(),
        "run.csv",
        "t,a,b,session\n0.0,-1,7,0\n0.5,2048,7.25,0\n1.0,5000,7.5,-1\n",
    );
    let table = write(
        dir.path(),
        "a.csv",
        &table_text(&[(0.0, 36.0), (180.0, -36.0)]),
    );
    let out = dir.path().join("fixed.csv");
    let o = calib(&[
        "apply",
        s(&table),
        s(&log),
        "-o",
        s(&out),
        "--unit",
        "counts:4096",
    ]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["3 readings of `a`", "left unwrapped (detected"],
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(rows[0], ["t", "a", "b", "session"]);
    // 36″ = 36/1296000 rev = 0.11378 counts; the table is ±36″ at 0°/180°, linear between.
    let count = 4096.0 / 1_296_000.0;
    let e = |x: f64| {
        let deg = (x / 4096.0 * 360.0).rem_euclid(360.0);
        36.0 * (1.0 - 2.0 * (deg.min(360.0 - deg) / 180.0))
    };
    // Written with the input's decimals, at least enough for 0.001″ (6 in counts of 4096): within
    // half of that.
    for (row, x) in rows[1..].iter().zip([-1.0, 2048.0, 5000.0]) {
        let v: f64 = row[1].parse().unwrap();
        assert!((v - (x - e(x) * count)).abs() <= 0.5e-6, "{row:?}");
        assert_eq!(
            row[1].split_once('.').map(|(_, d)| d.len()),
            Some(6),
            "{row:?}"
        );
    }
    assert_eq!((rows[1][0], rows[1][2], rows[1][3]), ("0.0", "7", "0"));
    assert_eq!((rows[3][0], rows[3][2], rows[3][3]), ("1.0", "7.5", "-1"));
}

/// Both `calib apply` and `calib export` refuse a table whose grid is not uniform or does not
/// cover a revolution, naming the file and the line, with exit 1.
#[test]
fn tables_off_the_grid_are_refused_by_apply_and_export() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "run.csv", "t,a\n0,10\n1,11\n");
    let cases: [(&[(f64, f64)], &str); 3] = [
        (
            &[(0.0, 1.0), (90.0, 0.0), (200.0, -1.0), (270.0, 0.0)],
            "not uniform",
        ),
        (
            &[(0.0, 1.0), (90.0, -1.0), (180.0, 1.0)],
            "does not cover a full revolution",
        ),
        (
            &[(0.0, 1.0), (180.0, -1.0), (360.0, 1.0)],
            "360°, which is 0° again",
        ),
    ];
    // Each case is blamed on its last row, line 4.
    for (rows, what) in cases {
        let table = write(dir.path(), "a.csv", &table_text(rows));
        let out = dir.path().join("out.csv");
        let err = expect_exit(&calib(&["apply", s(&table), s(&log), "-o", s(&out)]), 1);
        assert_mentions(&err, &["a.csv", "line 4", "angle_deg", what]);
        assert!(!out.exists());
        let err = expect_exit(&calib(&["export", s(&table), "--format", "csv"]), 1);
        assert_mentions(&err, &["a.csv", "line 4", "angle_deg", what]);
    }
}

#[test]
fn a_bad_reading_names_the_line_and_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "run.csv", "t,a\n0,10\n1,11\n2,\n");
    let table = write(
        dir.path(),
        "a.csv",
        &table_text(&[(0.0, 1.0), (180.0, -1.0)]),
    );
    let out = dir.path().join("out.csv");
    let err = expect_exit(&calib(&["apply", s(&table), s(&log), "-o", s(&out)]), 1);
    assert_mentions(&err, &["run.csv", "line 4", "`a`"]);
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(left.len(), 2, "{left:?}");
}

/// The Python-made fixture: the JSON field `ref` corrected (degrees), the JointState topic and
/// the foreign `/status` topic copied; the summary says so.
#[test]
fn mcap_fixture_json_channel_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let table = write(
        dir.path(),
        "t.csv",
        &table_text(&[(0.0, 1.0), (180.0, -1.0)]),
    );
    let out = dir.path().join("fixed.mcap");
    let fixture = testdata("mcap/fixture.mcap");
    let o = calib(&[
        "apply",
        s(&table),
        s(&fixture),
        "-o",
        s(&out),
        "--channel",
        "ref",
    ]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &[
            "297 readings of `ref`",
            "from -1 to 74.75 deg",
            "kept in [-180, 180) deg (detected; see --wrap)",
            "310 other messages copied unchanged",
            "topic `/status`",
        ],
    );
    let reader = LogReader::open(&out, &ReadOptions::default()).unwrap();
    assert_eq!(reader.count(), 295);
}

//! End-to-end tests of `calib shift-angle`, `calib uncertainty` and `calib compare` at the process
//! boundary: exit codes, written files, messages.

use crate::common;

use common::{calib, s, stderr};
use std::path::{Path, PathBuf};

/// `testdata/shift-angle/NAME`.
fn shift_angle_data(name: &str) -> PathBuf {
    common::testdata("shift-angle").join(name)
}

/// `(angle, error)` of a CSV with angle in column 0 and error in column `col`.
fn column(path: &Path, col: usize) -> Vec<(f64, f64)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), f[col].parse().unwrap())
        })
        .collect()
}

#[test]
fn shift_angle_writes_tables_and_report_that_match_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = calib(&[
        "shift-angle",
        s(&shift_angle_data("readings.csv")),
        "-o",
        s(&out),
        "--budget",
        s(&shift_angle_data("table3.toml")),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = String::from_utf8(o.stdout).unwrap();
    assert!(
        summary.contains("360 points") && summary.contains("k = 2.160"),
        "{summary}"
    );

    let encoder = std::fs::read_to_string(out.join("encoder.csv")).unwrap();
    assert!(encoder.starts_with(
        "angle_deg,error_arcsec,correction_arcsec,u_arcsec,expanded_uncertainty_arcsec\n"
    ));
    let got = column(&out.join("encoder.csv"), 1);
    let truth = column(&shift_angle_data("truth_encoder.csv"), 2);
    assert_eq!(got.len(), 360);
    // σ = 0.03″ per reading; one reading per α at S > 0: 5σ bounds the largest of 360 errors.
    for ((a, e), (ta, t)) in got.iter().zip(&truth) {
        assert_eq!(a, ta);
        assert!((e - t).abs() < 0.15, "{a}°: {e} vs {t}");
    }
    let polygon = column(&out.join("polygon.csv"), 1);
    let beta = column(&shift_angle_data("truth_polygon.csv"), 1);
    for ((_, b), (_, t)) in polygon.iter().zip(&beta) {
        // β: ≈ σ·sqrt(2/24) ≈ 0.009″; 0.045″ is 5 of those.
        assert!((b - t).abs() < 0.045, "{b} vs {t}");
    }

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["method"], "shift-angle");
    assert_eq!(report["channels"]["encoder"]["table"], "encoder.csv");
    assert_eq!(report["channels"]["encoder"]["points"], 360);
    assert_eq!(report["details"]["polygon"].as_array().unwrap().len(), 24);
    assert_eq!(report["details"]["budget"]["effective_dof"], 13);
    assert!(
        report["details"]["residuals"]["sigma_arcsec"]
            .as_f64()
            .unwrap()
            < 0.035
    );
    assert!(
        report["details"]["sin_fit"]["amplitude_arcsec"]
            .as_f64()
            .unwrap()
            > 4.9
    );
}

#[test]
fn the_papers_method_prints_json_and_agrees_with_the_joint_fit() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let readings = shift_angle_data("readings.csv");
    let o = calib(&[
        "shift-angle",
        s(&readings),
        "-o",
        s(&a),
        "--method",
        "paper",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["details"]["estimator"], "paper");
    // No per-point uncertainty without a budget: said in the warnings, empty u column.
    assert!(report["warnings"].to_string().contains("--budget"));
    assert!(
        calib(&["shift-angle", s(&readings), "-o", s(&b)])
            .status
            .success()
    );
    let (pa, jb) = (
        column(&a.join("encoder.csv"), 1),
        column(&b.join("encoder.csv"), 1),
    );
    for ((_, p), (_, j)) in pa.iter().zip(&jb) {
        // The fixture is the paper's design: both are its least-squares estimate.
        assert!((p - j).abs() < 2e-6, "{p} vs {j}");
    }
}

/// The fixture with `edit` applied to its lines (header included).
fn edited_readings(dir: &Path, edit: impl FnOnce(&mut Vec<String>)) -> PathBuf {
    let text = std::fs::read_to_string(shift_angle_data("readings.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    edit(&mut lines);
    let path = dir.join("readings.csv");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

#[test]
fn bad_readings_are_named_and_leave_no_tables() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // Line 100 is shift 0, start face 5, step 3.
    let missing = edited_readings(dir.path(), |l| {
        assert_eq!(
            l[99],
            format!("0,5,3,{}", l[99].rsplit(',').next().unwrap())
        );
        l.remove(99);
    });
    let o = calib(&["shift-angle", s(&missing), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("readings.csv") && e.contains("start face 5: no reading at step 3"),
        "{e}"
    );
    assert!(!out.join("encoder.csv").exists());

    let duplicate = edited_readings(dir.path(), |l| {
        let copy = l[99].clone();
        l.push(copy);
    });
    let o = calib(&["shift-angle", s(&duplicate), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("line 914") && e.contains("line 100") && e.contains("duplicate"),
        "{e}"
    );

    let o = calib(&[
        "shift-angle",
        s(&shift_angle_data("readings.csv")),
        "--faces",
        "12",
        "-o",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("12 faces"), "{}", stderr(&o));

    // Only start face 1 everywhere: the polygon is not determined.
    let single = edited_readings(dir.path(), |l| {
        l.retain(|x| x.starts_with("shift") || x.split(',').nth(1) == Some("1"));
    });
    let o = calib(&["shift-angle", s(&single), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("pitch deviations are not determined"),
        "{}",
        stderr(&o)
    );
    assert!(!out.join("encoder.csv").exists());

    let o = calib(&["shift-angle", s(&dir.path().join("nope.csv"))]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("nope.csv"));
    assert_eq!(
        calib(&["shift-angle", "--method", "best", "x.csv"])
            .status
            .code(),
        Some(2)
    );
}

#[test]
fn uncertainty_reproduces_table_3_and_names_bad_components() {
    let o = calib(&["uncertainty", s(&shift_angle_data("table3.toml")), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((r["combined_standard_uncertainty"].as_f64().unwrap() - 0.0692).abs() < 5e-4);
    assert_eq!(r["effective_dof"], 13);
    assert!((r["coverage_factor"].as_f64().unwrap() - 2.16).abs() < 5e-3);
    assert!((r["expanded_uncertainty"].as_f64().unwrap() - 0.15).abs() < 1e-3);
    assert_eq!(r["components"].as_array().unwrap().len(), 8);

    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("b.toml");
    std::fs::write(
        &bad,
        "[[component]]\nname = \"Lamp\"\nhalf_width = 0.1\ndistribution = \"gaussian\"\n",
    )
    .unwrap();
    let o = calib(&["uncertainty", s(&bad)]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("b.toml") && e.contains("component `Lamp`") && e.contains("rectangular"),
        "{e}"
    );
    std::fs::write(
        &bad,
        "[[component]]\nname = \"Lamp\"\nu = 0.1\ndof = 5\nwidth = 3\n",
    )
    .unwrap();
    let e = stderr(&calib(&["uncertainty", s(&bad)]));
    assert!(
        e.contains("b.toml: line 5") && e.contains("unknown field `width`"),
        "{e}"
    );
    std::fs::write(&bad, "[[component]\n").unwrap();
    let o = calib(&["uncertainty", s(&bad)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("b.toml: line 1"), "{}", stderr(&o));
}

#[test]
fn compare_passes_within_uncertainty_and_lists_failures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    assert!(
        calib(&[
            "shift-angle",
            s(&shift_angle_data("readings.csv")),
            "-o",
            s(&out),
            "--budget",
            s(&shift_angle_data("table3.toml")),
        ])
        .status
        .success()
    );
    // A "self-calibration" of the same encoder: the truth on a 0.5° grid, u = 0.01″.
    let truth = column(&shift_angle_data("truth_encoder.csv"), 2);
    let mut selfcal = String::from("angle_deg,error_arcsec,u_arcsec\n");
    for w in 0..720 {
        let (i, f) = (w / 2, (w % 2) as f64 * 0.5);
        let (a, b) = (truth[i].1, truth[(i + 1) % 360].1);
        selfcal += &format!("{},{},0.01\n", w as f64 * 0.5, a + (b - a) * f);
    }
    let selfcal_path = dir.path().join("self.csv");
    std::fs::write(&selfcal_path, &selfcal).unwrap();
    let enc = out.join("encoder.csv");
    let o = calib(&["compare", s(&enc), s(&selfcal_path), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("0 of 360 points with En > 1"), "{text}");
    assert!(out.join("compare.csv").exists());

    // One clear failure: the second map 1000″ off at 90°.
    let bumped: String = selfcal
        .lines()
        .map(|l| if l.starts_with("90,") { "90,1000,0.01".into() } else { l.to_string() } + "\n")
        .collect();
    let bumped_path = dir.path().join("bumped.csv");
    std::fs::write(&bumped_path, bumped).unwrap();
    // A failed gate: exit 3, the listing on standard output, compare.csv written all the same.
    std::fs::remove_file(out.join("compare.csv")).unwrap();
    let o = calib(&["compare", s(&enc), s(&bumped_path), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(3));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("1 of 360 points with En > 1") && text.contains("90.0000"),
        "{text}"
    );
    assert!(stderr(&o).contains("gate failed: 1 of 360 points with En > 1"));
    let csv = std::fs::read_to_string(out.join("compare.csv")).unwrap();
    assert_eq!(csv.lines().count(), 361, "a header and one row per point");

    // No uncertainty in the second map and no --U2: bad usage.
    let bare = dir.path().join("bare.csv");
    std::fs::write(&bare, "angle_deg,error_arcsec\n0,0\n180,0\n").unwrap();
    let o = calib(&["compare", s(&enc), s(&bare), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--U2"));
    let o = calib(&["compare", s(&enc), s(&bare), "--U2", "100", "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

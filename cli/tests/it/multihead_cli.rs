//! End-to-end tests of `calib multihead`: the SelfA 12-head run against its truth with both
//! methods, and bad inputs (exit code, message, nothing written).

use crate::common::{self, compare, json, multihead};

use common::*;
use compare::max_diff_zero_mean;
use json::read_json;
use multihead::{HEADS, multihead, selfa_log};
use serde_json::Value;
use std::path::Path;

/// Head angle errors the scenario gives h1..h12, arcsec.
const HEAD_ERRORS: [f64; 12] = [
    0.0, 1.8, -2.5, 0.9, 3.1, -1.2, 2.2, -0.7, -3.4, 1.5, 0.6, -2.0,
];

/// Largest |table − truth table| over the truth's grid, both with their mean removed, arcsec.
fn max_diff(table: &Path, truth: &Path) -> f64 {
    let got = read_table(table);
    max_diff_zero_mean(&read_table(truth), |a| interpolate(&got, a))
}

fn orders(v: &Value) -> Vec<u64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|o| o.as_u64().unwrap())
        .collect()
}

#[test]
fn selfa_joint_meets_the_bar_and_names_the_blind_orders() {
    let dir = tempfile::tempdir().unwrap();
    let log = selfa_log(dir.path());
    let out = dir.path().join("out");
    let o = multihead(&log, &out, &[]);
    expect_exit(&o, 0);
    // report.html: the map, its zoom and the spectrum with order 84 (lcm of 3, 4, 7) marked blind.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for id in [
        "fig-map-h1",
        "fig-zoom-h1",
        "fig-spectrum",
        "blind order (left out)",
        "h12",
    ] {
        assert!(html.contains(id), "report.html lacks {id}");
    }
    assert!(!html.contains("NaN"));
    // Bar 0.05″; measured 0.0075″.
    let err = max_diff(&out.join("h1.csv"), &dir.path().join("selfa.truth/h1.csv"));
    assert!(err < 0.05, "{err}″");
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["method"], "multihead");
    assert_eq!(report["channels"]["h1"]["table"], "h1.csv");
    let d = &report["details"];
    assert_eq!(d["solver"], "joint");
    assert_eq!(orders(&d["blind_orders"]), [84, 168, 252, 336, 420, 504]);
    assert_eq!(d["max_order"], 512);
    let heads = d["heads"].as_array().unwrap();
    assert_eq!(heads.len(), 12);
    for (h, want) in heads.iter().zip(HEAD_ERRORS) {
        let got = h["angle_error_arcsec"].as_f64().unwrap();
        assert!((got - want).abs() < 0.01, "{}: {got}″", h["name"]);
    }
    assert_eq!(heads[4]["readings"], "relative_to_nominal");
    assert!((heads[1]["nominal_deg"].as_f64().unwrap() - 360.0 / 7.0).abs() < 1e-12);
    let residual = d["residual_rms_arcsec"].as_f64().unwrap();
    assert!(residual < 0.02, "{residual}″");
    assert_eq!(report["warnings"].as_array().unwrap().len(), 0);
    // Every point has its standard uncertainty, summarized in the report, the html and stdout.
    let table = std::fs::read_to_string(out.join("h1.csv")).unwrap();
    assert!(
        table.starts_with("angle_deg,error_arcsec,correction_arcsec,u_arcsec"),
        "{}",
        &table[..80]
    );
    let u = &d["uncertainty"]["h1"];
    let u_max = u["u_max_arcsec"].as_f64().unwrap();
    // ≈ σ·sqrt(2K·(J+2)/(4J)/N): 0.0104″ per head, K = 506 orders, J = 12 heads, N = 8801
    // samples gives 0.0019″ (see the core's `multihead` test for its coverage of the truth).
    assert!((0.0005..0.01).contains(&u_max), "{u}");
    assert_eq!(u["components"][0]["type"], "A");
    assert!(html.contains("±2u"), "report.html lacks the band");
    assert_mentions(
        &stdout(&o),
        &[
            "standard uncertainty u of the table",
            "read by 12 heads — joint least squares",
            "h5 ",
            "3.1004",
            "blind orders (no head pair sees them; the map lacks them): 84, 168, 252",
            "residual RMS 0.01",
            "h1.csv",
        ],
    );
}

#[test]
fn eda_with_one_set_misses_its_multiples_and_json_goes_to_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let log = selfa_log(dir.path());
    let truth = dir.path().join("selfa.truth/h1.csv");

    // All three sets (inferred): meets the bar as well (measured 0.0116″).
    let out = dir.path().join("eda");
    let o = multihead(&log, &out, &["--method", "eda"]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &[
            "equal-division average",
            "h1, h5, h9",
            "h1, h3, h7, h11",
            "h1, h2, h4, h6, h8, h10, h12",
            "N = 7",
        ],
    );
    let err = max_diff(&out.join("h1.csv"), &truth);
    assert!(err < 0.05, "{err}″");

    // The square set alone cannot see the scale's orders 4, 12, 24, 36 and 72.
    let out = dir.path().join("square");
    let o = multihead(
        &log,
        &out,
        &[
            "--method",
            "eda",
            "--sets",
            "h1,h3,h7,h11",
            "--max-order",
            "100",
            "--json",
        ],
    );
    expect_exit(&o, 0);
    let report: Value = serde_json::from_str(&stdout(&o)).expect("--json prints the report");
    assert_eq!(report["details"]["solver"], "eda");
    let blind = orders(&report["details"]["blind_orders"]);
    assert_eq!(blind, (1..=25).map(|k| 4 * k).collect::<Vec<u64>>());
    assert_eq!(report["details"]["sets"][0]["blind_to_multiples_of"], 4);
    assert!(max_diff(&out.join("h1.csv"), &truth) > 0.1);
}

#[test]
fn bad_heads_are_usage_errors_that_say_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let log = selfa_log(dir.path());
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec!["multihead", s(&log), "-o", s(&out)];
        args.extend_from_slice(extra);
        calib(&args)
    };

    // A head the log does not have: the log's channels are listed.
    let o = run(&["--heads", "h1@0,h13@90"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["h13", "it has: h1, h2, h3", "h12"]);
    assert_no_output(&out);

    let o = run(&["--heads", "h1@0,h2@90,h1@180"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["`h1` twice"]);

    for spec in ["h1@0,h2", "h1@0,h2@ninety", "h1@0,@90", "h1@0,h2@1/0"] {
        let o = run(&["--heads", spec]);
        let err = expect_exit(&o, 2);
        assert_mentions(&err, &["NAME@DEG"]);
    }
    let o = run(&["--heads", "h1@0"]);
    expect_exit(&o, 2);

    let o = run(&["--heads", HEADS, "--sets", "h1,h5,h9"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["--method eda"]);

    let o = run(&["--heads", HEADS, "--method", "eda", "--sets", "h1,h5,h13"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["`h13` is not one of the heads"]);

    let o = run(&["--heads", HEADS, "--method", "eda", "--sets", "h1,h3,h9"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["h1, h3, h9", "equally spaced"]);

    let o = run(&["--heads", HEADS, "--method", "eda", "--sets", "h3,h11"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["first head `h1`"]);

    let o = run(&["--heads", "h1@0,h2@360/7", "--method", "eda"]);
    let err = expect_exit(&o, 2);
    assert_mentions(&err, &["no heads are equally spaced"]);

    let o = run(&["--heads", HEADS, "--max-order", "0"]);
    expect_exit(&o, 2);
    assert_no_output(&out);
}

#[test]
fn bad_data_are_data_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    // A quarter of a revolution of two heads 180° apart.
    let mut text = String::from("t,p,q\n");
    for k in 0..=90 {
        text.push_str(&format!("{:.2},{k}.0,{k}.0\n", k as f64 * 0.01));
    }
    let log = write(dir.path(), "short.csv", &text);
    let o = calib(&["multihead", s(&log), "--heads", "p@0,q@180", "-o", s(&out)]);
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &["short.csv", "`p`", "without samples", "whole revolution"],
    );
    assert_no_output(&out);

    // The SelfA log asked for more orders than its sampling resolves.
    let log = selfa_log(dir.path());
    let o = multihead(&log, &out, &["--max-order", "1000"]);
    let err = expect_exit(&o, 1);
    assert_mentions(&err, &["order 1000", "2048", "--max-order"]);
    assert_no_output(&out);
}

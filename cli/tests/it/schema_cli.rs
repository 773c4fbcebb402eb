//! Real outputs of every method against the published JSON Schemas (`docs/*.schema.json`,
//! generated from the types; `published_schemas_match_the_types` in the binary keeps them
//! current): report.json of csrr (joint with a truth, paper), multihead (joint, EDA), tdr (with a
//! reference), reference (a resolver with a gap) and shift-angle (joint with a budget, paper),
//! summary.json of a batch with a passed, a failed and an unreadable log, and `inspect --json`
//! of an MCAP log with three topics and of a CSV log. Every report is also read back into
//! `calib_core::Report` (unknown keys refused) and must serialize to the same bytes.

use crate::common::{self, coast, multihead, reference};

use coast::{coast_log, tdr_with_reference};
use common::*;
use multihead::{multihead, selfa_log};
use reference::reference;
use serde_json::Value;
use std::path::Path;

fn schema(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../docs")
        .join(name);
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

/// Asserts that `text` (from `what`) is valid against `docs/<schema_name>`.
#[track_caller]
fn assert_valid(schema_name: &str, text: &str, what: &str) -> Value {
    let validator = jsonschema::validator_for(&schema(schema_name)).unwrap();
    let instance: Value = serde_json::from_str(text).unwrap();
    let errors: Vec<String> = validator
        .iter_errors(&instance)
        .map(|e| format!("{} at {}", e, e.instance_path()))
        .collect();
    assert!(
        errors.is_empty(),
        "{what} against {schema_name}:\n{}",
        errors.join("\n")
    );
    instance
}

/// Validates `dir/report.json` of `method`, reads it back into the type and writes it again.
#[track_caller]
fn assert_report(dir: &Path, method: &str) -> Value {
    let text = std::fs::read_to_string(dir.join("report.json")).unwrap();
    let value = assert_valid("report.schema.json", &text, &format!("{method}'s report"));
    assert_eq!(value["method"], method);
    assert_eq!(value["schema_version"], 1);
    let report: calib_core::Report = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{method}'s report does not read back: {e}"));
    assert_eq!(
        calib_io::report::render_json(&report).unwrap(),
        text,
        "{method}'s report changes when read and written again"
    );
    value
}

#[test]
fn csrr_reports_match_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let truth = dir.path().join("run.truth");
    let out = dir.path().join("joint");
    expect_exit(
        &calib(&["csrr", s(&log), "--truth", s(&truth), "-o", s(&out)]),
        0,
    );
    let r = assert_report(&out, "csrr");
    assert_eq!(r["channels"]["a"]["after_correction"]["against"], "truth");
    let out = dir.path().join("paper");
    expect_exit(
        &calib(&["csrr", s(&log), "--method", "paper", "-o", s(&out)]),
        0,
    );
    let r = assert_report(&out, "csrr");
    assert!(!r["details"]["paper_points"].as_array().unwrap().is_empty());
}

#[test]
fn multihead_reports_match_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    let log = selfa_log(dir.path());
    for method in ["joint", "eda"] {
        let out = dir.path().join(method);
        expect_exit(&multihead(&log, &out, &["--method", method]), 0);
        let r = assert_report(&out, "multihead");
        assert_eq!(r["details"]["solver"], method);
    }
}

#[test]
fn tdr_report_matches_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    let log = coast_log(dir.path());
    let out = dir.path().join("out");
    expect_exit(&tdr_with_reference(&log, &out), 0);
    let r = assert_report(&out, "tdr");
    assert_eq!(r["details"]["reference"]["channel"], "ref");
    assert_eq!(
        r["channels"]["enc"]["after_correction"]["against"],
        "reference"
    );
}

#[test]
fn reference_report_matches_the_schema() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = write(dir.path(), "resolver.toml", RESOLVER_SWEEP);
    let log = simulate(&scenario, dir.path(), "resolver.csv");
    let out = dir.path().join("out");
    expect_exit(&reference(&log, "resolver", "counter", &out, &[]), 0);
    let r = assert_report(&out, "reference");
    assert!(r["details"]["gap"].is_object(), "{}", r["details"]);
}

#[test]
fn shift_angle_reports_and_a_summary_match_the_schemas() {
    let dir = tempfile::tempdir().unwrap();
    let readings = testdata("shift-angle/readings.csv");
    let out = dir.path().join("budget");
    expect_exit(
        &calib(&[
            "shift-angle",
            s(&readings),
            "--budget",
            s(&testdata("shift-angle/table3.toml")),
            "-o",
            s(&out),
        ]),
        0,
    );
    let r = assert_report(&out, "shift-angle");
    assert!(r["details"]["budget"].is_object());
    let out = dir.path().join("paper");
    expect_exit(
        &calib(&[
            "shift-angle",
            s(&readings),
            "--method",
            "paper",
            "-o",
            s(&out),
        ]),
        0,
    );
    assert_report(&out, "shift-angle");

    // A batch of two: the readings fail a gate no real encoder meets (--max-pp 0.001″), and a
    // file with no readings cannot be calibrated (status `error`).
    let bad = write(
        dir.path(),
        "bad.csv",
        "shift_deg,start_face,step,reading_arcsec\n",
    );
    let out = dir.path().join("batch");
    let o = calib(&[
        "shift-angle",
        s(&readings),
        s(&bad),
        "--max-pp",
        "0.001",
        "-o",
        s(&out),
    ]);
    assert!(matches!(code(&o), 1 | 3), "{}", stderr(&o));
    let text = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let summary = assert_valid("summary.schema.json", &text, "summary.json");
    assert_eq!(summary["schema_version"], 1);
    let statuses: Vec<&str> = summary["logs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["status"].as_str().unwrap())
        .collect();
    assert_eq!(statuses, ["fail", "error"]);
}

#[test]
fn inspect_json_matches_the_schema() {
    for log in [testdata("mcap/clocks.mcap"), testdata("csv/small.csv")] {
        let o = calib(&["inspect", s(&log), "--json"]);
        expect_exit(&o, 0);
        let v = assert_valid(
            "inspect.schema.json",
            &stdout(&o),
            &log.display().to_string(),
        );
        assert_eq!(v["schema_version"], 1);
    }
}

/// `--json` of simulate, export, import, apply and compose, on a simulated run: each valid against its
/// schema and saying what the command did (the files it names exist, the counts are the run's).
#[test]
fn tool_json_outputs_match_their_schemas() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.mcap");
    let o = calib(&[
        "simulate",
        s(&testdata("scenarios/quick.toml")),
        "-o",
        s(&log),
        "--json",
    ]);
    expect_exit(&o, 0);
    let sim = assert_valid("simulate.schema.json", &stdout(&o), "simulate --json");
    assert_eq!(sim["channels"], serde_json::json!(["a", "b"]));
    assert!(sim["samples"].as_u64().unwrap() > 1000);
    let truth_a = sim["truth"][0]["table"].as_str().unwrap().to_string();
    assert!(Path::new(&truth_a).exists(), "{truth_a}");
    assert!(sim["truth"][0]["peak_to_peak_arcsec"].as_f64().unwrap() > 1.0);

    let lut = dir.path().join("a.lut");
    let o = calib(&[
        "export",
        &truth_a,
        "--format",
        "lut-i16",
        "-o",
        s(&lut),
        "--json",
    ]);
    expect_exit(&o, 0);
    let exp = assert_valid("export.schema.json", &stdout(&o), "export --json");
    assert_eq!(exp["format"], "lut-i16");
    assert!(lut.exists());

    let back = dir.path().join("back.csv");
    let o = calib(&[
        "import",
        s(&lut),
        "--format",
        "lut-i16",
        "-o",
        s(&back),
        "--json",
    ]);
    expect_exit(&o, 0);
    let imp = assert_valid("import.schema.json", &stdout(&o), "import --json");
    // The table exported and read back holds the truth's error to the i16 quantum.
    let pp = |v: &Value| v["peak_to_peak_arcsec"].as_f64().unwrap();
    assert!((pp(&imp) - pp(&sim["truth"][0])).abs() < 0.1, "{imp}");

    let fixed = dir.path().join("fixed.mcap");
    let o = calib(&[
        "apply",
        &truth_a,
        s(&log),
        "--channel",
        "a",
        "-o",
        s(&fixed),
        "--json",
    ]);
    expect_exit(&o, 0);
    let app = assert_valid("apply.schema.json", &stdout(&o), "apply --json");
    assert_eq!(app["corrected"].as_u64(), sim["samples"].as_u64());
    assert_eq!(app["outside"], 0);
    assert!(fixed.exists());

    let composed = dir.path().join("c.csv");
    let o = calib(&["compose", &truth_a, &truth_a, "-o", s(&composed), "--json"]);
    expect_exit(&o, 0);
    let com = assert_valid("compose.schema.json", &stdout(&o), "compose --json");
    // As many points as the tables composed.
    let rows = std::fs::read_to_string(&truth_a)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .count()
        - 1;
    assert_eq!(com["points"].as_u64(), Some(rows as u64));
    assert!(com["peak_to_peak_arcsec"].as_f64().unwrap() > 1.0);
    assert!(composed.exists());
}

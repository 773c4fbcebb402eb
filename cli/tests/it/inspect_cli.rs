//! End-to-end tests of `calib inspect` at the process boundary: the committed MCAP and CSV
//! fixtures, `--json`, and a simulated CSRR run.

use crate::common::{self, inspect};

use common::*;
use inspect::{inspect, inspect_json};
use serde_json::Value;

/// Rows of the human channel table: `(name, unit)` for each line under `channels`.
fn channel_rows(out: &str) -> Vec<(String, String)> {
    out.lines()
        .skip_while(|l| l.trim() != "channels")
        .skip(2)
        .take_while(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[0].to_string(), f[1].to_string())
        })
        .collect()
}

#[test]
fn mcap_fixture_lists_channels_and_the_exact_sample_count() {
    // make_fixture.py: 300 JointStates joined with JSON /reference, which is missing for
    // i = 100..=104, plus two stray JSON messages: aligned on a's clock, 295 samples (ref has
    // a gap of 6 intervals there); /status is skipped.
    let log = testdata("mcap/fixture.mcap");
    let out = inspect(&log, &[]);
    assert!(out.contains("  295 samples over 2.990 s"), "{out}");
    assert_eq!(
        channel_rows(&out),
        [("a", "rad"), ("b", "rad"), ("ref", "deg")].map(|(n, u)| (n.into(), u.into()))
    );
    assert!(out.contains("segments of a and b"), "{out}");
    assert!(out.contains("0 CSRR session(s)"), "{out}");
    // The dropped messages and the skipped topic are reported, not silently ignored.
    assert_mentions(
        &out,
        &[
            "warning: ",
            "fixture.mcap: 5 of 300 sample(s) of the clock `a` were dropped because channel `ref` could not be aligned there",
            "`/status`",
        ],
    );
}

#[test]
fn mcap_fixture_json_has_samples_channels_and_segments() {
    let v = inspect_json(&testdata("mcap/fixture.mcap"), &[]);
    let i = &v["inspection"];
    assert_eq!(i["samples"], 295);
    let names: Vec<&str> = i["channels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["a", "b", "ref"]);
    assert_eq!(i["channels"][0]["unit"], "rad");
    assert_eq!(i["channels"][2]["unit"], "deg");
    // ref = i/4 degrees for i = 0..299: its range is 0 … 74.75°.
    assert_eq!(i["channels"][2]["min"], 0.0);
    assert_eq!(i["channels"][2]["max"], 74.75);
    assert_eq!(i["pair"], serde_json::json!(["a", "b"]));
    let segments = i["segments"].as_array().unwrap();
    assert!(!segments.is_empty());
    let in_segments: u64 = segments
        .iter()
        .map(|s| s["samples"].as_u64().unwrap())
        .sum();
    assert_eq!(in_segments, 295, "every sample lies in one segment");
    assert_eq!(v["warnings"].as_array().unwrap().len(), 2, "{v}");
    assert!(v["log"].as_str().unwrap().ends_with("fixture.mcap"));
}

#[test]
fn csv_fixture_lists_both_channels_and_four_samples() {
    // testdata/csv/README.md: four rows of a two-channel log in degrees, `a` wraps.
    let log = testdata("csv/small.csv");
    let out = inspect(&log, &[]);
    assert!(out.contains("  4 samples over 0.300 s"), "{out}");
    assert_eq!(
        channel_rows(&out),
        [("a", "deg"), ("b", "deg")].map(|(n, u)| (n.into(), u.into()))
    );
    let a_row = out
        .lines()
        .find(|l| l.trim_start().starts_with("a "))
        .unwrap();
    assert!(a_row.trim_end().ends_with("yes"), "a wraps: {a_row}");

    let v = inspect_json(&log, &[]);
    let i = &v["inspection"];
    assert_eq!(i["samples"], 4);
    assert_eq!(i["channels"].as_array().unwrap().len(), 2);
    assert_eq!(i["channels"][0]["wrapped"], true);
    assert_eq!(i["channels"][1]["wrapped"], false);
    assert_eq!(i["channels"][1]["min"], 10.0);
    assert_eq!(i["channels"][1]["max"], 11.2);
    assert!(i["segments"].is_array());
    assert_eq!(i["gaps"], 0);
    assert_eq!(i["non_monotonic"], 0);
}

const QUICK_DELTAS: [f64; 5] = [0.0, 7.3, 23.9, 61.7, 151.1];

/// |a − b| in degrees on the circle.
fn circular_diff(a: f64, b: f64) -> f64 {
    ((a - b + 180.0).rem_euclid(360.0) - 180.0).abs()
}

/// Rotating segments that are CSRR sessions: `(session, relative angle in degrees)`.
fn sessions_of(v: &Value) -> Vec<(u64, f64)> {
    v["inspection"]["segments"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["kind"] == "rotating" && !s["session"].is_null())
        .map(|s| {
            (
                s["session"].as_u64().unwrap(),
                s["relative_angle_deg"].as_f64().unwrap(),
            )
        })
        .collect()
}

#[test]
fn simulated_run_shows_five_sessions_at_the_scenario_rotations() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");

    let out = inspect(&log, &[]);
    assert!(out.contains("3301 samples"), "{out}");
    assert!(
        out.contains("5 CSRR session(s) of at least one revolution"),
        "{out}"
    );
    for k in 0..5 {
        let row = out
            .lines()
            .find(|l| l.trim_start().starts_with("rotating") && l.ends_with(&format!("#{k}")))
            .unwrap_or_else(|| panic!("no rotating segment #{k}:\n{out}"));
        let rel: f64 = row.split_whitespace().nth(5).unwrap().parse().unwrap();
        // The relative angle is read through both sensors' errors (51″ and 38″ p-p): within
        // 0.01° (36″) of Δ.
        assert!(circular_diff(rel, QUICK_DELTAS[k]) < 0.01, "{row}");
    }

    let v = inspect_json(&log, &[]);
    let sessions = sessions_of(&v);
    assert_eq!(sessions.len(), 5, "{sessions:?}");
    for (k, (session, rel)) in sessions.iter().enumerate() {
        assert_eq!(*session, k as u64);
        assert!(
            circular_diff(*rel, QUICK_DELTAS[k]) < 0.01,
            "session {k}: {rel}°"
        );
    }
    for s in v["inspection"]["segments"].as_array().unwrap() {
        if s["kind"] == "rotating" {
            let revs = s["revolutions"].as_f64().unwrap();
            assert!(
                revs > 2.0 && revs < 2.5,
                "quick.toml: 2 revolutions + ramps: {s}"
            );
        }
    }
}

#[test]
fn simulated_csv_with_session_marks_shows_the_same_sessions() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.csv");
    let v = inspect_json(&log, &[]);
    assert_eq!(v["inspection"]["samples"], 3301);
    let sessions = sessions_of(&v);
    assert_eq!(sessions.len(), 5, "{sessions:?}");
    for (k, (_, rel)) in sessions.iter().enumerate() {
        assert!(
            circular_diff(*rel, QUICK_DELTAS[k]) < 0.01,
            "session {k}: {rel}°"
        );
    }
}

/// The same simulated run inspected as MCAP shows session #0 at 0.0000°, as CSV (sessions from
/// the `session` column) at 360.0000°: equal on the circle, but the human table and the JSON
/// should not depend on the log format (and Δ = 360° reads like a full relative turn).
#[test]
fn relative_angle_does_not_depend_on_the_log_format() {
    let dir = tempfile::tempdir().unwrap();
    let quick = testdata("scenarios/quick.toml");
    let csv = sessions_of(&inspect_json(&simulate(&quick, dir.path(), "run.csv"), &[]));
    let mcap = sessions_of(&inspect_json(
        &simulate(&quick, dir.path(), "run.mcap"),
        &[],
    ));
    assert_eq!(csv.len(), mcap.len());
    for ((_, c), (_, m)) in csv.iter().zip(&mcap) {
        assert!((c - m).abs() < 0.01, "csv {c}° vs mcap {m}°");
    }
}

#[test]
fn inspect_bad_inputs_exit_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.mcap");
    let err = expect_exit(&calib(&["inspect", s(&missing)]), 2);
    assert_mentions(&err, &["missing.mcap", "check the path"]);

    let empty = write(dir.path(), "empty.csv", "");
    let err = expect_exit(&calib(&["inspect", s(&empty)]), 1);
    assert_mentions(&err, &["empty.csv", "empty"]);

    let log = testdata("csv/small.csv");
    let err = expect_exit(&calib(&["inspect", s(&log), "--a", "nope"]), 2);
    assert_mentions(&err, &["small.csv", "`nope`", "a, b"]);

    let err = expect_exit(&calib(&["inspect", s(&log), "--unit", "degs"]), 2);
    assert_mentions(&err, &["degs", "deg, rad"]);
}

/// `calib inspect` says it lists "time stamps that go backwards", but the CSV reader rejects such
/// a log before inspect can count them, so the tool meant to diagnose the log cannot.
#[test]
fn inspect_reports_time_going_backwards_in_a_csv() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "back.csv",
        "t,a,b\n0.0,1,1\n0.1,2,2\n0.05,3,3\n0.2,4,4\n",
    );
    let v = inspect_json(&log, &[]);
    assert_eq!(v["inspection"]["non_monotonic"], 1);
}

/// `calib inspect` says which method a log's motion suits and with which channels (issue 31):
/// each bundled kind of run, simulated, gets its own method first.
#[test]
fn inspect_names_the_method_a_log_suits() {
    let dir = tempfile::tempdir().unwrap();
    for (scenario, method, channels) in [
        ("quick.toml", "csrr", vec!["a", "b"]),
        ("joint.toml", "reference", vec!["b", "ref"]),
        ("multihead.toml", "multihead", vec!["h1", "h2", "h3"]),
        ("spindown.toml", "reference", vec!["enc", "ref"]),
    ] {
        let log = simulate(
            &testdata(&format!("scenarios/{scenario}")),
            dir.path(),
            &format!("{scenario}.mcap"),
        );
        let o = calib(&["inspect", s(&log), "--json"]);
        expect_exit(&o, 0);
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        let first = &v["suggestions"][0];
        assert_eq!(first["method"], method, "{scenario}: {}", v["suggestions"]);
        let got: Vec<&str> = first["channels"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_str().unwrap())
            .collect();
        assert_eq!(&got[..channels.len()], channels.as_slice(), "{scenario}");
        // The summary prints the command to run.
        let text = stdout(&calib(&["inspect", s(&log)]));
        assert!(
            text.contains(&format!("calib {method} {}", s(&log))),
            "{scenario}: {text}"
        );
        if scenario == "spindown.toml" {
            // A shaft of many revolutions may also be a coast.
            assert_eq!(v["suggestions"][1]["method"], "tdr", "{}", v["suggestions"]);
        }
    }
}

/// `text` (a CSV log) with an empty column `notes` added as column `at` of every line.
fn with_empty_column(text: &str, at: usize) -> String {
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        let mut fields: Vec<&str> = line.split(',').collect();
        fields.insert(at, if i == 0 { "notes" } else { "" });
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// A CSV log with one column empty in every row (a notes column nobody filled): `calib inspect`
/// lists the column as empty and inspects the rest as if it were not there, wherever the
/// column stands (after the channels, or first, where it would set the clock); naming it as a
/// channel of the pair is a data error naming it.
#[test]
fn an_entirely_empty_column_is_listed_and_the_rest_inspected() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "quick.csv", &[]);
    let text = std::fs::read_to_string(&log).unwrap();
    let rows = text.lines().count() as u64 - 1;
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let plain = inspect_json(&log, &[]);
    assert_eq!(plain["inspection"]["samples"], rows);
    for at in [header.len(), 1] {
        let with = write(
            dir.path(),
            &format!("notes{at}.csv"),
            &with_empty_column(&text, at),
        );
        let v = inspect_json(&with, &[]);
        // What the log holds is what the log without the column holds.
        assert_eq!(v["inspection"], plain["inspection"], "column {at}");
        assert_eq!(v["suggestions"], plain["suggestions"], "column {at}");
        let warnings = v["warnings"].to_string();
        assert!(
            warnings.contains("column `notes` is empty (no reading in any row)"),
            "column {at}: {warnings}"
        );
        let out = inspect(&with, &[]);
        assert_mentions(
            &out,
            &["column `notes` is empty", &format!("{rows} samples")],
        );
        let o = calib(&["inspect", s(&with), "--a", "notes", "--b", "b"]);
        let err = expect_exit(&o, 1);
        assert_mentions(&err, &["channel `notes` is an empty column"]);
    }
}

//! End-to-end tests of the pipeline options every method command shares: several logs in one
//! call, gates and their exit status, `summary.json`, the JUnit file, and byte-identical outputs
//! from equal runs.

use crate::common::{self, json};

use common::*;
use json::read_json;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `calib args` run in `dir`, so that every path in the outputs is relative to it.
fn calib_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("cannot start calib")
}

/// `dir/logs/` with two simulated quick runs (seeds 1 and 2), the first again under `x/` (same
/// stem), and a log whose sensors never move. The quick maps are 51.1″ (a) and 38.4″ (b) p-p.
fn lab_logs(dir: &Path) -> Vec<&'static str> {
    let logs = dir.join("logs");
    std::fs::create_dir_all(logs.join("x")).unwrap();
    simulate_quick(&logs, "run1.mcap", &[]);
    simulate_quick(&logs, "run2.mcap", &[("seed", "seed = 2")]);
    std::fs::copy(logs.join("run1.mcap"), logs.join("x/run1.mcap")).unwrap();
    write(&logs, "still.csv", "t,a,b\n0,0,0\n0.1,0,0\n0.2,0,0\n");
    vec![
        "logs/run1.mcap",
        "logs/run2.mcap",
        "logs/x/run1.mcap",
        "logs/still.csv",
    ]
}

/// Every file under `dir`, relative, sorted, with its bytes.
fn tree(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(PathBuf, Vec<u8>)>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                out.push((path.strip_prefix(root).unwrap().to_path_buf(), bytes));
            }
        }
    }
    let mut files = Vec::new();
    walk(dir, dir, &mut files);
    files.sort();
    files
}

#[test]
fn several_logs_give_one_folder_each_a_summary_and_junit_and_equal_runs_equal_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let logs = lab_logs(dir.path());
    let mut args = vec!["csrr"];
    args.extend(&logs);
    args.extend(["-o", "out", "--junit", "out/junit.xml", "--max-pp", "45"]);
    args.extend(["--jobs", "2"]);
    let o = calib_in(dir.path(), &args);
    // A log that cannot be calibrated outranks the failed gates: exit 1.
    let err = expect_exit(&o, 1);
    assert_mentions(
        &err,
        &["3 of 4 logs failed a gate, 1 could not be calibrated"],
    );

    let out = dir.path().join("out");
    for folder in ["run1", "run2", "run1-2"] {
        for f in ["a.csv", "b.csv", "report.json"] {
            assert!(out.join(folder).join(f).is_file(), "{folder}/{f} missing");
        }
        let report = read_json(&out.join(folder).join("report.json"));
        assert_eq!(report["method"], "csrr");
        // The program is named `calib`, not by the path that started it.
        let command = report["command_line"].as_str().unwrap();
        assert!(
            command.starts_with("calib csrr logs/run1.mcap "),
            "{command}"
        );
    }
    assert!(!out.join("still").join("report.json").exists());
    // Equal logs give equal tables.
    assert_eq!(
        std::fs::read(out.join("run1/a.csv")).unwrap(),
        std::fs::read(out.join("run1-2/a.csv")).unwrap()
    );

    // Standard output: each log in input order, then the verdicts.
    let text = stdout(&o);
    let at = |s: &str| {
        text.find(s)
            .unwrap_or_else(|| panic!("{s:?} not in:\n{text}"))
    };
    assert!(at("=== logs/run1.mcap") < at("=== logs/run2.mcap"));
    assert!(at("=== logs/run2.mcap") < at("=== logs/x/run1.mcap"));
    assert!(at("=== logs/x/run1.mcap") < at("=== logs/still.csv"));
    assert!(at("=== logs/still.csv") < at("\nsummary\n"));
    assert_mentions(
        &text,
        &[
            "into out/run1-2",
            "sensor A never moves",
            "wrote out/summary.json",
        ],
    );

    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["method"], "csrr");
    assert_eq!(summary["gates"]["max_pp_arcsec"], 45.0);
    assert_eq!(summary["gates"]["gate_on"], "before");
    assert_eq!(
        (&summary["passed"], &summary["failed"], &summary["errors"]),
        (&Value::from(0), &Value::from(3), &Value::from(1))
    );
    let entries = summary["logs"].as_array().unwrap();
    let names: Vec<_> = entries.iter().map(|e| e["log"].as_str().unwrap()).collect();
    assert_eq!(names, logs);
    let outputs: Vec<_> = entries
        .iter()
        .map(|e| e["output"].as_str().unwrap())
        .collect();
    assert_eq!(outputs, ["run1", "run2", "run1-2", "still"]);
    for e in &entries[..3] {
        assert_eq!(e["status"], "fail");
        let channels = e["channels"].as_array().unwrap();
        let pp: Vec<f64> = channels
            .iter()
            .map(|c| c["peak_to_peak_before_arcsec"].as_f64().unwrap())
            .collect();
        assert!(
            (pp[0] - 51.1).abs() < 0.2 && (pp[1] - 38.4).abs() < 0.2,
            "{pp:?}"
        );
        // Only `a` exceeds 45″.
        let failures = e["gate_failures"].as_array().unwrap();
        assert_eq!(failures.len(), 1, "{failures:?}");
        assert!(
            failures[0]
                .as_str()
                .unwrap()
                .starts_with("`a`: peak-to-peak before")
        );
        let rms = e["residual_rms_arcsec"].as_f64().unwrap();
        assert!(rms > 0.05 && rms < 0.1, "{rms}");
        assert_eq!(
            e["files"],
            serde_json::json!(["a.csv", "b.csv", "report.json", "report.html"])
        );
    }
    assert_eq!(entries[3]["status"], "error");
    assert!(
        entries[3]["error"]
            .as_str()
            .unwrap()
            .contains("logs/still.csv")
    );

    // JUnit: well formed, one test case per log, a failure per failed gate, an error per bad log.
    let xml = std::fs::read_to_string(out.join("junit.xml")).unwrap();
    let doc = roxmltree::Document::parse(&xml).expect("well-formed JUnit XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "testsuites");
    assert_eq!(root.attribute("tests"), Some("4"));
    assert_eq!(root.attribute("failures"), Some("3"));
    assert_eq!(root.attribute("errors"), Some("1"));
    let cases: Vec<_> = root
        .descendants()
        .filter(|n| n.has_tag_name("testcase"))
        .collect();
    let case_names: Vec<_> = cases.iter().map(|c| c.attribute("name").unwrap()).collect();
    assert_eq!(case_names, logs);
    for case in &cases[..3] {
        let failure = case.children().find(|n| n.has_tag_name("failure")).unwrap();
        assert!(
            failure
                .attribute("message")
                .unwrap()
                .contains("> 45″ (--max-pp)")
        );
        let out_text = case
            .children()
            .find(|n| n.has_tag_name("system-out"))
            .unwrap();
        assert!(out_text.text().unwrap().contains("joint least squares\n"));
    }
    let error = cases[3]
        .children()
        .find(|n| n.has_tag_name("error"))
        .unwrap();
    assert_eq!(error.attribute("type"), Some("data"));
    // The apostrophe of "shaft's" went through &apos; and back.
    assert!(error.text().unwrap().contains("the shaft's angle"));

    // The same run again gives the same bytes in every file.
    std::fs::rename(&out, dir.path().join("first")).unwrap();
    let again = calib_in(dir.path(), &args);
    expect_exit(&again, 1);
    assert_eq!(stdout(&again), text);
    let (first, second) = (tree(&dir.path().join("first")), tree(&out));
    assert_eq!(
        first.iter().map(|f| &f.0).collect::<Vec<_>>(),
        second.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((path, a), (_, b)) in first.iter().zip(&second) {
        assert!(a == b, "{} differs between equal runs", path.display());
    }
}

#[test]
fn gates_exit_3_with_outputs_written_and_passing_runs_exit_0() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    let log = simulate_quick(&logs, "run.mcap", &[]);
    let out = dir.path().join("out");

    // One log keeps the plain layout; a failed gate still writes everything.
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--max-pp", "45"]);
    let err = expect_exit(&o, 3);
    assert_mentions(
        &err,
        &["gate failed: `a`: peak-to-peak before correction 51.1"],
    );
    assert_mentions(&stdout(&o), &["joint least squares", "report.json"]);
    for f in ["a.csv", "b.csv", "report.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(!out.join("summary.json").exists());

    // Within the gates: exit 0.
    let junit = dir.path().join("one.xml");
    let o = calib(&[
        "csrr",
        s(&log),
        "-o",
        s(&out),
        "--max-pp",
        "60",
        "--max-residual",
        "0.2",
        "--fail-on-warning",
        "--junit",
        s(&junit),
    ]);
    expect_exit(&o, 0);
    let xml = std::fs::read_to_string(&junit).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    assert_eq!(doc.root_element().attribute("failures"), Some("0"));

    // The residual gate.
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--max-residual", "0.01"]);
    let err = expect_exit(&o, 3);
    assert_mentions(&err, &["fit residual RMS 0.07", "> 0.01″ (--max-residual)"]);

    // After correction needs a method that measures it: csrr without --ref fails the gate.
    let o = calib(&[
        "csrr",
        s(&log),
        "-o",
        s(&out),
        "--max-pp",
        "1",
        "--gate-on",
        "after",
    ]);
    let err = expect_exit(&o, 3);
    assert_mentions(
        &err,
        &["`a`: this method and its options give no peak-to-peak after correction"],
    );

    // Several logs, all within the gates: exit 0 and summary.json says so. `--per-log` gives the
    // same layout for one log.
    let o = calib(&[
        "csrr",
        s(&log),
        "-o",
        s(&out.join("p")),
        "--per-log",
        "--max-pp",
        "60",
    ]);
    expect_exit(&o, 0);
    let summary = read_json(&out.join("p/summary.json"));
    assert_eq!(summary["logs"][0]["status"], "pass");
    assert!(out.join("p/run/a.csv").is_file());
}

#[test]
fn gate_after_correction_from_a_reference_encoder() {
    let dir = tempfile::tempdir().unwrap();
    // quick.toml with a reference encoder on B's shaft, 0.3″ of its own error.
    let mut scenario = quick_with(&[]);
    scenario += "\n[[sensor]]\nname = \"r\"\nmount = \"b\"\nharmonics = [{ order = 3, amplitude_arcsec = 0.3, phase_deg = 0.0 }]\nquantization_arcsec = 0.001\nnoise_arcsec = 0.01\n";
    let scenario = write(dir.path(), "ref.toml", &scenario);
    let log = simulate(&scenario, dir.path(), "run.mcap");
    let out = dir.path().join("out");
    let o = calib(&[
        "csrr",
        s(&log),
        "--ref",
        "r",
        "-o",
        s(&out),
        "--per-log",
        "--max-pp",
        "2",
        "--gate-on",
        "after",
    ]);
    expect_exit(&o, 0);
    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["gates"]["gate_on"], "after");
    for c in summary["logs"][0]["channels"].as_array().unwrap() {
        let after = c["peak_to_peak_after_arcsec"].as_f64().unwrap();
        let before = c["peak_to_peak_before_arcsec"].as_f64().unwrap();
        // The reference's own 0.6″ p-p and noise remain; the sensors' 38–51″ do not.
        assert!(after > 0.1 && after < 2.0 && before > 30.0, "{c}");
    }
}

#[test]
fn bad_gate_values_and_options_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "l.csv", "t,a,b\n0,0,0\n");
    let out = dir.path().join("out");
    for (args, hint) in [
        (vec!["--max-pp", "-1"], "positive number of arcseconds"),
        (vec!["--max-pp", "nan"], "positive number of arcseconds"),
        (vec!["--max-residual", "0"], "positive number of arcseconds"),
        (vec!["--gate-on", "after"], "--max-pp"),
        (vec!["--jobs", "0"], "--jobs"),
    ] {
        let mut all = vec!["csrr", s(&log), "-o", s(&out)];
        all.extend(&args);
        let err = expect_exit(&calib(&all), 2);
        assert_mentions(&err, &[hint]);
    }
    assert_no_output(&out);
}

#[test]
fn shift_angle_and_reference_take_several_inputs_too() {
    let dir = tempfile::tempdir().unwrap();
    let readings = testdata("shift-angle/readings.csv");
    let copy = dir.path().join("readings.csv");
    std::fs::copy(&readings, &copy).unwrap();
    let out = dir.path().join("out");
    let o = calib(&[
        "shift-angle",
        s(&readings),
        s(&copy),
        "-o",
        s(&out),
        "--max-residual",
        "10",
        "--json",
    ]);
    expect_exit(&o, 0);
    // With several inputs, --json prints summary.json.
    let printed: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(printed, read_json(&out.join("summary.json")));
    assert_eq!(printed["method"], "shift-angle");
    assert_eq!(printed["passed"], 2);
    for folder in ["readings", "readings-2"] {
        for f in ["encoder.csv", "polygon.csv", "report.json"] {
            assert!(out.join(folder).join(f).is_file(), "{folder}/{f} missing");
        }
    }

    // reference: a missing log is bad usage (exit 2), the other log is calibrated all the same.
    let log = write(dir.path(), "ref.csv", &handwritten_log(&[0.0], |th| th));
    let missing = dir.path().join("missing.csv");
    let o = calib(&[
        "reference",
        s(&log),
        s(&missing),
        "--dut",
        "b",
        "--ref",
        "a",
        "-o",
        s(&out.join("r")),
    ]);
    expect_exit(&o, 2);
    let summary = read_json(&out.join("r/summary.json"));
    assert_eq!(summary["logs"][0]["status"], "pass");
    assert_eq!(summary["logs"][1]["status"], "error");
    assert!(out.join("r/ref/b.csv").is_file());
}

/// A log of several zstd chunks, whose chunks are decompressed on worker threads: alone, and in a
/// batch with another log with one and two jobs, its tables and report are the same bytes (the
/// report but for its command line).
#[test]
fn a_log_of_several_chunks_gives_the_same_bytes_alone_and_in_a_batch_with_any_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    // 4 kHz: about 45 000 messages, 1 MiB chunks of about 10 000.
    let big = simulate_quick(&logs, "big.mcap", &[("rate_hz", "rate_hz = 4000.0")]);
    simulate_quick(&logs, "small.mcap", &[]);
    let bytes = std::fs::read(&big).unwrap();
    let (mut at, mut chunks) = (8, 0);
    while bytes[at] != 0x0F {
        chunks += usize::from(bytes[at] == 0x06);
        at += 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
    }
    assert!(chunks >= 3, "{chunks} chunks");

    let o = calib_in(dir.path(), &["csrr", "logs/big.mcap", "-o", "alone", "-q"]);
    expect_exit(&o, 0);
    let outputs = |folder: &Path| {
        let mut report = read_json(&folder.join("report.json"));
        report["command_line"] = Value::Null;
        let table = |f: &str| std::fs::read(folder.join(f)).unwrap();
        (table("a.csv"), table("b.csv"), report)
    };
    let alone = outputs(&dir.path().join("alone"));
    for jobs in ["1", "2"] {
        let out = format!("jobs{jobs}");
        let args = [
            "csrr",
            "logs/big.mcap",
            "logs/small.mcap",
            "-o",
            &out,
            "--jobs",
            jobs,
        ];
        expect_exit(&calib_in(dir.path(), &args), 0);
        assert!(
            outputs(&dir.path().join(&out).join("big")) == alone,
            "--jobs {jobs}"
        );
    }
}

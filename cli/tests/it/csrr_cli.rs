//! End-to-end tests of `calib csrr`: a simulated run calibrated and checked against its truth,
//! and every kind of bad input (exit code, a message naming file, line/channel and what to do,
//! and no output left behind).

use crate::common::{self, compare, json};

use common::*;
use compare::max_diff_zero_mean;
use json::read_json;
use serde_json::Value;
use std::path::{Path, PathBuf};

const QUICK_DELTAS: [f64; 5] = [0.0, 7.3, 23.9, 61.7, 151.1];

/// Largest |calibrated − true| of a channel's map, both with their mean removed, over the
/// calibrated table's grid (the truth interpolated there).
fn max_map_error(out: &Path, truth_dir: &Path, channel: &str) -> f64 {
    let got = read_table(&out.join(format!("{channel}.csv")));
    let truth = read_table(&truth_dir.join(format!("{channel}.csv")));
    max_diff_zero_mean(&got, |a| interpolate(&truth, a))
}

/// Largest standard uncertainty in a channel's table (its `u_arcsec` column).
fn max_u(out: &Path, channel: &str) -> f64 {
    let text = std::fs::read_to_string(out.join(format!("{channel}.csv"))).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "u_arcsec").unwrap();
    lines
        .map(|l| l.split(',').nth(col).unwrap().parse::<f64>().unwrap())
        .fold(0.0, f64::max)
}

/// Bound on the map error for quick.toml. Measured (seed 1, joint method, orders 1–84 fitted
/// automatically): 0.089″ (a) and 0.087″ (b) from the MCAP, about 0.12″ from the truncated MCAP
/// (4 sessions). The per-sample residual is 0.074″ (noise 0.05″ ⊕ quantization 0.09″/√12), and
/// with 84 orders × 2 maps fitted from ~2500 samples the worst of 3600 grid points lands near
/// that. 0.25″ leaves ~2–3× margin for solver changes (the lead is working on it) while still
/// catching anything real: the smallest true harmonic is 2″ and the maps are 51″/38″ p-p, so a
/// lost or mis-phased harmonic, a sign error or a swapped map is off by ≥ 2″.
const QUICK_TOL_ARCSEC: f64 = 0.25;

#[test]
fn csrr_on_simulated_mcap_matches_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out)]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(
        &summary,
        &["`a` and `b`", "joint least squares", "report.json"],
    );

    for f in ["a.csv", "b.csv", "report.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["method"], "csrr");
    assert!(report["calib_version"].is_string());
    assert!(report["inputs"][0].as_str().unwrap().ends_with("run.mcap"));
    let sessions = report["sessions"].as_array().unwrap();
    assert_eq!(sessions.len(), 5);
    for (k, sess) in sessions.iter().enumerate() {
        let rel = sess["relative_rotation_deg"].as_f64().unwrap();
        assert!((rel - QUICK_DELTAS[k]).abs() < 0.01, "session {k}: {rel}");
        let revs = sess["revolutions"].as_f64().unwrap();
        assert!(
            (2.0..2.5).contains(&revs),
            "session {k}: {revs} revolutions"
        );
    }
    // The largest harmonics are the scenario's: a = 20″@8, 6″@16, 3″@1; b = 15″@6, 5″@12, 2″@2.
    for (ch, orders) in [
        ("a", [(8, 20.0), (16, 6.0), (1, 3.0)]),
        ("b", [(6, 15.0), (12, 5.0), (2, 2.0)]),
    ] {
        let c = &report["channels"][ch];
        assert_eq!(c["table"], format!("{ch}.csv"));
        assert_eq!(c["points"], 3600);
        let h = c["harmonics"].as_array().unwrap();
        assert!(h.len() >= 3, "{ch}: {h:?}");
        for (i, (order, amp)) in orders.iter().enumerate() {
            assert_eq!(h[i]["order"], *order, "{ch} harmonic {i}");
            let got = h[i]["amplitude_arcsec"].as_f64().unwrap();
            assert!((got - amp).abs() < 0.05, "{ch} order {order}: {got}″");
        }
        assert_eq!(read_table(&out.join(format!("{ch}.csv"))).len(), 3600);
    }
    assert_eq!(report["warnings"].as_array().unwrap().len(), 0, "{report}");

    let truth = dir.path().join("run.truth");
    for ch in ["a", "b"] {
        let e = max_map_error(&out, &truth, ch);
        assert!(e < QUICK_TOL_ARCSEC, "{ch}: max |map − truth| = {e}″");
    }
}

#[test]
fn csrr_on_simulated_csv_with_session_column_and_json_output() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.csv");
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--json"]);
    expect_exit(&o, 0);
    let printed: Value = serde_json::from_str(&stdout(&o))
        .unwrap_or_else(|e| panic!("--json output is not JSON ({e}):\n{}", stdout(&o)));
    assert_eq!(printed, read_json(&out.join("report.json")));
    assert_eq!(printed["method"], "csrr");
    assert_eq!(printed["sessions"].as_array().unwrap().len(), 5);
    assert!(printed["channels"]["a"]["harmonics"].is_array());
    assert!(printed["channels"]["b"]["harmonics"].is_array());
    let truth = dir.path().join("run.truth");
    for ch in ["a", "b"] {
        let e = max_map_error(&out, &truth, ch);
        assert!(e < QUICK_TOL_ARCSEC, "{ch}: max |map − truth| = {e}″");
    }
}

#[test]
fn points_option_sets_the_table_grid() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let out = dir.path().join("out");
    expect_exit(
        &calib(&["csrr", s(&log), "-o", s(&out), "--points", "720"]),
        0,
    );
    let rows = read_table(&out.join("a.csv"));
    assert_eq!(rows.len(), 720);
    for (i, (a, _)) in rows.iter().enumerate() {
        assert!((a - i as f64 * 0.5).abs() < 1e-9, "row {i}: {a}");
    }
    assert_eq!(
        read_json(&out.join("report.json"))["channels"]["b"]["points"],
        720
    );
}

/// quick.toml has 5 sessions; the paper method gets one map point per session, so it runs but
/// resolves only order 1 and warns to use the joint method.
#[test]
fn paper_method_on_five_sessions_runs_and_warns() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--method", "paper"]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["paper", "5 map points", "warning:", "joint method"],
    );
    let report = read_json(&out.join("report.json"));
    assert_eq!(report["method"], "csrr");
    assert_eq!(report["sessions"].as_array().unwrap().len(), 5);
    assert_eq!(
        report["details"]["paper_points"].as_array().unwrap().len(),
        5
    );
    let warnings = report["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("use the joint method")),
        "{warnings:?}"
    );
    assert!(out.join("a.csv").is_file() && out.join("b.csv").is_file());
}

/// Runs `calib csrr log -o DIR/out extra…`, asserts the exit code and that `out` stays empty;
/// returns standard error.
#[track_caller]
fn csrr_fails(log: &Path, extra: &[&str], want: i32) -> String {
    let out = log.parent().unwrap().join("out");
    let mut args = vec!["csrr", s(log), "-o", s(&out)];
    args.extend_from_slice(extra);
    let err = expect_exit(&calib(&args), want);
    assert_no_output(&out);
    err
}

#[test]
fn one_session_only() {
    let dir = tempfile::tempdir().unwrap();
    // MCAP: no session column, so the session is found from the motion.
    let log = simulate_quick(
        dir.path(),
        "one.mcap",
        &[("relative_deg = ", "relative_deg = [0.0]")],
    );
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(
        &err,
        &[
            "one.mcap",
            "`a` and `b`",
            "found 1 session",
            "at least 2",
            "turn one rotor",
        ],
    );
}

#[test]
fn all_sessions_at_the_same_relative_rotation() {
    let dir = tempfile::tempdir().unwrap();
    for (name, deltas) in [
        ("same.csv", "[0.0, 0.0, 0.0]"),
        ("full.mcap", "[0.0, 360.0]"),
    ] {
        let sub = dir.path().join(name.replace('.', "_"));
        std::fs::create_dir(&sub).unwrap();
        let log = simulate_quick(
            &sub,
            name,
            &[("relative_deg = ", &format!("relative_deg = {deltas}"))],
        );
        let err = csrr_fails(&log, &[], 1);
        assert_mentions(
            &err,
            &[
                name,
                "`a` and `b`",
                "(nearly) equal",
                "different relative rotations",
            ],
        );
    }
}

#[test]
fn sessions_shorter_than_a_revolution() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(
        dir.path(),
        "half.csv",
        &[("revolutions = ", "revolutions = 0.5")],
    );
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(
        &err,
        &[
            "half.csv",
            "`a` and `b`",
            "0 session(s) of at least one revolution",
            "record whole revolutions",
        ],
    );
}

/// Control for the hand-written logs below: the generator gives three usable sessions.
#[test]
fn handwritten_log_with_three_sessions_calibrates() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "good.csv",
        &handwritten_log(&[0.0, 40.0, 100.0], |th| th),
    );
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out), "--json"]);
    expect_exit(&o, 0);
    let report: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(report["sessions"].as_array().unwrap().len(), 3);
}

#[test]
fn a_channel_that_never_moves() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "still.csv",
        &handwritten_log(&[0.0, 40.0, 100.0], |_| 12.5),
    );
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(&err, &["still.csv", "`a` and `b`", "session"]);
}

/// The message for a stuck channel says "found 0 session(s) … record whole revolutions with both
/// rotors locked": true, but it does not say which channel is the problem (`b` never moves),
/// which is what the user needs to know (a disconnected encoder, a wrong channel name).
#[test]
fn a_channel_that_never_moves_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "still.csv",
        &handwritten_log(&[0.0, 40.0, 100.0], |_| 12.5),
    );
    let err = csrr_fails(&log, &[], 1);
    let lower = err.to_lowercase();
    assert!(
        [
            "not move",
            "never move",
            "does not turn",
            "stationary",
            "constant",
            "stuck"
        ]
        .iter()
        .any(|w| lower.contains(w)),
        "{err}"
    );
    assert_mentions(&err, &["channel `b`"]);
}

#[test]
fn channels_counting_in_opposite_directions() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "swapped.csv",
        &handwritten_log(&[0.0, 40.0, 100.0], |th| -th),
    );
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(
        &err,
        &[
            "swapped.csv",
            "`a` and `b`",
            "opposite directions",
            "negate",
        ],
    );
}

#[test]
fn max_order_too_high_for_the_sample_density() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    // About 200 samples per revolution (200 Hz, 60 r/min); order 150 needs 375.
    let err = csrr_fails(&log, &["--max-order", "150"], 1);
    assert_mentions(
        &err,
        &[
            "run.mcap",
            "`a` and `b`",
            "order 150",
            "samples per revolution",
            "densest session has",
            "lower --max-order",
        ],
    );
    let err = csrr_fails(&log, &["--max-order", "1000000"], 1);
    assert_mentions(&err, &["run.mcap", "lower --max-order"]);
}

/// `--max-order 0` asks for a map without any harmonic; calib silently fits order 1 instead and
/// exits 0 with a map that misses every harmonic of the sensors.
#[test]
fn max_order_zero_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let err = csrr_fails(&log, &["--max-order", "0"], 2);
    assert_mentions(&err, &["--max-order"]);
}

#[test]
fn unknown_channel_lists_the_available_ones() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let err = csrr_fails(&log, &["--a", "nope"], 2);
    assert_mentions(&err, &["run.mcap", "`nope`", "it has: a, b", "pick one"]);
    let err = csrr_fails(&log, &["--b", "nope", "--a", "b"], 2);
    assert_mentions(&err, &["run.mcap", "`nope`"]);
    let err = csrr_fails(&log, &["--ref", "nope"], 2);
    assert_mentions(&err, &["run.mcap", "`nope`"]);
    let err = csrr_fails(&log, &["--a", "b"], 2);
    assert_mentions(&err, &["--a and --b", "`b`"]);
}

#[test]
fn unit_typo_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.csv");
    let err = csrr_fails(&log, &["--unit", "degs"], 2);
    assert_mentions(&err, &["degs", "deg, rad, arcsec, rev or counts:N"]);
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let err = csrr_fails(&dir.path().join("missing.csv"), &[], 2);
    assert_mentions(&err, &["missing.csv", "no such file", "check the path"]);
}

#[test]
fn empty_files() {
    let dir = tempfile::tempdir().unwrap();
    let csv = write(dir.path(), "empty.csv", "");
    let err = csrr_fails(&csv, &[], 1);
    assert_mentions(&err, &["empty.csv", "line 1", "empty", "header row"]);
    let mcap = write(dir.path(), "empty.mcap", "");
    let err = csrr_fails(&mcap, &[], 1);
    assert_mentions(&err, &["empty.mcap", "empty (0 bytes)"]);
    let header_only = write(dir.path(), "header.csv", "t,a,b\n");
    let err = csrr_fails(&header_only, &[], 1);
    assert_mentions(&err, &["header.csv"]);
}

/// The simulated quick.toml CSV with line `line` (1-based, header = 1) replaced.
fn quick_csv_with_line(
    dir: &Path,
    name: &str,
    line: usize,
    edit: impl Fn(&str) -> String,
) -> PathBuf {
    let log = simulate(&testdata("scenarios/quick.toml"), dir, "run.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    lines[line - 1] = edit(&lines[line - 1]);
    write(dir, name, &(lines.join("\n") + "\n"))
}

#[test]
fn text_in_a_number_names_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let log = quick_csv_with_line(dir.path(), "text.csv", 100, |l| {
        let f: Vec<&str> = l.split(',').collect();
        format!("{},12.5x,{},{}", f[0], f[2], f[3])
    });
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(
        &err,
        &[
            "text.csv",
            "line 100",
            "column `a`",
            "`12.5x`",
            "not a number",
        ],
    );
}

#[test]
fn non_monotonic_time_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let log = quick_csv_with_line(dir.path(), "back.csv", 101, |l| {
        let rest = l.split_once(',').unwrap().1;
        format!("0.3,{rest}")
    });
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(
        &err,
        &[
            "back.csv",
            "line 101",
            "column `t`",
            "goes back",
            "sort the log by `t`",
        ],
    );
}

/// A crashed recording: the simulated MCAP cut in half. calib reads what is there, warns with
/// the byte offset and the number of messages used, and calibrates from the 4 whole sessions.
#[test]
fn truncated_mcap_works_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let bytes = std::fs::read(&log).unwrap();
    let cut = write_bytes(dir.path(), "cut.mcap", &bytes[..bytes.len() / 2]);
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&cut), "-o", s(&out)]);
    expect_exit(&o, 0);
    let report = read_json(&out.join("report.json"));
    let warnings: Vec<&str> = report["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    let w = warnings
        .iter()
        .find(|w| w.contains("ends early"))
        .unwrap_or_else(|| panic!("no truncation warning: {warnings:?}"));
    assert_mentions(
        w,
        &[
            "cut.mcap",
            "at byte ",
            "messages before the break were used",
        ],
    );
    assert_mentions(&stdout(&o), &["warning: ", "ends early at byte"]);
    let sessions = report["sessions"].as_array().unwrap();
    assert_eq!(sessions.len(), 4, "the fifth session is past the cut");
    let truth = dir.path().join("run.truth");
    for ch in ["a", "b"] {
        let e = max_map_error(&out, &truth, ch);
        assert!(e < QUICK_TOL_ARCSEC, "{ch}: max |map − truth| = {e}″");
    }
}

/// The truncation warning names where reading stopped (`Truncation::byte_offset`). The simulated
/// log is one zstd chunk (from byte 40) and its message index; the half file cuts the chunk,
/// which streams up to the cut, so the offset lies near the end of the half file, not at the
/// chunk's start.
#[test]
fn truncated_mcap_warning_names_where_the_data_stops() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let bytes = std::fs::read(&log).unwrap();
    let keep = bytes.len() / 2;
    let cut = write_bytes(dir.path(), "cut.mcap", &bytes[..keep]);
    let o = calib(&["inspect", s(&cut), "--json"]);
    expect_exit(&o, 0);
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    let w = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|w| w.as_str())
        .find(|w| w.contains("at byte "))
        .unwrap()
        .to_string();
    let offset: usize = w
        .split("at byte ")
        .nth(1)
        .unwrap()
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        offset > keep / 2 && offset <= keep,
        "{w} (file cut at {keep})"
    );
}

fn write_bytes(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn corrupt_mcap() {
    let dir = tempfile::tempdir().unwrap();
    // Deterministic "random" bytes (xorshift), no MCAP magic.
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let noise: Vec<u8> = (0..5000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    let log = write_bytes(dir.path(), "noise.mcap", &noise);
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(&err, &["noise.mcap", "not an MCAP file", "magic"]);

    // The magic followed by garbage: still a clean data error naming the file.
    let mut damaged = b"\x89MCAP0\r\n".to_vec();
    damaged.extend_from_slice(&noise);
    let log = write_bytes(dir.path(), "damaged.mcap", &damaged);
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(&err, &["damaged.mcap"]);

    // A CSV under an .mcap name.
    let log = write(dir.path(), "text.mcap", "t,a,b\n0,1,2\n");
    let err = csrr_fails(&log, &[], 1);
    assert_mentions(&err, &["text.mcap", "not an MCAP file"]);
}

/// A run that fails while writing its outputs must not leave part of them: here report.json
/// cannot be written (a folder is in the way), and a.csv and b.csv of the failed run stay behind
/// — beside an old report.json they would not match, if one existed.
#[test]
fn failed_report_write_leaves_no_tables() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("report.json")).unwrap();
    let err = expect_exit(&calib(&["csrr", s(&log), "-o", s(&out)]), 1);
    assert_mentions(&err, &["report.json"]);
    assert!(!out.join("a.csv").exists(), "a.csv of a failed run");
    assert!(!out.join("b.csv").exists(), "b.csv of a failed run");
}

/// Issue 24 item 1: magnetic-class sensors (±1700″, 79″ quantum, three of six sessions
/// backwards, 20–45 r/min; `csrr-large.toml`) from MCAP and from a CSV without a `session`
/// column: every session found from the motion, the tolerance reported, the maps as accurate as
/// from the CSV's marks (within 30 % + 0.2″: the sessions found differ from the marked ones by a
/// few samples at their ends; measured 5.49″/7.72″ p-p vs the truth from the MCAP, a's and b's
/// max |map − truth| 4.3″ at most against 4.4″ marked), each within 3u of the truth, and the
/// solver converged with no structure reported.
#[test]
fn csrr_finds_the_sessions_of_sensors_with_degree_size_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = testdata("scenarios/csrr-large.toml");
    let marked = simulate(&scenario, dir.path(), "run.csv");
    let truth = dir.path().join("run.truth");
    // The same rows without the `session` column.
    let text = std::fs::read_to_string(&marked).unwrap();
    let unmarked: String = text
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string() + "\n")
        .collect();
    assert!(unmarked.starts_with("t,a,b\n"));
    let csv = write(dir.path(), "unmarked.csv", &unmarked);
    let mcap = simulate(&scenario, dir.path(), "run.mcap");
    let mut errors = Vec::new();
    for (log, name) in [(&marked, "marked"), (&csv, "csv"), (&mcap, "mcap")] {
        let out = dir.path().join(format!("out-{name}"));
        let o = calib(&["csrr", s(log), "-o", s(&out), "--truth", s(&truth)]);
        expect_exit(&o, 0);
        let summary = stdout(&o);
        let report = read_json(&out.join("report.json"));
        assert_eq!(
            report["sessions"].as_array().unwrap().len(),
            6,
            "{name}: {summary}"
        );
        if name != "marked" {
            assert_mentions(&summary, &["found          from the motion"]);
        }
        for warning in report["warnings"].as_array().unwrap() {
            let w = warning.as_str().unwrap();
            assert!(
                !w.contains("stopped after") && !w.contains("periodic structure"),
                "{name}: {w}"
            );
        }
        let err = [
            max_map_error(&out, &truth, "a"),
            max_map_error(&out, &truth, "b"),
        ];
        if name == "marked" {
            errors = err.to_vec();
        } else {
            for (e, m) in err.iter().zip(&errors) {
                assert!(*e <= 1.3 * m + 0.2, "{name}: {e:.3}″ (marked {m:.3}″)");
            }
        }
        // And within 3u everywhere: the largest of a turn's errors, made of ~10 fitted orders,
        // lands near 2–3 standard deviations (2u coverage per point is `coverage.rs`'s Monte
        // Carlo; marked, a's max is 2.28″ with u = 1.09″).
        for (channel, e) in ["a", "b"].iter().zip(err) {
            let u = max_u(&out, channel);
            assert!(
                e <= 3.0 * u,
                "{name}, {channel}: {e:.3}″ beyond 3u = {:.3}″",
                3.0 * u
            );
        }
    }
}

/// Issue 24 item 3: B read 5 ms late (`testdata/scenarios/csrr-latency.toml`). By default the
/// lag is found from the sessions and removed, reported in the summary and report.json, and the
/// maps reach the truth as a run without a lag does (crates/calib-core/tests/it/csrr_latency.rs
/// gives the reasons for the bounds); `--latency 0` leaves it in, and the refusal names it.
#[test]
fn a_lag_between_the_channels_is_found_and_removed() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = simulate(
        &testdata("scenarios/csrr-latency.toml"),
        dir.path(),
        "run.mcap",
    );
    let truth = dir.path().join("run.truth");
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&mcap), "-o", s(&out), "--truth", s(&truth)]);
    expect_exit(&o, 0);
    let summary = stdout(&o);
    assert_mentions(
        &summary,
        &["latency        `b`'s samples 5.000 ms older, removed"],
    );
    let report = read_json(&out.join("report.json"));
    let details = &report["details"];
    let lag = details["latency_s"].as_f64().unwrap();
    assert!((lag - 0.005).abs() < 0.005 * 0.01, "lag {lag}");
    assert_eq!(details["latency"]["mode"], "auto");
    assert_eq!(details["latency"]["left_significant"], false);
    for name in ["a", "b"] {
        let err = max_map_error(&out, &truth, name);
        assert!(err < 0.05, "{name}: max |map − truth| {err:.4}″");
    }

    let o = calib(&[
        "csrr",
        s(&mcap),
        "-o",
        s(&dir.path().join("out0")),
        "--latency",
        "0",
    ]);
    expect_exit(&o, 1);
    let err = stderr(&o);
    assert_mentions(
        &err,
        &[
            "B's samples are 4.9",
            "older than A's",
            "leave --latency at auto",
        ],
    );
    // What the solve said is words, not a residual of 10²¹ degrees (it diverged).
    let longest_number = err
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(longest_number < 10, "{err}");

    let o = calib(&[
        "csrr",
        s(&mcap),
        "-o",
        s(&dir.path().join("outx")),
        "--latency",
        "soon",
    ]);
    expect_exit(&o, 2);
}

/// Issue 30: a planned run whose every relative rotation is a multiple of 4° (0°, 8°, 28°, 52°,
/// 124°), sensor a erring only at order 90 (30″) — the order those rotations make blind. Both
/// solvers refuse it (exit 1) with the residual and the sessions' repeatability named, and
/// write nothing: a zero map with u = 0 would look certain. (The joint method measured 20.9″
/// against 0.21″, `calib_core`'s `csrr_outcomes`.)
#[test]
fn error_all_in_blind_orders_is_refused_by_both_solvers() {
    let dir = tempfile::tempdir().unwrap();
    let sensor = |name: &str, harmonics: &str| {
        format!(
            "[[sensor]]\nname = \"{name}\"\nmount = \"{name}\"\nharmonics = [{harmonics}]\n\
             quantization_arcsec = 0.09\nnoise_arcsec = 0.05\n"
        )
    };
    let scenario = format!(
        "seed = 30\nrate_hz = 1000.0\nspeed_rpm = 60.0\n{}{}[procedure]\n\
         relative_deg = [0.0, 8.0, 28.0, 52.0, 124.0]\nrevolutions = 2.0\nramp_s = 0.25\n\
         pause_s = 0.2\nturn_s = 0.5\n",
        sensor(
            "a",
            "{ order = 90, amplitude_arcsec = 30.0, phase_deg = 10.0 }"
        ),
        sensor("b", "")
    );
    let scenario = write(dir.path(), "blind4.toml", &scenario);
    let log = simulate(&scenario, dir.path(), "blind4.csv");
    for method in ["joint", "paper"] {
        let out = dir.path().join(method);
        let o = calib(&["csrr", s(&log), "--method", method, "-o", s(&out)]);
        let err = expect_exit(&o, 1);
        println!("{method}: {err}");
        assert_mentions(
            &err,
            &[
                "RMS per sample",
                "more than 10× the noise",
                "cannot explain",
            ],
        );
        assert_no_output(&out);
    }
}

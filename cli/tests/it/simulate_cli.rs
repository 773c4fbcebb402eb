//! End-to-end tests of `calib simulate`: written logs and truth tables, determinism, and bad
//! scenarios or outputs.

use crate::common;

use common::*;
use std::path::Path;

const TRUTH_HEADER: &str = "angle_deg,error_arcsec,correction_arcsec\n";

fn assert_truth_tables(dir: &Path, stem: &str) {
    for sensor in ["a", "b"] {
        let path = dir.join(format!("{stem}.truth/{sensor}.csv"));
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(text.starts_with(TRUTH_HEADER), "{}", path.display());
        // Default --points 36000: a 0.01° grid.
        let rows = read_table(&path);
        assert_eq!(rows.len(), 36000);
        assert_eq!(rows[0].0, 0.0);
        assert!((rows[1].0 - 0.01).abs() < 1e-9);
        assert!((rows[35999].0 - 359.99).abs() < 1e-9);
        // Zero mean; quick.toml's harmonics give 51.1″ (a) and 38.4″ (b) peak to peak.
        let mean = rows.iter().map(|r| r.1).sum::<f64>() / rows.len() as f64;
        assert!(mean.abs() < 1e-3, "{sensor}: mean {mean}");
        let (lo, hi) = rows.iter().fold((f64::MAX, f64::MIN), |(lo, hi), r| {
            (lo.min(r.1), hi.max(r.1))
        });
        let want = if sensor == "a" { 51.104 } else { 38.391 };
        assert!((hi - lo - want).abs() < 0.01, "{sensor}: p-p {}", hi - lo);
    }
}

#[test]
fn simulate_writes_csv_log_and_truth_tables() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let o = calib(&[
        "simulate",
        s(&testdata("scenarios/quick.toml")),
        "-o",
        s(&log),
    ]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["run.csv", "3301 samples", "2 channels"]);
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,a,b,session"));
    assert_eq!(lines.count(), 3301);
    assert_truth_tables(dir.path(), "run");
}

#[test]
fn simulate_writes_mcap_log_and_truth_tables() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/quick.toml"), dir.path(), "run.mcap");
    let bytes = std::fs::read(&log).unwrap();
    assert!(bytes.starts_with(b"\x89MCAP0\r\n"), "MCAP magic");
    assert!(bytes.ends_with(b"\x89MCAP0\r\n"), "MCAP footer magic");
    assert_truth_tables(dir.path(), "run");
    // Only the log, its truth folder and the manifest listing the log as calib's (issue 52): no
    // temporary left behind.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, [".calib-manifest", "run.mcap", "run.truth"]);
    assert_eq!(
        std::fs::read_to_string(dir.path().join(".calib-manifest")).unwrap(),
        "/run.mcap\n"
    );
}

#[test]
fn same_seed_gives_byte_identical_csv_and_another_seed_does_not() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = testdata("scenarios/quick.toml");
    let one = simulate(&scenario, dir.path(), "one.csv");
    let two = simulate(&scenario, dir.path(), "two.csv");
    let one_bytes = std::fs::read(&one).unwrap();
    assert_eq!(one_bytes, std::fs::read(&two).unwrap());
    for sensor in ["a", "b"] {
        assert_eq!(
            std::fs::read(dir.path().join(format!("one.truth/{sensor}.csv"))).unwrap(),
            std::fs::read(dir.path().join(format!("two.truth/{sensor}.csv"))).unwrap()
        );
    }
    let other = simulate_quick(dir.path(), "seed2.csv", &[("seed = ", "seed = 2")]);
    assert_ne!(
        one_bytes,
        std::fs::read(&other).unwrap(),
        "noise follows the seed"
    );
}

#[test]
fn smaller_truth_grid_with_points() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.csv");
    let o = calib(&[
        "simulate",
        s(&testdata("scenarios/quick.toml")),
        "-o",
        s(&log),
        "--points",
        "360",
    ]);
    expect_exit(&o, 0);
    let rows = read_table(&dir.path().join("run.truth/a.csv"));
    assert_eq!(rows.len(), 360);
    assert_eq!(rows[359].0, 359.0);
}

/// A failed simulate leaves no log, no truth folder and no temporary behind.
#[track_caller]
fn assert_nothing_written(dir: &Path, keep: &[&str]) {
    let left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| !keep.contains(&n.as_str()))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn unknown_key_is_a_usage_error_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = quick_with(&[("seed = ", "seed = 1\nsede = 2")]);
    let scenario = write(dir.path(), "typo.toml", &text);
    let out = dir.path().join("run.csv");
    let err = expect_exit(&calib(&["simulate", s(&scenario), "-o", s(&out)]), 2);
    assert_mentions(
        &err,
        &["typo.toml", "line 4", "unknown field `sede`", "`seed`"],
    );
    assert_nothing_written(dir.path(), &["typo.toml"]);
}

#[test]
fn unknown_key_in_a_sensor_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = quick_with(&[]).replacen("noise_arcsec = 0.05", "nois_arcsec = 0.05", 1);
    let scenario = write(dir.path(), "sensor.toml", &text);
    let out = dir.path().join("run.mcap");
    let err = expect_exit(&calib(&["simulate", s(&scenario), "-o", s(&out)]), 2);
    assert_mentions(
        &err,
        &["sensor.toml", "line 21", "unknown field `nois_arcsec`"],
    );
    assert_nothing_written(dir.path(), &["sensor.toml"]);
}

#[test]
fn negative_values_are_usage_errors_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, &[&str]); 4] = [
        (
            "rate_hz = ",
            "rate_hz = -200.0",
            &["rate_hz", "-200", "> 0"],
        ),
        ("speed_rpm = ", "speed_rpm = -60.0", &["speed_rpm", "> 0"]),
        ("revolutions = ", "revolutions = -2.0", &["revolutions"]),
        ("pause_s = ", "pause_s = -0.2", &["pause_s"]),
    ];
    for (i, (prefix, line, parts)) in cases.iter().enumerate() {
        let name = format!("bad{i}.toml");
        let scenario = write(dir.path(), &name, &quick_with(&[(prefix, line)]));
        let out = dir.path().join("run.csv");
        let err = expect_exit(&calib(&["simulate", s(&scenario), "-o", s(&out)]), 2);
        assert_mentions(&err, &[&name]);
        assert_mentions(&err, parts);
        assert!(!out.exists(), "{line}");
    }
    let text = quick_with(&[]).replacen(
        "quantization_arcsec = 0.09",
        "quantization_arcsec = -0.09",
        1,
    );
    let scenario = write(dir.path(), "q.toml", &text);
    let out = dir.path().join("run.csv");
    let err = expect_exit(&calib(&["simulate", s(&scenario), "-o", s(&out)]), 2);
    assert_mentions(&err, &["q.toml", "sensor `a`", "quantization_arcsec"]);
    assert_nothing_written(
        dir.path(),
        &["bad0.toml", "bad1.toml", "bad2.toml", "bad3.toml", "q.toml"],
    );
}

#[test]
fn text_where_a_number_belongs_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = write(
        dir.path(),
        "text.toml",
        &quick_with(&[("rate_hz = ", "rate_hz = \"fast\"")]),
    );
    let out = dir.path().join("run.csv");
    let err = expect_exit(&calib(&["simulate", s(&scenario), "-o", s(&out)]), 2);
    assert_mentions(&err, &["text.toml", "line 4", "rate_hz"]);
    assert!(!out.exists());
}

#[test]
fn missing_scenario_exits_nonzero_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.csv");
    let o = calib(&["simulate", s(&dir.path().join("nope.toml")), "-o", s(&out)]);
    let err = stderr(&o);
    assert!(matches!(code(&o), 1 | 2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_mentions(&err, &["nope.toml"]);
    assert_nothing_written(dir.path(), &[]);
}

/// A missing input is bad usage everywhere else (`calib csrr missing.csv` exits 2 with "check the
/// path"); `calib simulate` exits 1 and only relays the OS error.
#[test]
fn missing_scenario_is_a_usage_error_like_a_missing_log() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.csv");
    let err = expect_exit(
        &calib(&["simulate", s(&dir.path().join("nope.toml")), "-o", s(&out)]),
        2,
    );
    assert_mentions(&err, &["nope.toml", "check the path"]);
}

#[test]
fn txt_output_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run.txt");
    let err = expect_exit(
        &calib(&[
            "simulate",
            s(&testdata("scenarios/quick.toml")),
            "-o",
            s(&out),
        ]),
        2,
    );
    assert_mentions(&err, &["run.txt", ".csv", ".mcap"]);
    assert_nothing_written(dir.path(), &[]);
}

#[test]
fn too_few_points_and_a_missing_output_folder_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let quick = testdata("scenarios/quick.toml");
    let out = dir.path().join("run.csv");
    let err = expect_exit(
        &calib(&["simulate", s(&quick), "-o", s(&out), "--points", "1"]),
        2,
    );
    assert_mentions(&err, &["--points"]);
    let out = dir.path().join("nodir/run.csv");
    // Checked before any work, as a usage error (as apply, compose, export and import do).
    let err = expect_exit(&calib(&["simulate", s(&quick), "-o", s(&out)]), 2);
    assert_mentions(&err, &["nodir/run.csv", "does not exist"]);
    assert_nothing_written(dir.path(), &[]);
}

#[test]
fn a_file_in_the_way_of_the_truth_folder_fails_without_writing_the_log() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "run.truth", "");
    let out = dir.path().join("run.csv");
    let err = expect_exit(
        &calib(&[
            "simulate",
            s(&testdata("scenarios/quick.toml")),
            "-o",
            s(&out),
        ]),
        1,
    );
    assert_mentions(&err, &["run.truth"]);
    assert_nothing_written(dir.path(), &["run.truth"]);
}

/// The CSV log and the truth tables are created 0666 & !umask (like any output); the MCAP writer
/// keeps the temporary file's private 0600 mode when it renames it into place.
#[cfg(unix)]
#[test]
fn mcap_log_has_the_same_permissions_as_a_csv_log() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let quick = testdata("scenarios/quick.toml");
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let csv = simulate(&quick, dir.path(), "run.csv");
    let mcap = simulate(&quick, dir.path(), "run.mcap");
    assert_eq!(
        format!("{:o}", mode(&mcap)),
        format!("{:o}", mode(&csv)),
        "run.mcap vs run.csv"
    );
}

/// `--example` prints each method's scenario (shift-angle: its readings table), and every
/// scenario it prints is one `calib simulate` reads.
#[test]
fn examples_print_and_simulate() {
    let dir = tempfile::tempdir().unwrap();
    for method in ["csrr", "multihead", "tdr", "reference"] {
        let o = calib(&["simulate", "--example", method]);
        assert!(o.status.success(), "{method}");
        let path = dir.path().join(format!("{method}.toml"));
        std::fs::write(&path, &o.stdout).unwrap();
        let log = dir.path().join(format!("{method}.csv"));
        let o = calib(&["simulate", s(&path), "-o", s(&log), "--points", "360"]);
        assert!(
            o.status.success(),
            "{method}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let o = calib(&["simulate", "--example", "shift-angle"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("shift_deg,start_face,step,reading_arcsec"),
        "{text}"
    );
    expect_exit(&calib(&["simulate", "--example", "nonsense"]), 2);
}

/// `calib plan csrr --procedure` writes the procedure and a scenario that simulates the planned
/// rotations, and the simulated run has the planned sessions.
#[test]
fn plan_writes_a_procedure_and_a_scenario_that_simulates() {
    let dir = tempfile::tempdir().unwrap();
    let procedure = dir.path().join("run.md");
    let o = calib(&[
        "plan",
        "csrr",
        "--max-order",
        "30",
        "--sessions",
        "4",
        "--revolutions",
        "1",
        "--rpm",
        "60",
        "--rate",
        "100",
        "--procedure",
        s(&procedure),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(&procedure).unwrap();
    assert_eq!(md.matches("r/min |").count(), 4, "{md}");
    let scenario = dir.path().join("run.toml");
    let log = dir.path().join("sim.csv");
    let o = calib(&["simulate", s(&scenario), "-o", s(&log), "--points", "360"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // `--procedure` given a .toml name would put the scenario over it: refused.
    let clash = dir.path().join("run2.toml");
    let o = calib(&["plan", "csrr", "--max-order", "8", "--procedure", s(&clash)]);
    expect_exit(&o, 2);
    assert!(!clash.exists());
}

/// `calib plan tdr --procedure` and `calib plan reference --procedure` write scenarios that
/// simulate, and the methods run on the simulations (the planned coast is one coast; the planned
/// sweep gives the planned passes in each direction).
#[test]
fn tdr_and_reference_plans_write_scenarios_that_calibrate() {
    let dir = tempfile::tempdir().unwrap();
    let coast = dir.path().join("coast.md");
    let o = calib(&[
        "plan",
        "tdr",
        "--max-order",
        "8",
        "--start-rpm",
        "600",
        "--decel",
        "30",
        "--procedure",
        s(&coast),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let scenario = std::fs::read_to_string(dir.path().join("coast.toml")).unwrap();
    let with_error = scenario.replacen(
        "name = \"enc\"\n",
        "name = \"enc\"\nharmonics = [{ order = 2, amplitude_arcsec = 2.0, phase_deg = 0.0 }]\n",
        1,
    );
    std::fs::write(dir.path().join("coast.toml"), with_error).unwrap();
    let log = dir.path().join("coast.mcap");
    let o = calib(&["simulate", s(&dir.path().join("coast.toml")), "-o", s(&log)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("tdr");
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--max-order",
        "8",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let run = dir.path().join("ref.md");
    let o = calib(&[
        "plan",
        "reference",
        "--speed",
        "90",
        "--passes",
        "2",
        "--procedure",
        s(&run),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let log = dir.path().join("ref.csv");
    let o = calib(&[
        "simulate",
        s(&dir.path().join("ref.toml")),
        "-o",
        s(&log),
        "--points",
        "360",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.path().join("ref");
    let o = calib(&[
        "reference",
        s(&log),
        "--dut",
        "dut",
        "--ref",
        "ref",
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["details"]["min_passes"]["increasing"], 2);
    assert_eq!(report["details"]["min_passes"]["decreasing"], 2);
}

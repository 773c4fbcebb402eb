//! Outputs that cannot destroy or mislead: no command writes over one of its inputs, whatever
//! the spelling of the path (issue 33 item 1); a folder holding another run's results is
//! replaced only with --force (issue 30 item 6); readings in radians or counts read in the
//! default degrees are refused, naming the unit (issue 30 item 4); a file calib did not write is
//! replaced only with --force, two runs into one folder exclude each other, and stale temporary
//! entries are removed only where calib can prove them its own (issue 52).

use crate::common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

/// Runs calib with `args` in the folder `dir`.
fn calib_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("cannot start calib")
}

/// The DUT's error of [`dut_log`], arcsec, at θ radians.
fn dut_error(r: f64) -> f64 {
    20.0 * (2.0 * r).sin() + 5.0 * (7.0 * r + 1.0).cos()
}

/// A DUT against a reference on one shaft, CSV in degrees: two turns each way at 90°/s,
/// 200 Hz; the DUT errs by 20″ at order 2 and 5″ at order 7 ([`dut_error`]), the reference not
/// at all.
fn dut_log() -> String {
    dut_log_with(|_| 0.0)
}

/// [`dut_log`] with the reference erring by `ref_error(θ)` arcsec.
fn dut_log_with(ref_error: impl Fn(f64) -> f64) -> String {
    let mut text = String::from("t,dut,ref\n");
    let rows = 2 * 2 * 800;
    for k in 0..=rows {
        let t = k as f64 / 200.0;
        let turns = 2.0 * 2.0 * k as f64 / rows as f64;
        let th = 360.0 * if turns <= 2.0 { turns } else { 4.0 - turns };
        let r = th.to_radians();
        text.push_str(&format!(
            "{t:.3},{:.7},{:.7}\n",
            (th + dut_error(r) / 3600.0).rem_euclid(360.0),
            (th + ref_error(r) / 3600.0).rem_euclid(360.0)
        ));
    }
    text
}

/// A table of `(angle_deg, error_arcsec)` rows.
fn table(dir: &Path, name: &str, rows: &[(f64, f64)]) -> PathBuf {
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec\n");
    for (a, e) in rows {
        text.push_str(&format!("{a},{e},{}\n", -e));
    }
    write(dir, name, &text)
}

/// Asserts exit 2 with a message naming the output and the input, and the input unchanged.
#[track_caller]
fn refused(o: &Output, input: &Path, before: &[u8], names: &[&str]) -> String {
    let err = expect_exit(o, 2);
    assert_mentions(
        &err,
        &["an input of this run", "never writes over its inputs"],
    );
    assert_mentions(&err, names);
    assert_eq!(
        std::fs::read(input).unwrap(),
        before,
        "{} changed",
        input.display()
    );
    err
}

/// `cd lab && calib reference dut.csv --dut dut --ref ref -o .` replaced the log by its table
/// (1.6 MB by 51 KB, exit 0, in the report); now exit 2 naming both, the log unchanged.
#[test]
fn reference_into_the_logs_folder_keeps_the_log() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(dir.path(), "dut.csv", &dut_log());
    let before = std::fs::read(&log).unwrap();
    let o = calib_in(
        dir.path(),
        &[
            "reference",
            "dut.csv",
            "--dut",
            "dut",
            "--ref",
            "ref",
            "-o",
            ".",
        ],
    );
    refused(&o, &log, &before, &["-o .", "./dut.csv", "the log dut.csv"]);
    assert!(!dir.path().join("report.json").exists());
    // Into another folder it calibrates.
    let o = calib_in(
        dir.path(),
        &[
            "reference",
            "dut.csv",
            "--dut",
            "dut",
            "--ref",
            "ref",
            "-o",
            "out",
        ],
    );
    expect_exit(&o, 0);
}

/// `calib csrr DIR/a.csv -o DIR` (a log named after its channel); and a --truth folder or a
/// --plots folder that is the truth folder: nothing is written.
#[test]
fn csrr_keeps_its_log_and_truth_folder() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate_quick(dir.path(), "a.csv", &[]);
    let before = std::fs::read(&log).unwrap();
    let o = calib(&["csrr", s(&log), "-o", s(dir.path())]);
    refused(&o, &log, &before, &["a.csv", "would replace the log"]);

    let truth = dir.path().join("a.truth");
    let truth_a = std::fs::read(truth.join("a.csv")).unwrap();
    let o = calib(&["csrr", s(&log), "--truth", s(&truth), "-o", s(&truth)]);
    refused(
        &o,
        &truth.join("a.csv"),
        &truth_a,
        &["would write into the truth"],
    );
    let out = dir.path().join("out");
    let o = calib(&[
        "csrr",
        s(&log),
        "--truth",
        s(&truth),
        "-o",
        s(&out),
        "--plots",
        s(&truth.join("plots")),
    ]);
    refused(&o, &truth.join("a.csv"), &truth_a, &["--plots", "truth"]);
    assert_no_output(&out);
    assert!(!truth.join("plots").exists());
}

/// `calib apply T LOG -o T`, by its own path, a symbolic link and a hard link.
#[test]
fn apply_keeps_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(dir.path(), "a.csv", &[(0.0, 1.0), (180.0, -1.0)]);
    let log = write(dir.path(), "run.csv", "t,a,b\n0,10,20\n1,11,21\n");
    let before = std::fs::read(&t).unwrap();
    let hard = dir.path().join("hard.csv");
    std::fs::hard_link(&t, &hard).unwrap();
    let mut spellings = vec![t.clone(), dir.path().join(".").join("a.csv"), hard];
    #[cfg(unix)]
    {
        let link = dir.path().join("link.csv");
        std::os::unix::fs::symlink(&t, &link).unwrap();
        spellings.push(link);
    }
    for out in &spellings {
        let o = calib(&["apply", s(&t), s(&log), "-o", s(out)]);
        refused(&o, &t, &before, &["the table", "a.csv"]);
    }
    // The log itself, as before.
    let o = calib(&["apply", s(&t), s(&log), "-o", s(&log)]);
    refused(
        &o,
        &log,
        b"t,a,b\n0,10,20\n1,11,21\n",
        &["the log", "run.csv"],
    );
}

/// `calib export T -o T` and `calib compose T1 R -o R` destroyed their input table, exit 0.
#[test]
fn export_and_compose_keep_their_tables() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<(f64, f64)> = (0..360)
        .map(|k| (k as f64, 3.0 * (k as f64).to_radians().sin()))
        .collect();
    let t = table(dir.path(), "a.csv", &rows);
    let r = table(dir.path(), "r.csv", &rows);
    let before = std::fs::read(&t).unwrap();
    let o = calib_in(
        dir.path(),
        &["export", "a.csv", "--format", "csv", "-o", "./a.csv"],
    );
    refused(&o, &t, &before, &["-o ./a.csv", "the table a.csv"]);
    let o = calib(&["compose", s(&t), s(&r), "-o", s(&r)]);
    refused(&o, &r, &before, &["the table", "r.csv"]);
    let o = calib(&[
        "compose",
        s(&t),
        s(&r),
        "-o",
        s(&dir.path().join("next.csv")),
    ]);
    expect_exit(&o, 0);
}

/// `calib compare` into the folder of a map named compare.csv, and `calib simulate` of a
/// scenario whose name is the log to write.
#[test]
fn compare_and_simulate_keep_their_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let rows = [(0.0, 1.0), (90.0, 0.0), (180.0, -1.0), (270.0, 0.0)];
    let first = table(dir.path(), "compare.csv", &rows);
    let second = table(dir.path(), "b.csv", &rows);
    let before = std::fs::read(&first).unwrap();
    let o = calib(&["compare", s(&first), s(&second), "-o", s(dir.path())]);
    refused(&o, &first, &before, &["compare.csv", "the table"]);

    let scenario = write(dir.path(), "run.csv", &quick_with(&[]));
    let before = std::fs::read(&scenario).unwrap();
    let o = calib(&["simulate", s(&scenario), "-o", s(&scenario)]);
    refused(&o, &scenario, &before, &["the scenario", "run.csv"]);
}

/// `calib shift-angle` of a readings file named as one of its outputs.
#[test]
fn shift_angle_keeps_its_readings() {
    let dir = tempfile::tempdir().unwrap();
    let readings = dir.path().join("encoder.csv");
    std::fs::copy(testdata("shift-angle/readings.csv"), &readings).unwrap();
    let before = std::fs::read(&readings).unwrap();
    let o = calib(&["shift-angle", s(&readings), "-o", s(dir.path())]);
    refused(&o, &readings, &before, &["the readings", "encoder.csv"]);
}

/// `calib reference …` after `calib csrr …`, both into the default folder, removed a.csv and
/// b.csv without a word (issue 30); now refused naming the run and its files, replaced with
/// --force, and a rerun of the same command on the same log replaces its results.
#[test]
fn another_runs_results_are_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    simulate_quick(dir.path(), "run.csv", &[]);
    write(dir.path(), "dut.csv", &dut_log());
    expect_exit(&calib_in(dir.path(), &["csrr", "run.csv"]), 0);
    let out = dir.path().join("calib-out");
    let a = std::fs::read(out.join("a.csv")).unwrap();
    let reference = ["reference", "dut.csv", "--dut", "dut", "--ref", "ref"];
    let err = expect_exit(&calib_in(dir.path(), &reference), 2);
    assert_mentions(
        &err,
        &[
            "-o calib-out",
            "`calib csrr run.csv`",
            "a.csv, b.csv, report.json, report.html",
            "--force",
        ],
    );
    assert_eq!(std::fs::read(out.join("a.csv")).unwrap(), a);
    // The same command on another log is another run too.
    simulate_quick(dir.path(), "run2.csv", &[]);
    let err = expect_exit(&calib_in(dir.path(), &["csrr", "run2.csv"]), 2);
    assert_mentions(&err, &["`calib csrr run.csv`", "csrr of run2.csv"]);
    // Rerunning the same command on the same log (by another spelling) replaces its results.
    let again = calib_in(dir.path(), &["csrr", "./run.csv", "--points", "3600"]);
    expect_exit(&again, 0);
    let mut forced = reference.to_vec();
    forced.push("--force");
    expect_exit(&calib_in(dir.path(), &forced), 0);
    assert!(out.join("dut.csv").exists());
    assert!(!out.join("a.csv").exists());
}

/// A log in radians (readings in [0, 2π)) or in counts read in the default degrees was taken
/// as a 6.3° sweep or as 45 turns; now refused naming the unit, and with it the run calibrates.
/// A data error, exit 1, as degrees read as radians are (`unit_hints_cli`): it was exit 2, a
/// usage error, though the same command line is right for a log in degrees.
#[test]
fn readings_in_another_unit_are_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let convert = |f: &dyn Fn(f64) -> String| -> String {
        dut_log()
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 0 {
                    return format!("{l}\n");
                }
                let c: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                format!("{},{},{}\n", c[0], f(c[1]), f(c[2]))
            })
            .collect()
    };
    let rad = write(
        dir.path(),
        "rad.csv",
        &convert(&|deg: f64| format!("{:.9}", deg.to_radians())),
    );
    let out = dir.path().join("out");
    let run = |log: &Path, extra: &[&str]| {
        let mut args = vec![
            "reference",
            s(log),
            "--dut",
            "dut",
            "--ref",
            "ref",
            "-o",
            s(&out),
        ];
        args.extend_from_slice(extra);
        calib(&args)
    };
    let err = expect_exit(&run(&rad, &[]), 1);
    assert_mentions(
        &err,
        &["rad.csv", "`dut`", "a whole turn in radians", "--unit rad"],
    );
    assert_no_output(&out);
    expect_exit(&run(&rad, &["--unit", "rad", "--force"]), 0);

    let counts = write(
        dir.path(),
        "counts.csv",
        &convert(&|deg: f64| format!("{}", (deg / 360.0 * 16384.0).floor() as i64 % 16384)),
    );
    let err = expect_exit(&run(&counts, &["--force"]), 1);
    assert_mentions(
        &err,
        &[
            "counts.csv",
            "whole numbers",
            "--unit counts:N",
            "counts:16384",
        ],
    );
    expect_exit(&run(&counts, &["--unit", "counts:16384", "--force"]), 0);
}

/// The largest |map − DUT's true error| of `out/dut.csv`, arcsec, and its largest u.
fn map_off_and_u(out: &Path) -> (f64, f64) {
    let text = std::fs::read_to_string(out.join("dut.csv")).unwrap();
    let (mut off, mut u) = (0.0f64, 0.0f64);
    for line in text.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        off = off.max((f[1] - dut_error(f[0].to_radians())).abs());
        u = u.max(f[3]);
    }
    (off, u)
}

/// `calib reference` without --ref-u took the reference's u as 0 without a word; now u is said
/// to exclude the reference (summary, report, a warning --fail-on-warning catches). With the
/// reference's calibrated table its error is taken out of the map and its u enters.
#[test]
fn reference_u_says_whether_it_includes_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    // The reference errs by 10″ at order 3; its calibrated table says so with u = 0.3″.
    let ref_error = |r: f64| 10.0 * (3.0 * r).sin();
    let log = write(dir.path(), "run.csv", &dut_log_with(ref_error));
    let mut text = String::from("angle_deg,error_arcsec,correction_arcsec,u_arcsec\n");
    for k in 0..360 {
        let e = ref_error((k as f64).to_radians());
        text.push_str(&format!("{k},{e:.6},{:.6},0.3\n", -e));
    }
    let ref_table = write(dir.path(), "ref-table.csv", &text);
    let out = dir.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "reference",
            s(&log),
            "--dut",
            "dut",
            "--ref",
            "ref",
            "-o",
            s(&out),
        ];
        args.extend_from_slice(extra);
        calib(&args)
    };

    let o = run(&[]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["max u (excludes the reference)", "u excludes the reference"],
    );
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert_mentions(
        &report,
        &["\"u_excludes_reference\": true", "u excludes the reference"],
    );
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_mentions(&html, &["u excludes the reference"]);
    let (off, u) = map_off_and_u(&out);
    // The map holds the reference's 10″ error, which u (the repeatability) does not cover.
    assert!(off > 9.0 && u < 0.1 * off, "off {off}″, u {u}″");
    let err = expect_exit(&run(&["--fail-on-warning"]), 3);
    assert_mentions(&err, &["u excludes the reference"]);

    let o = run(&["--ref-u", "0.5"]);
    expect_exit(&o, 0);
    assert!(!stdout(&o).contains("excludes"), "{}", stdout(&o));

    let o = run(&["--ref-table", s(&ref_table)]);
    expect_exit(&o, 0);
    assert!(!stdout(&o).contains("excludes"), "{}", stdout(&o));
    let (off, u) = map_off_and_u(&out);
    eprintln!("with --ref-table: map within {off:.4}″ of the DUT's error, u max {u:.4}″");
    // Linear interpolation of the 1° reference table errs by at most h²/8·|e''| = 0.0034″, the
    // readings are written to 0.00036″, and the method's 0.1° grid of a 20″ order-2 error adds
    // a few thousandths (0.0083″ measured): 0.02″ is far below the 10″ the table takes out.
    assert!(u >= 0.3, "u {u}″ below the reference's own 0.3″");
    assert!(off < 0.02, "off {off}″");
}

/// `calib csrr --ref ref` printed "→ after 1.446″" where the map was within 0.005″ of the
/// truth: the figure was the reference's own error. Now it reads "vs reference", and with the
/// reference's own table it is split into that error and the rest, which is what the truth
/// says the correction leaves.
#[test]
fn after_correction_against_a_reference_is_labelled_and_split() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = quick_with(&[])
        + r#"
[[sensor]]
name = "ref"
mount = "b"
harmonics = [{ order = 5, amplitude_arcsec = 1.5, phase_deg = 20.0 }]
quantization_arcsec = 0.01
noise_arcsec = 0.0
"#;
    let scenario = write(dir.path(), "run.toml", &scenario);
    let log = simulate(&scenario, dir.path(), "run.csv");
    let truth = dir.path().join("run.truth");
    let out = dir.path().join("out");
    let csrr = |extra: &[&str]| {
        let mut args = vec!["csrr", s(&log), "-o", s(&out), "--force"];
        args.extend_from_slice(extra);
        calib(&args)
    };
    let after_b = |field: &str| -> serde_json::Value {
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        report["channels"]["b"]["after_correction"][field].clone()
    };

    let o = csrr(&["--truth", s(&truth)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["vs truth"]);
    let vs_truth = after_b("peak_to_peak_arcsec").as_f64().unwrap();

    let o = csrr(&["--ref", "ref"]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &["vs reference", "holds the reference's own error"],
    );
    let vs_reference = after_b("peak_to_peak_arcsec").as_f64().unwrap();
    assert_eq!(after_b("against"), "reference");
    // The reference's 3″ peak-to-peak error is in the figure.
    assert!(vs_reference > 2.5, "{vs_reference}″");

    let table = truth.join("ref.csv");
    let o = csrr(&["--ref", "ref", "--ref-table", s(&table)]);
    expect_exit(&o, 0);
    assert_mentions(&stdout(&o), &["vs reference = reference's own"]);
    let split = after_b("reference_split");
    let own = split["reference_error_arcsec"].as_f64().unwrap();
    let rest = split["rest_arcsec"].as_f64().unwrap();
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_mentions(&html, &["against the reference: its own error explains"]);
    eprintln!(
        "b after correction: vs truth {vs_truth:.4}″, vs reference {vs_reference:.4}″ = \
         reference's own {own:.4}″ + rest {rest:.4}″"
    );
    // The reference's own error is its 1.5″ order-5 sine: 3″ peak to peak at the checked
    // points (bins a fraction of a degree wide: the sine's peaks are reached to 0.01″).
    assert!((own - 3.0).abs() < 0.01, "{own}″");
    // The rest is what the truth says the correction leaves, up to the noise of the binned
    // check (0.05″ readings averaged over a bin of B's 2 revolutions × 5 sessions).
    assert!(
        (rest - vs_truth).abs() < 0.1,
        "rest {rest}″, truth {vs_truth}″"
    );
    assert!(rest < vs_reference / 3.0, "rest {rest}″");
}

/// The entries of `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// `-o a/b/c` where neither `a` nor `b` exists: a run that failed after taking the folder's
/// lock left `a/b` behind, empty (issue 52). Now a failed run removes the folders it made, for
/// `-o` and `--plots`; a folder that was there before the run stays even when empty, and a
/// run that succeeds keeps the folders with its outputs.
#[test]
fn a_failed_run_leaves_no_folder_it_made() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "run.csv", &dut_log());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "reference",
            "run.csv",
            "--dut",
            "dut",
            "--ref",
            "ref",
            "-o",
            "a/b/c",
        ];
        args.extend_from_slice(extra);
        calib_in(dir.path(), &args)
    };
    // Degrees read as radians: refused once the log is read, the lock long taken.
    let err = expect_exit(&run(&["--unit", "rad"]), 1);
    assert_mentions(&err, &["--unit deg"]);
    assert_eq!(entries(dir.path()), ["run.csv"]);
    expect_exit(&run(&["--unit", "rad", "--plots", "p/q"]), 1);
    assert_eq!(entries(dir.path()), ["run.csv"]);
    // The user's own (empty) folder is not calib's to remove.
    std::fs::create_dir_all(dir.path().join("a/b")).unwrap();
    expect_exit(&run(&["--unit", "rad"]), 1);
    assert_eq!(entries(dir.path()), ["a", "run.csv"]);
    assert!(entries(&dir.path().join("a/b")).is_empty());
    std::fs::remove_dir_all(dir.path().join("a")).unwrap();
    expect_exit(&run(&["--plots", "p/q"]), 0);
    assert!(dir.path().join("a/b/c/report.json").is_file());
    assert!(!entries(&dir.path().join("p/q")).is_empty());
}

/// `cd lab && calib reference run.csv --dut dut --ref ref -o .` beside the user's own
/// `dut.csv` and `report.json` (not inputs, no calib manifest) replaced both, exit 0; now exit 2
/// naming both and --force, before anything is written, and both as they were. With --force they
/// are replaced; calib's own earlier outputs (listed in the manifest it wrote) are replaced
/// without it.
#[test]
fn files_calib_did_not_write_are_replaced_only_with_force() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "run.csv", &dut_log());
    let dut = write(dir.path(), "dut.csv", "my own table, not calib's\n");
    let report = write(dir.path(), "report.json", "{\"mine\": true}\n");
    let run = [
        "reference",
        "run.csv",
        "--dut",
        "dut",
        "--ref",
        "ref",
        "-o",
        ".",
    ];
    let err = expect_exit(&calib_in(dir.path(), &run), 2);
    assert_mentions(
        &err,
        &["-o .", "./report.json", "calib did not write", "--force"],
    );
    assert_eq!(
        std::fs::read_to_string(&dut).unwrap(),
        "my own table, not calib's\n"
    );
    assert_eq!(
        std::fs::read_to_string(&report).unwrap(),
        "{\"mine\": true}\n"
    );
    assert_eq!(entries(dir.path()), ["dut.csv", "report.json", "run.csv"]);
    // The table alone in the way: found once its name is known, still before anything is written.
    std::fs::rename(&report, dir.path().join("my-report.json")).unwrap();
    let err = expect_exit(&calib_in(dir.path(), &run), 2);
    assert_mentions(
        &err,
        &["-o .", "./dut.csv", "calib did not write it", "--force"],
    );
    assert_eq!(
        std::fs::read_to_string(&dut).unwrap(),
        "my own table, not calib's\n"
    );
    assert_eq!(
        entries(dir.path()),
        ["dut.csv", "my-report.json", "run.csv"]
    );
    std::fs::rename(dir.path().join("my-report.json"), &report).unwrap();
    // --force replaces them.
    let mut forced = run.to_vec();
    forced.push("--force");
    expect_exit(&calib_in(dir.path(), &forced), 0);
    assert!(read_table(&dut).len() > 10);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["method"], "reference");
    // Now calib's own (the manifest lists them): rerun without --force replaces them.
    let manifest = std::fs::read_to_string(dir.path().join(".calib-manifest")).unwrap();
    assert_mentions(&manifest, &["dut.csv\n", "report.json\n", "report.html\n"]);
    std::fs::write(&dut, "stale").unwrap();
    expect_exit(&calib_in(dir.path(), &run), 0);
    assert!(read_table(&dut).len() > 10);
}

/// `--plots DIR` holding the user's own `map-a.png` replaced it, exit 0; now exit 2 naming it,
/// nothing written (neither the plots nor the output folder), and --force replaces it; the
/// plots calib wrote there are replaced by the next run without --force.
#[test]
fn a_plots_folder_keeps_files_calib_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    simulate_quick(dir.path(), "run.csv", &[]);
    let plots = dir.path().join("plots");
    std::fs::create_dir(&plots).unwrap();
    let mine = write(&plots, "map-a.png", "my own picture");
    let run = ["csrr", "run.csv", "-o", "out", "--plots", "plots"];
    let err = expect_exit(&calib_in(dir.path(), &run), 2);
    assert_mentions(
        &err,
        &[
            "--plots plots",
            "plots/map-a.png",
            "calib did not write",
            "--force",
        ],
    );
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "my own picture");
    assert_eq!(entries(&plots), ["map-a.png"]);
    assert_no_output(&dir.path().join("out"));
    let mut forced = run.to_vec();
    forced.push("--force");
    expect_exit(&calib_in(dir.path(), &forced), 0);
    assert!(std::fs::read(&mine).unwrap().starts_with(b"\x89PNG"));
    expect_exit(&calib_in(dir.path(), &run), 0);
    assert!(dir.path().join("out/report.json").is_file());
}

/// `calib export -o FILE` over the user's own FILE: exit 2 and FILE kept; --force replaces it,
/// and the file calib wrote is replaced by the next export without --force.
#[test]
fn a_single_output_file_is_replaced_only_when_calib_wrote_it() {
    let dir = tempfile::tempdir().unwrap();
    let t = table(
        dir.path(),
        "t.csv",
        &[(0.0, 1.0), (90.0, -1.0), (180.0, 2.0), (270.0, 0.5)],
    );
    let header = write(dir.path(), "enc.h", "// my own header\n");
    let export = ["export", s(&t), "--format", "c-array", "-o", "enc.h"];
    let err = expect_exit(&calib_in(dir.path(), &export), 2);
    assert_mentions(&err, &["-o enc.h", "calib did not write it", "--force"]);
    assert_eq!(
        std::fs::read_to_string(&header).unwrap(),
        "// my own header\n"
    );
    let mut forced = export.to_vec();
    forced.push("--force");
    expect_exit(&calib_in(dir.path(), &forced), 0);
    let written = std::fs::read_to_string(&header).unwrap();
    assert_ne!(written, "// my own header\n");
    expect_exit(&calib_in(dir.path(), &export), 0);
    assert_eq!(std::fs::read_to_string(&header).unwrap(), written);
}

/// `calib csrr A -o o` and `calib csrr B -o o` started together into one new folder: both
/// exited 0 and printed "wrote … into o" (8 of 8 trials) while one's results were gone. Now one
/// runs and the other refuses at once (exit 2) naming the folder and the run holding it; the
/// folder then holds the survivor's complete set. The logs are 10× quick.toml's rate, so that a
/// run (over a second here) outlasts the few milliseconds between the two starts.
#[test]
fn two_runs_into_one_folder_exclude_each_other() {
    let dir = tempfile::tempdir().unwrap();
    let a = simulate_quick(dir.path(), "a.csv", &[("rate_hz", "rate_hz = 2000.0")]);
    let b = dir.path().join("b.csv");
    std::fs::copy(&a, &b).unwrap();
    for trial in 0..4 {
        let out = dir.path().join(format!("o{trial}"));
        let spawn = |log: &Path| {
            Command::new(env!("CARGO_BIN_EXE_calib"))
                .args(["csrr", s(log), "-o", s(&out)])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("cannot start calib")
        };
        let runs = [spawn(&a), spawn(&b)];
        let pids = [runs[0].id(), runs[1].id()];
        let [ra, rb] = runs.map(|c| c.wait_with_output().unwrap());
        let (won, lost, log, pid) = match (code(&ra), code(&rb)) {
            (0, 2) => (ra, rb, &a, pids[0]),
            (2, 0) => (rb, ra, &b, pids[1]),
            (x, y) => panic!(
                "trial {trial}: exits {x} and {y}\n{}\n{}",
                stderr(&ra),
                stderr(&rb)
            ),
        };
        assert!(stdout(&won).contains("wrote"), "{}", stdout(&won));
        assert_mentions(
            &stderr(&lost),
            &[
                &format!("-o {}", out.display()),
                "another calib run is writing into this folder",
                &format!("(process {pid} on "),
            ],
        );
        // The survivor's set, complete: exactly the files its manifest lists.
        let manifest = std::fs::read_to_string(out.join(".calib-manifest")).unwrap();
        let mut listed: Vec<&str> = manifest.lines().collect();
        listed.push(".calib-manifest");
        listed.sort();
        assert_eq!(entries(&out), listed, "trial {trial}");
        assert_eq!(listed.len(), 5, "{listed:?}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        assert_eq!(report["inputs"][0], s(log), "trial {trial}");
        assert!(read_table(&out.join("a.csv")).len() > 100);
        assert!(read_table(&out.join("b.csv")).len() > 100);
        // Nothing of either run is left beside the folder: no lock file, no staging folder.
        let beside: Vec<String> = entries(dir.path())
            .into_iter()
            .filter(|n| n.starts_with('.') && n != ".calib-manifest")
            .collect();
        assert!(beside.is_empty(), "{beside:?}");
    }
}

/// A single output file (`export`, `apply`, `import`, `compose`, `simulate -o FILE`) took no
/// lock: a run writing into a folder while another run swapped that folder, or wrote its
/// manifest, could lose the other's file or its listing. Now a single-file run locks its folder
/// as a folder run does: while another run holds it, `export` and `compose` refuse at once
/// (exit 2) naming the file, its folder and the run holding it, and write nothing; once it is
/// released they run.
#[test]
fn a_single_output_file_waits_for_no_run_in_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<(f64, f64)> = (0..360)
        .map(|k| (k as f64, 3.0 * (k as f64).to_radians().sin()))
        .collect();
    let t = table(dir.path(), "a.csv", &rows);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let exported = out.join("a.h");
    let composed = out.join("sum.csv");
    let export = ["export", s(&t), "--format", "c-array", "-o", s(&exported)];
    let compose = ["compose", s(&t), s(&t), "-o", s(&composed)];
    let held = calib_io::folder_lock::FolderLock::acquire(&out).unwrap();
    for (args, file) in [(&export[..], &exported), (&compose[..], &composed)] {
        let o = calib(args);
        expect_exit(&o, 2);
        assert_mentions(
            &stderr(&o),
            &[
                &format!("-o {}", file.display()),
                "another calib run is writing into its folder",
                &format!("(process {} on ", std::process::id()),
            ],
        );
        assert!(
            !file.exists(),
            "{} written while the folder was held",
            file.display()
        );
    }
    drop(held);
    expect_exit(&calib(&export), 0);
    expect_exit(&calib(&compose), 0);
    assert!(exported.exists() && composed.exists());
}

/// Stale cleanup removed, recursively, any `.X.calib-<pid>.Y.tmp` entry whose pid was not
/// alive here — a live run's staging folder on another host sharing the folder too. Now: a
/// dead run's staging folder of this host goes; another host's stays; a folder that is not
/// calib's staging layout (it holds a subfolder), or a name without a host (an earlier calib),
/// stays and is reported.
#[test]
fn stale_cleanup_removes_only_what_is_provably_calibs() {
    let dir = tempfile::tempdir().unwrap();
    let host = this_host(dir.path());
    // Simulated first: `calib simulate` cleans its folder too.
    let log = simulate_quick(dir.path(), "run.csv", &[]);
    let mut gone = Command::new("true").spawn().unwrap();
    gone.wait().unwrap();
    let dead = gone.id();
    let staging = |owner: &str, random: &str| {
        let name = format!(".out.calib-{owner}.{random}.tmp");
        let path = dir.path().join(&name);
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("a.csv"), "staged").unwrap();
        name
    };
    let ours = staging(&format!("{dead}@{host}"), "AbC123");
    let elsewhere = staging(&format!("{dead}@another-host+4026531836"), "XyZ789");
    let earlier = staging(&dead.to_string(), "QqQ111");
    let foreign = staging(&format!("{dead}@{host}"), "WwW222");
    std::fs::create_dir(dir.path().join(&foreign).join("results")).unwrap();
    std::fs::write(dir.path().join(&foreign).join("results/keep.csv"), "mine").unwrap();
    // An existing folder: its parent, where the staging folders are, is cleaned too.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let o = calib(&["csrr", s(&log), "-o", s(&out)]);
    let err = expect_exit(&o, 0);
    assert_mentions(&err, &["removed 1 temporary file(s)"]);
    assert_mentions(
        &err,
        &[
            &earlier,
            "did not record its host",
            &foreign,
            "more than calib's staged files",
        ],
    );
    assert!(!dir.path().join(&ours).exists(), "{ours}");
    assert_eq!(entries(&dir.path().join(&elsewhere)), ["a.csv"]);
    assert_eq!(entries(&dir.path().join(&earlier)), ["a.csv"]);
    assert_eq!(
        std::fs::read_to_string(dir.path().join(&foreign).join("results/keep.csv")).unwrap(),
        "mine"
    );
}

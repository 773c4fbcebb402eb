//! Reliability at the process boundary: a run killed (SIGKILL) mid-write leaves no partial file at
//! a final output name, and results no table may hold are refused rather than written.

use crate::common::{self, long};

use calib_io::{LogReader, ReadOptions};
use common::{calib, code, s, stderr, testdata};
use long::long_scenario;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Waits until `dir` holds a non-empty temporary file of `name` (`.<name>.XXXX.tmp`); false if
/// the process ended first.
fn wait_for_temp(child: &mut Child, dir: &Path, name: &str) -> bool {
    let prefix = format!(".{name}.");
    let deadline = Instant::now() + Duration::from_secs(120);
    while Instant::now() < deadline {
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        let found = std::fs::read_dir(dir)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| {
                let n = e.file_name().to_string_lossy().into_owned();
                n.starts_with(&prefix)
                    && n.ends_with(".tmp")
                    && e.metadata().is_ok_and(|m| m.len() > 0)
            });
        if found {
            return true;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    panic!("no temporary file of {name} appeared in {}", dir.display());
}

/// SIGKILLs `child` if it still runs; whether it did.
fn kill(child: &mut Child) -> bool {
    let running = child.try_wait().unwrap().is_none();
    if running {
        child.kill().unwrap();
    }
    child.wait().unwrap();
    running
}

/// Every sample of a log, or the first error.
fn read_log(path: &Path) -> Result<usize, String> {
    let mut reader = LogReader::open(path, &ReadOptions::default()).map_err(|e| e.to_string())?;
    let mut n = 0;
    for sample in reader.by_ref() {
        sample.map_err(|e| e.to_string())?;
        n += 1;
    }
    match &reader.diagnostics().truncated {
        Some(t) => Err(format!("truncated at byte {}", t.byte_offset)),
        None => Ok(n),
    }
}

/// The files at final names (not hidden temporaries) in `dir`.
fn final_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && !p.file_name().unwrap().to_string_lossy().starts_with('.'))
        .collect();
    files.sort();
    files
}

/// Checks that whatever a (possibly killed) `simulate` left at final names is complete.
fn check_simulate_outputs(log: &Path, samples: usize, points: usize) {
    if log.exists() {
        assert_eq!(read_log(log), Ok(samples), "{}", log.display());
    }
    let truth = log.with_file_name(format!(
        "{}.truth",
        log.file_stem().unwrap().to_string_lossy()
    ));
    for table in final_files(&truth) {
        let t = calib_io::table::read_turn_table(&table)
            .unwrap_or_else(|e| panic!("a partial table at a final name: {e}"));
        assert_eq!(t.map.len(), points, "{}", table.display());
    }
}

#[test]
fn killed_runs_leave_no_partial_file_at_a_final_name() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = long_scenario(dir.path());
    let points = "36000";
    for ext in ["mcap", "csv"] {
        // A complete run gives the reference sample count.
        let full_dir = dir.path().join(format!("full-{ext}"));
        std::fs::create_dir(&full_dir).unwrap();
        let full = full_dir.join(format!("run.{ext}"));
        let started = Instant::now();
        let o = calib(&["simulate", s(&scenario), "-o", s(&full), "--points", points]);
        let full_run = started.elapsed();
        assert_eq!(code(&o), 0, "{}", stderr(&o));
        let samples = read_log(&full).unwrap();
        assert!(samples > 150_000, "{ext}: {samples}");
        std::fs::remove_dir_all(&full_dir).unwrap();

        // Kill at several moments: while the log is written (just after its temporary file
        // appears, and a fifth and a half of a whole run later, so the moments scale with the
        // machine's speed) and while the truth tables are written.
        let mut killed_mid_write = 0;
        for (k, (wait_name, delay)) in [
            (format!("run.{ext}"), 0.0),
            (format!("run.{ext}"), 0.2),
            (format!("run.{ext}"), 0.5),
            ("a.csv".to_string(), 0.0),
            ("b.csv".to_string(), 0.0),
        ]
        .into_iter()
        .enumerate()
        {
            let run_dir = dir.path().join(format!("{ext}-{k}"));
            std::fs::create_dir(&run_dir).unwrap();
            let log = run_dir.join(format!("run.{ext}"));
            let watch = if wait_name.starts_with("run.") {
                run_dir.clone()
            } else {
                run_dir.join("run.truth")
            };
            let mut child = spawn(&["simulate", s(&scenario), "-o", s(&log), "--points", points]);
            if wait_for_temp(&mut child, &watch, &wait_name) {
                std::thread::sleep(full_run.mul_f64(delay));
            }
            if kill(&mut child) {
                killed_mid_write += 1;
            }
            check_simulate_outputs(&log, samples, 36000);
        }
        assert!(
            killed_mid_write >= 3,
            "{ext}: only {killed_mid_write} runs were caught mid-write"
        );
    }
}

#[test]
fn a_killed_calibration_leaves_only_complete_files() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = long_scenario(dir.path());
    let log = dir.path().join("run.mcap");
    let o = calib(&["simulate", s(&scenario), "-o", s(&log), "--points", "3600"]);
    assert_eq!(code(&o), 0, "{}", stderr(&o));
    for (k, delay_ms) in [0u64, 50, 200, 400, 800].into_iter().enumerate() {
        let out = dir.path().join(format!("out-{k}"));
        let mut child = spawn(&["csrr", s(&log), "-o", s(&out)]);
        std::thread::sleep(Duration::from_millis(delay_ms));
        kill(&mut child);
        let files = final_files(&out);
        // Each file is renamed into place complete, tables first and the report last (a kill
        // can fall between two renames): a report means every table is there.
        let names: Vec<String> = files
            .iter()
            .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        if names.iter().any(|n| n.starts_with("report.")) {
            assert!(
                ["a.csv", "b.csv"]
                    .iter()
                    .all(|n| names.iter().any(|m| m == n)),
                "{names:?}"
            );
        }
        for f in files {
            if f.extension().is_some_and(|e| e == "csv") {
                calib_io::table::read_turn_table(&f).unwrap();
            } else if f.extension().is_some_and(|e| e == "html") {
                let html = std::fs::read_to_string(&f).unwrap();
                assert!(
                    html.trim_end().ends_with("</html>"),
                    "{} is cut",
                    f.display()
                );
            } else {
                let text = std::fs::read_to_string(&f).unwrap();
                serde_json::from_str::<serde_json::Value>(&text).unwrap();
            }
        }
    }
}

#[test]
fn shift_angle_refuses_to_write_tables_from_absurd_readings() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(testdata("shift-angle/readings.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // Line 100 is shift 0, start face 5, step 3: a reading of 1e12″.
    let head: Vec<&str> = lines[99].rsplitn(2, ',').collect();
    lines[99] = format!("{},1e12", head[1]);
    let readings = dir.path().join("readings.csv");
    std::fs::write(&readings, lines.join("\n") + "\n").unwrap();
    let out = dir.path().join("out");
    let o = calib(&["shift-angle", s(&readings), "-o", s(&out)]);
    assert_eq!(code(&o), 1);
    let e = stderr(&o);
    assert!(
        e.contains("readings.csv") && e.contains("no table was written"),
        "{e}"
    );
    assert!(final_files(&out).is_empty());
}

//! The number of threads (`--jobs`, `CALIB_JOBS`) changes how fast calib runs, never what it
//! writes: every method's tables and report.json, and `inspect --json`, are the same bytes on one
//! thread (the log read inline, no chunk workers, the solvers' halves in turn) and on two (read
//! ahead, the halves side by side).

use crate::common::coast::coast_log;
use crate::common::multihead::{HEADS, selfa_log};
use crate::common::{calib, expect_exit, s, simulate, simulate_quick, testdata};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};

/// Runs `calib` with `args` and `CALIB_JOBS=jobs`.
fn calib_with_env(jobs: &str, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .env("CALIB_JOBS", jobs)
        .args(args)
        .output()
        .expect("cannot start calib")
}

/// Every file of a method's output folder by name, report.json without its command line (which
/// names the folder and the flags) and report.html left out (it embeds report.json).
fn outputs(folder: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut files = BTreeMap::new();
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let bytes = match name.as_str() {
            "report.html" => continue,
            "report.json" => {
                let mut report: Value =
                    serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
                report["command_line"] = Value::Null;
                serde_json::to_vec(&report).unwrap()
            }
            _ => std::fs::read(&path).unwrap(),
        };
        files.insert(name, bytes);
    }
    assert!(files.contains_key("report.json"), "{}", folder.display());
    files
}

/// Runs `method_args` (a method with its log and options, without `-o`) with `--jobs 1`,
/// `--jobs 2` and `CALIB_JOBS=1`, and asserts the three output folders hold the same bytes.
fn same_on_any_threads(dir: &Path, method_args: &[&str]) {
    let run = |name: &str, jobs: Option<&str>, env: Option<&str>| {
        let out = dir.join(name);
        let mut args = method_args.to_vec();
        args.extend(["-o", s(&out), "-q"]);
        if let Some(j) = jobs {
            args.extend(["--jobs", j]);
        }
        let o = match env {
            Some(e) => calib_with_env(e, &args),
            None => calib(&args),
        };
        expect_exit(&o, 0);
        outputs(&out)
    };
    let one = run("jobs1", Some("1"), None);
    assert!(
        one == run("jobs2", Some("2"), None),
        "{}: --jobs 1 and --jobs 2 differ",
        method_args[0]
    );
    assert!(
        one == run("env1", None, Some("1")),
        "{}: CALIB_JOBS=1 and --jobs 1 differ",
        method_args[0]
    );
}

#[test]
fn csrr_writes_the_same_bytes_on_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    let log = testdata("examples/quick.mcap");
    same_on_any_threads(dir.path(), &["csrr", s(&log)]);
}

#[test]
fn multihead_writes_the_same_bytes_on_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    let log = selfa_log(dir.path());
    same_on_any_threads(dir.path(), &["multihead", s(&log), "--heads", HEADS]);
}

#[test]
fn tdr_writes_the_same_bytes_on_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    let log = coast_log(dir.path());
    same_on_any_threads(
        dir.path(),
        &["tdr", s(&log), "--channel", "enc", "--ref", "ref"],
    );
}

#[test]
fn reference_writes_the_same_bytes_on_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/joint.toml"), dir.path(), "joint.mcap");
    same_on_any_threads(
        dir.path(),
        &["reference", s(&log), "--dut", "b", "--ref", "ref"],
    );
}

#[test]
fn inspect_says_the_same_on_one_thread_and_two() {
    let log = testdata("examples/quick.mcap");
    let json = |jobs: &str| stdout_of(&calib(&["inspect", s(&log), "--json", "--jobs", jobs]));
    assert_eq!(json("1"), json("2"));
}

/// Every message of MCAP `bytes`: topic, log time, publish time, sequence and data.
fn messages(bytes: &[u8]) -> Vec<(String, u64, u64, u32, Vec<u8>)> {
    mcap::MessageStream::new(bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            let topic = m.channel.topic.clone();
            (
                topic,
                m.log_time,
                m.publish_time,
                m.sequence,
                m.data.into_owned(),
            )
        })
        .collect()
}

/// `calib apply` writes the same MCAP bytes with `--jobs 1` (read, corrected, compressed and
/// written on one thread), `--jobs 2` (chunks decompressed and compressed on worker threads,
/// written on a thread of its own) and `CALIB_JOBS=1`, with and without `--keep`, on a log of
/// many chunks; the copy holds every message of the log, in order, with its times and sequence.
#[test]
fn apply_writes_the_same_bytes_on_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    // 5 kHz: some 80,000 JointState messages, a dozen chunks of 1 MiB.
    let log = simulate_quick(dir.path(), "run.mcap", &[("rate_hz", "rate_hz = 5000.0")]);
    let table = testdata("examples/quick.truth/a.csv");
    let input = std::fs::read(&log).unwrap();
    let chunks = mcap::Summary::read(&input)
        .unwrap()
        .unwrap()
        .chunk_indexes
        .len();
    assert!(chunks >= 8, "{chunks} chunks");
    for keep in [false, true] {
        let run = |name: &str, jobs: Option<&str>, env: Option<&str>| {
            let out = dir.path().join(format!("{name}-{keep}.mcap"));
            let mut args = vec!["apply", s(&table), s(&log), "-o", s(&out), "--channel", "a"];
            if keep {
                args.push("--keep");
            }
            if let Some(j) = jobs {
                args.extend(["--jobs", j]);
            }
            let o = match env {
                Some(e) => calib_with_env(e, &args),
                None => calib(&args),
            };
            expect_exit(&o, 0);
            std::fs::read(&out).unwrap()
        };
        let one = run("jobs1", Some("1"), None);
        assert!(
            one == run("jobs2", Some("2"), None),
            "--keep {keep}: --jobs 1 and 2 differ"
        );
        assert!(
            one == run("env1", None, Some("1")),
            "--keep {keep}: CALIB_JOBS=1 differs"
        );
        let copied = messages(&one);
        let original = messages(&input);
        if keep {
            // The original messages as they were, each followed by its corrected copy.
            let (kept, corrected): (Vec<_>, Vec<_>) =
                copied.into_iter().partition(|m| m.0 == "/joint_states");
            assert_eq!(kept, original);
            assert_eq!(corrected.len(), original.len());
            for (c, o) in corrected.iter().zip(&original) {
                assert_eq!((c.1, c.2, c.3), (o.1, o.2, o.3));
                assert_ne!(c.4, o.4, "the position of `a` is corrected");
            }
        } else {
            assert_eq!(copied.len(), original.len());
            for (c, o) in copied.iter().zip(&original) {
                assert_eq!((&c.0, c.1, c.2, c.3), (&o.0, o.1, o.2, o.3));
                assert_eq!(c.4.len(), o.4.len());
            }
        }
    }
}

fn stdout_of(o: &Output) -> String {
    expect_exit(o, 0);
    String::from_utf8(o.stdout.clone()).unwrap()
}

#[test]
fn a_bad_calib_jobs_is_a_usage_error_naming_the_variable() {
    let log = testdata("examples/quick.mcap");
    for bad in ["0", "two", "-1", ""] {
        let o = calib_with_env(bad, &["inspect", s(&log)]);
        let err = expect_exit(&o, 2);
        assert!(
            err.contains("CALIB_JOBS") && err.contains("whole number from 1"),
            "CALIB_JOBS={bad:?}: {err}"
        );
    }
    // The flag wins over the variable.
    expect_exit(
        &calib_with_env("two", &["inspect", s(&log), "--jobs", "1"]),
        0,
    );
}

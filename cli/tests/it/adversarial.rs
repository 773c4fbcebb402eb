//! The adversarial cases of issue 18, each reproduced so that none comes back: damaged MCAP
//! chunks, output sets that must be all-or-nothing (a fault-injection hook stops a run at every
//! step in turn), temporary files after signals, unbounded work, and messages that must name the
//! option, the path and what to do.

use crate::common::{self, long};

use common::{calib, code, s, stderr, stdout, testdata};
use long::long_scenario;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The exit status of a run stopped by `CALIB_TEST_KILL_AT` (`calib_io::atomic::KILLED_EXIT`).
const KILLED: i32 = calib_io::atomic::KILLED_EXIT;

fn quick_mcap() -> PathBuf {
    testdata("examples/quick.mcap")
}

/// `bytes` with bit `bit` of byte `offset` flipped, written to `dir/name`.
fn flipped(dir: &Path, name: &str, bytes: &[u8], offset: usize, bit: u8) -> PathBuf {
    let mut b = bytes.to_vec();
    b[offset] ^= 1 << bit;
    let p = dir.join(name);
    std::fs::write(&p, b).unwrap();
    p
}

/// The offsets and lengths of an MCAP file's top-level chunk records (opcode 0x06).
fn chunks(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut at = 8;
    let mut found = Vec::new();
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        match bytes[at] {
            0x06 => found.push((at, 9 + len)),
            0x0F => break,
            _ => {}
        }
        at += 9 + len;
    }
    found
}

/// Every file of `dir` (hidden ones included) with its contents.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap_or_default(),
            )
        })
        .collect()
}

/// calib's temporary files and folders (`.<name>.calib-<pid>.<random>.tmp`) in `dir`.
fn temps(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".calib-") && n.ends_with(".tmp"))
        .collect()
}

fn calib_env(args: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .unwrap()
}

/// The quick scenario's log with a third channel, `ref`, on B's shaft.
fn three_channel_log(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(testdata("scenarios/quick.toml")).unwrap();
    let text = text.replace(
        "[procedure]",
        "[[sensor]]\nname = \"ref\"\nmount = \"b\"\nharmonics = [{ order = 3, amplitude_arcsec = 1.0, phase_deg = 0.0 }]\n\n[procedure]",
    );
    let scenario = common::write(dir, "three.toml", &text);
    common::simulate(&scenario, dir, "three.mcap")
}

/// A simulated MCAP log of the quick scenario long enough to hold several chunks.
fn multi_chunk_log(dir: &Path) -> PathBuf {
    let log = common::simulate_quick(
        dir,
        "long.mcap",
        &[
            ("revolutions = 2.0", "revolutions = 8.0"),
            ("rate_hz = 200.0", "rate_hz = 1000.0"),
        ],
    );
    let n = chunks(&std::fs::read(&log).unwrap()).len();
    assert!(n >= 3, "{n} chunks");
    log
}

// --- 1. Chunk CRCs ----------------------------------------------------------------------------

/// The issue's own case: bit 0 of byte 131 of quick.mcap lies in its first zstd chunk and
/// decompresses to other valid readings; the chunk's CRC catches it.
#[test]
fn a_flipped_bit_in_a_zstd_chunk_is_an_error_naming_the_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(quick_mcap()).unwrap();
    let (first, _) = chunks(&bytes)[0];
    let log = flipped(dir.path(), "bad.mcap", &bytes, 131, 0);
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&log), "-o", s(&out)]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    let e = stderr(&o);
    common::assert_mentions(
        &e,
        &[
            &format!("the chunk at byte {first}"),
            "messages logged",
            "CRC",
            "--skip-damaged",
        ],
    );
    common::assert_no_output(&out);
    // apply reads through the same check: nothing is written.
    let table = dir.path().join("a.csv");
    let good = dir.path().join("good");
    common::expect_exit(&calib(&["csrr", s(&quick_mcap()), "-o", s(&good)]), 0);
    std::fs::copy(good.join("a.csv"), &table).unwrap();
    let fixed = dir.path().join("fixed.mcap");
    let o = calib(&["apply", s(&table), s(&log), "-o", s(&fixed)]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("CRC"), "{}", stderr(&o));
    assert!(!fixed.exists());
}

#[test]
fn skip_damaged_leaves_the_chunk_out_and_says_so_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let log = multi_chunk_log(dir.path());
    let bytes = std::fs::read(&log).unwrap();
    let (at, len) = chunks(&bytes)[1];
    let bad = flipped(dir.path(), "bad.mcap", &bytes, at + len / 2, 3);
    let out = dir.path().join("out");
    let o = calib(&["csrr", s(&bad), "-o", s(&out)]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("the chunk at byte {at}")),
        "{}",
        stderr(&o)
    );

    let o = calib(&["csrr", s(&bad), "-o", s(&out), "--skip-damaged"]);
    common::expect_exit(&o, 0);
    let text = stdout(&o);
    assert!(text.contains("skipped 1 damaged chunk"), "{text}");
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(report.contains("skipped 1 damaged chunk"), "{report}");
    assert!(
        report.contains(&format!("the chunk at byte {at}")),
        "{report}"
    );

    // apply --skip-damaged writes the rest, and says what it left out.
    let fixed = dir.path().join("fixed.mcap");
    let o = calib(&[
        "apply",
        s(&out.join("a.csv")),
        s(&bad),
        "-o",
        s(&fixed),
        "--skip-damaged",
    ]);
    common::expect_exit(&o, 0);
    let text = stdout(&o);
    assert!(text.contains("skipped 1 damaged chunk"), "{text}");
    assert!(fixed.exists());
}

/// A cut file is called cut at any length: it either calibrates with a warning that it ends
/// early, or fails saying it is cut; never "no samples" alone.
#[test]
fn a_cut_file_is_called_cut_at_any_length() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(quick_mcap()).unwrap();
    let data_end = chunks(&bytes).last().map(|(a, l)| a + l).unwrap();
    let mut lengths: Vec<usize> = (1..20).map(|k| k * data_end / 20).collect();
    lengths.extend([9, 100, data_end - 1]);
    for len in lengths {
        let log = dir.path().join(format!("cut{len}.mcap"));
        std::fs::write(&log, &bytes[..len]).unwrap();
        let out = dir.path().join(format!("out{len}"));
        let o = calib(&["csrr", s(&log), "-o", s(&out)]);
        let all = format!("{}{}", stdout(&o), stderr(&o));
        assert!(
            all.contains("ends early") || all.contains("cut short"),
            "{len} bytes: {all}"
        );
    }
}

// --- 2. Output sets all-or-nothing ------------------------------------------------------------

/// Two runs into the same folder with different file sets (`--b b`, then `--b ref`): a run
/// stopped at each step of writing in turn leaves the folder holding exactly one run's files,
/// and the next run removes what the stopped one left beside it.
#[test]
fn a_run_stopped_at_any_step_leaves_exactly_one_runs_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let log = three_channel_log(dir.path());
    let run_a = ["csrr", s(&log), "-o", s(&out), "--b", "b"];
    let run_b = ["csrr", s(&log), "-o", s(&out), "--b", "ref"];
    common::expect_exit(&calib(&run_b), 0);
    let set_b = snapshot(&out);
    common::expect_exit(&calib(&run_a), 0);
    let set_a = snapshot(&out);
    let names = |m: &BTreeMap<String, Vec<u8>>| m.keys().cloned().collect::<Vec<_>>();
    assert!(set_a.contains_key("b.csv") && !set_a.contains_key("ref.csv"));
    assert!(set_b.contains_key("ref.csv") && !set_b.contains_key("b.csv"));

    let mut stopped = 0;
    for step in 1.. {
        // Start from run A's folder, then run B stopped at `step`.
        common::expect_exit(&calib(&run_a), 0);
        assert_eq!(snapshot(&out), set_a);
        let o = calib_env(&run_b, &[("CALIB_TEST_KILL_AT", &step.to_string())]);
        if code(&o) == 0 {
            assert_eq!(snapshot(&out), set_b);
            break;
        }
        assert_eq!(code(&o), KILLED, "step {step}: {}", stderr(&o));
        stopped += 1;
        let now = snapshot(&out);
        assert!(
            now == set_a || now == set_b,
            "step {step}: the folder holds {:?}, neither run A's {:?} nor B's {:?}",
            names(&now),
            names(&set_a),
            names(&set_b)
        );
        // What the stopped run left (its staging folder, beside `out`) goes with the next run.
        let o = calib(&run_b);
        common::expect_exit(&o, 0);
        assert_eq!(snapshot(&out), set_b, "step {step}");
        assert!(
            temps(dir.path()).is_empty(),
            "step {step}: {:?}",
            temps(dir.path())
        );
        assert!(temps(&out).is_empty(), "step {step}: {:?}", temps(&out));
        assert!(step < 50, "the run never finished");
    }
    // Four files staged, the manifest, the swap and the removal of the old set.
    assert!(stopped >= 6, "only {stopped} steps");
}

#[test]
fn a_later_run_into_the_same_folder_leaves_no_earlier_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let log = three_channel_log(dir.path());
    common::expect_exit(&calib(&["csrr", s(&log), "-o", s(&out), "--b", "b"]), 0);
    common::expect_exit(&calib(&["csrr", s(&log), "-o", s(&out), "--b", "ref"]), 0);
    let names: Vec<String> = snapshot(&out).into_keys().collect();
    assert_eq!(
        names,
        [
            ".calib-manifest",
            "a.csv",
            "ref.csv",
            "report.html",
            "report.json"
        ]
    );
}

// --- 3. Temporary files -----------------------------------------------------------------------

#[test]
fn sigterm_and_sigint_while_writing_leave_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = long_scenario(dir.path());
    for (signal, status) in [("TERM", 143), ("INT", 130)] {
        let run = dir.path().join(signal);
        std::fs::create_dir(&run).unwrap();
        let log = run.join("run.csv");
        let mut child = Command::new(env!("CARGO_BIN_EXE_calib"))
            .args(["simulate", s(&scenario), "-o", s(&log)])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(60);
        while temps(&run).is_empty() {
            assert!(Instant::now() < deadline, "no temporary file appeared");
            assert!(child.try_wait().unwrap().is_none(), "finished too soon");
            std::thread::sleep(Duration::from_millis(1));
        }
        Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        let exit = child.wait().unwrap();
        assert_eq!(exit.code(), Some(status), "SIG{signal}");
        assert!(temps(&run).is_empty(), "SIG{signal}: {:?}", temps(&run));
        assert!(!log.exists());
    }
}

#[test]
fn stale_temporary_files_of_dead_runs_are_removed_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    // Temporary names say which process on which host made them (issue 52).
    let host = common::this_host(dir.path());
    // A process that has ended: its pid names a dead run.
    let mut gone = Command::new("true").spawn().unwrap();
    gone.wait().unwrap();
    let dead = format!(".a.csv.calib-{}@{host}.AbC123.tmp", gone.id());
    let live = format!(".a.csv.calib-{}@{host}.XyZ789.tmp", std::process::id());
    std::fs::write(out.join(&dead), "half a table").unwrap();
    std::fs::write(out.join(&live), "a concurrent run's table").unwrap();
    let o = calib(&["csrr", s(&quick_mcap()), "-o", s(&out)]);
    common::expect_exit(&o, 0);
    assert!(
        stderr(&o).contains("removed 1 temporary file(s)"),
        "{}",
        stderr(&o)
    );
    assert!(!out.join(&dead).exists());
    assert!(out.join(&live).exists());
}

// --- 4. Limits --------------------------------------------------------------------------------

#[test]
fn absurd_points_are_refused_at_once_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let log = s(&quick_mcap()).to_string();
    let good = dir.path().join("good");
    common::expect_exit(&calib(&["csrr", &log, "-o", s(&good)]), 0);
    let table = good.join("a.csv");
    let cases: Vec<Vec<String>> = vec![
        vec!["csrr".into(), log.clone()],
        vec![
            "multihead".into(),
            log.clone(),
            "--heads".into(),
            "a@0,b@180".into(),
        ],
        vec!["tdr".into(), log.clone(), "--channel".into(), "a".into()],
        vec![
            "reference".into(),
            log.clone(),
            "--dut".into(),
            "a".into(),
            "--ref".into(),
            "ref".into(),
        ],
        vec![
            "export".into(),
            s(&table).into(),
            "--format".into(),
            "csv".into(),
        ],
        vec![
            "simulate".into(),
            s(&testdata("scenarios/quick.toml")).into(),
        ],
    ];
    for mut args in cases {
        let out = dir.path().join(format!("{}-out", args[0]));
        args.extend([
            "-o".into(),
            s(&out).into(),
            "--points".into(),
            "100000000".into(),
        ]);
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let started = Instant::now();
        let o = calib(&argv);
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("--points 100000000"),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(started.elapsed() < Duration::from_secs(5), "{args:?}");
    }
}

#[test]
fn absurd_scenarios_are_refused_at_once_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    for (edit, new) in [
        ("rate_hz = 200.0", "rate_hz = 1e12"),
        ("revolutions = 2.0", "revolutions = 1e9"),
    ] {
        let scenario = common::write(dir.path(), "big.toml", &common::quick_with(&[(edit, new)]));
        let log = dir.path().join("big.csv");
        let started = Instant::now();
        let o = calib(&["simulate", s(&scenario), "-o", s(&log)]);
        assert_eq!(code(&o), 2, "{new}: {}", stderr(&o));
        common::assert_mentions(&stderr(&o), &["samples", "--force"]);
        assert!(started.elapsed() < Duration::from_secs(5), "{new}");
        assert!(!log.exists());
    }
}

#[test]
fn dev_zero_and_endless_lines_fail_within_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let zero = dir.path().join("zero.csv");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let started = Instant::now();
    let o = calib(&["csrr", s(&zero), "-o", s(&dir.path().join("o1"))]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("device"), "{}", stderr(&o));
    assert!(started.elapsed() < Duration::from_secs(5));

    // A named pipe that never ends a line: refused at once, without hanging or growing (the CSV
    // dialect detection needs to seek, which a pipe cannot).
    let pipe = dir.path().join("pipe.csv");
    assert!(
        Command::new("mkfifo")
            .arg(&pipe)
            .status()
            .unwrap()
            .success()
    );
    let mut writer = Command::new("sh")
        .args([
            "-c",
            &format!("yes y | tr -d '\\n' | head -c 2000000000 > '{}'", s(&pipe)),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    let o = calib(&["csrr", s(&pipe), "-o", s(&dir.path().join("o3"))]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    assert!(stderr(&o).contains("pipe.csv"), "{}", stderr(&o));
    assert!(started.elapsed() < Duration::from_secs(10));
    let _ = writer.kill();
    let _ = writer.wait();
    // calib refuses the pipe without opening it, so the shell's `head` still waits to open it
    // for writing: opened and closed here, it ends (SIGPIPE) instead of outliving the test. On
    // a thread, in case it has already ended and the open would wait for a writer forever.
    let fifo = pipe.clone();
    std::thread::spawn(move || drop(std::fs::File::open(fifo)));

    // A file of one 8 MB line: refused at the limit, naming the line, without reading it all.
    let long = dir.path().join("long.csv");
    let mut text = b"t,a,b\n".to_vec();
    text.extend(std::iter::repeat_n(b'9', 8 << 20));
    std::fs::write(&long, text).unwrap();
    let o = calib(&["csrr", s(&long), "-o", s(&dir.path().join("o2"))]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    common::assert_mentions(&stderr(&o), &["line 2", "longer than 1048576 bytes"]);
}

// --- 5. Messages ------------------------------------------------------------------------------

#[test]
fn a_folder_as_a_log_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = calib(&["csrr", s(dir.path()), "-o", s(&dir.path().join("out"))]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is a folder, not a log"),
        "{}",
        stderr(&o)
    );
    let o = calib(&["inspect", s(dir.path())]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
}

#[test]
fn an_unusable_output_folder_is_refused_before_reading() {
    let dir = tempfile::tempdir().unwrap();
    let file = common::write(dir.path(), "taken", "x");
    // The log does not even exist: the output is checked first.
    for (out, says) in [
        (s(&file), "is a file, not a folder"),
        ("/proc/x", "cannot write into /proc"),
    ] {
        let o = calib(&["csrr", s(&quick_mcap()), "-o", out]);
        assert_eq!(code(&o), 2, "{out}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
        assert!(!stderr(&o).contains("os error"), "{}", stderr(&o));
    }
}

#[test]
fn os_errors_are_printed_once_without_the_system_suffix() {
    let dir = tempfile::tempdir().unwrap();
    // A folder where the table should be.
    let o = calib(&[
        "apply",
        s(dir.path()),
        s(&quick_mcap()),
        "-o",
        s(&dir.path().join("fixed.mcap")),
    ]);
    assert_ne!(code(&o), 0);
    let e = stderr(&o);
    assert!(!e.contains("os error"), "{e}");
    assert_eq!(e.matches("Is a directory").count(), 1, "{e}");
}

#[test]
fn bad_option_values_are_named_with_their_range() {
    let log = s(&quick_mcap()).to_string();
    for (option, value, says) in [
        (
            "--min-speed",
            "1e12",
            "--min-speed 1.0000e12 is outside its range",
        ),
        (
            "--session-tol",
            "-1",
            "--session-tol -1 is outside its range",
        ),
        (
            "--session-tol",
            "1e300",
            "--session-tol 1.0000e300 is outside its range",
        ),
        (
            "--min-observability",
            "2",
            "--min-observability 2 is outside its range",
        ),
    ] {
        let o = calib(&[
            "csrr",
            &log,
            &format!("{option}={value}"),
            "-o",
            "/nonexistent/never",
        ]);
        assert_eq!(code(&o), 2, "{option}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{option}: {}", stderr(&o));
    }
    // The same for the other methods' options.
    for (args, says) in [
        (
            vec!["tdr", &log, "--channel", "a", "--motion-degree", "99"],
            "--motion-degree 99 is outside its range: at least 1 and at most",
        ),
        (
            vec!["tdr", &log, "--channel", "a", "--min-revolutions", "0.5"],
            "--min-revolutions 0.5 is outside its range: a finite number of at least 1",
        ),
        (
            vec![
                "multihead",
                &log,
                "--heads",
                "a@0,b@90",
                "--min-observability",
                "1.5",
            ],
            "--min-observability 1.5 is outside its range: at least 0 and below 1",
        ),
        // One phrasing for `--max-order 0` whichever method refuses it.
        (
            vec!["csrr", &log, "--max-order", "0"],
            "--max-order 0 is outside its range: at least 1",
        ),
        (
            vec!["multihead", &log, "--heads", "a@0,b@90", "--max-order", "0"],
            "--max-order 0 is outside its range: at least 1",
        ),
        (
            vec!["tdr", &log, "--channel", "a", "--max-order", "0"],
            "--max-order 0 is outside its range: at least 1 and at most",
        ),
        (
            vec!["csrr", &log, "--points", "1"],
            "--points 1 is outside its range: at least 2 and at most",
        ),
    ] {
        let o = calib(&[args.as_slice(), &["-o", "/nonexistent/never"]].concat());
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    }
}

#[test]
fn a_reference_equal_to_a_calibrated_channel_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let o = calib(&[
        "csrr",
        s(&quick_mcap()),
        "--ref",
        "a",
        "-o",
        s(&dir.path().join("o")),
    ]);
    assert_eq!(code(&o), 2, "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--ref `a` is also a calibrated sensor"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn control_characters_are_escaped_and_numbers_readable() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("o")).to_string();
    // A NUL byte in a field after the first bytes, and a time stamp of 1e300 s.
    let nul = common::write(
        dir.path(),
        "nul.csv",
        "t,a,b\n0.00,1.000,2.000\n0.01,1.001,2.001\n0.02,\u{0}\u{1b}[31m,2\n",
    );
    let o = calib(&["csrr", s(&nul), "-o", &out]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    let e = stderr(&o);
    assert!(!e.contains('\u{0}') && !e.contains('\u{1b}'), "{e:?}");
    assert!(e.contains("\\0") || e.contains("\\u{0}"), "{e:?}");

    let huge = common::write(dir.path(), "huge.csv", "t,a,b\n0,1,2\n1e300,1,2\n");
    let o = calib(&["csrr", s(&huge), "-o", &out]);
    assert_eq!(code(&o), 1, "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("1.0000e300") || e.contains("1e300"), "{e}");
    assert!(!e.contains("0000000000000000000000"), "{e}");
}

#[test]
fn a_files_real_type_is_told_from_its_bytes() {
    let dir = tempfile::tempdir().unwrap();
    // An MCAP file named .csv is read as the MCAP it is.
    let disguised = dir.path().join("run.csv");
    std::fs::copy(quick_mcap(), &disguised).unwrap();
    let o = calib(&["inspect", s(&disguised)]);
    common::expect_exit(&o, 0);
    // A gzip file named .csv is called gzip.
    let gz = dir.path().join("gz.csv");
    std::fs::write(&gz, [0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3]).unwrap();
    let o = calib(&["inspect", s(&gz)]);
    assert_eq!(code(&o), 1);
    assert!(stderr(&o).contains("gzip-compressed"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("UTF-8"), "{}", stderr(&o));
}

/// A file output into a folder that does not exist is a usage error naming the folder, before
/// any work (it was an I/O error naming a temporary file, after simulating the whole run).
#[test]
fn file_outputs_into_a_missing_folder_are_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing");
    let table = dir.path().join("a.csv");
    let map: String = (0..360)
        .map(|i| {
            format!(
                "{i},{:.6},{:.6}\n",
                f64::from(i).to_radians().sin(),
                -f64::from(i).to_radians().sin()
            )
        })
        .collect();
    std::fs::write(
        &table,
        format!("angle_deg,error_arcsec,correction_arcsec\n{map}"),
    )
    .unwrap();
    let quick = testdata("scenarios/quick.toml");
    let out = |name: &str| missing.join(name).to_str().unwrap().to_string();
    for args in [
        vec![
            "simulate".to_string(),
            s(&quick).into(),
            "-o".into(),
            out("run.mcap"),
        ],
        vec![
            "compose".into(),
            s(&table).into(),
            s(&table).into(),
            "-o".into(),
            out("c.csv"),
        ],
        vec![
            "export".into(),
            s(&table).into(),
            "--format".into(),
            "csv".into(),
            "-o".into(),
            out("e.csv"),
        ],
        vec![
            "import".into(),
            s(&table).into(),
            "--format".into(),
            "csv".into(),
            "-o".into(),
            out("i.csv"),
        ],
    ] {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = calib(&args);
        assert_eq!(code(&o), 2, "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("does not exist") && stderr(&o).contains(s(&missing)),
            "{args:?}: {}",
            stderr(&o)
        );
        assert!(!missing.exists(), "{args:?} created the folder");
    }
}

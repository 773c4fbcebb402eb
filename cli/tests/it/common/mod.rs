//! Helpers shared by the end-to-end tests of `calib`.
//!
//! The modules beside this one hold helpers of one kind each (ROS recordings, report.json, one
//! method's runs, …); a test file imports those it uses, e.g. `use crate::common::ros;`.

pub mod coast;
pub mod columns;
pub mod compare;
pub mod inspect;
pub mod json;
pub mod long;
pub mod multihead;
pub mod reference;
pub mod ros;
#[cfg(feature = "remote")]
pub mod servers;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `calib` with `args`.
pub fn calib(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(args)
        .output()
        .expect("cannot start calib")
}

/// A path as `&str` (the temporary folders have UTF-8 names).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The repository's `testdata/` folder joined with `rel`.
pub fn testdata(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../testdata")
        .join(rel)
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit code, with both streams in the message if the process was killed.
pub fn code(o: &Output) -> i32 {
    o.status
        .code()
        .unwrap_or_else(|| panic!("killed by a signal\n{}\n{}", stdout(o), stderr(o)))
}

/// Asserts the exit code and that calib did not panic; returns standard error.
#[track_caller]
pub fn expect_exit(o: &Output, want: i32) -> String {
    let err = stderr(o);
    assert_eq!(
        code(o),
        want,
        "exit code\nstdout:\n{}\nstderr:\n{err}",
        stdout(o)
    );
    assert!(!err.contains("panicked"), "calib panicked:\n{err}");
    assert!(!err.contains("RUST_BACKTRACE"), "calib panicked:\n{err}");
    err
}

/// Asserts `text` contains every one of `parts`.
#[track_caller]
pub fn assert_mentions(text: &str, parts: &[&str]) {
    for p in parts {
        assert!(text.contains(p), "expected {p:?} in:\n{text}");
    }
}

/// Asserts that a failed run left nothing behind in `out`: the folder is absent or empty.
#[track_caller]
pub fn assert_no_output(out: &Path) {
    if out.exists() {
        let left: Vec<_> = std::fs::read_dir(out)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(left.is_empty(), "{} holds {left:?}", out.display());
    }
}

/// `testdata/scenarios/quick.toml` with each `(line prefix, new line)` edit applied: the line
/// starting with the prefix is replaced (the prefix must match exactly one line).
pub fn quick_with(edits: &[(&str, &str)]) -> String {
    let text = std::fs::read_to_string(testdata("scenarios/quick.toml")).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for (prefix, new) in edits {
        let hits: Vec<usize> = (0..lines.len())
            .filter(|&i| lines[i].starts_with(prefix))
            .collect();
        assert_eq!(hits.len(), 1, "prefix {prefix:?} in quick.toml");
        lines[hits[0]] = new.to_string();
    }
    lines.join("\n") + "\n"
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// `calib simulate scenario -o dir/log`; asserts success and returns the log's path.
#[track_caller]
pub fn simulate(scenario: &Path, dir: &Path, log: &str) -> PathBuf {
    let out = dir.join(log);
    let o = calib(&["simulate", s(scenario), "-o", s(&out)]);
    expect_exit(&o, 0);
    assert!(out.is_file(), "{} missing", out.display());
    out
}

/// Simulates quick.toml edited by `edits` into `dir/log`.
#[track_caller]
pub fn simulate_quick(dir: &Path, log: &str, edits: &[(&str, &str)]) -> PathBuf {
    let stem = log.split('.').next().unwrap();
    let scenario = write(dir, &format!("{stem}.toml"), &quick_with(edits));
    simulate(&scenario, dir, log)
}

/// The rows of a table CSV `angle_deg,error_arcsec,...`: `(angle, error)`; asserts the header.
pub fn read_table(path: &Path) -> Vec<(f64, f64)> {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(
        header.starts_with("angle_deg,error_arcsec,correction_arcsec"),
        "{}: header {header}",
        path.display()
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let (a, e, c): (f64, f64, f64) = (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            );
            assert!(
                (e + c).abs() < 1e-6,
                "{}: correction ≠ −error: {l}",
                path.display()
            );
            (a, e)
        })
        .collect()
}

/// A table interpolated linearly and periodically at `deg` (the grid is uniform over 360°).
pub fn interpolate(table: &[(f64, f64)], deg: f64) -> f64 {
    let n = table.len();
    let x = deg.rem_euclid(360.0) / 360.0 * n as f64;
    let i = x.floor() as usize % n;
    let f = x - x.floor();
    table[i].1 * (1.0 - f) + table[(i + 1) % n].1 * f
}

/// Hand-written CSV log `t,a,b` at 100 Hz: for each relative offset, two revolutions of the
/// shaft at 1 r/s (`a = θ + offset`, `b = b_of(θ)`, wrapped to [0, 360)) then half a second
/// at rest; one session per offset, found from the motion.
pub fn handwritten_log(offsets: &[f64], b_of: impl Fn(f64) -> f64) -> String {
    let mut text = String::from("t,a,b\n");
    let mut t = 0.0;
    let mut row = |text: &mut String, a: f64, b: f64| {
        text.push_str(&format!(
            "{t:.3},{:.6},{:.6}\n",
            a.rem_euclid(360.0),
            b.rem_euclid(360.0)
        ));
        t += 0.01;
    };
    for &off in offsets {
        for j in 0..=200 {
            let th = 720.0 * j as f64 / 200.0;
            row(&mut text, th + off, b_of(th));
        }
        for _ in 0..50 {
            row(&mut text, 720.0 + off, b_of(720.0));
        }
    }
    text
}

/// A resolver against a motor's counter as a TwinCAT Scope export would give them (converted to
/// calib's CSV): one sweep 0 → 358.5° → 0 at 100 Hz (10 ms), 36°/s; the resolver errs by ±15°
/// (order 1) and 2° (order 2), 16-bit resolution (19.775″) with 5″ noise; the counter is exact to
/// 0.01″. 1.5° of the turn is never reached.
pub const RESOLVER_SWEEP: &str = r#"
seed = 7
rate_hz = 100.0
wrap = true

[[sensor]]
name = "resolver"
harmonics = [
  { order = 1, amplitude_arcsec = 54000.0, phase_deg = 0.0 },
  { order = 2, amplitude_arcsec = 7200.0, phase_deg = 30.0 },
]
quantization_arcsec = 19.775
noise_arcsec = 5.0

[[sensor]]
name = "counter"
quantization_arcsec = 0.01

[sweep]
from_deg = 0.0
to_deg = 358.5
cycles = 1
speeds_deg_s = [36.0]
ramp_s = 0.5
pause_s = 0.5
"#;

/// This host as calib's temporary names carry it (`.<name>.calib-<pid>@<host>.<random>.tmp`):
/// read from the staging folder a run stopped by the fault-injection hook leaves.
pub fn this_host(dir: &Path) -> String {
    let log = simulate_quick(dir, "host.csv", &[]);
    let out = dir.join("host-out");
    let o = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(["csrr", s(&log), "-o", s(&out)])
        .env("CALIB_TEST_KILL_AT", "1")
        .output()
        .unwrap();
    assert_eq!(code(&o), 86, "{}", stderr(&o));
    let staging = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .find(|n| n.starts_with(".host-out.calib-") && n.ends_with(".tmp"))
        .expect("no staging folder left");
    std::fs::remove_dir_all(dir.join(&staging)).unwrap();
    let owner = staging.trim_start_matches(".host-out.calib-");
    let host = owner.split_once('@').expect("no host in the name").1;
    host.split_once('.').unwrap().0.to_string()
}

//! Snapshots of what users read: every command's summary on standard output, on committed
//! fixtures, and the output of each export format. A change to any of them shows as a diff to
//! review; accept it with `INSTA_UPDATE=always cargo test -p calib-cli --test it snapshots::` (or
//! `cargo insta review`) once it is meant. The committed `.snap` files are in `snapshots/`.
//!
//! Nothing machine-dependent is kept: calib runs in the repository's root with its inputs named
//! relative to it, paths under the test's temporary folder read `[TMP]`, and calib's version
//! reads `[VERSION]`. The summaries print no timings. The logs of tdr, multihead and reference
//! are simulated from committed scenarios (seeded, so the same on every run).

use std::path::{Path, PathBuf};
use std::process::Command;

/// The repository's root, where calib runs.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// A temporary folder for outputs.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new() -> Self {
        Scratch(tempfile::tempdir().unwrap())
    }

    /// `name` inside the folder, as an argument.
    fn path(&self, name: &str) -> String {
        self.0.path().join(name).to_str().unwrap().to_string()
    }

    /// Runs calib in the repository's root with `args`; asserts success; returns standard
    /// output with this folder's path as `[TMP]` and the version as `[VERSION]`.
    #[track_caller]
    fn run(&self, args: &[&str]) -> String {
        self.run_exit(args, 0)
    }

    /// [`Scratch::run`] expecting the exit status `code`.
    #[track_caller]
    fn run_exit(&self, args: &[&str], code: i32) -> String {
        let o = Command::new(env!("CARGO_BIN_EXE_calib"))
            .current_dir(root())
            .args(args)
            .output()
            .expect("cannot start calib");
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            o.status.code() == Some(code),
            "calib {args:?}: {:?}\nstdout:\n{stdout}\nstderr:\n{stderr}",
            o.status
        );
        let tmp = self.0.path().to_str().unwrap();
        let text = stdout.replace(tmp, "[TMP]").replace(
            concat!("calib ", env!("CARGO_PKG_VERSION")),
            "calib [VERSION]",
        );
        rounding_noise(&text)
    }

    /// Simulates a committed scenario into this folder; returns the log's path.
    fn simulate(&self, scenario: &str, log: &str) -> String {
        let out = self.path(log);
        self.run(&[
            "simulate",
            &format!("testdata/scenarios/{scenario}"),
            "-o",
            &out,
        ]);
        out
    }
}

/// `text` with figures that are zero up to floating-point rounding written `[≈0]`: their digits
/// depend on the CPU's and the maths library's last bits, not on calib. Only the shift-angle
/// summary's sin-fit check prints one (`max |U_fit − U| = 1.5e-15″`).
fn rounding_noise(text: &str) -> String {
    const KEY: &str = "max |U_fit − U| = ";
    text.split_inclusive('\n')
        .map(|line| {
            let Some((head, rest)) = line.split_once(KEY) else {
                return line.to_string();
            };
            let (number, tail) = rest.split_at(rest.find('″').unwrap_or(rest.len()));
            match number.parse::<f64>() {
                Ok(v) if v.abs() < 1e-9 => format!("{head}{KEY}[≈0]{tail}"),
                _ => line.to_string(),
            }
        })
        .collect()
}

const QUICK: &str = "testdata/examples/quick.mcap";
const TRUTH_A: &str = "testdata/examples/quick.truth/a.csv";
const TRUTH_B: &str = "testdata/examples/quick.truth/b.csv";

#[test]
fn inspect() {
    let s = Scratch::new();
    insta::assert_snapshot!("inspect", s.run(&["inspect", QUICK]));
}

#[test]
fn simulate() {
    let s = Scratch::new();
    let out = s.path("quick.csv");
    insta::assert_snapshot!(
        "simulate",
        s.run(&[
            "simulate",
            "testdata/scenarios/quick.toml",
            "-o",
            &out,
            "--points",
            "720"
        ])
    );
}

#[test]
fn csrr() {
    let s = Scratch::new();
    let out = s.path("csrr");
    insta::assert_snapshot!("csrr", s.run(&["csrr", QUICK, "-o", &out]));
    let with_truth = s.path("csrr-truth");
    insta::assert_snapshot!(
        "csrr_truth",
        s.run(&[
            "csrr",
            QUICK,
            "-o",
            &with_truth,
            "--truth",
            "testdata/examples/quick.truth"
        ])
    );
}

#[test]
fn reference() {
    let s = Scratch::new();
    let log = s.simulate("joint.toml", "joint.mcap");
    let out = s.path("reference");
    insta::assert_snapshot!(
        "reference",
        s.run(&["reference", &log, "--dut", "b", "--ref", "ref", "-o", &out])
    );
}

#[test]
fn tdr() {
    let s = Scratch::new();
    let log = s.simulate("spindown.toml", "coast.mcap");
    let out = s.path("tdr");
    insta::assert_snapshot!(
        "tdr",
        s.run(&["tdr", &log, "--channel", "enc", "--ref", "ref", "-o", &out])
    );
}

/// A driven run at two speeds (issue 48): the motor's orders separated by their 1/ω²
/// dependence.
#[test]
fn tdr_driven() {
    let s = Scratch::new();
    let log = s.simulate("driven-two-speeds.toml", "driven.mcap");
    let out = s.path("tdr_driven");
    insta::assert_snapshot!(
        "tdr_driven",
        s.run(&[
            "tdr",
            &log,
            "--channel",
            "enc",
            "--pole-pairs",
            "7",
            "-o",
            &out
        ])
    );
}

#[test]
fn multihead() {
    let s = Scratch::new();
    let log = s.simulate("multihead.toml", "selfa.mcap");
    let heads = "h1@0,h2@360/7,h3@90,h4@720/7,h5@120,h6@1080/7,h7@180,h8@1440/7,h9@240,\
                 h10@1800/7,h11@270,h12@2160/7";
    for (name, method) in [("multihead", "joint"), ("multihead_eda", "eda")] {
        let out = s.path(name);
        insta::assert_snapshot!(
            name,
            s.run(&[
                "multihead",
                &log,
                "--heads",
                heads,
                "--method",
                method,
                "-o",
                &out
            ])
        );
    }
}

#[test]
fn shift_angle() {
    let s = Scratch::new();
    let readings = "testdata/shift-angle/readings.csv";
    let out = s.path("shift-angle");
    insta::assert_snapshot!("shift_angle", s.run(&["shift-angle", readings, "-o", &out]));
    let out = s.path("shift-angle-budget");
    insta::assert_snapshot!(
        "shift_angle_budget",
        s.run(&[
            "shift-angle",
            readings,
            "-o",
            &out,
            "--budget",
            "testdata/shift-angle/table3.toml"
        ])
    );
    let out = s.path("shift-angle-paper");
    insta::assert_snapshot!(
        "shift_angle_paper",
        s.run(&["shift-angle", readings, "-o", &out, "--method", "paper"])
    );
}

#[test]
fn uncertainty() {
    let s = Scratch::new();
    insta::assert_snapshot!(
        "uncertainty",
        s.run(&["uncertainty", "testdata/shift-angle/table3.toml"])
    );
}

#[test]
fn compare() {
    let s = Scratch::new();
    let out = s.path("compare");
    insta::assert_snapshot!(
        "compare",
        s.run(&[
            "compare",
            "testdata/shift-angle/truth_encoder.csv",
            "testdata/shift-angle/truth_encoder.csv",
            "--U1",
            "0.1",
            "--U2",
            "0.1",
            "-o",
            &out
        ])
    );
    // The shift-angle method's encoder.csv (with its budget's U) against the fixture's truth.
    let calibrated = s.path("sa");
    s.run(&[
        "shift-angle",
        "testdata/shift-angle/readings.csv",
        "-o",
        &calibrated,
        "--budget",
        "testdata/shift-angle/table3.toml",
    ]);
    let out = s.path("compare-truth");
    insta::assert_snapshot!(
        "compare_with_truth",
        s.run(&[
            "compare",
            &format!("{calibrated}/encoder.csv"),
            "testdata/shift-angle/truth_encoder.csv",
            "--U2",
            "0.3",
            "-o",
            &out
        ])
    );
    // The same with too small a U: the gate fails (exit 3) and the failing points are listed.
    let out = s.path("compare-fails");
    insta::assert_snapshot!(
        "compare_failing_points",
        s.run_exit(
            &[
                "compare",
                &format!("{calibrated}/encoder.csv"),
                "testdata/shift-angle/truth_encoder.csv",
                "--U2",
                "0.05",
                "-o",
                &out
            ],
            3
        )
    );
}

#[test]
fn apply() {
    let s = Scratch::new();
    let out = s.path("corrected.mcap");
    insta::assert_snapshot!("apply", s.run(&["apply", TRUTH_A, QUICK, "-o", &out]));
}

#[test]
fn compose() {
    let s = Scratch::new();
    let out = s.path("composed.csv");
    insta::assert_snapshot!(
        "compose",
        s.run(&[
            "compose", TRUTH_A, TRUTH_B, "-o", &out, "--factor", "0.5", "--points", "720"
        ])
    );
}

/// Each export format's output (on standard output), and the summary of one written to a file.
#[test]
fn export() {
    let s = Scratch::new();
    for (format, extra) in [
        ("lut-f32-rad", &["--points", "32"][..]),
        ("lut-i16", &["--points", "32"]),
        ("lut-u16", &["--points", "32"]),
        ("lut-i8", &["--points", "32", "--scale", "0.5"]),
        ("c-array", &["--points", "32"]),
        ("csv", &["--points", "32"]),
        ("harmonic", &["--harmonics", "4"]),
        ("moteus", &[]),
        ("moteus-config", &[]),
        ("simplefoc", &["--points", "32"]),
        ("simplefoc-float", &["--points", "32"]),
    ] {
        let mut args = vec!["export", TRUTH_A, "--format", format];
        args.extend_from_slice(extra);
        insta::assert_snapshot!(format!("export_{format}"), s.run(&args));
    }
    let out = s.path("a.h");
    insta::assert_snapshot!(
        "export_to_file",
        s.run(&["export", TRUTH_A, "--format", "c-array", "-o", &out])
    );
}

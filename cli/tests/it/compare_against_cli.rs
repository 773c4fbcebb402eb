//! `calib compare NEW --against OLD`: two runs of a fleet compared joint by joint, against a
//! known truth: two simulated nights of two robots, one joint's error changed between them.

use crate::common::{calib, expect_exit, s, simulate_quick, stdout};
use std::path::{Path, PathBuf};

/// One night of the fleet: `r1.mcap` (quick.toml, seed 1) and `r2.mcap` (seed 2, B's order-6
/// amplitude `b6` arcseconds; quick.toml's is 15), calibrated by `calib csrr` into `out`.
fn night(dir: &Path, b6: f64) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let r1 = simulate_quick(dir, "r1.mcap", &[]);
    let b6_line = format!("  {{ order = 6, amplitude_arcsec = {b6}, phase_deg = -120.0 }},");
    let r2 = simulate_quick(
        dir,
        "r2.mcap",
        &[("seed =", "seed = 2"), ("  { order = 6,", &b6_line)],
    );
    let out = dir.join("out");
    expect_exit(&calib(&["csrr", s(&r1), s(&r2), "-o", s(&out)]), 0);
    out
}

/// The rows of drift.csv, split on commas (no field of these runs is quoted).
fn rows(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "log,channel,status,points,max_abs_difference_arcsec,rms_difference_arcsec,\
         mean_difference_arcsec,max_en,points_over_1"
    );
    lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

/// Only the changed joint moves. The nights share their noise (the same seeds): what differs
/// is B's order 6 of robot 2, by 0.5″ in amplitude, so its map differs by a 0.5″ sinusoid
/// (max |Δ| 0.5″, against U ≈ 0.013″ at k = 2); the other maps by what the change does to the
/// joint fit (measured max En 0.41 for r2's A). Different noise alone takes the max En over
/// 3600 points of this short run to about 1 (1.01 measured with seeds 1 and 7), which is why
/// the test keeps it equal.
#[test]
fn the_one_changed_joint_is_the_one_that_moved() {
    let dir = tempfile::tempdir().unwrap();
    let old = night(&dir.path().join("night1"), 15.0);
    let new = night(&dir.path().join("night2"), 15.5);
    let drift = dir.path().join("drift");
    let o = calib(&["compare", s(&new), "--against", s(&old), "-o", s(&drift)]);
    let err = expect_exit(&o, 3);
    assert!(err.contains("1 of 4 channels moved"), "{err}");
    let text = stdout(&o);
    assert!(
        text.contains("1 channels moved (some En > 1), 3 steady, 0 new, 0 gone"),
        "{text}"
    );
    let rows = rows(&drift.join("drift.csv"));
    let keys: Vec<(&str, &str, &str)> = rows
        .iter()
        .map(|r| (r[0].as_str(), r[1].as_str(), r[2].as_str()))
        .collect();
    assert_eq!(
        keys,
        [
            ("r1", "a", "steady"),
            ("r1", "b", "steady"),
            ("r2", "a", "steady"),
            ("r2", "b", "moved"),
        ]
    );
    let number = |r: &Vec<String>, k: usize| r[k].parse::<f64>().unwrap();
    // Robot 1's nights are the same run: the same maps, to the digit.
    for r in &rows[..2] {
        assert_eq!(number(r, 4), 0.0, "{r:?}");
    }
    let moved = &rows[3];
    assert!(
        (0.45..0.55).contains(&number(moved, 4)),
        "max |Δ| {moved:?}"
    );
    assert!(number(moved, 7) > 10.0, "max En {moved:?}");
    assert!(number(&rows[2], 7) < 1.0, "r2's a: {:?}", rows[2]);

    // --json: the same rows.
    let o = calib(&[
        "compare",
        s(&new),
        "--against",
        s(&old),
        "-o",
        s(&drift),
        "--json",
    ]);
    expect_exit(&o, 3);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let list = json.as_array().unwrap();
    assert_eq!(list.len(), 4);
    assert_eq!(list[3]["status"], "moved");
    assert_eq!(list[3]["log"], "r2");
    assert_eq!(list[3]["points"], 3600);
}

/// A log in one run only is `new` or `gone`, not a failure; nothing moved: exit 0.
#[test]
fn logs_in_one_run_only_are_new_or_gone() {
    let dir = tempfile::tempdir().unwrap();
    let old = night(&dir.path().join("night1"), 15.0);
    let new = dir.path().join("new");
    std::fs::create_dir_all(new.join("r3")).unwrap();
    for f in ["a.csv", "b.csv", "report.json"] {
        std::fs::copy(old.join("r1").join(f), new.join("r3").join(f)).unwrap();
    }
    let drift = dir.path().join("drift");
    let o = calib(&["compare", s(&new), "--against", s(&old), "-o", s(&drift)]);
    expect_exit(&o, 0);
    let keys: Vec<String> = rows(&drift.join("drift.csv"))
        .iter()
        .map(|r| format!("{} {} {}", r[0], r[1], r[2]))
        .collect();
    assert_eq!(
        keys,
        [
            "r3 a new",
            "r3 b new",
            "r1 a gone",
            "r1 b gone",
            "r2 a gone",
            "r2 b gone"
        ]
    );
}

/// Usage errors name the folder or the flags.
#[test]
fn a_folder_without_reports_and_two_second_maps_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let o = calib(&[
        "compare",
        s(&empty),
        "--against",
        s(&empty),
        "-o",
        s(&dir.path().join("d")),
    ]);
    let err = expect_exit(&o, 2);
    assert!(
        err.contains("no report.json in it or under it") && err.contains(s(&empty)),
        "{err}"
    );
    let o = calib(&["compare", "a.csv", "b.csv", "--against", s(&empty)]);
    let err = expect_exit(&o, 2);
    assert!(err.contains("--against"), "{err}");
    let o = calib(&[
        "compare",
        s(&dir.path().join("missing")),
        "--against",
        s(&empty),
    ]);
    let err = expect_exit(&o, 2);
    assert!(err.contains("no such folder"), "{err}");
}

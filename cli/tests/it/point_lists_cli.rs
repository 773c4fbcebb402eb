//! Point lists (issue 25's leftovers): a `direction` column stating each point's direction of
//! approach where the order of the points cannot show it, and `inspect --json` saying a file is
//! a point list.

use crate::common::{self, json, reference};

use common::*;
use json::read_json;
use reference::reference;
use serde_json::Value;

/// The hand-worked ISO 230-2 set (targets 10°, 20°, 30°, two cycles; errors in ″ per target:
/// ↑ cycle 1, 2, ↓ cycle 1, 2) measured target by target: each target approached from below,
/// then overshot and approached from above, before the next target. `direction(up)` writes a
/// row's direction cell.
const ERRORS: [[f64; 4]; 3] = [
    [2.0, 4.0, 0.0, 0.0],
    [6.0, 6.0, 2.0, 4.0],
    [1.0, 3.0, 5.0, 5.0],
];

/// How a row's direction cell is written, from whether the point was reached increasing.
type Spelling = fn(bool) -> &'static str;

fn overshoot_list(direction: impl Fn(bool) -> &'static str) -> String {
    let mut text = String::from("dut;ref;direction\n");
    for c in 0..2 {
        for (i, t) in [10.0, 20.0, 30.0].into_iter().enumerate() {
            for (up, e) in [(true, ERRORS[i][c]), (false, ERRORS[i][2 + c])] {
                text.push_str(&format!("{t};{};{}\n", t - e / 3600.0, direction(up)));
            }
        }
    }
    text
}

/// The step into each ↓ point is zero (the overshoot is not in the list), so the order of the
/// points calls it ↑: without the column every target is measured "increasing" only and the
/// reversal value is lost. With it the figures are the hand-worked ones (see
/// `labfiles_cli::iso_230_2_of_a_point_list_by_hand`): B = 3″, M = 3″, E = 6″, R = 3 + 2√2″,
/// A = 4 + 2√2″, in each spelling.
#[test]
fn a_direction_column_makes_iso_230_2_right_where_the_order_cannot() {
    let dir = tempfile::tempdir().unwrap();
    let r2 = 2f64.sqrt();
    let want = [
        ("reversal_arcsec", 3.0),
        ("mean_bidirectional_arcsec", 3.0),
        ("systematic_arcsec", 6.0),
        ("repeatability_arcsec", 3.0 + 2.0 * r2),
        ("accuracy_arcsec", 4.0 + 2.0 * r2),
    ];
    let spellings: [(&str, Spelling); 3] = [
        ("signs.csv", |up| if up { "+" } else { "-" }),
        ("words.csv", |up| if up { "Up" } else { "DOWN" }),
        ("numbers.csv", |up| if up { "1" } else { "-1" }),
    ];
    for (name, spelling) in spellings {
        let log = write(dir.path(), name, &overshoot_list(spelling));
        let out = dir.path().join(format!("out-{name}"));
        expect_exit(&reference(&log, "dut", "ref", &out, &[]), 0);
        let iso = &read_json(&out.join("report.json"))["details"]["iso230_2"];
        for (k, v) in want {
            // Decimal degrees with 17 digits: the figures are exact to ~1e-9″.
            let got = iso[k].as_f64().unwrap();
            assert!((got - v).abs() < 1e-6, "{name} {k}: {got} vs {v}");
        }
    }

    // The same rows without the column: the order alone puts 20°'s four points "increasing".
    let plain: String = overshoot_list(|_| "")
        .lines()
        .map(|l| l.trim_end_matches(';').replace(";direction", "") + "\n")
        .collect();
    let log = write(dir.path(), "plain.csv", &plain);
    let out = dir.path().join("out-plain");
    let o = reference(&log, "dut", "ref", &out, &[]);
    expect_exit(&o, 0);
    assert!(
        stdout(&o).contains("in one direction only"),
        "{}",
        stdout(&o)
    );
    let targets = &read_json(&out.join("report.json"))["details"]["iso230_2_targets"];
    let at_20 = &targets[1];
    assert_eq!(at_20["target_deg"].as_f64(), Some(20.0));
    assert_eq!(at_20["increasing"]["passes"].as_u64(), Some(4), "{at_20}");
    assert_eq!(
        at_20["decreasing"]["passes"].as_u64().unwrap_or(0),
        0,
        "{at_20}"
    );
}

#[test]
fn a_bad_direction_is_named_by_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let text = overshoot_list(|up| if up { "+" } else { "-" }).replacen(";-\n", ";sideways\n", 1);
    let log = write(dir.path(), "bad.csv", &text);
    let out = dir.path().join("out");
    let err = expect_exit(&reference(&log, "dut", "ref", &out, &[]), 1);
    assert_mentions(
        &err,
        &[
            "bad.csv: line 3, column `direction`",
            "`sideways` is not a direction of approach",
            "write `+` or `-`",
        ],
    );
    assert_no_output(&out);
}

/// `inspect --json` says a file is a point list, with its points and the directions its column
/// states; a timed log says it is not. The text report says the same.
#[test]
fn inspect_says_a_file_is_a_point_list() {
    let dir = tempfile::tempdir().unwrap();
    let text = overshoot_list(|up| if up { "" } else { "-" });
    let log = write(dir.path(), "list.csv", &text);
    let o = calib(&["inspect", s(&log), "--json"]);
    expect_exit(&o, 0);
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["point_list"], Value::Bool(true));
    assert_eq!(v["points"].as_u64(), Some(12));
    assert_eq!(v["stated_directions"].as_u64(), Some(6));
    let o = calib(&["inspect", s(&log)]);
    expect_exit(&o, 0);
    let text = stdout(&o);
    assert_mentions(
        &text,
        &[
            "a list of 12 stationary points",
            "directions of approach: 6 of 12 stated by its direction column",
        ],
    );

    let timed = simulate_quick(dir.path(), "run.csv", &[]);
    let o = calib(&["inspect", s(&timed), "--json"]);
    expect_exit(&o, 0);
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["point_list"], Value::Bool(false));
    assert_eq!(v["points"], Value::Null);
    assert_eq!(v["stated_directions"], Value::Null);
}

//! Correction tables: rendering, write → read round trips, and the reader's validation.

use calib_core::ErrorMap;
use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_io::Error;
use calib_io::table::{RenderError, read_table, read_turn_table, render_table, write_table};
use std::path::{Path, PathBuf};

fn arcsec(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| v / ARCSEC_PER_RAD).collect()
}

/// A zero-mean map of awkward values (a seeded LCG), `n` points.
fn random_map(n: usize, seed: u64) -> ErrorMap {
    let mut state = seed;
    ErrorMap::new(
        (0..n)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 200.0 / ARCSEC_PER_RAD
            })
            .collect(),
    )
}

#[test]
fn render_is_fixed_precision_and_symmetric() {
    let map = ErrorMap::new(arcsec(&[1.25, -0.5, 0.0, -0.75]));
    let u = arcsec(&[0.05, 0.05, 0.1, 1e-9]);
    let text = render_table(&map.clone().into(), Some(&u)).unwrap();
    assert_eq!(
        text,
        "angle_deg,error_arcsec,correction_arcsec,u_arcsec\n\
         0.000000,1.250000,-1.250000,0.050000\n\
         90.000000,-0.500000,0.500000,0.050000\n\
         180.000000,0.000000,0.000000,0.100000\n\
         270.000000,-0.750000,0.750000,0.000000\n"
    );
    // Deterministic: the same input, the same bytes.
    let m = random_map(4096, 1);
    assert_eq!(
        render_table(&m.clone().into(), None),
        render_table(&m.clone().into(), None)
    );
    // Angles of a grid that 6 decimals cannot show exactly are rounded labels.
    let t = render_table(&m.clone().into(), None).unwrap();
    assert!(t.lines().nth(2).unwrap().starts_with("0.087891,"), "{t}");
}

#[test]
fn render_refuses_what_it_cannot_write() {
    let map = ErrorMap::new(arcsec(&[1.0, -1.0]));
    assert_eq!(
        render_table(&map.clone().into(), Some(&[0.1])),
        Err(RenderError::UncertaintyCount {
            points: 2,
            given: 1
        })
    );
    assert!(matches!(
        render_table(&map.clone().into(), Some(&[0.1, -0.1])),
        Err(RenderError::BadValue { index: 1, .. })
    ));
    let nan = ErrorMap::new(vec![0.0, f64::NAN]);
    assert!(matches!(
        render_table(&nan.clone().into(), None),
        Err(RenderError::BadValue { what: "error", .. })
    ));

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.csv");
    let err = write_table(&path, &nan.clone().into(), None).unwrap_err();
    assert!(matches!(err, Error::Write { .. }), "{err:?}");
    assert!(err.to_string().contains("a.csv"), "{err}");
    assert!(!path.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn write_read_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.csv");
    for (n, seed) in [(2, 3), (3600, 4), (4096, 5), (1000, 6)] {
        let map = random_map(n, seed);
        let u: Vec<f64> = (0..n)
            .map(|i| (0.01 + i as f64 * 1e-4) / ARCSEC_PER_RAD)
            .collect();
        write_table(&path, &map.clone().into(), Some(&u)).unwrap();
        let back = read_turn_table(&path).unwrap();
        assert_eq!(back.map.len(), n);
        // 6-decimal rounding: at most 5e-7″ per value, plus the re-removed mean of the roundings.
        let diff = map.minus(&back.map).max_abs_arcsec();
        assert!(diff <= 1e-6, "n={n}: {diff}");
        let bu = back.u.as_ref().unwrap();
        for (a, b) in u.iter().zip(bu) {
            assert!((a - b).abs() * ARCSEC_PER_RAD <= 5e-7 + 1e-12);
        }
        // Writing what was read gives back the same bytes: the format is a fixed point.
        let first = std::fs::read(&path).unwrap();
        write_table(&path, &back.map.clone().into(), back.u.as_deref()).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), first, "n={n}");
    }
    // Values representable at 6 decimals survive exactly, without `u`.
    let map = ErrorMap::new(arcsec(&[0.5, -0.25, 0.125, -0.375]));
    write_table(&path, &map.clone().into(), None).unwrap();
    let back = read_turn_table(&path).unwrap();
    assert!(back.u.is_none());
    assert!(map.minus(&back.map).max_abs_arcsec() < 1e-12);
}

fn write_tmp(dir: &tempfile::TempDir, content: &str) -> PathBuf {
    let path = dir.path().join("table.csv");
    std::fs::write(&path, content).unwrap();
    path
}

#[test]
fn hand_written_tables_are_accepted() {
    let dir = tempfile::tempdir().unwrap();
    // Other column order, fewer decimals, BOM, spaces, a correction rounded differently from the
    // error but within the rounding of the two fields, a mean that is removed on reading.
    let path = write_tmp(
        &dir,
        "\u{feff}error_arcsec, angle_deg ,correction_arcsec\n\
         1.2345, 0, -1.234\n\
         2, 120.0000001, -2\n\
         3.0, 240, -3.0\n",
    );
    let t = read_turn_table(&path).unwrap();
    let v: Vec<f64> = t.map.values().iter().map(|v| v * ARCSEC_PER_RAD).collect();
    for (got, want) in v.iter().zip([1.2345 - 6.2345 / 3.0, 2.0 - 6.2345 / 3.0]) {
        assert!((got - want).abs() < 1e-9, "{v:?}");
    }
}

/// The error for a table, checked to be a CSV error naming the file, the line and the column.
#[track_caller]
fn error_of(content: &str, line: u64, column: Option<&str>) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tmp(&dir, content);
    let err = read_turn_table(&path).unwrap_err();
    let text = err.to_string();
    let Error::Csv {
        path: p,
        line: l,
        channel,
        ..
    } = &err
    else {
        panic!("expected a CSV error, got {err:?}");
    };
    assert_eq!(p.as_path(), Path::new(&path), "{text}");
    assert_eq!((*l, channel.as_deref()), (line, column), "{text}");
    assert!(text.contains(&format!("line {line}")), "{text}");
    text
}

const H: &str = "angle_deg,error_arcsec,correction_arcsec\n";

#[test]
fn bad_tables_name_file_line_and_column() {
    let m = error_of("", 1, None);
    assert!(m.contains("empty"), "{m}");
    let m = error_of(H, 2, None);
    assert!(m.contains("0 rows") && m.contains("at least 2"), "{m}");
    let m = error_of(&format!("{H}0,1,-1\n"), 3, None);
    assert!(m.contains("1 row;"), "{m}");
    let m = error_of("angle_deg,error_arcsec\n0,1\n", 1, None);
    assert!(m.contains("the header is `angle_deg,error_arcsec`"), "{m}");
    let m = error_of(
        "angle_deg,error_arcsec,correction_arcsec,u_arcsecs\n",
        1,
        Some("u_arcsecs"),
    );
    assert!(m.contains("unknown column"), "{m}");
    let m = error_of(
        "angle_deg,error_arcsec,error_arcsec\n",
        1,
        Some("error_arcsec"),
    );
    assert!(m.contains("both named"), "{m}");
    let m = error_of(&format!("{H}0,1,-1\n180,x,1\n"), 3, Some("error_arcsec"));
    assert!(m.contains("`x` is not a number"), "{m}");
    let m = error_of(&format!("{H}0,1,-1\n180,NaN,1\n"), 3, Some("error_arcsec"));
    assert!(m.contains("not a finite number"), "{m}");
    let m = error_of(&format!("{H}0,1,-1\n180,-1\n"), 3, None);
    assert!(m.contains("2 fields but the header has 3"), "{m}");
    let m = error_of(
        &format!("{H}0,1,-1\n180,-1,-1\n"),
        3,
        Some("correction_arcsec"),
    );
    assert!(
        m.contains("correction -1 is not the negated error -1"),
        "{m}"
    );
    let m = error_of(
        &format!("{H}0,1.000000,-1.000002\n180,-1,1\n"),
        2,
        Some("correction_arcsec"),
    );
    assert!(m.contains("must be −error"), "{m}");
    let m = error_of(
        "angle_deg,error_arcsec,correction_arcsec,u_arcsec\n0,1,-1,0.1\n180,-1,1,-0.1\n",
        3,
        Some("u_arcsec"),
    );
    assert!(m.contains("negative"), "{m}");
}

#[test]
fn the_grid_must_be_uniform_from_zero_over_one_revolution() {
    // Not starting at 0: the first row (line 2) is blamed.
    let m = error_of(&format!("{H}1,1,-1\n181,-1,1\n"), 2, Some("angle_deg"));
    assert!(
        m.contains("the first row is at 1° but the grid starts at 0°"),
        "{m}"
    );
    // Non-uniform: the row whose step differs (line 4).
    let m = error_of(
        &format!("{H}0,1,-1\n90,0,0\n200,-1,1\n270,0,0\n"),
        4,
        Some("angle_deg"),
    );
    assert!(
        m.contains("not uniform: row 3 is at 200°, 110° after the previous row, but rows 1 and 2 are 90° apart"),
        "{m}"
    );
    // Out of order is not uniform either.
    let m = error_of(
        &format!("{H}0,1,-1\n240,0,0\n120,-1,1\n"),
        4,
        Some("angle_deg"),
    );
    assert!(m.contains("not uniform: row 3"), "{m}");
    // 360° repeated as a last row.
    let m = error_of(
        &format!("{H}0,1,-1\n180,-1,1\n360,1,-1\n"),
        4,
        Some("angle_deg"),
    );
    assert!(
        m.contains("the last row is at 360°, which is 0° again: remove it"),
        "{m}"
    );
    // Uniform but half a revolution only: blamed on the last row.
    let m = error_of(&format!("{H}0,1,-1\n90,-1,1\n"), 3, Some("angle_deg"));
    assert!(
        m.contains("does not cover a full revolution: its 2 rows are 90° apart, so they span 180°"),
        "{m}"
    );
    assert!(m.contains("needs 4 rows"), "{m}");
    // A full revolution written with too few decimals: the row and its expected angle.
    let m = error_of(
        &format!("{H}0,1,-1\n120.001,0,0\n240.002,-1,1\n"),
        3,
        Some("angle_deg"),
    );
    assert!(m.contains("row 2 of 3 must be at 120°"), "{m}");
    // Within the tolerance is fine, beyond it is not.
    let dir = tempfile::tempdir().unwrap();
    let ok = write_tmp(&dir, &format!("{H}0,1,-1\n180.0000009,-1,1\n"));
    assert!(read_turn_table(&ok).is_ok());
    error_of(
        &format!("{H}0,1,-1\n180.0000011,-1,1\n"),
        3,
        Some("angle_deg"),
    );
}

#[test]
fn missing_table_names_the_file() {
    let err = read_turn_table(Path::new("/no/such/table.csv")).unwrap_err();
    assert!(matches!(err, Error::Io { .. }));
    assert!(err.to_string().contains("/no/such/table.csv"), "{err}");
}

#[test]
fn absurd_values_are_refused_in_both_directions() {
    use calib_io::table::MAX_TABLE_ARCSEC;
    // Half a revolution passes; beyond it no sensor errs.
    let edge = ErrorMap::new(arcsec(&[MAX_TABLE_ARCSEC, -MAX_TABLE_ARCSEC]));
    assert!(render_table(&edge.clone().into(), None).is_ok());
    let huge = ErrorMap::new(arcsec(&[0.0, 0.0, 3e6, -3e6]));
    let err = render_table(&huge.clone().into(), None).unwrap_err();
    assert!(
        matches!(
            err,
            RenderError::Absurd {
                index: 2,
                what: "error",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("no table was written"), "{err}");
    let small = ErrorMap::new(arcsec(&[1.0, -1.0]));
    assert!(matches!(
        render_table(&small.clone().into(), Some(&arcsec(&[0.1, 1e9]))),
        Err(RenderError::Absurd {
            index: 1,
            what: "uncertainty",
            ..
        })
    ));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.csv");
    assert!(write_table(&path, &huge.clone().into(), None).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    // Reading: a table of such values was damaged or written in another unit.
    let m = error_of(
        &format!("{H}0,1,-1\n180,1e7,-1e7\n"),
        3,
        Some("error_arcsec"),
    );
    assert!(m.contains("beyond half a revolution"), "{m}");
    let m = error_of(
        "angle_deg,error_arcsec,correction_arcsec,u_arcsec\n0,1,-1,0.1\n180,-1,1,7e5\n",
        3,
        Some("u_arcsec"),
    );
    assert!(m.contains("beyond half a revolution"), "{m}");
}

#[test]
fn range_tables_round_trip_and_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    // 330°…390° (across 0), 61 points 1° apart: written signed, −30° to 30°, never above 360°.
    let values: Vec<f64> = (0..61).map(|i| f64::from(i) / ARCSEC_PER_RAD).collect();
    let map = calib_core::RangeMap::new((-30f64).to_radians(), 1f64.to_radians(), values).unwrap();
    let text = render_table(&map.clone().into(), None).unwrap();
    assert!(
        text.starts_with("# range_deg: -30.000000 to 30.000000 "),
        "{text}"
    );
    let path = write_tmp(&dir, &text);
    let TableMap::Range(back) = read_table(&path).unwrap().map else {
        panic!("not read as a range table")
    };
    assert_eq!(back.len(), 61);
    assert!((back.start() - map.start()).abs() < 1e-9);
    assert!(
        back.values()
            .iter()
            .zip(map.values())
            .all(|(a, b)| (a - b).abs() * ARCSEC_PER_RAD < 1e-6)
    );
    // Whole-turn readers refuse it, saying what it is.
    let err = read_turn_table(&path).unwrap_err().to_string();
    assert!(
        err.contains("range table") && err.contains("whole-turn"),
        "{err}"
    );

    // A range table with its last rows missing: the last row is blamed (line 3 = row 2).
    let m = error_of(
        &format!("# range_deg: 10 to 30\n{H}10,1,-1\n20,-1,1\n"),
        4,
        Some("angle_deg"),
    );
    assert!(
        m.contains("the last row is at 20° but the range line (line 1) puts that end at 30°"),
        "{m}"
    );
    // A range line that is not one.
    let m = error_of(
        &format!("# range_deg: 10 30\n{H}10,1,-1\n30,-1,1\n"),
        1,
        None,
    );
    assert!(m.contains("not a range line"), "{m}");
    let m = error_of(
        &format!("# range_deg: 10 to 400\n{H}10,1,-1\n400,-1,1\n"),
        1,
        None,
    );
    assert!(m.contains("less than 360°"), "{m}");
    // Without the range line, a half revolution is still a broken whole-turn table.
    let m = error_of(&format!("{H}0,1,-1\n90,-1,1\n"), 3, Some("angle_deg"));
    assert!(
        m.contains("does not cover a full revolution") && m.contains("# range_deg"),
        "{m}"
    );
}

//! Parquet files (pyarrow), end to end: what `calib inspect` lists, `calib csrr`'s maps against
//! the MCAP example of the same run, damaged files. The fixtures and how they were written:
//! `testdata/parquet/README.md`.

use crate::common::ros::table_difference;
use crate::common::{assert_mentions, calib, expect_exit, s, stderr, stdout, testdata};

#[test]
fn inspect_lists_the_columns_and_the_time() {
    let o = calib(&["inspect", s(&testdata("parquet/quick.parquet"))]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(
        &out,
        &[
            "Parquet file, 3301 rows in 4 row groups, 3 columns",
            "`stamp`: int64 TIMESTAMP(ns), optional → channel `stamp`",
            "`a`: double, optional → channel `a`",
            "3301 samples over 16.500 s",
        ],
    );
}

/// The fixture's stamps are the simulator's times from 2025-12-01 in whole nanoseconds, the
/// MCAP's the same times from 0: calib counts epoch stamps from their whole second, so the
/// run is timed as the MCAP's, and its degrees are the same doubles the MCAP holds in radians
/// (an ulp of ~6 rad apart, 2·10⁻¹⁰″): the maps agree far inside 1e-6″.
#[test]
fn csrr_of_a_pyarrow_file_gives_the_mcap_maps() {
    let dir = tempfile::tempdir().unwrap();
    let want = dir.path().join("mcap");
    expect_exit(
        &calib(&["csrr", s(&testdata("examples/quick.mcap")), "-o", s(&want)]),
        0,
    );
    let got = dir.path().join("parquet");
    let o = calib(&[
        "csrr",
        s(&testdata("parquet/quick.parquet")),
        "--a",
        "a",
        "--b",
        "b",
        "-o",
        s(&got),
    ]);
    expect_exit(&o, 0);
    for table in ["a.csv", "b.csv"] {
        let worst = table_difference(&want.join(table), &got.join(table));
        eprintln!("quick.parquet vs MCAP, {table}: max |difference| {worst:e}″");
        assert!(worst < 1e-6, "{table}: {worst}″");
    }
}

#[test]
fn a_damaged_file_is_an_error_naming_it_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(testdata("parquet/quick.parquet")).unwrap();
    let n = bytes.len();
    let mut footer = bytes.clone();
    footer[n - 8..n - 4].copy_from_slice(&(n as u32).to_le_bytes());
    let mut flipped = bytes.clone();
    for i in (4..n - 8).step_by(997) {
        flipped[i] ^= 0xff;
    }
    for (what, data, says) in [
        (
            "cut",
            bytes[..n / 2].to_vec(),
            Some("cut short, or damaged"),
        ),
        ("footer", footer, Some("footer states")),
        ("flipped", flipped, None),
    ] {
        let log = dir.path().join(format!("{what}.parquet"));
        std::fs::write(&log, &data).unwrap();
        let o = calib(&["inspect", s(&log)]);
        let code = o.status.code().unwrap_or_else(|| panic!("{what}: killed"));
        let err = stderr(&o);
        assert!(!err.contains("panicked"), "{what}: {err}");
        if let Some(says) = says {
            assert_ne!(code, 0, "{what}");
            assert_mentions(&err, &[&format!("{what}.parquet"), says]);
        } else if code != 0 {
            assert!(err.contains(&format!("{what}.parquet")), "{what}: {err}");
        }
    }
}

//! HDF5 files (h5py) and MATLAB v7.3 MAT-files (hdf5storage), end to end: what `calib inspect`
//! lists, `calib csrr`'s maps against the MCAP example of the same run, damaged files. The
//! fixtures and how they were written: `testdata/hdf5/README.md`.

use crate::common::ros::table_difference;
use crate::common::{assert_mentions, calib, expect_exit, s, stdout, testdata};
use std::path::Path;

/// `calib csrr` of the MCAP example into `dir/mcap`, the maps the other formats must give.
fn mcap_maps(dir: &Path) -> std::path::PathBuf {
    let want = dir.join("mcap");
    expect_exit(
        &calib(&["csrr", s(&testdata("examples/quick.mcap")), "-o", s(&want)]),
        0,
    );
    want
}

/// Every map of `got` against the MCAP example's. The fixtures hold the simulator's degrees as
/// the CSV prints them (shortest round trip, so the same doubles) and the MCAP the same values
/// in radians; converting either way differs by at most an ulp of ~6 rad (2·10⁻¹⁰″), so the
/// maps agree far inside 1e-6″ (the bound the ROS 1 MCAP test uses for the same run).
/// `tables` are `got`'s tables of the MCAP's `a` and `b` (named after the channels: `enc/a` is
/// `enc_a.csv`, `enc[0]` is `enc_0_.csv`).
fn assert_same_maps(want: &Path, got: &Path, tables: [&str; 2], what: &str) {
    for (table, mine) in ["a.csv", "b.csv"].into_iter().zip(tables) {
        let worst = table_difference(&want.join(table), &got.join(mine));
        eprintln!("{what} vs MCAP, {table}: max |difference| {worst:e}″");
        assert!(worst < 1e-6, "{what} {table}: {worst}″");
    }
}

#[test]
fn inspect_lists_the_datasets_and_the_channels() {
    let o = calib(&["inspect", s(&testdata("hdf5/quick.h5"))]);
    expect_exit(&o, 0);
    let out = stdout(&o);
    assert_mentions(
        &out,
        &[
            "HDF5",
            "3301 samples over 16.500 s",
            "`enc/a`: float64 [3301], shuffle+deflate → channel `enc/a`",
            "`t`: float64 [3301], shuffle+deflate → channel `t`",
            "`notes`: string [2] — not taken: not numbers",
        ],
    );
    let channels = out
        .split("channels")
        .nth(1)
        .unwrap_or_else(|| panic!("{out}"));
    assert_mentions(channels, &["enc/a", "enc/b", "deg"]);
}

#[test]
fn csrr_of_h5py_and_matlab_v73_files_gives_the_mcap_maps() {
    let dir = tempfile::tempdir().unwrap();
    let want = mcap_maps(dir.path());
    let got = dir.path().join("h5");
    let o = calib(&[
        "csrr",
        s(&testdata("hdf5/quick.h5")),
        "--a",
        "enc/a",
        "--b",
        "enc/b",
        "-o",
        s(&got),
    ]);
    expect_exit(&o, 0);
    assert_same_maps(&want, &got, ["enc_a.csv", "enc_b.csv"], "quick.h5");

    // MATLAB's 2×N matrix `enc` = [a; b]: its rows enc[0] and enc[1].
    let o = calib(&["inspect", s(&testdata("hdf5/quick_v73.mat"))]);
    expect_exit(&o, 0);
    assert_mentions(
        &stdout(&o),
        &[
            "MATLAB v7.3 MAT-file (HDF5 after a 512-byte header)",
            "`enc`: float64 [3301×2], shuffle+deflate+fletcher32 → 2 channels `enc[0]` … `enc[1]`",
            "`label`: uint16 [5×1] — not taken: MATLAB class `char`",
        ],
    );
    let got = dir.path().join("mat");
    let o = calib(&[
        "csrr",
        s(&testdata("hdf5/quick_v73.mat")),
        "--a",
        "enc[0]",
        "--b",
        "enc[1]",
        "-o",
        s(&got),
    ]);
    expect_exit(&o, 0);
    assert_same_maps(&want, &got, ["enc_0_.csv", "enc_1_.csv"], "quick_v73.mat");
}

#[test]
fn a_damaged_file_is_an_error_naming_it_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(testdata("hdf5/quick.h5")).unwrap();
    let mut cases = vec![
        ("cut", bytes[..bytes.len() / 3].to_vec()),
        ("superblock", bytes[..64].to_vec()),
    ];
    // A byte in each 1024-byte block flipped: object headers, B-trees and chunks alike.
    let mut flipped = bytes.clone();
    for i in (700..flipped.len()).step_by(1024) {
        flipped[i] ^= 0xff;
    }
    cases.push(("flipped", flipped));
    for (what, data) in cases {
        let log = dir.path().join(format!("{what}.h5"));
        std::fs::write(&log, &data).unwrap();
        let o = calib(&["inspect", s(&log)]);
        let code = o.status.code().unwrap_or_else(|| panic!("{what}: killed"));
        let err = crate::common::stderr(&o);
        assert!(!err.contains("panicked"), "{what}: {err}");
        if code != 0 {
            assert!(err.contains(&format!("{what}.h5")), "{what}: {err}");
        }
    }
}

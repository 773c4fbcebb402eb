//! End-to-end tests of MATLAB `.mat` files: the fixtures scipy wrote of the bundled example run
//! (`testdata/mat/`, v4 and compressed v5), and damaged copies of them.

use crate::common::columns::csrr_like_the_mcap_example;
use crate::common::inspect::inspect;
use crate::common::*;
use std::path::{Path, PathBuf};

#[test]
fn inspect_lists_variables_and_channels() {
    let text = inspect(&testdata("mat/quick_v4.mat"), &[]);
    assert_mentions(
        &text,
        &[
            "read as: MATLAB file",
            "MATLAB v4 MAT-file (Level 1.0), little-endian, 5 matrices",
            "`data_1`: 3 × 3301 double → rows `data_1[0]` … `data_1[2]`, 3301 samples each",
            "`t`: 1 × 3301 double → `t`, 3301 samples",
            "`note`: 1 × 23 uint8: not taken: text is not readings",
            "time: `t` (by its name), in seconds",
            "3301 samples over 16.500 s (0.000 … 16.500 s)",
        ],
    );
    let text = inspect(&testdata("mat/quick_v5.mat"), &[]);
    assert_mentions(
        &text,
        &[
            "MATLAB v5 MAT-file, little-endian (`MATLAB 5.0 MAT-file Platform: posix",
            "`data_1`: 3 × 3301 double (compressed) → rows `data_1[0]` … `data_1[2]`",
            "`note`: 1 × 23 char (compressed): not taken: text is not readings",
            "`info`: 1 × 1 struct (compressed) of fields rate_hz, index",
            "`info.rate_hz`: 1 × 1 double: not taken: one value or none, not a channel",
            "`info.index`: 1 × 3301 int32 → `info.index`, 3301 samples",
            "3301 samples over 16.500 s",
        ],
    );
}

#[test]
fn csrr_of_vectors_or_matrix_rows_gives_the_mcap_examples_maps() {
    let dir = tempfile::tempdir().unwrap();
    let v4 = dir.path().join("v4");
    csrr_like_the_mcap_example(&v4, &testdata("mat/quick_v4.mat"), "a", "b", &[]);
    // The matrix laid out as the real recording: rows t, a, b; the time named by the option.
    let v5 = dir.path().join("v5");
    csrr_like_the_mcap_example(
        &v5,
        &testdata("mat/quick_v5.mat"),
        "data_1[1]",
        "data_1[2]",
        &["--time-column", "data_1[0]"],
    );
}

/// A copy of the fixture `name` in `dir`, changed by `edit`, saved as `copy`.
fn damaged(dir: &Path, name: &str, copy: &str, edit: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(testdata("mat").join(name)).unwrap();
    edit(&mut bytes);
    let path = dir.join(copy);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn hostile_files_fail_naming_the_variable_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        // v4: `data_1` said to have 2^31 − 1 columns (its header's third i32).
        (
            damaged(dir.path(), "quick_v4.mat", "wide.mat", |b| {
                b[8..12].copy_from_slice(&i32::MAX.to_le_bytes())
            }),
            vec![
                "wide.mat",
                "matrix 0 `data_1` (at byte 0)",
                "3 × 2147483647 double values need",
                "save the variables again",
            ],
        ),
        // v5: the first variable said to be 4 GiB long (its tag's length, after the header).
        (
            damaged(dir.path(), "quick_v5.mat", "long.mat", |b| {
                b[132..136].copy_from_slice(&u32::MAX.to_le_bytes())
            }),
            vec![
                "long.mat",
                "variable 0 (at byte 128)",
                "4294967295 bytes long",
            ],
        ),
        // v5: the first variable's compressed bytes overwritten.
        (
            damaged(dir.path(), "quick_v5.mat", "zlib.mat", |b| {
                b[136..200].fill(0x55)
            }),
            vec!["zlib.mat", "variable 0 (at byte 128)", "does not inflate"],
        ),
        // Cut in the middle of a variable.
        (
            damaged(dir.path(), "quick_v4.mat", "cut.mat", |b| {
                b.truncate(100_000)
            }),
            vec![
                "cut.mat",
                "matrix 1 `t` (at byte 79251)",
                "but only 20727 are left",
            ],
        ),
    ];
    for (path, parts) in cases {
        let o = calib(&["inspect", s(&path)]);
        let err = expect_exit(&o, 1);
        assert_mentions(&err, &parts);
    }
}

//! End-to-end tests of LabVIEW TDMS files: the fixtures nptdms wrote of the bundled example run
//! (`testdata/tdms/`), and damaged copies of them.

use crate::common::columns::csrr_like_the_mcap_example;
use crate::common::inspect::inspect;
use crate::common::*;
use std::path::{Path, PathBuf};

#[test]
fn inspect_lists_groups_channels_and_the_waveform() {
    let text = inspect(&testdata("tdms/waveform.tdms"), &[]);
    assert_mentions(
        &text,
        &[
            "read as: TDMS file",
            "TDMS version 4712, 3 segments, little-endian",
            "group `Encoders`: `a` (f64, 3301 values, unit `deg`, waveform at 200 Hz), \
             `b` (f64, 3301 values, unit `deg`, waveform at 200 Hz)",
            "group `Notes`: `operator` (string, not taken)",
            "`Notes/operator`: not taken: strings are not readings",
            "time: the channels' waveform, every 0.005 s",
            // wf_start_time 2023-11-14 22:13:20 UTC is 1.7e9 s since 1970.
            "3301 samples over 16.500 s (1700000000.000 … 1700000016.500 s)",
            "calib csrr",
            "--a Encoders/a --b Encoders/b",
        ],
    );
    let text = inspect(&testdata("tdms/timed.tdms"), &[]);
    assert_mentions(
        &text,
        &[
            "TDMS version 4712, 2 segments",
            "group `Run`: `t` (timestamp, 3301 values, time stamps), `a` (f64, 3301 values, \
             unit `deg`), `b` (f64, 3301 values, unit `deg`)",
            "time: `Run/t`",
            "3301 samples over 16.500 s (1700000000.000 … 1700000016.500 s)",
        ],
    );
}

#[test]
fn csrr_of_either_file_gives_the_mcap_examples_maps() {
    let dir = tempfile::tempdir().unwrap();
    let waveform = dir.path().join("waveform");
    csrr_like_the_mcap_example(
        &waveform,
        &testdata("tdms/waveform.tdms"),
        "Encoders/a",
        "Encoders/b",
        &[],
    );
    let timed = dir.path().join("timed");
    csrr_like_the_mcap_example(&timed, &testdata("tdms/timed.tdms"), "Run/a", "Run/b", &[]);
}

/// A copy of `testdata/tdms/waveform.tdms` in `dir`, changed by `edit`.
fn damaged(dir: &Path, name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(testdata("tdms/waveform.tdms")).unwrap();
    edit(&mut bytes);
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// The byte after the raw data index's type and dimension of `/'Encoders'/'a'` in the first
/// segment: where its count of values is.
fn count_of_a(bytes: &[u8]) -> usize {
    let path = b"/'Encoders'/'a'";
    let at = bytes.windows(path.len()).position(|w| w == path).unwrap();
    at + path.len() + 12
}

#[test]
fn hostile_files_fail_naming_the_segment_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        // A segment longer than the file (its length, bytes 12..20 of the lead-in).
        (
            damaged(dir.path(), "long.tdms", |b| {
                b[12..20].copy_from_slice(&(1u64 << 50).to_le_bytes())
            }),
            vec![
                "long.tdms",
                "TDMS segment 0 (at byte 0)",
                "the file ends",
                "save it again",
            ],
        ),
        // A copy cut in its second segment.
        (
            damaged(dir.path(), "cut.tdms", |b| b.truncate(b.len() / 2)),
            vec!["cut.tdms", "TDMS segment 1", "the file ends"],
        ),
        // A channel claiming 10^15 values.
        (
            damaged(dir.path(), "huge.tdms", |b| {
                let at = count_of_a(b);
                b[at..at + 8].copy_from_slice(&1_000_000_000_000_000u64.to_le_bytes());
            }),
            vec![
                "huge.tdms",
                "TDMS segment 0",
                "less than one chunk",
                "`Encoders/a` 1000000000000000 × f64",
            ],
        ),
        // A dimension TDMS does not have.
        (
            damaged(dir.path(), "dims.tdms", |b| {
                let at = count_of_a(b) - 4;
                b[at..at + 4].copy_from_slice(&7u32.to_le_bytes());
            }),
            vec!["dims.tdms", "object `Encoders/a`", "array dimension 7"],
        ),
        // Junk after the first segment.
        (
            damaged(dir.path(), "junk.tdms", |b| {
                b.extend(b"PK\x03\x04 a zip's bytes appended by mistake")
            }),
            vec!["junk.tdms", "TDMS segment 3", "instead of `TDSm`"],
        ),
    ];
    for (path, parts) in cases {
        let o = calib(&["inspect", s(&path)]);
        let err = expect_exit(&o, 1);
        assert_mentions(&err, &parts);
    }
}

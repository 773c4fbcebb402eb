//! Columnar logs (TDMS, MATLAB, …) against the MCAP example of the same run.

use crate::common::{calib, expect_exit, read_table, s, testdata};
use std::path::Path;

/// The most a correction table of a columnar log may differ from the MCAP example's, arcsec:
/// one unit of the 6 decimals a table is written with. The files hold the readings `calib
/// simulate` wrote to CSV in degrees, the MCAP the same readings in radians, so the maps agree
/// to ~10⁻¹² arcsec before rounding; a value on a rounding boundary may round the other way.
pub const SAME_MAP_ARCSEC: f64 = 1e-6;

/// Runs `calib csrr LOG --a A --b B EXTRA…` and `calib csrr` on `testdata/examples/quick.mcap`
/// (the same run) into folders of `dir`, and asserts the two tables of each channel agree
/// within [`SAME_MAP_ARCSEC`] at every point. Returns the largest difference.
#[track_caller]
pub fn csrr_like_the_mcap_example(dir: &Path, log: &Path, a: &str, b: &str, extra: &[&str]) -> f64 {
    let mcap_out = dir.join("mcap");
    let log_out = dir.join("log");
    expect_exit(
        &calib(&[
            "csrr",
            s(&testdata("examples/quick.mcap")),
            "-o",
            s(&mcap_out),
        ]),
        0,
    );
    let mut args = vec!["csrr", s(log), "--a", a, "--b", b, "-o", s(&log_out)];
    args.extend_from_slice(extra);
    expect_exit(&calib(&args), 0);
    let mut worst: f64 = 0.0;
    for (name, table) in [("a", a), ("b", b)] {
        let file = table.replace(['/', '[', ']'], "_");
        let want = read_table(&mcap_out.join(format!("{name}.csv")));
        let got = read_table(&log_out.join(format!("{file}.csv")));
        assert_eq!(got.len(), want.len(), "{table}: points");
        for ((angle, e), (want_angle, want_e)) in got.iter().zip(&want) {
            assert_eq!(angle, want_angle);
            let d = (e - want_e).abs();
            assert!(
                d <= SAME_MAP_ARCSEC,
                "{table} at {angle}°: {e}″, the MCAP example's {want_e}″"
            );
            worst = worst.max(d);
        }
    }
    worst
}

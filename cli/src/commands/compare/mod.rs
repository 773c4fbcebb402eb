//! `calib compare`: load two maps → En comparison → render; exit 3 (a gate) when a point fails.

mod against;

use crate::summary::TextTable;
use anyhow::Context as _;
use calib_core::compare::{self, Comparison, MapPoint};
use calib_io::points::PointTable;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Compare two error maps of the same sensor point by point with the En number.
///
/// MAP1 and MAP2 are CSV tables with columns angle_deg and error_arcsec, and optionally u_arcsec
/// (standard uncertainty) and expanded_uncertainty_arcsec; other columns are ignored. calib's
/// correction tables and the shift-angle method's encoder.csv qualify. The grids may differ and
/// need not be uniform: MAP2 is interpolated (periodic, linear) at MAP1's angles.
///
/// At each of MAP1's angles:  En = |x₁ − x₂| / √(U₁² + U₂²),  U the expanded uncertainties.
/// (The shift-angle paper's eq. 13 prints a minus under the root; the standard form, used here,
/// has a plus: uncertainties of independent results add.) U comes from --U1/--U2 if given, else
/// from the table's expanded_uncertainty_arcsec column, else from k·u_arcsec (--k).
///
/// Range tables (joints that never turn a whole revolution: a `# range_deg: LO to HI` first line)
/// are compared over the range common to both maps, and since each is zero-mean over its own
/// range, with the mean difference over the common range removed (said in the summary).
///
/// Writes DIR/compare.csv: angle_deg, error1_arcsec, error2_arcsec, difference_arcsec
/// (error1 − error2), U1_arcsec, U2_arcsec, En.
///
/// Exit status: 0 when every En ≤ 1; 3 (a failed gate, for pipelines that check a calibration
/// against a stored one) when some En > 1, with the points that fail listed and compare.csv
/// written all the same; 1 bad or insufficient data; 2 bad usage.
///
/// Two runs over a fleet: `calib compare NEW --against OLD`, NEW and OLD the output folders of
/// two runs over the same logs (`calib <method> LOG... -o DIR`, or Python's calib.map_logs).
/// Every folder with a report.json is a log's; a log's channel in NEW is compared with the
/// same channel of the log at the same place in OLD, as MAP1 with MAP2 above (--U1, --U2, --k,
/// --remove-mean apply to every pair). Writes DIR/drift.csv, one row per channel: log,
/// channel, status (moved: some En > 1; steady; new: not in OLD; gone: only in OLD), points,
/// max_abs_difference_arcsec, rms_difference_arcsec, mean_difference_arcsec, max_en,
/// points_over_1. Exit 3 when a channel moved, the moved ones listed.
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The first map (its angles are the comparison's grid).
    pub map1: PathBuf,
    /// The second map (with --against: none; MAP1 is a run's output folder).
    #[arg(required_unless_present = "against", conflicts_with = "against")]
    pub map2: Option<PathBuf>,
    /// Compare the run in the folder MAP1 with the earlier run in PREFIX, channel by channel
    /// (see above): which joints moved.
    #[arg(long, value_name = "PREFIX")]
    pub against: Option<PathBuf>,
    /// Expanded uncertainty of MAP1 at every point, arcsec (overrides its columns).
    #[arg(long = "U1", value_name = "ARCSEC")]
    pub u1: Option<f64>,
    /// Expanded uncertainty of MAP2 at every point, arcsec (overrides its columns).
    #[arg(long = "U2", value_name = "ARCSEC")]
    pub u2: Option<f64>,
    /// Coverage factor applied to a table's u_arcsec when it has no expanded column.
    #[arg(long, default_value_t = 2.0)]
    pub k: f64,
    /// Subtract the mean difference first (maps are defined up to a constant offset).
    #[arg(long)]
    pub remove_mean: bool,
    /// Output folder (created if missing).
    #[arg(
        short = 'o',
        long = "output",
        value_name = "DIR",
        default_value = "calib-out"
    )]
    pub output: PathBuf,
    /// Print the comparison as JSON instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Replace files in DIR that calib did not write (without it, a file there that DIR's calib
    /// manifest does not list is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
}

/// Runs `calib compare`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    for (flag, v) in [("--U1", args.u1), ("--U2", args.u2), ("--k", Some(args.k))] {
        if let Some(v) = v
            && !(v.is_finite() && v >= 0.0)
        {
            return Err(crate::exit::Usage(format!("{flag} {v}: give a number ≥ 0")).into());
        }
    }
    let map2 = match (&args.map2, &args.against) {
        (_, Some(against)) => return against::run(args, against),
        (Some(map2), None) => map2,
        (None, None) => unreachable!("clap requires MAP2 unless --against is given"),
    };
    let csv_path = args.output.join("compare.csv");
    crate::overwrite::check(&csv_path, &format!("-o {}", crate::ui::shown(&args.output)))?;
    crate::output::check_replaces_only_calibs(
        &args.output,
        ["compare.csv"],
        &format!("-o {}", crate::ui::shown(&args.output)),
    )?;
    let Pair {
        comparison: c,
        common,
        forced,
    } = compare_files(args, &args.map1, map2)?;
    std::fs::create_dir_all(&args.output).with_context(|| {
        format!(
            "cannot create the output directory {}",
            args.output.display()
        )
    })?;
    calib_io::atomic::write_atomic(
        &csv_path,
        calib_io::compare::render_compare_csv(&c).as_bytes(),
    )?;
    crate::output::record_written([&csv_path]);
    let stdout = if args.json {
        serde_json::to_string_pretty(&c)? + "\n"
    } else {
        let mut s = render_summary(args, map2, &c, &csv_path);
        if let Some((lo, hi)) = common {
            s.insert_str(
                0,
                &format!(
                    "range tables: compared over the common range {lo:.6}° to {hi:.6}°{}\n",
                    if forced {
                        " (mean difference removed: each map is zero-mean over its own range)"
                    } else {
                        ""
                    }
                ),
            );
        }
        s
    };
    if c.failures > 0 {
        return Err(crate::exit::Failed {
            stdout,
            code: crate::exit::GATE,
            message: format!(
                "gate failed: {} of {} points with En > 1 (max {:.3}): the maps disagree beyond their uncertainties",
                c.failures,
                c.points.len(),
                c.max_en
            ),
        }
        .into());
    }
    Ok(stdout)
}

/// Two maps compared: the comparison, the range common to both where either is a range table,
/// and whether the mean difference was removed because their ranges differ.
struct Pair {
    comparison: Comparison,
    common: Option<(f64, f64)>,
    forced: bool,
}

/// Reads the maps `map1` and `map2` and compares them with `args`' uncertainties and options:
/// MAP2 interpolated at MAP1's angles, over their common range where either is a range table.
fn compare_files(args: &Args, map1: &Path, map2: &Path) -> anyhow::Result<Pair> {
    let t1 = calib_io::points::read_points(map1)?;
    let t2 = calib_io::points::read_points(map2)?;
    let mut m1 = with_expanded(&t1, map1, args.u1, args.k, "--U1")?;
    let m2 = with_expanded(&t2, map2, args.u2, args.k, "--U2")?;
    let common = common_range(&t1, &t2);
    if let Some((lo, hi)) = common {
        let before = m1.len();
        m1.retain(|p| inside(p.angle_deg, lo, hi));
        if m1.is_empty() {
            return Err(crate::exit::Usage(format!(
                "{} and {} have no range in common ({}): nothing to compare",
                map1.display(),
                map2.display(),
                describe(&t1, &t2)
            ))
            .into());
        }
        if m1.len() < before {
            eprintln!(
                "note: {}: comparing over the common range {lo:.6}° to {hi:.6}° ({} of MAP1's {before} points)",
                map1.display(),
                m1.len()
            );
        }
    }
    // Range maps are zero-mean over their own ranges: over another range they differ by a constant.
    let forced = common.is_some() && !args.remove_mean && !same_range(&t1, &t2);
    let comparison = compare::compare(&m1, &m2, args.remove_mean || forced)
        .with_context(|| format!("comparing {} with {}", map1.display(), map2.display()))?;
    Ok(Pair {
        comparison,
        common,
        forced,
    })
}

/// A table's range, degrees: its own for a range table, the whole turn otherwise.
fn range_of(t: &PointTable) -> (f64, f64) {
    t.range.unwrap_or((0.0, 360.0))
}

/// The range common to two tables when either is a range table, `(lo, hi)` in degrees with `lo`
/// in MAP1's range; `None` if both cover the whole turn (or nothing is common, as an empty range
/// `lo > hi`).
fn common_range(t1: &PointTable, t2: &PointTable) -> Option<(f64, f64)> {
    if t1.range.is_none() && t2.range.is_none() {
        return None;
    }
    let (a1, b1) = range_of(t1);
    let (a2, b2) = range_of(t2);
    // Shift MAP2's range by whole turns to overlap MAP1's where it can.
    let shift = ((a1 - a2) / 360.0).round() * 360.0;
    let best = [shift - 360.0, shift, shift + 360.0]
        .into_iter()
        .map(|k| (a1.max(a2 + k), b1.min(b2 + k)))
        .max_by(|x, y| (x.1 - x.0).total_cmp(&(y.1 - y.0)))?;
    Some(best)
}

fn same_range(t1: &PointTable, t2: &PointTable) -> bool {
    let ((a1, b1), (a2, b2)) = (range_of(t1), range_of(t2));
    (a1 - a2).abs() < 1e-6 && (b1 - b2).abs() < 1e-6
}

/// Whether `deg` (any turn) lies in `[lo, hi]` (within the 6-decimal rounding of a table).
fn inside(deg: f64, lo: f64, hi: f64) -> bool {
    lo <= hi && lo + (deg - lo + 1e-6).rem_euclid(360.0) - 1e-6 <= hi + 1e-6
}

fn describe(t1: &PointTable, t2: &PointTable) -> String {
    let ((a1, b1), (a2, b2)) = (range_of(t1), range_of(t2));
    format!("MAP1 covers {a1}° to {b1}°, MAP2 {a2}° to {b2}°")
}

/// The map's points with their expanded uncertainties.
fn with_expanded(
    table: &PointTable,
    path: &Path,
    given: Option<f64>,
    k: f64,
    flag: &str,
) -> anyhow::Result<Vec<MapPoint>> {
    table
        .points
        .iter()
        .map(|p| {
            let u = given
                .or(p.expanded_uncertainty_arcsec)
                .or(p.u_arcsec.map(|u| k * u))
                .ok_or_else(|| {
                    crate::exit::Usage(format!(
                        "{}: no uncertainty at {}° (no expanded_uncertainty_arcsec or u_arcsec value): pass {flag} ARCSEC",
                        path.display(),
                        p.angle_deg
                    ))
                })?;
            Ok(MapPoint {
                angle_deg: p.angle_deg,
                error_arcsec: p.error_arcsec,
                expanded_uncertainty_arcsec: u,
            })
        })
        .collect()
}

fn render_summary(args: &Args, map2: &Path, c: &Comparison, csv_path: &Path) -> String {
    let mut s = String::new();
    let interpolated = c.points.iter().filter(|p| p.interpolated).count();
    let _ = writeln!(
        s,
        "compare {} − {}: {} points ({} interpolated in the second map)",
        args.map1.display(),
        map2.display(),
        c.points.len(),
        interpolated
    );
    let _ = writeln!(
        s,
        "difference: max |Δ| {:.4}″, RMS {:.4}″, mean {:+.4}″{}",
        c.max_abs_difference_arcsec,
        c.rms_difference_arcsec,
        c.mean_difference_arcsec,
        if c.mean_removed { " (removed)" } else { "" }
    );
    let _ = writeln!(
        s,
        "En = |Δ| / √(U₁² + U₂²): max {:.3}; {} of {} points with En > 1",
        c.max_en,
        c.failures,
        c.points.len()
    );
    if c.failures > 0 {
        let _ = writeln!(s, "points that fail (En > 1):");
        let mut table = TextTable::new(&[
            "angle °",
            "error1 ″",
            "error2 ″",
            "Δ ″",
            "U1 ″",
            "U2 ″",
            "En",
        ])
        .min_widths(&[10, 10, 10, 10, 8, 8, 6])
        .align_first_column();
        for p in c.points.iter().filter(|p| p.en > 1.0) {
            table.row(vec![
                format!("{:.4}", p.angle_deg),
                format!("{:.4}", p.error1_arcsec),
                format!("{:.4}", p.error2_arcsec),
                format!("{:+.4}", p.difference_arcsec),
                format!("{:.4}", p.expanded1_arcsec),
                format!("{:.4}", p.expanded2_arcsec),
                format!("{:.3}", p.en),
            ]);
        }
        s += &table.render();
    }
    let _ = writeln!(s, "wrote {}", csv_path.display());
    s
}

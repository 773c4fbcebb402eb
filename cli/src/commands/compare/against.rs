//! `calib compare NEW --against OLD`: every channel of every log of a run compared with the
//! same channel of the same log in an earlier run (En per point, as `calib compare`), one row
//! per channel in `drift.csv`, exit 3 when one moved: the nightly "which joints moved".
//!
//! A run is a folder as `calib <method> LOG... -o DIR` or Python's `calib.map_logs(out=DIR)`
//! writes it: a log's files in a folder of their own (or the run folder itself for one log),
//! its `report.json` naming each channel's table. Logs are matched by that folder's path
//! relative to the run folder, channels by name.

use super::{Args, Pair, compare_files};
use anyhow::Context as _;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What happened to a channel between the runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
enum Status {
    /// Some point with En > 1: the map changed beyond both runs' uncertainties.
    Moved,
    /// Every En ≤ 1.
    Steady,
    /// In the new run only.
    New,
    /// In the earlier run only.
    Gone,
}

impl Status {
    fn name(self) -> &'static str {
        match self {
            Status::Moved => "moved",
            Status::Steady => "steady",
            Status::New => "new",
            Status::Gone => "gone",
        }
    }
}

/// One channel's line of `drift.csv` (and of `--json`).
#[derive(Debug, Serialize)]
struct Drift {
    /// The log's folder relative to the run folder (`.`: the run folder itself).
    log: String,
    /// The channel, as in report.json.
    channel: String,
    status: Status,
    /// The comparison where the channel is in both runs.
    #[serde(flatten)]
    figures: Option<Figures>,
}

/// The figures of a channel in both runs (`calib compare`'s, for its pair of tables).
#[derive(Debug, Serialize)]
struct Figures {
    points: usize,
    max_abs_difference_arcsec: f64,
    rms_difference_arcsec: f64,
    mean_difference_arcsec: f64,
    max_en: f64,
    points_over_1: usize,
}

/// The channels of every log of a run: the log's folder (relative, `/`-separated) → channel
/// → its table's path.
type Run = BTreeMap<String, BTreeMap<String, PathBuf>>;

/// Runs `calib compare NEW --against OLD` (`args.map1` is NEW).
pub fn run(args: &Args, against: &Path) -> anyhow::Result<String> {
    let csv_path = args.output.join("drift.csv");
    let via = format!("-o {}", crate::ui::shown(&args.output));
    crate::overwrite::check(&csv_path, &via)?;
    crate::output::check_replaces_only_calibs(&args.output, ["drift.csv"], &via)?;
    let new = read_run(&args.map1, "MAP1")?;
    let old = read_run(against, "--against")?;
    let mut rows = Vec::new();
    for (log, channels) in &new {
        for (channel, table) in channels {
            let figures = match old.get(log).and_then(|c| c.get(channel)) {
                Some(earlier) => Some(figures(compare_files(args, table, earlier)?)),
                None => None,
            };
            let status = match &figures {
                None => Status::New,
                Some(f) if f.points_over_1 > 0 => Status::Moved,
                Some(_) => Status::Steady,
            };
            rows.push(Drift {
                log: log.clone(),
                channel: channel.clone(),
                status,
                figures,
            });
        }
    }
    for (log, channels) in &old {
        for channel in channels.keys() {
            if !new.get(log).is_some_and(|c| c.contains_key(channel)) {
                rows.push(Drift {
                    log: log.clone(),
                    channel: channel.clone(),
                    status: Status::Gone,
                    figures: None,
                });
            }
        }
    }
    std::fs::create_dir_all(&args.output).with_context(|| {
        format!(
            "cannot create the output directory {}",
            args.output.display()
        )
    })?;
    calib_io::atomic::write_atomic(&csv_path, render_csv(&rows).as_bytes())?;
    crate::output::record_written([&csv_path]);
    let stdout = if args.json {
        serde_json::to_string_pretty(&rows)? + "\n"
    } else {
        render_summary(args, against, &rows, &csv_path)
    };
    let moved = rows.iter().filter(|r| r.status == Status::Moved).count();
    if moved > 0 {
        return Err(crate::exit::Failed {
            stdout,
            code: crate::exit::GATE,
            message: format!(
                "gate failed: {moved} of {} channels moved (some En > 1) since {}",
                rows.iter().filter(|r| r.figures.is_some()).count(),
                against.display()
            ),
        }
        .into());
    }
    Ok(stdout)
}

fn figures(pair: Pair) -> Figures {
    let c = pair.comparison;
    Figures {
        points: c.points.len(),
        max_abs_difference_arcsec: c.max_abs_difference_arcsec,
        rms_difference_arcsec: c.rms_difference_arcsec,
        mean_difference_arcsec: c.mean_difference_arcsec,
        max_en: c.max_en,
        points_over_1: c.failures,
    }
}

/// Every log of the run in `root`: each folder under it holding a `report.json`, with the
/// table of each channel that report names.
fn read_run(root: &Path, flag: &str) -> anyhow::Result<Run> {
    if !root.is_dir() {
        return Err(crate::exit::Usage(format!(
            "{flag} {}: no such folder; with --against, MAP1 and PREFIX are the output folders \
             of two runs (calib <method> LOG... -o DIR, or calib.map_logs(out=DIR))",
            root.display()
        ))
        .into());
    }
    let mut run = Run::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        let entries = std::fs::read_dir(&folder)
            .with_context(|| format!("cannot list the folder {}", folder.display()))?;
        for entry in entries {
            let path = entry
                .with_context(|| format!("cannot list the folder {}", folder.display()))?
                .path();
            if path.is_dir() {
                folders.push(path);
            } else if path.file_name().is_some_and(|n| n == "report.json") {
                let log = relative(root, &folder);
                run.insert(log, channel_tables(&path, &folder)?);
            }
        }
    }
    if run.is_empty() {
        return Err(crate::exit::Usage(format!(
            "{flag} {}: no report.json in it or under it: not the output folder of a run",
            root.display()
        ))
        .into());
    }
    Ok(run)
}

/// `folder` relative to `root`, `/`-separated, `.` for `root` itself.
fn relative(root: &Path, folder: &Path) -> String {
    let parts: Vec<String> = folder
        .strip_prefix(root)
        .unwrap_or(folder)
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.is_empty() {
        ".".into()
    } else {
        parts.join("/")
    }
}

/// The channels of a report.json and their tables, beside it.
fn channel_tables(report: &Path, folder: &Path) -> anyhow::Result<BTreeMap<String, PathBuf>> {
    let text = std::fs::read_to_string(report)
        .with_context(|| format!("cannot read {}", report.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not JSON; is it calib's report.json?", report.display()))?;
    let channels = json
        .get("channels")
        .and_then(|c| c.as_object())
        .with_context(|| {
            format!(
                "{}: no `channels` object; is it calib's report.json?",
                report.display()
            )
        })?;
    channels
        .iter()
        .map(|(name, ch)| {
            let table = ch.get("table").and_then(|t| t.as_str()).with_context(|| {
                format!(
                    "{}: channel `{name}` names no table; is it calib's report.json?",
                    report.display()
                )
            })?;
            Ok((name.clone(), folder.join(table)))
        })
        .collect()
}

/// A CSV field, quoted where it holds a comma, a quote or a line break (RFC 4180).
fn field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `drift.csv`: one row per channel; the figures empty where the channel is in one run only.
fn render_csv(rows: &[Drift]) -> String {
    let mut s = String::from(
        "log,channel,status,points,max_abs_difference_arcsec,rms_difference_arcsec,\
         mean_difference_arcsec,max_en,points_over_1\n",
    );
    for r in rows {
        let _ = write!(
            s,
            "{},{},{}",
            field(&r.log),
            field(&r.channel),
            r.status.name()
        );
        match &r.figures {
            Some(f) => {
                let _ = writeln!(
                    s,
                    ",{},{:.6},{:.6},{:.6},{:.4},{}",
                    f.points,
                    f.max_abs_difference_arcsec,
                    f.rms_difference_arcsec,
                    f.mean_difference_arcsec,
                    f.max_en,
                    f.points_over_1
                );
            }
            None => s.push_str(",,,,,,\n"),
        }
    }
    s
}

fn render_summary(args: &Args, against: &Path, rows: &[Drift], csv_path: &Path) -> String {
    let count = |st: Status| rows.iter().filter(|r| r.status == st).count();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "compare {} against {}: {} channels moved (some En > 1), {} steady, {} new, {} gone",
        args.map1.display(),
        against.display(),
        count(Status::Moved),
        count(Status::Steady),
        count(Status::New),
        count(Status::Gone)
    );
    let mut table = crate::summary::TextTable::new(&["log", "channel", "max |Δ| ″", "max En"])
        .min_widths(&[10, 8, 10, 8])
        .align_first_column();
    let mut any = false;
    for r in rows.iter().filter(|r| r.status == Status::Moved) {
        if let Some(f) = &r.figures {
            any = true;
            table.row(vec![
                r.log.clone(),
                r.channel.clone(),
                format!("{:.4}", f.max_abs_difference_arcsec),
                format!("{:.3}", f.max_en),
            ]);
        }
    }
    if any {
        let _ = writeln!(s, "moved:");
        s += &table.render();
    }
    let _ = writeln!(s, "wrote {}", csv_path.display());
    s
}

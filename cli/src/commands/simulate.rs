//! `calib simulate`: a recorded run with a known truth.

use crate::exit::Usage;
use crate::output::table_name;
use anyhow::Context;
use calib_io::LogWriter;
use calib_io::limits::MAX_SIMULATED_SAMPLES;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Write a simulated run with a known truth, from a scenario file.
///
/// The scenario (TOML; see testdata/scenarios/ for complete, commented examples) describes the
/// sensors and their harmonic errors, quantization and noise, a reference encoder, heads on a
/// shared scale, the shaft's speed non-uniformity and the CSRR procedure (sessions at relative
/// rotations Δ_k with ramps, pauses and relative turns) — or, with `[spin_down]` instead of
/// `[procedure]`, a free coast-down with friction and angle-dependent drag (for `calib tdr`; see
/// testdata/scenarios/spindown.toml). The log is written as MCAP (ROS 2
/// JointState, radians) or CSV (degrees) by the output's extension, and the true error map of
/// every sensor, as a function of its own reading, beside it in `<stem>.truth/<sensor>.csv`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The scenario file (TOML).
    pub scenario: PathBuf,
    /// The log to write: `run.mcap` or `run.csv`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Grid points of the truth tables (default 36000: 0.01° steps, fine enough to interpolate
    /// linearly to 0.02″ for errors of ±700″ at order 84).
    #[arg(long, default_value_t = 36000)]
    pub points: usize,
    /// Write the run even when it has more samples than the limit (see Limits in `calib --help`).
    #[arg(long)]
    pub force: bool,
}

/// Runs `calib simulate`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if !args.scenario.exists() {
        return Err(Usage(format!(
            "{}: no such scenario file; check the path",
            args.scenario.display()
        ))
        .into());
    }
    let scenario = calib_io::scenario::read_scenario(&args.scenario).map_err(|e| match e {
        calib_io::Error::Io { source, .. } => anyhow::Error::new(source).context(format!(
            "cannot read the scenario {}",
            args.scenario.display()
        )),
        e => Usage(e.to_string()).into(),
    })?;
    crate::input::check_points(Some(args.points))?;
    calib_io::LogFormat::for_output(&args.output).map_err(|e| Usage(e.to_string()))?;
    let via = format!("-o {}", crate::ui::shown(&args.output));
    crate::overwrite::check(&args.output, &via)?;

    let channels = scenario.channels();
    let samples = scenario.samples()?;
    let count = samples.len();
    // The sample count is exact from the scenario's timeline and rate: a mistyped rate or
    // revolution count is refused before anything is written.
    if count as u64 > MAX_SIMULATED_SAMPLES && !args.force {
        let seconds = samples.duration_s();
        return Err(Usage(format!(
            "{}: the run would have {} samples ({} s at the scenario's rate), more than the \
             {MAX_SIMULATED_SAMPLES} calib simulate writes without --force; check rate_hz and \
             the revolutions, or add --force",
            crate::ui::shown(&args.scenario),
            calib_io::limits::readable(count as f64),
            calib_io::limits::readable(seconds)
        ))
        .into());
    }
    let mut writer = LogWriter::create(&args.output, &channels, scenario.mark_sessions)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    for sample in samples {
        writer.write(&sample)?;
    }
    let truths = scenario.truth(args.points)?;
    // A swept joint's truth covers the readings it swept (a range table), where that is less
    // than a whole turn.
    let ranges = scenario.range_truth(args.points)?;
    let dir = truth_dir(&args.output);
    for (name, _) in &truths {
        crate::overwrite::check(&dir.join(table_name(name)), &via)?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    let mut peaks = Vec::new();
    for (k, (name, map)) in truths.iter().enumerate() {
        let path = dir.join(table_name(name));
        match ranges.as_ref().and_then(|r| r[k].1.as_ref()) {
            Some(range) => {
                let text = calib_io::table::render_range_table(range, None)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                calib_io::atomic::write_atomic(&path, text.as_bytes())?;
                peaks.push((range.peak_to_peak(), " (range table)"));
            }
            None => {
                calib_io::table::write_table(&path, map, None)?;
                peaks.push((map.peak_to_peak(), ""));
            }
        }
        written.push(path);
    }
    writer.finish()?;

    let mut out = String::new();
    let _ = writeln!(
        out,
        "wrote {} ({} samples, {} channels)",
        args.output.display(),
        count,
        channels.len()
    );
    for (((name, _), path), (pp, kind)) in truths.iter().zip(&written).zip(&peaks) {
        let _ = writeln!(
            out,
            "  truth of {:<12} peak-to-peak {:>10.3}″ → {}{kind}",
            name,
            pp * calib_core::angle::ARCSEC_PER_RAD,
            path.display()
        );
    }
    Ok(out)
}

/// `run.mcap` → `run.truth/`.
fn truth_dir(log: &Path) -> PathBuf {
    let stem = log
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    log.with_file_name(format!("{stem}.truth"))
}

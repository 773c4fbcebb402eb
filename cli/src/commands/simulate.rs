//! `calib simulate`: a recorded run with a known truth.

use crate::exit::Usage;
use crate::json::{SimulateJson, TruthJson};
use crate::output::table_name;
use anyhow::Context;
use calib_io::LogWriter;
use calib_io::limits::MAX_SIMULATED_SAMPLES;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Write a simulated run with a known truth, from a scenario file.
///
/// The log is written as MCAP (ROS 2 JointState, radians) or CSV (degrees) by the output's
/// extension, and the true error map of every sensor, as a function of its own reading, beside it
/// in `<stem>.truth/<sensor>.csv`. `calib simulate --example METHOD` prints a complete, commented
/// scenario for a method (csrr, multihead, tdr, reference, shift-angle); `calib plan` writes one
/// for a planned run.
///
/// The scenario format (TOML; unknown keys are errors):
///
///   seed = 1             noise seed (same scenario and seed, same samples)
///   rate_hz = 400.0      sample rate;  speed_rpm = 10.0  shaft speed in sessions
///   wrap = true          readings wrapped to [0, 360°);  mark_sessions = false
///   [speed]              variation_percent = 1.0, or harmonic = [{ order, amplitude_arcsec,
///                        phase_deg }]: the shaft's sampling non-uniformity (CSRR eq. 9)
///   [[sensor]]           one channel: name, mount = "a" | "b" (rotor A or the shaft),
///                        harmonics = [{ order, amplitude_arcsec, phase_deg }] (its error,
///                        amplitude·cos(order·θ + phase)), quantization_arcsec, noise_arcsec;
///                        delay_s (latency), backlash_arcsec (play of its coupling),
///                        commanded = true (reads the drive's commanded angle), ratio = 50.0
///                        (behind a gear: turns 50 times per turn of its rotor, its error a
///                        function of its own angle, as an actuator's motor encoder);
///                        or a head on a shared scale: scale = "NAME", head_deg,
///                        head_error_arcsec
///   [[scale]]            a graduated scale read by several heads: name, harmonics, mount
///
/// and one motion:
///
///   [procedure]          CSRR sessions: relative_deg = [0.0, 7.3, ...] (Δ_k), revolutions,
///                        ramp_s, pause_s, turn_s (or [[procedure.sessions]] one by one)
///   [spin_down]          a free coast-down (for tdr): speed_rpm, duration_s,
///                        friction = { coulomb, viscous, quadratic }, drag_harmonics; with
///                        drive = { time_constant_s, steps = [{ from_s, speed_rpm }] } a motor
///                        at constant voltage drives it (a driven run, for tdr --run driven)
///   [sweep]              a joint swept back and forth (for reference over a range): from_deg,
///                        to_deg, cycles, speeds_deg_s, ramp_s, pause_s; random = true: moved
///                        by hand (reversals at random points, random speeds and rests)
///
/// One example per method (print the whole file with --example):
///
///   csrr         two sensors, mount "a" and "b", and a [procedure] with relative_deg
///   multihead    one [[scale]] and heads with scale = "selfa", head_deg = 0, 51.43, 90, ...
///   tdr          [spin_down] with speed_rpm = 600, duration_s = 30 and a sensor "enc"
///   reference    a [sweep] of 15°–135° with a joint encoder "b" and a reference "ref"
///   shift-angle  not simulated: the example shows the readings table calib shift-angle reads
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The scenario file (TOML).
    #[arg(required_unless_present = "example")]
    pub scenario: Option<PathBuf>,
    /// The log to write: `run.mcap` or `run.csv`.
    #[arg(short, long, value_name = "FILE", required_unless_present = "example")]
    pub output: Option<PathBuf>,
    /// Print a complete, commented example scenario for a method and exit.
    #[arg(long, value_enum, value_name = "METHOD", conflicts_with_all = ["scenario", "output"])]
    pub example: Option<Example>,
    /// Grid points of the truth tables (default 36000: 0.01° steps, fine enough to interpolate
    /// linearly to 0.02″ for errors of ±700″ at order 84).
    #[arg(long, default_value_t = 36000)]
    pub points: usize,
    /// Write the run even when it has more samples than the limit (see Limits in `calib --help`),
    /// and replace FILE and its truth tables even if calib did not write them (without it, a
    /// file there that no calib manifest of its folder lists is refused, exit 2, and left as it
    /// is).
    #[arg(long)]
    pub force: bool,
    /// Print what was written as JSON (docs/simulate.schema.json) instead of the summary.
    #[arg(long, conflicts_with = "example")]
    pub json: bool,
}

/// The methods `--example` has a scenario for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Example {
    /// Two coaxial sensors, five sessions (testdata/scenarios/quick.toml).
    Csrr,
    /// The SelfA layout of 12 heads on one scale (testdata/scenarios/multihead.toml).
    Multihead,
    /// A free coast-down on an air bearing (testdata/scenarios/spindown.toml).
    Tdr,
    /// A robot joint swept against a reference encoder (testdata/scenarios/joint.toml).
    Reference,
    /// The readings table of a 24-face polygon (testdata/shift-angle/readings.csv, first rows).
    ShiftAngle,
}

impl Example {
    /// The example's text.
    pub fn text(self) -> String {
        match self {
            Example::Csrr => include_str!("../../../testdata/scenarios/quick.toml").into(),
            Example::Multihead => include_str!("../../../testdata/scenarios/multihead.toml").into(),
            Example::Tdr => include_str!("../../../testdata/scenarios/spindown.toml").into(),
            Example::Reference => include_str!("../../../testdata/scenarios/joint.toml").into(),
            Example::ShiftAngle => {
                let readings = include_str!("../../../testdata/shift-angle/readings.csv");
                let mut out = String::from(
                    "# The shift-angle method is not simulated from a scenario: its input is the\n\
                     # autocollimator's readings, one row per shift, start face and step\n\
                     # (eq. 3 of Hsieh, Watanabe, Hsu 2022), read by `calib shift-angle FILE`.\n\
                     # These are the first rows of testdata/shift-angle/readings.csv (24 faces);\n\
                     # Columns: shift angle (degrees), start face, step i = 1..n, reading (arcsec).\n",
                );
                for line in readings.lines().take(30) {
                    out.push_str(line);
                    out.push('\n');
                }
                out
            }
        }
    }
}

/// Runs `calib simulate`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if let Some(example) = args.example {
        return Ok(example.text());
    }
    let (Some(scenario_path), Some(output)) = (&args.scenario, &args.output) else {
        return Err(Usage("give a scenario file and -o OUTPUT, or --example METHOD".into()).into());
    };
    run_scenario(args, scenario_path, output)
}

fn run_scenario(args: &Args, scenario_path: &Path, output: &Path) -> anyhow::Result<String> {
    let _lock = crate::output::prepare_file(output, "-o")?;
    if !scenario_path.exists() {
        return Err(Usage(format!(
            "{}: no such scenario file; check the path",
            scenario_path.display()
        ))
        .into());
    }
    let scenario = calib_io::scenario::read_scenario(scenario_path).map_err(|e| match e {
        calib_io::Error::Io { source, .. } => anyhow::Error::new(source).context(format!(
            "cannot read the scenario {}",
            scenario_path.display()
        )),
        e => Usage(e.to_string()).into(),
    })?;
    crate::input::check_points(Some(args.points))?;
    calib_io::LogFormat::for_output(output).map_err(|e| Usage(e.to_string()))?;
    let via = format!("-o {}", crate::ui::shown(output));
    crate::overwrite::check(output, &via)?;

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
            crate::ui::shown(scenario_path),
            calib_io::limits::readable(count as f64),
            calib_io::limits::readable(seconds)
        ))
        .into());
    }
    let mut writer = LogWriter::create(output, &channels, scenario.mark_sessions)
        .with_context(|| format!("cannot write {}", output.display()))?;
    for sample in samples {
        writer.write(&sample)?;
    }
    let truths = scenario.truth(args.points)?;
    // A swept joint's truth covers the readings it swept (a range table), where that is less
    // than a whole turn.
    let ranges = scenario.range_truth(args.points)?;
    let dir = truth_dir(output);
    for (name, _) in &truths {
        crate::overwrite::check(&dir.join(table_name(name)), &via)?;
    }
    crate::output::check_replaces_only_calibs(
        &dir,
        truths
            .iter()
            .map(|(name, _)| table_name(name))
            .collect::<Vec<_>>()
            .iter()
            .map(String::as_str),
        &format!("-o {} (its truth tables)", crate::ui::shown(output)),
    )?;
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let mut written = Vec::new();
    let mut peaks = Vec::new();
    for (k, (name, map)) in truths.iter().enumerate() {
        let path = dir.join(table_name(name));
        match ranges.as_ref().and_then(|r| r[k].1.as_ref()) {
            Some(range) => {
                let text = calib_io::table::render_table(&range.clone().into(), None)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                calib_io::atomic::write_atomic(&path, text.as_bytes())?;
                peaks.push((range.peak_to_peak(), " (range table)"));
            }
            None => {
                calib_io::table::write_table(&path, &map.clone().into(), None)?;
                peaks.push((map.peak_to_peak(), ""));
            }
        }
        written.push(path);
    }
    writer.finish()?;
    crate::output::record_written(
        std::iter::once(output).chain(written.iter().map(PathBuf::as_path)),
    );

    if args.json {
        return crate::json::render(&SimulateJson {
            schema_version: calib_core::report::SCHEMA_VERSION,
            scenario: scenario_path.display().to_string(),
            output: output.display().to_string(),
            samples: count as u64,
            channels: channels.iter().map(|c| c.name.clone()).collect(),
            truth: truths
                .iter()
                .zip(&written)
                .zip(&peaks)
                .map(|(((name, _), path), (pp, kind))| TruthJson {
                    channel: name.clone(),
                    table: path.display().to_string(),
                    range: !kind.is_empty(),
                    peak_to_peak_arcsec: pp * calib_core::angle::ARCSEC_PER_RAD,
                })
                .collect(),
        });
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "wrote {} ({} samples, {} channels)",
        output.display(),
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

//! `calib moteus-dump`: moteus' own encoder calibration dump calibrated into a table.

use crate::output::write_outputs;
use crate::summary::key_values;
use anyhow::Context;
use calib_core::Report;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{Latency, ReferenceCal, ReferenceKind, ReferenceOptions};
use calib_io::export::{self, ExportOptions};
use calib_io::moteus_dump::{SETTLING_SAMPLES, read_cal_dump};
use std::fmt::Write;
use std::path::PathBuf;

/// Calibrate an encoder from moteus' own calibration dump (`moteus_tool --calibrate
/// --cal-write-raw FILE`).
///
/// The dump holds the raw encoder against the commanded electrical phase over one mechanical
/// turn each way (`CAL start`, `direction phase encoder` lines, `CAL done`). calib reads it as
/// `calib reference --ref-kind commanded` would a log: the encoder is the DUT, the commanded
/// angle (phase / pole pairs) the reference, and the motor's ripple — the components periodic in
/// the electrical angle, orders k × pole pairs — is fitted, taken out of the map and reported
/// (moteus' calibrate_encoder.py averages over a window instead, which also attenuates the
/// encoder's own orders). The pole pairs come from the dump (the phase's travel over the
/// encoder's, rounded; --pole-pairs overrides), the first 4 rising samples are dropped as moteus
/// drops them, and the dump's samples, which carry no time, are taken 0.01 s apart (no latency
/// is estimated). Lines missing from a pass (a step of both readings more than 2.5 times its
/// neighbours') are not interpolated across: the points there hold the other pass's
/// measurements, and a warning names the readings.
///
/// Writes DIR/encoder.csv (the calib table with u_arcsec, of the raw encoder reading),
/// DIR/moteus.txt (the 256-entry compensation table as `conf set` lines, see `calib export
/// --help`; the map's orders 1 to pole pairs − 1, below the electrical frequency, which is what
/// moteus' own average leaves and what 256 entries hold), DIR/report.json and DIR/report.html, and prints a summary with the ripple, the
/// table's u and how closely the moteus table holds the map. An encoder that counts against the
/// phase is calibrated in its raw reading (the commanded angle negated): a source with `sign`
/// −1 needs the table of the reading it uses.
///
/// Exit status: 0 success, 1 the dump cannot be read or calibrated, 2 bad usage.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The dump (`moteus_tool --calibrate --cal-write-raw FILE`).
    #[arg(value_name = "DUMP")]
    pub dump: PathBuf,
    /// Output folder (created if missing): encoder.csv, moteus.txt, report.json and report.html.
    #[arg(
        short,
        long = "output",
        value_name = "DIR",
        default_value = "calib-out"
    )]
    pub output: PathBuf,
    /// Pole pairs of the motor (default: from the dump).
    #[arg(long)]
    pub pole_pairs: Option<u32>,
    /// Points of encoder.csv: the grid at which the encoder is measured against the commanded
    /// angle, 0.1° apart by default, fixed as `calib reference --points` is (the map is measured
    /// at its points, not summed from fitted harmonics as csrr's, multihead's and tdr's).
    #[arg(long, default_value_t = 3600)]
    pub points: usize,
    /// The `motor_position.sources.N` index of moteus.txt's lines.
    #[arg(long, default_value_t = 0)]
    pub moteus_source: u8,
    /// Print report.json on standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Replace files in DIR that calib did not write (without it, a file there that DIR's calib
    /// manifest does not list is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
}

/// Runs `calib moteus-dump`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    crate::input::check_points(Some(args.points))?;
    // Held until the run returns: a second run into the folder refuses at once.
    let _lock = crate::output::lock_folder(&args.output, "-o")?;
    if args.pole_pairs == Some(0) {
        return Err(crate::exit::Usage("--pole-pairs must be at least 1".to_string()).into());
    }
    let dump = read_cal_dump(&args.dump, args.pole_pairs)?;
    let pole_pairs = dump.pole_pairs;
    if args.points < 8 * pole_pairs as usize {
        return Err(crate::exit::Usage(format!(
            "--points {} is too coarse for {pole_pairs} pole pairs: give at least {}",
            args.points,
            8 * pole_pairs
        ))
        .into());
    }
    let mut cal = ReferenceCal::new(ReferenceOptions {
        points: args.points,
        latency: Latency::Fixed(0.0),
        reference_kind: ReferenceKind::Commanded { pole_pairs },
        ..ReferenceOptions::default()
    });
    for &(t, encoder, commanded) in &dump.samples {
        cal.push(t, encoder, commanded);
    }
    let (dut, reference) = ("encoder", "commanded");
    let cal = cal.finish().with_context(|| {
        format!(
            "{}: the encoder against the commanded angle",
            args.dump.display()
        )
    })?;
    if cal.map.turn().is_none() {
        anyhow::bail!(
            "{}: the encoder covered only part of a turn; moteus' table needs a whole turn (record the calibration \
             again: moteus_tool turns the rotor a whole turn each way)",
            args.dump.display()
        );
    }
    let mut warnings = Vec::new();
    if dump.encoder_reversed {
        warnings.push(
            "the encoder counts against the commanded phase: the table is of its raw reading; a motor_position source \
             with sign −1 reads the other way round and needs the table of that reading"
                .to_string(),
        );
    }
    let report = Report::new(
        cal.report_section(dut, reference, None),
        vec![args.dump.display().to_string()],
        Some(crate::input::command_line()),
        warnings,
    );
    let json = calib_io::report::render_json(&report)?;
    let doc = crate::method::reference::document::document(dut, reference, &cal, &report);
    let table = calib_io::table::render_table(&cal.map, Some(&cal.u))
        .context("the table of the encoder")?;
    let mut opts = ExportOptions::new(
        export::Format::Moteus,
        format!(
            "calib {} moteus-dump of {}",
            env!("CARGO_PKG_VERSION"),
            args.dump.display()
        ),
    );
    opts.moteus_source = args.moteus_source;
    // The orders below the electrical frequency: what the firmware's own average over an
    // electrical period leaves, and all a 256-entry table holds without aliasing the rotor's
    // motion between the samples into it.
    opts.keep = export::Keep::Orders((1..pole_pairs.max(2) as usize).collect());
    let moteus = export::export(&cal.map, &opts).context("the moteus table")?;
    write_outputs(
        &args.output,
        &[
            ("encoder.csv".to_string(), table.into_bytes()),
            ("moteus.txt".to_string(), moteus.text.into_bytes()),
            ("report.json".to_string(), json.as_bytes().to_vec()),
        ],
        &doc,
        None,
    )?;
    if args.json {
        return Ok(json);
    }
    let mut o = String::new();
    let _ = writeln!(o, "moteus calibration dump {}\n", args.dump.display());
    let ch = &report.channels[dut];
    let orders: Vec<String> = ch
        .harmonics
        .iter()
        .take(4)
        .map(|h| format!("{}: {:.3}″", h.order, h.amplitude_arcsec))
        .collect();
    let ripple = cal.ripple.as_ref().map_or_else(String::new, |r| {
        let mut terms: Vec<_> = r.terms.iter().collect();
        terms.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
        terms
            .iter()
            .take(2)
            .map(|t| {
                format!(
                    "order {} {:.3}″ ± {:.3}″",
                    t.order,
                    t.amplitude * ARCSEC_PER_RAD,
                    t.u_amplitude * ARCSEC_PER_RAD
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    });
    let u_max = cal.u.iter().fold(0.0f64, |m, u| m.max(*u)) * ARCSEC_PER_RAD;
    o += &key_values(&[
        (
            "dump",
            format!(
                "{} rising samples (first {SETTLING_SAMPLES} dropped), {} falling; phase travel / encoder travel {:.4} → {pole_pairs} pole pairs{}",
                dump.rising,
                dump.falling,
                dump.ratio,
                if args.pole_pairs.is_some() { " (given)" } else { "" }
            ),
        ),
        (
            "encoder map",
            format!(
                "p-p {:.3}″, rms {:.3}″, largest orders {}; u at most {u_max:.3}″",
                ch.peak_to_peak_arcsec,
                ch.rms_arcsec,
                orders.join(", ")
            ),
        ),
        ("motor ripple", format!("taken out of the map: {ripple}")),
        (
            "quantization",
            crate::method::reference::summary::quantization_text(&cal)
                .unwrap_or_else(|| "none found in the encoder's readings".to_string()),
        ),
        (
            "moteus table",
            moteus.fit.map_or_else(
                || "written".to_string(),
                |f| {
                    format!(
                        "256 entries holding the map's orders 1–{}; as the firmware interpolates them they differ from the \
                         whole map (all its orders) by at most {:.3}″, rms {:.3}″",
                        pole_pairs.max(2) - 1,
                        f.max * ARCSEC_PER_RAD,
                        f.rms * ARCSEC_PER_RAD
                    )
                },
            ),
        ),
    ]);
    for w in &report.warnings {
        let _ = writeln!(o, "warning: {w}");
    }
    let _ = writeln!(
        o,
        "\nwrote {}/encoder.csv, moteus.txt (conf set lines), report.json, report.html",
        args.output.display()
    );
    Ok(o)
}

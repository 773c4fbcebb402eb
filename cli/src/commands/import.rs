//! `calib import`: a table as a controller holds it, read back into a calib table. The formats
//! live in `calib_io::import`; this command parses, reads, and writes the table.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_io::export;
use calib_io::import::{self, ImportOptions};
use std::path::PathBuf;

/// The form the file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// mjbots moteus: `conf set KEY VALUE` lines (calib's `moteus`, a --write-config file, a
    /// console transcript), `KEY VALUE` lines (`moteus-config`, `moteus_tool --dump-config`) or
    /// `conf get KEY` answered by its value; other keys are skipped.
    #[value(alias = "moteus-config")]
    Moteus,
    /// SimpleFOC (since PR #75): `uint16_t calibrationLut[N] = {…};` as printLUT() prints it, or
    /// calib's `simplefoc` output.
    Simplefoc,
    /// SimpleFOC releases before PR #75: a `float NAME[N] = {…};` table (calib's
    /// `simplefoc-float`).
    SimplefocFloat,
    /// calib's `lut-f32-rad`: one f32 per line, the correction in radians.
    LutF32Rad,
    /// calib's `lut-i16` (scale from its header, or --scale).
    LutI16,
    /// calib's `lut-u16` (scale from its header, or --scale).
    LutU16,
    /// calib's `lut-i8` (scale from its header, or --scale).
    LutI8,
    /// calib's `c-array`: a float array of the correction in arcseconds.
    CArray,
    /// calib's `csv`: `angle_deg,correction_arcsec` rows.
    Csv,
}

impl Format {
    fn to_io(self) -> export::Format {
        match self {
            Format::Moteus => export::Format::Moteus,
            Format::Simplefoc => export::Format::Simplefoc,
            Format::SimplefocFloat => export::Format::SimplefocFloat,
            Format::LutF32Rad => export::Format::LutF32Rad,
            Format::LutI16 => export::Format::LutI16,
            Format::LutU16 => export::Format::LutU16,
            Format::LutI8 => export::Format::LutI8,
            Format::CArray => export::Format::CArray,
            Format::Csv => export::Format::Csv,
        }
    }
}

/// Read a table as a controller holds it into a calib correction table.
///
/// The inverse of `calib export`: a table already on a controller — moteus compensation settings
/// (`conf get`/`conf set` lines, --write-config and --dump-config files), SimpleFOC printLUT()
/// output, or any of calib's own look-up tables — becomes a calib table
/// (`angle_deg,error_arcsec,correction_arcsec`), so that `compose` (refining the table in use),
/// `compare`, `apply` and `export` work from it.
///
/// Each format is decoded as its controller decodes it: moteus adds code·compensation_scale/127
/// revolutions at i/256 of a turn (the correction); SimpleFOC subtracts (code − 32767)/10430.2191955
/// rad at raw angle i·2π/N (the error). The table keeps the controller's size and grid (entry i at
/// reading i·360/N). Like every calib table it has zero mean: a constant offset in the controller's
/// table is removed and the summary says how much. printLUT()'s zero_electric_angle and
/// sensor_direction are printed, not kept: they are the motor's settings.
///
/// Integer look-up tables take their scale from the header calib wrote (`# scale: …`); a file
/// without one needs --scale. Range tables (a joint that never turns a whole revolution) and the
/// harmonic listing are not read.
///
/// Example: `calib import --format moteus conf.txt -o in-use.csv`, then
/// `calib compose in-use.csv recal/a.csv -o next.csv`
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The file the controller's table is in.
    pub file: PathBuf,
    /// The form it holds.
    #[arg(long, value_enum)]
    pub format: Format,
    /// The calib correction table to write.
    #[arg(short, long = "output", value_name = "FILE")]
    pub output: PathBuf,
    /// Print what was read as JSON (docs/import.schema.json) instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// moteus: the motor_position source to read (0, 1 or 2; default: the only one the file
    /// has a table for).
    #[arg(long, value_parser = clap::value_parser!(u8).range(0..3))]
    pub source: Option<u8>,
    /// lut-i8/i16/u16 without calib's header: arcseconds a code stands for.
    #[arg(long)]
    pub scale: Option<f64>,
}

/// Runs `calib import`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if args.scale.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        return Err(
            Usage("--scale must be a positive number of arcseconds per code".into()).into(),
        );
    }
    if !args.file.exists() {
        return Err(Usage(format!(
            "{}: no such file; check the path",
            args.file.display()
        ))
        .into());
    }
    crate::overwrite::check(
        &args.output,
        &format!("-o {}", crate::ui::shown(&args.output)),
    )?;
    crate::output::prepare_file(&args.output, "-o")?;
    let mut opts = ImportOptions::new(args.format.to_io());
    opts.moteus_source = args.source;
    opts.scale_arcsec = args.scale;
    let table = import::import(&args.file, &opts)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    calib_io::table::write_table(&args.output, &table.map.clone().into(), None)?;
    let map = &table.map;
    if args.json {
        return crate::json::render(&crate::json::ImportJson {
            schema_version: calib_core::report::SCHEMA_VERSION,
            file: args.file.display().to_string(),
            format: opts.format.name().to_string(),
            output: args.output.display().to_string(),
            points: map.len(),
            notes: table.notes.clone(),
            peak_to_peak_arcsec: map.peak_to_peak() * ARCSEC_PER_RAD,
            rms_arcsec: map.rms() * ARCSEC_PER_RAD,
        });
    }
    let mut o = format!(
        "wrote {}: {} points from {} (--format {})\n",
        args.output.display(),
        map.len(),
        args.file.display(),
        opts.format.name()
    );
    for note in &table.notes {
        o.push_str(&format!("  {note}\n"));
    }
    o.push_str(&format!(
        "  error: {:.6} arcsec peak-to-peak, {:.6} arcsec RMS\n",
        map.peak_to_peak() * ARCSEC_PER_RAD,
        map.rms() * ARCSEC_PER_RAD
    ));
    Ok(o)
}

//! `calib import`: a table as a controller holds it, read back into a calib table. The formats
//! live in `calib_io::import`; this command parses, reads, and writes the table.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_io::export;
use calib_io::import::{self, ImportOptions};
use std::path::PathBuf;

/// The form the file holds: one of `calib_io::import::FORMATS`, each described there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Format(export::Format);

/// Every format read back, for clap's list of values.
const FORMATS: [Format; 9] = {
    let mut all = [Format(export::Format::Csv); 9];
    let mut i = 0;
    while i < all.len() {
        all[i] = Format(import::FORMATS[i]);
        i += 1;
    }
    all
};

impl clap::ValueEnum for Format {
    fn value_variants<'a>() -> &'a [Self] {
        &FORMATS
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        let value = clap::builder::PossibleValue::new(self.0.name())
            .help(crate::flags::in_cli_words(import::about(self.0)));
        // moteus reads `moteus-config` files too.
        Some(if self.0 == export::Format::Moteus {
            value.alias(export::Format::MoteusConfig.name())
        } else {
            value
        })
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
    /// Replace FILE even if calib did not write it (without it, a file there that no calib
    /// manifest of its folder lists is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
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
    if let Some(scale) = args
        .scale
        .filter(|s| !calib_io::export::SCALE_ARCSEC_RANGE.contains(s))
    {
        let range = calib_io::export::SCALE_ARCSEC_RANGE;
        return Err(Usage(format!(
            "--scale {} is outside the scales calib's tables have, {:e} to {:e} arcseconds a \
             code; give the scale the table was exported with (calib writes it in the header)",
            calib_io::limits::readable(scale),
            range.start(),
            range.end()
        ))
        .into());
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
    let _lock = crate::output::prepare_file(&args.output, "-o")?;
    let mut opts = ImportOptions::new(args.format.0);
    opts.moteus_source = args.source;
    opts.scale_arcsec = args.scale;
    let table = import::import(&args.file, &opts)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    calib_io::table::write_table(&args.output, &table.map.clone().into(), None)?;
    crate::output::record_written([&args.output]);
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

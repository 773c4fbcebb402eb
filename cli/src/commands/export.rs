//! `calib export`: a correction table in the forms controllers load. The formats live in
//! `calib_io::export`; this command parses, reads the table, and writes.

use crate::exit::Usage;
use crate::json::{ExportJson, FitJson};
use anyhow::Context;
use calib_io::export::{self, ExportError, ExportOptions, Keep};
use std::path::PathBuf;

/// The output form, and where it is loaded: one of `calib_io::export::Format::ALL`, each named
/// and described there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Format(export::Format);

/// Every format, for clap's list of values.
const FORMATS: [Format; 11] = {
    let mut all = [Format(export::Format::Csv); 11];
    let mut i = 0;
    while i < all.len() {
        all[i] = Format(export::Format::ALL[i]);
        i += 1;
    }
    all
};

impl clap::ValueEnum for Format {
    fn value_variants<'a>() -> &'a [Self] {
        &FORMATS
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.0.name()).help(self.0.about()))
    }
}

/// Export a correction table (from any method) in a form a controller loads.
///
/// Every output starts with a header stating calib's sign convention (correction = −error,
/// applied as reading + correction(reading)), the grid (entry i at reading i·360/N degrees), the
/// units and, for integer tables, the scale; then what the controller does with the numbers. The
/// controllers differ: moteus adds its table (it holds the correction, in revolutions), SimpleFOC
/// subtracts its table (it holds the error, in radians). Integer formats refuse to saturate: a
/// scale too small for the table is an error naming the smallest that fits.
///
/// moteus: 256 int8 entries (the firmware's fixed size) and compensation_scale, the largest
/// |correction| so no entry saturates; entry i at i/256 of a revolution of the source's reading
/// after its offset and sign (offset_value), interpolated linearly, added to the reading
/// (mjbots/moteus fw/motor_position.h, commit 06a3d52). Not established from the source: whether
/// the firmware parses exponent notation, so the scale is written in plain decimals.
///
/// SimpleFOC: CalibratedSensor(sensor, N, lut) subtracts lut(raw), interpolated linearly between
/// entries at raw angle i·2π/N of the wrapped sensor's getMechanicalAngle()
/// (simplefoc/Arduino-FOC-drivers src/encoders/calibrated/CalibratedSensor.cpp). Since PR #75
/// (merged 2025-12) the table is uint16_t: entry = round(error·10430.2191955 + 32767), one code
/// = 19.78″, decoded (code − 32767)/10430.2191955; `simplefoc` writes that (its --points default
/// is the driver's 200, or more where the table has orders 200 entries cannot hold to the code).
/// Changed: `simplefoc` used to write the float table of earlier releases, which current ones do
/// not compile; that is now `simplefoc-float`, and `simplefoc-u16` (calib's own storage for the
/// float table) is gone.
///
/// No folding: a table of N entries holds only the orders below N/2. On a grid smaller than the
/// table, every order the grid holds is kept and evaluated exactly at its points; the orders
/// above are dropped and named with their peak to peak in the header (resampling by
/// interpolation would fold them onto lower orders: errors the sensor never had). --harmonics N
/// / --orders LIST keep only those orders the same way. Controller formats, and any export that
/// drops orders, end their header with the fit: how close the table, decoded and interpolated as
/// the controller does, is to the source table at its points, and what it leaves of the table's
/// error. A table that would leave as much error as it corrects, or more, is refused (exit 1); one
/// that leaves more than a quarter of its RMS is written with a warning on standard error.
///
/// A range table (a joint that never turns a whole revolution, from calib reference) exports as
/// a look-up table (lut-*, c-array, csv) whose header names the range: entry i at reading
/// LO + i·(HI − LO)/(N − 1), both ends included, readings outside left uncorrected. The formats a
/// controller interpolates periodically (moteus, simplefoc, harmonic) and chosen orders need a
/// whole turn and refuse it.
///
/// Example: `calib export calib-out/a.csv --format moteus --source 0 -o a.moteus`
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The correction table (`angle_deg,error_arcsec,correction_arcsec[,u_arcsec]`).
    pub table: PathBuf,
    /// The output form (see --help for where each is loaded).
    #[arg(long, value_enum)]
    pub format: Format,
    /// Points of the output grid (default: the table's; moteus: 256, the only size it takes;
    /// simplefoc: 200, the driver's default, or the fewest that hold the table's orders to the
    /// code); orders the grid cannot hold are dropped, never folded.
    #[arg(long)]
    pub points: Option<usize>,
    /// Arcseconds per LSB of integer formats (lut-i8/i16/u16, moteus; default: the smallest that
    /// holds the table; a scale so large that every code is 0 is refused; simplefoc's code is
    /// fixed by the driver).
    #[arg(long)]
    pub scale: Option<f64>,
    /// Keep the N orders of largest amplitude (among those the output grid holds); with
    /// --format harmonic, list those N.
    #[arg(long, value_name = "N", conflicts_with = "orders")]
    pub harmonics: Option<usize>,
    /// Keep these orders, e.g. `1,2,72` or `1-8,72,144`.
    #[arg(long, value_name = "LIST", value_parser = parse_orders)]
    pub orders: Option<Orders>,
    /// `harmonic` without --harmonics or --orders: smallest amplitude listed, arcseconds.
    #[arg(long, default_value_t = 0.01)]
    pub min_amplitude: f64,
    /// moteus: the motor_position source the table is for (0, 1 or 2).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..3))]
    pub source: u8,
    /// Output file (default: standard output).
    #[arg(short, long = "output", value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Print what was written as JSON (docs/export.schema.json) instead of the header; needs -o.
    #[arg(long, requires = "output")]
    pub json: bool,
    /// Replace FILE even if calib did not write it (without it, a file there that no calib
    /// manifest of its folder lists is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
}

/// A list of harmonic orders (`--orders`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Orders(pub Vec<usize>);

/// Largest order a range in `--orders` may reach (the largest order of a 3,600,000-point table).
const MAX_ORDER: usize = calib_io::limits::MAX_TABLE_POINTS / 2;

/// Parses `1,2,72` or `1-8,72,144`.
fn parse_orders(text: &str) -> Result<Orders, String> {
    let bad = |part: &str| {
        format!("`{part}` is not an order or a range of orders; write e.g. 1,2,72 or 1-8,72,144")
    };
    let order = |s: &str| -> Result<usize, String> {
        match s.trim().parse::<usize>() {
            Ok(h) if (1..=MAX_ORDER).contains(&h) => Ok(h),
            _ => Err(bad(s.trim())),
        }
    };
    let mut orders = Vec::new();
    for part in text.split(',') {
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (order(a)?, order(b)?);
                if a > b {
                    return Err(bad(part.trim()));
                }
                orders.extend(a..=b);
            }
            None => orders.push(order(part)?),
        }
    }
    Ok(Orders(orders))
}

/// An export error as an exit status: a table that cannot be written usefully in the format
/// whatever the options (it would leave its error, or holds a value the format cannot encode) is
/// a data error (exit 1); the others are a choice of options this table cannot be written with (a
/// scale that saturates or zeroes every code, a size or orders the format does not take, a
/// periodic format for a range table), so a usage error (exit 2).
fn classify(err: ExportError) -> anyhow::Error {
    match err {
        ExportError::NoBetter { .. }
        | ExportError::OutOfRange { .. }
        | ExportError::NothingListed { .. } => err.into(),
        _ => Usage(err.to_string()).into(),
    }
}

/// Runs `calib export`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    crate::input::check_points(args.points)?;
    if args.scale.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        return Err(Usage("--scale must be a positive number of arcseconds per LSB".into()).into());
    }
    crate::input::check_non_negative("--min-amplitude", args.min_amplitude, "arcseconds")?;
    if args.harmonics == Some(0) {
        return Err(Usage("--harmonics 0 is outside its range: at least 1".into()).into());
    }
    let _lock = match &args.output {
        Some(path) => {
            crate::overwrite::check(path, &format!("-o {}", crate::ui::shown(path)))?;
            Some(crate::output::prepare_file(path, "-o")?)
        }
        None => None,
    };
    if !args.table.exists() {
        return Err(Usage(format!(
            "{}: no such file; check the path",
            args.table.display()
        ))
        .into());
    }
    let table = calib_io::table::read_table(&args.table)
        .with_context(|| format!("cannot read {}", args.table.display()))?;
    let mut opts = ExportOptions::new(
        args.format.0,
        format!(
            "calib {} export of {}",
            env!("CARGO_PKG_VERSION"),
            args.table.display()
        ),
    );
    opts.points = args.points;
    opts.scale_arcsec = args.scale;
    opts.keep = match (&args.harmonics, &args.orders) {
        (Some(n), _) => Keep::Largest(*n),
        (None, Some(Orders(list))) => Keep::Orders(list.clone()),
        (None, None) => Keep::All,
    };
    opts.min_amplitude_arcsec = args.min_amplitude;
    opts.moteus_source = args.source;
    // A range table is refused by every format that needs a whole turn.
    let out = export::export(&table.map, &opts)
        .map_err(classify)
        .with_context(|| format!("{}", args.table.display()))?;
    // moteus's `conf set` lines cannot carry comments: their header goes to the terminal.
    let uncommented = opts.format == export::Format::Moteus;
    match &args.output {
        Some(path) => {
            calib_io::atomic::write_atomic(path, out.text.as_bytes())?;
            crate::output::record_written([path]);
            if args.json {
                return crate::json::render(&ExportJson {
                    schema_version: calib_core::report::SCHEMA_VERSION,
                    table: args.table.display().to_string(),
                    format: opts.format.name().to_string(),
                    output: path.display().to_string(),
                    header: out.header.clone(),
                    fit: out.fit.as_ref().map(FitJson::from),
                    warnings: out.warnings.clone(),
                });
            }
            // What the table is, then where it went.
            let mut o = String::new();
            let shown =
                out.header.iter().skip(1).filter(|l| {
                    uncommented || l.starts_with("fit: ") || l.starts_with("warning: ")
                });
            for line in shown {
                o.push_str(&format!("  {line}\n"));
            }
            o.push_str(&format!("wrote {}\n", path.display()));
            Ok(o)
        }
        None => {
            if uncommented {
                for line in &out.header {
                    eprintln!("# {line}");
                }
            } else {
                // The table goes to standard output; what the user must know, to the terminal.
                for warning in &out.warnings {
                    eprintln!("warning: {warning}");
                }
            }
            Ok(out.text)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orders_parse_as_lists_and_ranges() {
        assert_eq!(parse_orders("1,2,72"), Ok(Orders(vec![1, 2, 72])));
        assert_eq!(
            parse_orders("1-4, 72,144"),
            Ok(Orders(vec![1, 2, 3, 4, 72, 144]))
        );
        for bad in ["", "0", "3-1", "a", "1,,2", "-3", "2-"] {
            assert!(parse_orders(bad).is_err(), "{bad}");
        }
    }
}

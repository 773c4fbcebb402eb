//! Correction tables read back from the forms controllers hold: what `calib import` reads, the
//! inverse of [`crate::export`].
//!
//! A table already on a controller — moteus `conf get`/`conf set` lines or a `--write-config`
//! file, SimpleFOC `printLUT()` output, or any of calib's own exports — becomes a calib table, so
//! that `compose`, `compare`, `apply` and `export` work from it. Each format is decoded as its
//! consumer decodes it (the arithmetic cited in [`crate::export`]'s modules, in `f32` where the
//! firmware uses `f32`):
//! - [`moteus`]: `motor_position.sources.N.compensation_table.I` and `compensation_scale`;
//! - [`c_array`]: SimpleFOC's `uint16_t calibrationLut[N] = {…}` (and the `float` table of
//!   releases before PR #75), and calib's `c-array`;
//! - [`lines`]: calib's one-value-a-line look-up tables and its `csv`.
//!
//! # Sign, grid and mean
//! Every format's entry `i` sits at reading `i·360/N` of one whole revolution; each is turned
//! into calib's error (`reading − true angle`): SimpleFOC's tables hold the error, the others the
//! correction (`−error`). [`Imported::values`] are the errors as the controller holds them;
//! [`Imported::map`] is the same with its mean removed, as every calib table (a constant offset
//! is no calibration's), and [`Imported::mean`] says how much that was.
//!
//! # Limits
//! A file is read only up to [`MAX_IMPORT_BYTES`], and a table of more than
//! [`crate::limits::MAX_TABLE_POINTS`] entries is refused as it is counted, before it is held.

pub mod c_array;
pub mod lines;
pub mod moteus;

use crate::Error;
use crate::export::Format;
use crate::limits::MAX_TABLE_POINTS;
use calib_core::ErrorMap;
use std::io::Read as _;
use std::path::Path;

/// The largest file `calib import` reads, bytes: a table at the point limit with 32 bytes an
/// entry (more than any format writes for one entry, comments aside).
pub const MAX_IMPORT_BYTES: u64 = 32 * MAX_TABLE_POINTS as u64;

/// How to read a table.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    /// The form the file holds.
    pub format: Format,
    /// moteus: the `motor_position.sources.N` to read; `None`: the only one the file holds.
    pub moteus_source: Option<u8>,
    /// Integer look-up tables: arcseconds per code, where the file's header does not say.
    pub scale_arcsec: Option<f64>,
}

impl ImportOptions {
    /// Options for `format` with every other choice at its default.
    pub fn new(format: Format) -> Self {
        ImportOptions {
            format,
            moteus_source: None,
            scale_arcsec: None,
        }
    }
}

/// A table read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The errors as the controller holds them (radians), entry `i` at reading `i·2π/N`.
    pub values: Vec<f64>,
    /// The same as a calib error map: mean removed.
    pub map: ErrorMap,
    /// The mean of `values`, radians: a constant offset, which calib's tables do not hold.
    pub mean: f64,
    /// What was read, for the user: source, size, scale, settings found beside the table.
    pub notes: Vec<String>,
}

/// The formats `calib import` reads: every export format but `harmonic`.
pub fn readable(format: Format) -> bool {
    format != Format::Harmonic
}

/// The formats `calib import` reads, in the order its `--help` lists them; `moteus` also reads
/// `moteus-config` files (the same settings as `key value` lines).
pub const FORMATS: [Format; 9] = [
    Format::Moteus,
    Format::Simplefoc,
    Format::SimplefocFloat,
    Format::LutF32Rad,
    Format::LutI16,
    Format::LutU16,
    Format::LutI8,
    Format::CArray,
    Format::Csv,
];

/// What a file in `format` holds, as read back, in one line (the `--help` of `calib import`
/// lists it beside the name); empty for a format not read back ([`readable`]).
pub fn about(format: Format) -> &'static str {
    match format {
        Format::Moteus | Format::MoteusConfig => {
            "mjbots moteus: `conf set KEY VALUE` lines (calib's `moteus`, a --write-config file, a \
             console transcript), `KEY VALUE` lines (`moteus-config`, `moteus_tool \
             --dump-config`) or `conf get KEY` answered by its value; other keys are skipped"
        }
        Format::Simplefoc => {
            "SimpleFOC (since PR #75): `uint16_t calibrationLut[N] = {…};` as printLUT() prints \
             it, or calib's `simplefoc` output"
        }
        Format::SimplefocFloat => {
            "SimpleFOC releases before PR #75: a `float NAME[N] = {…};` table (calib's \
             `simplefoc-float`)"
        }
        Format::LutF32Rad => "calib's `lut-f32-rad`: one f32 per line, the correction in radians",
        Format::LutI16 => "calib's `lut-i16` (scale from its header, or the `scale_arcsec` option)",
        Format::LutU16 => "calib's `lut-u16` (scale from its header, or the `scale_arcsec` option)",
        Format::LutI8 => "calib's `lut-i8` (scale from its header, or the `scale_arcsec` option)",
        Format::CArray => "calib's `c-array`: a float array of the correction in arcseconds",
        Format::Csv => "calib's `csv`: `angle_deg,correction_arcsec` rows",
        Format::Harmonic => "",
    }
}

/// Reads the table `path` holds in `opts.format`.
///
/// Errors name the file and, where one is concerned, the line; a file beyond
/// [`MAX_IMPORT_BYTES`] or a table beyond [`MAX_TABLE_POINTS`] entries is refused before it is
/// read whole.
pub fn import(path: &Path, opts: &ImportOptions) -> Result<Imported, Error> {
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size > MAX_IMPORT_BYTES {
        return Err(data(
            path,
            format!(
                "the file has {size} bytes, more than a table of {MAX_TABLE_POINTS} entries (the \
                 most calib holds) takes ({MAX_IMPORT_BYTES} bytes); this is not a controller's \
                 table"
            ),
        ));
    }
    let mut bytes = Vec::new();
    file.take(MAX_IMPORT_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    let text = String::from_utf8_lossy(&bytes);
    parse(&text, path, opts)
}

/// [`import`] of `text`; `path` names it in errors.
pub fn parse(text: &str, path: &Path, opts: &ImportOptions) -> Result<Imported, Error> {
    let (values, notes) = match opts.format {
        Format::Moteus | Format::MoteusConfig => moteus::parse(text, path, opts.moteus_source)?,
        Format::Simplefoc | Format::SimplefocFloat | Format::CArray => {
            c_array::parse(text, path, opts.format)?
        }
        Format::Harmonic => {
            return Err(data(
                path,
                "`format = harmonic` is not read back (a listing of orders, not a table); read \
                 the table it was exported from instead"
                    .into(),
            ));
        }
        _ => lines::parse(text, path, opts.format, opts.scale_arcsec)?,
    };
    finish(values, notes, path)
}

/// The [`Imported`] of `values` (errors, radians), checked for size.
fn finish(values: Vec<f64>, mut notes: Vec<String>, path: &Path) -> Result<Imported, Error> {
    if values.len() < 2 {
        return Err(data(
            path,
            format!(
                "the table has {} entr{}; a table needs at least 2",
                values.len(),
                if values.len() == 1 { "y" } else { "ies" }
            ),
        ));
    }
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    let map = ErrorMap::new(values.clone());
    let arcsec = mean * calib_core::angle::ARCSEC_PER_RAD;
    // Tables hold 6 decimals of an arcsecond.
    if arcsec.abs() >= 5e-7 {
        notes.push(format!(
            "mean {arcsec:.6} arcsec removed: a constant offset, which calib's tables do not hold \
             (no calibration observes it)"
        ));
    }
    Ok(Imported {
        values,
        map,
        mean,
        notes,
    })
}

/// An error about the whole file.
fn data(path: &Path, message: String) -> Error {
    Error::Data {
        path: path.to_path_buf(),
        message,
    }
}

/// An error at a 1-based line.
fn at(path: &Path, line: usize, message: String) -> Error {
    crate::error::csv_error(path, line as u64, None, message)
}

/// Refuses an entry beyond [`MAX_TABLE_POINTS`], before it is held: `count` entries so far.
fn check_count(path: &Path, line: usize, count: usize) -> Result<(), Error> {
    if count >= MAX_TABLE_POINTS {
        return Err(at(
            path,
            line,
            format!(
                "the table has more than {MAX_TABLE_POINTS} entries, the most calib holds (0.36″ \
                 steps); this is not a controller's table"
            ),
        ));
    }
    Ok(())
}

/// Refuses a table whose header says it covers a range, not a whole turn.
fn refuse_range(path: &Path, line: usize) -> Error {
    at(
        path,
        line,
        "this is a range table (a joint that never turns a whole revolution); calib import reads \
         whole-turn tables only: use the calib range table it was exported from"
            .into(),
    )
}

#[cfg(test)]
mod tests;

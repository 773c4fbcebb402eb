//! Correction tables in the forms controllers load: what `calib export` writes.
//!
//! One module per family of formats, each with round-trip tests that decode the output the way
//! its consumer does:
//! - [`lut`]: generic look-up tables (`lut-f32-rad`, `lut-i16`, `lut-u16`, `lut-i8`), a C array
//!   and CSV;
//! - [`harmonic`]: the harmonic listing, and the choice of orders ([`Keep`]) every format can be
//!   resynthesized from;
//! - [`moteus`]: the encoder compensation table of an mjbots moteus `motor_position` source, as
//!   `conf set` lines;
//! - [`simplefoc`]: the look-up table of SimpleFOC's `CalibratedSensor`, as C++ (the current
//!   `uint16_t` table, and the `float` table of releases before PR #75).
//!
//! # Steps
//! 1. The size of the output grid: `--points`, or the size the format requires (moteus 256), or
//!    the format's default ([`Format::default_points`]: for SimpleFOC the larger of the driver's
//!    own 200 and the smallest size that holds the table's orders to the firmware's quantum), or
//!    the table's own size for the generic formats.
//! 2. The values on the output grid. A table of `N` entries holds only the orders below `N/2`;
//!    resampling a larger table onto it by interpolation would fold every higher order onto a
//!    lower one — errors the sensor never had. So with [`Keep::All`] on a grid smaller than the
//!    table, every order the grid holds is kept, evaluated exactly at its points, and the orders
//!    above are dropped and named with their peak-to-peak ([`harmonic`]); on a grid at least as
//!    large, the table is interpolated linearly (which folds nothing). Chosen orders
//!    ([`Keep::Largest`], [`Keep::Orders`]) are evaluated the same way.
//! 3. The format quantizes them and writes them with a header: calib's sign convention and grid,
//!    then what the consumer does with the numbers.
//! 4. Where it matters (the controller formats, and whenever orders are dropped), the table as the
//!    controller will use it — decoded and interpolated linearly — is compared with the source
//!    table at the source table's points ([`Fit`]), and the header says how close it is.
//!
//! # Tables that would not help
//! The [`Fit`] leaves `RMS(source − table as used)` of the source's `RMS`. A table that leaves
//! all of it or more (it would make the sensor no better, or worse) is refused
//! ([`ExportError::NoBetter`]); one that leaves more than [`WARN_LEFT_FRACTION`] of it is written
//! with a warning ([`Export::warnings`]) that names both figures and what to do. The harmonic
//! listing is judged alike, its orders summed on the output grid against the source table; a
//! listing of no order at all is refused ([`ExportError::NothingListed`]).
//!
//! # Sign
//! calib's tables hold `error = reading − true angle`; the correction is `−error`, applied as
//! `reading + correction(reading)`. Each format says in its header which of the two it holds,
//! because the controllers differ: moteus adds its table (it holds the correction), SimpleFOC
//! subtracts its table (it holds the error).

pub mod harmonic;
pub mod lut;
pub mod moteus;
pub mod simplefoc;

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::interpolate_periodic;
use calib_core::{ErrorMap, TableMap};
use std::fmt::Write as _;

pub use harmonic::Keep;

/// An output format of `calib export`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// One f32 per line: the correction in radians.
    LutF32Rad,
    /// One signed 16-bit code per line: correction = code × scale.
    LutI16,
    /// One unsigned 16-bit code per line (offset binary): correction = (code − 32768) × scale.
    LutU16,
    /// One signed 8-bit code per line: correction = code × scale.
    LutI8,
    /// A C header with a `float` array of the correction in arcseconds.
    CArray,
    /// `angle_deg,correction_arcsec` rows.
    Csv,
    /// The correction's harmonics: `order,amplitude_arcsec,phase_deg` rows.
    Harmonic,
    /// moteus `conf set` lines (no comments: `moteus_tool --write-config` sends every line).
    Moteus,
    /// The same settings as `key value` lines with a `#` header, for `moteus_tool
    /// --restore-config`.
    MoteusConfig,
    /// SimpleFOC's `CalibratedSensor` table as current releases take it (since
    /// simplefoc/Arduino-FOC-drivers PR #75): `uint16_t` codes of the error.
    Simplefoc,
    /// SimpleFOC's `CalibratedSensor` table as releases before PR #75 took it: a `float` array
    /// of the error in radians.
    SimplefocFloat,
}

impl Format {
    /// The format's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Format::LutF32Rad => "lut-f32-rad",
            Format::LutI16 => "lut-i16",
            Format::LutU16 => "lut-u16",
            Format::LutI8 => "lut-i8",
            Format::CArray => "c-array",
            Format::Csv => "csv",
            Format::Harmonic => "harmonic",
            Format::Moteus => "moteus",
            Format::MoteusConfig => "moteus-config",
            Format::Simplefoc => "simplefoc",
            Format::SimplefocFloat => "simplefoc-float",
        }
    }

    /// Every format, in the order `calib export --help` lists them.
    pub const ALL: [Format; 11] = [
        Format::LutF32Rad,
        Format::LutI16,
        Format::LutU16,
        Format::LutI8,
        Format::CArray,
        Format::Csv,
        Format::Harmonic,
        Format::Moteus,
        Format::MoteusConfig,
        Format::Simplefoc,
        Format::SimplefocFloat,
    ];

    /// The format named `name` ([`Format::name`]), if there is one.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.name() == name)
    }

    /// What the format holds and where it is loaded, in one line (the `--help` of `calib
    /// export` lists it beside the name).
    pub fn about(self) -> &'static str {
        match self {
            Format::LutF32Rad => "Own firmware: one f32 per line, the correction in radians",
            Format::LutI16 => "Own firmware: one int16 code per line, correction = code × scale",
            Format::LutU16 => {
                "Own firmware: one uint16 code per line, correction = (code − 32768) × scale"
            }
            Format::LutI8 => "Own firmware: one int8 code per line, correction = code × scale",
            Format::CArray => {
                "Own firmware: a C header, a float array of the correction in arcseconds"
            }
            Format::Csv => "Spreadsheets and scripts: `angle_deg,correction_arcsec` rows",
            Format::Harmonic => {
                "Own firmware summing harmonics: `order,amplitude_arcsec,phase_deg` rows of the \
                 correction"
            }
            Format::Moteus => {
                "mjbots moteus (firmware ≥ 0x0109): `conf set` lines for `moteus_tool -t ID \
                 --write-config FILE` or its `--console`, ending with `conf write` (no comments: \
                 the header goes to the terminal)"
            }
            Format::MoteusConfig => {
                "mjbots moteus: the same settings as `key value` lines with a `#` header, for \
                 `moteus_tool -t ID --restore-config FILE`"
            }
            Format::Simplefoc => {
                "SimpleFOC (Arduino-FOC-drivers since PR #75): `uint16_t calibrationLut[N]`, as \
                 printLUT() prints it, for `CalibratedSensor(sensor, N, calibrationLut)` in the \
                 sketch"
            }
            Format::SimplefocFloat => {
                "SimpleFOC releases before PR #75: `float calib_lut[N]` for their `float*` \
                 constructor"
            }
        }
    }

    /// The number of points written when `--points` is not given, for `map`: the size the format
    /// requires; for SimpleFOC the larger of the driver's default (200) and the smallest size
    /// that holds the map's orders to the firmware's quantum ([`simplefoc::default_points`]);
    /// else the table's own size.
    pub fn default_points(self, map: &TableMap) -> usize {
        match (self, map) {
            (Format::Simplefoc | Format::SimplefocFloat, TableMap::Turn(m)) => {
                simplefoc::default_points(m)
            }
            _ => self.required_points().unwrap_or(map.len()),
        }
    }

    /// The number of points the consumer requires, where it fixes one.
    pub fn required_points(self) -> Option<usize> {
        match self {
            Format::Moteus | Format::MoteusConfig => Some(moteus::TABLE_SIZE),
            _ => None,
        }
    }

    /// Whether the consumer interpolates the table periodically over one whole revolution, so
    /// that only a table over a whole revolution can be written in it.
    pub fn periodic(self) -> bool {
        matches!(
            self,
            Format::Harmonic
                | Format::Moteus
                | Format::MoteusConfig
                | Format::Simplefoc
                | Format::SimplefocFloat
        )
    }

    /// The line comment of the format, if it can carry comments.
    fn comment(self) -> Option<&'static str> {
        match self {
            Format::Moteus => None,
            Format::CArray | Format::Simplefoc | Format::SimplefocFloat => Some("//"),
            _ => Some("#"),
        }
    }

    /// Whether the header reports the [`Fit`] even when every order is kept.
    fn always_fit(self) -> bool {
        matches!(
            self,
            Format::Moteus | Format::MoteusConfig | Format::Simplefoc | Format::SimplefocFloat
        )
    }
}

/// What to export and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportOptions {
    /// The output format.
    pub format: Format,
    /// Points of the output grid; `None`: [`Format::default_points`].
    pub points: Option<usize>,
    /// Arcseconds per LSB of integer formats; `None`: the smallest that holds the table.
    pub scale_arcsec: Option<f64>,
    /// Which orders to keep.
    pub keep: Keep,
    /// [`Format::Harmonic`] with [`Keep::All`]: the smallest amplitude listed, arcseconds.
    pub min_amplitude_arcsec: f64,
    /// [`Format::Moteus`] / [`Format::MoteusConfig`]: the `motor_position.sources.N` index.
    pub moteus_source: u8,
    /// The first header line, saying what wrote the file from what (e.g. `calib 0.1.0 export
    /// of a.csv`).
    pub title: String,
}

impl ExportOptions {
    /// Options for `format` with every other choice at its default.
    pub fn new(format: Format, title: impl Into<String>) -> Self {
        ExportOptions {
            format,
            points: None,
            scale_arcsec: None,
            keep: Keep::All,
            min_amplitude_arcsec: 0.01,
            moteus_source: 0,
            title: title.into(),
        }
    }
}

/// An exported table.
#[derive(Debug, Clone, PartialEq)]
pub struct Export {
    /// The file's content.
    pub text: String,
    /// The header lines (without comment markers). Formats with comments also hold them in
    /// `text`; [`Format::Moteus`] cannot, and its caller shows them to the user instead.
    pub header: Vec<String>,
    /// How close the table, as the controller will use it, is to the source table (where
    /// measured; see the [module docs](self)).
    pub fit: Option<Fit>,
    /// What the user must know before loading the table (also the header's `warning:` lines):
    /// a table that leaves more than [`WARN_LEFT_FRACTION`] of the error.
    pub warnings: Vec<String>,
}

/// The fraction of the source's RMS error a table may leave (as the controller uses it) before
/// the export warns: a quarter. A table that leaves a quarter still removes most of the error, but
/// the user should know that a finer table, or another controller setting, would do better.
pub const WARN_LEFT_FRACTION: f64 = 0.25;

/// Why a table cannot be exported as asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExportError {
    /// An integer code would leave its range at the given scale.
    #[error(
        "the largest |correction| is {largest_arcsec:.6}″, which at `scale_arcsec = {scale_arcsec}` \
         ″/LSB needs code {code:.0}, beyond ±{max_code}; use `scale_arcsec = {fits:.6e}` or larger"
    )]
    Saturated {
        /// The largest magnitude to encode, arcseconds.
        largest_arcsec: f64,
        /// The scale asked for, arcseconds per LSB.
        scale_arcsec: f64,
        /// The code that would be needed.
        code: f64,
        /// The largest code the format holds.
        max_code: i64,
        /// The smallest scale that holds the table, arcseconds per LSB.
        fits: f64,
    },
    /// A scale so coarse that every code rounds to zero: the table would correct nothing.
    #[error(
        "the largest |correction| is {largest_arcsec:.6}″, less than half a code at \
         `scale_arcsec = {scale_arcsec}` ″/LSB, so every code would be 0 and the table would \
         correct nothing; use `scale_arcsec = {fits:.6e}` (the finest that holds the table) or any \
         scale up to {coarsest:.6e}, or leave the `scale_arcsec` option out"
    )]
    ScaleAboveTable {
        /// The largest magnitude to encode, arcseconds.
        largest_arcsec: f64,
        /// The scale asked for, arcseconds per LSB.
        scale_arcsec: f64,
        /// The smallest scale that holds the table, arcseconds per LSB.
        fits: f64,
        /// Twice the largest magnitude: the coarsest scale that leaves one non-zero code.
        coarsest: f64,
    },
    /// The format's quantum is fixed by its consumer.
    #[error(
        "`format = {format}` takes no `scale_arcsec` option: {why}; leave the `scale_arcsec` option \
         out (or use `format = lut-u16`, whose scale is free)"
    )]
    FixedScale {
        /// The format's name.
        format: &'static str,
        /// Where the fixed quantum comes from.
        why: &'static str,
    },
    /// A scale outside [`SCALE_ARCSEC_RANGE`], whatever the table.
    #[error(
        "`scale_arcsec = {shown}` ″/LSB is outside the scales calib writes, {lo:e} to {hi:e} \
         ″/LSB (a microarcsecond to a whole turn a code); give a scale in that range, or leave \
         the `scale_arcsec` option out for the finest that holds the table",
        shown = crate::limits::readable(*scale_arcsec),
        lo = SCALE_ARCSEC_RANGE.start(),
        hi = SCALE_ARCSEC_RANGE.end()
    )]
    ScaleRange {
        /// The scale asked for, arcseconds per LSB.
        scale_arcsec: f64,
    },
    /// A value beyond what the format can encode.
    #[error(
        "the error at reading {angle_deg:.6}° is {arcsec:.3}″, beyond the ±{limit_arcsec:.0}″ \
         `format = {format}` can encode ({why}); no sensor errs by that much: check the table"
    )]
    OutOfRange {
        /// The format's name.
        format: &'static str,
        /// Where the value is, degrees of the reading.
        angle_deg: f64,
        /// The value, arcseconds.
        arcsec: f64,
        /// The largest magnitude the format holds, arcseconds.
        limit_arcsec: f64,
        /// Why.
        why: &'static str,
    },
    /// The table as the controller would use it leaves as much error as it corrects, or more.
    #[error(
        "as `format = {format}` loads it ({points} entries), this table would leave {left_rms:.3}″ \
         RMS ({left_pp:.3}″ p-p) of the table's {source_rms:.3}″ RMS ({source_pp:.3}″ p-p): it \
         would make the sensor no better or worse, so it was not written. {advice}"
    )]
    NoBetter {
        /// The format's name.
        format: &'static str,
        /// Entries of the output table.
        points: usize,
        /// RMS left, arcseconds.
        left_rms: f64,
        /// Peak to peak left, arcseconds.
        left_pp: f64,
        /// RMS of the source table, arcseconds.
        source_rms: f64,
        /// Peak to peak of the source table, arcseconds.
        source_pp: f64,
        /// What to do.
        advice: String,
    },
    /// The consumer takes a table of one size only.
    #[error("`format = {format}` takes exactly {required} points ({why}); not {given}")]
    Points {
        /// The format's name.
        format: &'static str,
        /// The size it requires.
        required: usize,
        /// The size asked for.
        given: usize,
        /// Where the size comes from.
        why: &'static str,
    },
    /// A chosen order is at or above the output grid's Nyquist order: it would alias.
    #[error(
        "order {order} cannot be held by a table of {points} points, which holds orders below \
         {points}/2 (at most {max}); leave it out of the orders chosen (or export more points, the \
         `points` option, where the format allows)"
    )]
    AboveNyquist {
        /// The order.
        order: usize,
        /// Points of the output grid.
        points: usize,
        /// The highest order the grid holds.
        max: usize,
    },
    /// `format = harmonic` would list no order: every one is below the threshold.
    #[error(
        "no order of the table reaches the `min_amplitude` option's {min_amplitude_arcsec}″ (the \
         largest, order {order}, is {amplitude_arcsec:.6}″): the file would list no order and \
         correct nothing, so it was not written; give a lower `min_amplitude` option (at most \
         {amplitude_arcsec:.6})"
    )]
    NothingListed {
        /// The threshold asked for, arcseconds.
        min_amplitude_arcsec: f64,
        /// The table's largest order.
        order: usize,
        /// Its amplitude, arcseconds.
        amplitude_arcsec: f64,
    },
    /// A chosen order is not in the source table.
    #[error(
        "order {order} is not in the table: a table of {points} points holds orders 1 to \
         {max}; choose the orders among them"
    )]
    NoSuchOrder {
        /// The order.
        order: usize,
        /// Points of the source table.
        points: usize,
        /// Its highest order.
        max: usize,
    },
    /// moteus has no such source.
    #[error(
        "moteus has sources 0 to {} (motor_position.sources.N); not {given}",
        moteus::SOURCES - 1
    )]
    MoteusSource {
        /// The source index asked for.
        given: u8,
    },
    /// The table does not cover one whole revolution but its consumer interpolates over one.
    #[error(
        "{what} needs a table over one whole turn (it is interpolated periodically over \
         0–360°), but this is a range table over {}° to {}° of the reading (a joint that never \
         turned a whole revolution); export it as a look-up table (format `csv`, `lut-f32-rad`, \
         `c-array`, …) without choosing orders, or calibrate over whole turns",
        trimmed(*.start_deg),
        trimmed(*.end_deg)
    )]
    PartialTurn {
        /// What needs it (a format or command).
        what: String,
        /// Where the table starts, degrees.
        start_deg: f64,
        /// Where it ends, degrees.
        end_deg: f64,
    },
}

/// Refuses a table over part of a turn for `what` (a format or a use, named as the library
/// names it) that interpolates it periodically: the one place where range tables are turned
/// away, with an error saying what to do.
pub fn require_whole_revolution(what: &str, map: &TableMap) -> Result<(), ExportError> {
    match map.range_deg() {
        None => Ok(()),
        Some((start_deg, end_deg)) => Err(ExportError::PartialTurn {
            what: what.to_string(),
            start_deg,
            end_deg,
        }),
    }
}

/// Refuses a table that `opts` cannot be written from: formats interpolated periodically, and
/// resynthesis from chosen orders (a Fourier series is periodic), need a whole revolution.
pub fn check_range(opts: &ExportOptions, map: &TableMap) -> Result<(), ExportError> {
    if opts.format.periodic() {
        require_whole_revolution(&format!("`format = {}`", opts.format.name()), map)
    } else if opts.keep != Keep::All {
        require_whole_revolution("choosing orders", map)
    } else {
        Ok(())
    }
}

/// How close a table, decoded and interpolated linearly as its consumer does, is to the source
/// table at the source table's grid points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// Largest difference, radians.
    pub max: f64,
    /// Root mean square difference, radians.
    pub rms: f64,
    /// Peak to peak of the difference (what the sensor is left with), radians.
    pub left_pp: f64,
    /// Root mean square of the source table (what it would be left with uncorrected), radians.
    pub source_rms: f64,
    /// Peak to peak of the source table, radians.
    pub source_pp: f64,
    /// Points of the source table compared.
    pub points: usize,
}

impl Fit {
    /// `decoded` (errors in radians on their own uniform grid, as the consumer holds them)
    /// against `source`, at each of `source`'s grid points.
    pub fn measure(decoded: &[f64], source: &ErrorMap) -> Fit {
        let (mut max, mut sum) = (0.0f64, 0.0);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for (i, &e) in source.values().iter().enumerate() {
            let d = interpolate_periodic(decoded, source.grid_angle(i)) - e;
            max = max.max(d.abs());
            sum += d * d;
            lo = lo.min(d);
            hi = hi.max(d);
        }
        Fit {
            max,
            rms: (sum / source.len() as f64).sqrt(),
            left_pp: hi - lo,
            source_rms: source.rms(),
            source_pp: source.peak_to_peak(),
            points: source.len(),
        }
    }

    /// The fraction of the source's RMS the table leaves: `RMS(source − table) / RMS(source)`
    /// (0 for a source without error).
    pub fn left_fraction(&self) -> f64 {
        if self.source_rms > 0.0 {
            self.rms / self.source_rms
        } else {
            0.0
        }
    }

    fn describe(&self) -> String {
        format!(
            "fit: interpolated linearly as the controller does, this table is within {:.6} arcsec \
             of the source table at its {} points (RMS {:.6} arcsec; it leaves {:.6} arcsec p-p \
             of the table's {:.6} arcsec p-p)",
            self.max * ARCSEC_PER_RAD,
            self.points,
            self.rms * ARCSEC_PER_RAD,
            self.left_pp * ARCSEC_PER_RAD,
            self.source_pp * ARCSEC_PER_RAD
        )
    }
}

/// What a format writes for a table: its own header lines, the body, and the table as its
/// consumer will hold it (errors in radians, on the output grid) for the [`Fit`].
struct Rendered {
    lines: Vec<String>,
    body: String,
    decoded: Vec<f64>,
}

/// Exports `table` (the source table's errors, over a whole turn or a range) as `opts` asks;
/// the pure core of `calib export`. A range table takes only the generic formats with every
/// order ([`check_range`]).
///
/// ```
/// use calib_core::{ErrorMap, angle::ARCSEC_PER_RAD};
/// use calib_io::export::{ExportOptions, Format, export};
///
/// let map = ErrorMap::new((0..720).map(|i| (i as f64).to_radians().sin() / ARCSEC_PER_RAD).collect());
/// let out = export(&map.into(), &ExportOptions::new(Format::Moteus, "example"))?;
/// assert!(out.text.starts_with("conf set motor_position.sources.0.compensation_scale 0\n"));
/// assert_eq!(out.text.lines().count(), 256 + 3);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn export(table: &TableMap, opts: &ExportOptions) -> Result<Export, ExportError> {
    check_range(opts, table)?;
    let format = opts.format;
    let points = match (format.required_points(), opts.points) {
        (Some(required), Some(given)) if given != required => {
            return Err(ExportError::Points {
                format: format.name(),
                required,
                given,
                why: moteus::SIZE_SOURCE,
            });
        }
        (_, Some(given)) => given,
        (_, None) => format.default_points(table),
    };
    let mut header = vec![
        opts.title.clone(),
        "sign: correction = -error (error = reading - true angle); corrected = reading + \
         correction(reading)"
            .to_string(),
    ];
    let map = match table {
        TableMap::Turn(turn) => turn,
        TableMap::Range(range) => {
            // Only the generic formats with every order get here (check_range).
            let (lo, hi) = range.ends_deg();
            header.push(format!(
                "range: {lo:.6} to {hi:.6} deg of the reading (a range table: a joint that never \
                 turns a whole revolution)"
            ));
            header.push(format!(
                "grid: entry i at reading {lo:.6} + i*{}/{} deg (i = 0..{}), both ends included, \
                 step {} deg, not periodic; interpolate linearly inside the range, leave readings \
                 outside it uncorrected",
                trimmed(hi - lo),
                points - 1,
                points - 1,
                trimmed(table.step_deg(points))
            ));
            let rendered = lut::render(table, table.resample(points).values(), opts)?;
            header.extend(rendered.lines);
            return Ok(assemble(format, header, &rendered.body, None, Vec::new()));
        }
    };
    let resampled = || {
        if points == map.len() {
            map.clone()
        } else {
            map.resample_linear(points)
        }
    };
    header.push(format!(
        "grid: entry i at reading i*360/{points} deg (i = 0..{}), 0 at reading 0, step {} deg, \
         periodic; interpolate linearly",
        points - 1,
        360.0 / points as f64
    ));
    if format == Format::Harmonic {
        let resampled = resampled();
        let listing = harmonic::listing(&resampled, opts)?;
        header.extend(listing.lines);
        // What the orders listed leave of the source table, judged as every format's table is.
        let listed = ErrorMap::from_series(&resampled.series().only(&listing.orders), points);
        let fit = Fit::measure(listed.values(), map);
        header.push(format!(
            "fit: the orders listed, summed as the consumer does, leave {:.6} arcsec p-p and \
             {:.6} arcsec RMS of the table's {:.6} arcsec p-p and {:.6} arcsec RMS ({:.2} % of \
             its RMS)",
            fit.left_pp * ARCSEC_PER_RAD,
            fit.rms * ARCSEC_PER_RAD,
            fit.source_pp * ARCSEC_PER_RAD,
            fit.source_rms * ARCSEC_PER_RAD,
            100.0 * fit.left_fraction()
        ));
        let advice = match opts.keep {
            Keep::All => "List more orders: a lower --min-amplitude.",
            Keep::Largest(_) => "List more orders: a larger --harmonics N.",
            Keep::Orders(_) => "List more orders in --orders.",
        };
        let warnings: Vec<String> = judge(&fit, format, points, advice.to_string())?
            .into_iter()
            .collect();
        header.extend(warnings.iter().map(|w| format!("warning: {w}")));
        return Ok(assemble(format, header, &listing.body, Some(fit), warnings));
    }
    // A whole-turn table on a smaller grid keeps the orders the grid holds instead of folding
    // the others onto them.
    let chosen = if opts.keep == Keep::All && points < map.len() {
        harmonic::choose_held(map, points)
    } else {
        harmonic::choose(map, &opts.keep, points)?
    };
    let target = match &chosen {
        Some(chosen) => ErrorMap::from_series(&chosen.series, points),
        None => resampled(),
    };
    let rendered = match format {
        Format::Moteus | Format::MoteusConfig => moteus::render(&target, opts)?,
        Format::Simplefoc | Format::SimplefocFloat => simplefoc::render(&target, opts)?,
        _ => lut::render(table, target.values(), opts)?,
    };
    header.extend(rendered.lines);
    let fit =
        (chosen.is_some() || format.always_fit()).then(|| Fit::measure(&rendered.decoded, map));
    if let Some(chosen) = &chosen {
        header.push(chosen.describe());
    }
    let mut warnings = Vec::new();
    if let Some(fit) = &fit {
        header.push(fit.describe());
        let advice = match &chosen {
            Some(chosen) if chosen.dropped_pp > fit.rms => format!(
                "The orders this {points}-entry table cannot hold are most of it ({}): {}",
                chosen.dropped_summary(),
                if format.required_points().is_some() {
                    "this controller's fixed table cannot correct them; correct them elsewhere \
                     (a finer table in your own firmware: --format lut-*) or accept them"
                } else {
                    "export more --points (a table of N entries holds the orders below N/2)"
                }
            ),
            _ if format == Format::Simplefoc => simplefoc_advice(fit),
            _ => "Check the fit line of the header: the table's quantum (--scale) or its size \
                  (--points) is too coarse for this table."
                .to_string(),
        };
        warnings.extend(judge(fit, format, points, advice)?);
    }
    header.extend(warnings.iter().map(|w| format!("warning: {w}")));
    Ok(assemble(format, header, &rendered.body, fit, warnings))
}

/// What to do about a SimpleFOC table that leaves `fit`: its code is fixed by the driver
/// (19.78″, no `--scale`), so where what is left is about the rounding to it (at most 0.6 of a
/// code RMS; rounding alone leaves 0.29), the cause is the format's quantum, which no option
/// changes; else the table's size.
fn simplefoc_advice(fit: &Fit) -> String {
    let quantum = simplefoc::QUANTUM_RAD * ARCSEC_PER_RAD;
    if fit.rms <= 0.6 * simplefoc::QUANTUM_RAD {
        format!(
            "The cause is the format's quantum: SimpleFOC's uint16 table holds the error in \
             codes of {quantum:.2} arcsec, fixed by the driver (CalibratedSensor's LUT_SCALE; \
             the `scale_arcsec` option does not apply), coarse against this table's error, and the \
             `points` option cannot change that. Load it as it is if that is good enough, or \
             correct this error with a finer table: `format = simplefoc-float` (SimpleFOC \
             releases before PR #75) or a `format = lut-*` table in your own firmware."
        )
    } else {
        "Check the fit line of the header: the table's size (the `points` option) is too coarse \
         for this table (its code, 19.78 arcsec, is fixed by the driver)."
            .to_string()
    }
}

/// The verdict on a table that leaves `fit` of its source (see [Tables that would not
/// help](self#tables-that-would-not-help)): refused if it leaves all of the source's RMS or more,
/// a warning if more than [`WARN_LEFT_FRACTION`] of it; `advice` says what to do.
fn judge(
    fit: &Fit,
    format: Format,
    points: usize,
    advice: String,
) -> Result<Option<String>, ExportError> {
    let arcsec = |x: f64| x * ARCSEC_PER_RAD;
    if fit.left_fraction() >= 1.0 {
        return Err(ExportError::NoBetter {
            format: format.name(),
            points,
            left_rms: arcsec(fit.rms),
            left_pp: arcsec(fit.left_pp),
            source_rms: arcsec(fit.source_rms),
            source_pp: arcsec(fit.source_pp),
            advice,
        });
    }
    Ok((fit.left_fraction() > WARN_LEFT_FRACTION).then(|| {
        format!(
            "as the controller uses it, this table leaves {:.3} arcsec RMS ({:.3} arcsec p-p) of \
             the table's {:.3} arcsec RMS ({:.3} arcsec p-p), {:.0} % of the RMS, more than the \
             {:.0} % calib accepts without a word. {advice}",
            arcsec(fit.rms),
            arcsec(fit.left_pp),
            arcsec(fit.source_rms),
            arcsec(fit.source_pp),
            100.0 * fit.left_fraction(),
            100.0 * WARN_LEFT_FRACTION
        )
    }))
}

/// `x` with at most 9 decimals, trailing zeros dropped (`117.3`, `0.1`).
fn trimmed(x: f64) -> String {
    calib_core::report::trimmed(x, 9)
}

/// The file: the header as comments (where the format has them), then the body.
fn assemble(
    format: Format,
    header: Vec<String>,
    body: &str,
    fit: Option<Fit>,
    warnings: Vec<String>,
) -> Export {
    let mut text = String::new();
    if let Some(comment) = format.comment() {
        for line in &header {
            // Writing into a String cannot fail.
            let _ = writeln!(text, "{comment} {line}");
        }
    }
    text.push_str(body);
    Export {
        text,
        header,
        fit,
        warnings,
    }
}

/// The scales an integer table may be given, arcseconds per LSB: from a microarcsecond (a
/// thousand times finer than any encoder resolves) to a whole turn a code. Beyond them a scale
/// is a typing error, and its messages would print its hundreds of digits.
pub const SCALE_ARCSEC_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=1_296_000.0;

/// Integer codes for `values` (arcseconds) of at most `max_code` in magnitude: the scale
/// (arcseconds per LSB) given, or the smallest that holds the largest value, and
/// `round(value / scale)` for each. A scale too small for the values is refused, never
/// saturated; so is one so large that every code would be 0.
fn quantize(
    values: &[f64],
    max_code: i64,
    scale: Option<f64>,
) -> Result<(f64, Vec<i64>), ExportError> {
    if let Some(scale) = scale.filter(|s| !SCALE_ARCSEC_RANGE.contains(s)) {
        return Err(ExportError::ScaleRange {
            scale_arcsec: scale,
        });
    }
    let largest = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // The smallest scale that fits: the largest value on the largest code.
    let fits = largest / max_code as f64;
    let scale = scale.unwrap_or(if fits > 0.0 { fits } else { 1.0 });
    // From half a code above the largest, rounding would reach the next code.
    if largest / scale >= max_code as f64 + 0.5 {
        return Err(ExportError::Saturated {
            largest_arcsec: largest,
            scale_arcsec: scale,
            code: largest / scale,
            max_code,
            fits,
        });
    }
    // Below half a code every value rounds to 0: a table that corrects nothing.
    if largest > 0.0 && largest / scale < 0.5 {
        return Err(ExportError::ScaleAboveTable {
            largest_arcsec: largest,
            scale_arcsec: scale,
            fits,
            coarsest: 2.0 * largest,
        });
    }
    let codes = values.iter().map(|v| (v / scale).round() as i64).collect();
    Ok((scale, codes))
}

/// The correction at each grid point, arcseconds.
fn corrections(map: &ErrorMap) -> Vec<f64> {
    map.values().iter().map(|e| -e * ARCSEC_PER_RAD).collect()
}

/// `x` in plain decimal notation (no exponent) with 9 significant digits, enough to give back
/// the same `f32`: for consumers whose number parsers are not documented to take exponents.
fn plain_decimal(x: f32) -> String {
    if x == 0.0 {
        return "0".into();
    }
    let magnitude = f64::from(x.abs()).log10().floor() as i32;
    let decimals = (8 - magnitude).max(0) as usize;
    calib_core::report::trimmed(f64::from(x), decimals)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_turns_are_refused_where_the_format_is_periodic() {
        let turn = TableMap::from(ErrorMap::new(vec![0.0; 4]));
        assert!(require_whole_revolution("x", &turn).is_ok());
        let d = f64::to_radians;
        let range = TableMap::from(
            calib_core::RangeMap::new(d(30.0), d(20.0), vec![1.0, 0.0, -1.0, 0.0]).unwrap(),
        );
        let err = require_whole_revolution("`format = moteus`", &range).unwrap_err();
        let text = err.to_string();
        assert!(
            text.contains("`format = moteus`") && text.contains("30° to 90°"),
            "{text}"
        );
        let mut opts = ExportOptions::new(Format::Csv, "t");
        assert!(check_range(&opts, &range).is_ok());
        opts.keep = Keep::Largest(2);
        assert!(check_range(&opts, &range).is_err());
        for format in [Format::Harmonic, Format::Simplefoc, Format::MoteusConfig] {
            assert!(check_range(&ExportOptions::new(format, "t"), &range).is_err());
        }
    }

    #[test]
    fn quantization_refuses_to_saturate() {
        let (scale, codes) = quantize(&[12.7, -6.35, 0.0], 127, None).unwrap();
        assert!((scale - 0.1).abs() < 1e-15);
        assert_eq!(codes, vec![127, -64, 0]);
        // 127.5 codes would round to 128: refused, naming the scale that fits.
        let err = quantize(&[12.75], 127, Some(0.1)).unwrap_err();
        assert!(err.to_string().contains("1.003937e-1"), "{err}");
        assert!(quantize(&[12.74], 127, Some(0.1)).is_ok());
    }

    #[test]
    fn tables_that_leave_their_error_are_refused_and_those_that_leave_much_warned() {
        let fit = |rms: f64| Fit {
            max: 2.0 * rms,
            rms,
            left_pp: 4.0 * rms,
            source_rms: 1.0,
            source_pp: 3.0,
            points: 360,
        };
        let judged = |rms| judge(&fit(rms), Format::Moteus, 256, "do this".into());
        assert_eq!(judged(0.25).unwrap(), None);
        let warning = judged(0.5).unwrap().unwrap();
        assert!(warning.contains("50 % of the RMS") && warning.ends_with("do this"));
        assert!(matches!(
            judged(1.0),
            Err(ExportError::NoBetter { points: 256, .. })
        ));
        let err = judged(1.5).unwrap_err().to_string();
        assert!(
            err.contains("no better or worse") && err.ends_with("do this"),
            "{err}"
        );
        // A source without error leaves nothing to judge.
        let flat = Fit {
            source_rms: 0.0,
            ..fit(0.0)
        };
        assert_eq!(flat.left_fraction(), 0.0);
    }

    /// A scale far out of range is refused with the range, in a line, not with the 300-digit
    /// code it would need (`--scale 1e-300`) or its own 300 digits (`--scale 1e300`).
    #[test]
    fn a_scale_out_of_range_is_refused_with_the_range() {
        for scale in [1e-300, 1e300, 5e-7, 1.3e6] {
            let err = quantize(&[12.0, -3.0], 127, Some(scale)).unwrap_err();
            assert!(matches!(err, ExportError::ScaleRange { .. }), "{err}");
            let text = err.to_string();
            assert!(
                text.contains("1e-6 to 1.296e6") && text.len() < 300,
                "{text}"
            );
        }
        // Its ends are accepted.
        assert!(quantize(&[12.0, -3.0], 32767, Some(1e-3)).is_ok());
        assert!(quantize(&[1e6, -3.0], 127, Some(1_296_000.0)).is_ok());
    }

    #[test]
    fn a_scale_that_zeroes_every_code_is_refused() {
        let err = quantize(&[12.0, -3.0], 127, Some(24.5)).unwrap_err();
        assert!(matches!(err, ExportError::ScaleAboveTable { .. }));
        let text = err.to_string();
        assert!(
            text.contains("12.000000″") && text.contains("2.400000e1"),
            "{text}"
        );
        // Up to twice the largest, one code is left.
        assert_eq!(
            quantize(&[12.0, -3.0], 127, Some(23.9)).unwrap().1,
            vec![1, 0]
        );
    }

    #[test]
    fn plain_decimals_give_back_the_same_f32() {
        for x in [5.817764e-5f32, 1.0, 0.3, 123.456, 9.999999e-9, -2.5e-6] {
            let s = plain_decimal(x);
            assert!(!s.contains('e'), "{s}");
            assert_eq!(s.parse::<f32>().unwrap(), x, "{s}");
        }
        assert_eq!(plain_decimal(0.0), "0");
    }
}

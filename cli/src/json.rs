//! The `--json` outputs of `simulate`, `export`, `import`, `apply` and `compose` (a method's is its report.json):
//! each a type here, with its published schema in `docs/` (`crate::schema`), rendered with its
//! keys in alphabetical order at every depth, as report.json is.

use calib_core::angle::ARCSEC_PER_RAD;
use schemars::JsonSchema;
use serde::Serialize;

/// `value` as a command prints it: pretty JSON, keys sorted at every depth, a final newline.
pub fn render<T: Serialize>(value: &T) -> anyhow::Result<String> {
    Ok(calib_io::report::render_json(&serde_json::to_value(
        value,
    )?)?)
}

/// `calib export --json`: what was written and how closely it holds the table.
#[derive(Debug, Serialize, JsonSchema)]
pub struct ExportJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The table exported, as given.
    pub table: String,
    /// The format written (`--format`).
    pub format: String,
    /// The file written.
    pub output: String,
    /// The lines of the file's header (moteus's go to the terminal instead): sign, grid, the
    /// format's facts, harmonics, fit, warnings.
    pub header: Vec<String>,
    /// How closely the table, decoded and interpolated as its controller does, holds the source
    /// table; absent where the format reproduces it exactly.
    pub fit: Option<FitJson>,
    /// What the user should know about the table.
    pub warnings: Vec<String>,
}

/// How closely an exported table holds its source, at the source's grid points.
#[derive(Debug, Serialize, JsonSchema)]
pub struct FitJson {
    /// Largest difference, arcsec.
    pub max_arcsec: f64,
    /// RMS difference, arcsec.
    pub rms_arcsec: f64,
    /// Peak-to-peak the sensor is left with after this table's correction, arcsec.
    pub left_peak_to_peak_arcsec: f64,
    /// Peak-to-peak of the source table, arcsec.
    pub source_peak_to_peak_arcsec: f64,
    /// Points of the source table compared.
    pub points: usize,
}

impl From<&calib_io::export::Fit> for FitJson {
    fn from(f: &calib_io::export::Fit) -> Self {
        FitJson {
            max_arcsec: f.max * ARCSEC_PER_RAD,
            rms_arcsec: f.rms * ARCSEC_PER_RAD,
            left_peak_to_peak_arcsec: f.left_pp * ARCSEC_PER_RAD,
            source_peak_to_peak_arcsec: f.source_pp * ARCSEC_PER_RAD,
            points: f.points,
        }
    }
}

/// `calib apply --json`: what was corrected and what was copied.
#[derive(Debug, Serialize, JsonSchema)]
pub struct ApplyJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The log corrected, as given.
    pub log: String,
    /// The correction table, as given.
    pub table: String,
    /// The corrected log written.
    pub output: String,
    /// The channel corrected.
    pub channel: String,
    /// The unit of its readings (as `--unit` names it).
    pub unit: String,
    /// Readings corrected.
    pub corrected: u64,
    /// Readings outside a range table's range, copied unchanged (0 for a whole-turn table).
    pub outside: u64,
    /// The smallest and largest reading before correction, in `unit`.
    pub range: [f64; 2],
    /// How the corrected readings are wrapped: `positive` ([0, 1 rev)), `signed`
    /// ([−½, ½ rev)) or `unwrapped`.
    pub wrapping: String,
    /// With `--keep`: the CSV column or MCAP topics holding the corrected readings beside the
    /// unchanged channel; empty without it.
    pub beside: Vec<String>,
    /// MCAP messages copied unchanged (other topics', and those without the channel); absent
    /// for CSV.
    pub copied: Option<u64>,
    /// What the user should know: an early end, damaged chunks left out, readings outside the
    /// table's range.
    pub warnings: Vec<String>,
    /// Parts of the log that hold no reading of the channel, copied unchanged.
    pub notes: Vec<String>,
}

/// `calib compose --json`: the table written and how it compares with applying the two in turn.
#[derive(Debug, Serialize, JsonSchema)]
pub struct ComposeJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The table in use, as given.
    pub first: String,
    /// The residual table measured with the first applied, as given.
    pub residual: String,
    /// The factor the residual is applied with (`--factor`).
    pub factor: f64,
    /// The composed table written.
    pub output: String,
    /// Points of the composed table.
    pub points: usize,
    /// Peak-to-peak of the composed error map, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// Its RMS, arcsec.
    pub rms_arcsec: f64,
    /// Mean offset of the composed correction from applying the two tables in turn, arcsec (the
    /// mean every table drops).
    pub sequential_offset_arcsec: f64,
    /// Largest departure from applying the two in turn beyond that offset, arcsec.
    pub sequential_deviation_arcsec: f64,
    /// How far adding the two tables instead would be off, at most, arcsec.
    pub adding_off_arcsec: f64,
    /// Whether the composed table has a `u_arcsec` column (both tables had one).
    pub uncertainty: bool,
}

/// `calib simulate --json`: the log written and the true error tables beside it.
#[derive(Debug, Serialize, JsonSchema)]
pub struct SimulateJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The scenario, as given.
    pub scenario: String,
    /// The log written.
    pub output: String,
    /// Samples written.
    pub samples: u64,
    /// The log's channels, in order.
    pub channels: Vec<String>,
    /// The true error table of each sensor, in `<log stem>.truth/` beside the log.
    pub truth: Vec<TruthJson>,
}

/// One sensor's true error table, written by `calib simulate`.
#[derive(Debug, Serialize, JsonSchema)]
pub struct TruthJson {
    /// The sensor's channel.
    pub channel: String,
    /// The table written.
    pub table: String,
    /// Whether it is a range table (a joint that swept less than a whole turn).
    pub range: bool,
    /// Peak-to-peak of the true error, arcsec.
    pub peak_to_peak_arcsec: f64,
}

/// `calib import --json`: the table read and written.
#[derive(Debug, Serialize, JsonSchema)]
pub struct ImportJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The file read, as given.
    pub file: String,
    /// Its format (`--format`).
    pub format: String,
    /// The calib table written.
    pub output: String,
    /// Points of the table.
    pub points: usize,
    /// What the file said of itself (a SimpleFOC table's `zero_electric_angle`, a scale read
    /// from a header, …).
    pub notes: Vec<String>,
    /// Peak-to-peak of the error, arcsec.
    pub peak_to_peak_arcsec: f64,
    /// Its RMS, arcsec.
    pub rms_arcsec: f64,
}

//! `calib export`: a correction table in the forms controllers load.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::ErrorMap;
use calib_core::angle::{ARCSEC_PER_RAD, DEG_PER_RAD};
use std::f64::consts::PI;
use std::fmt::Write;
use std::path::PathBuf;

/// The output form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
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
    /// The correction's largest harmonics: `order,amplitude_arcsec,phase_deg` rows.
    Harmonic,
}

/// Export a correction table (from any method) in a form a controller loads.
///
/// Every output starts with a comment stating the sign convention (correction = −error, applied
/// as reading + correction(reading)), the grid (entry i at reading i·360/N degrees), the units
/// and, for integer look-up tables, the scale. Integer formats refuse to saturate: a scale too
/// small for the table is an error naming the smallest that fits.
///
/// A range table (a joint that never turns a whole revolution) exports the same way, its header
/// naming the range (entry i at reading LO + i·(HI − LO)/(N − 1), both ends included, nothing
/// outside); `harmonic` refuses it, since a Fourier series needs a whole turn.
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The correction table (`angle_deg,error_arcsec,correction_arcsec[,u_arcsec]`).
    pub table: PathBuf,
    /// The output form.
    #[arg(long, value_enum)]
    pub format: Format,
    /// Points of the output grid (default: the table's); resampled by periodic linear
    /// interpolation.
    #[arg(long)]
    pub points: Option<usize>,
    /// Arcseconds per LSB of integer formats (default: the smallest that fits the table).
    #[arg(long)]
    pub scale: Option<f64>,
    /// `harmonic`: keep the K largest orders (default: all of at least --min-amplitude).
    #[arg(long)]
    pub orders: Option<usize>,
    /// `harmonic`: smallest amplitude kept, arcseconds.
    #[arg(long, default_value_t = 0.01)]
    pub min_amplitude: f64,
    /// Output file (default: standard output).
    #[arg(short, long = "output")]
    pub output: Option<PathBuf>,
}

/// Largest `--points` accepted.
const MAX_POINTS: usize = 3_600_000;

/// Runs `calib export`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if args.points.is_some_and(|p| !(2..=MAX_POINTS).contains(&p)) {
        return Err(Usage(format!("--points must be between 2 and {MAX_POINTS}")).into());
    }
    if args.scale.is_some_and(|s| !(s.is_finite() && s > 0.0)) {
        return Err(Usage("--scale must be a positive number of arcseconds per LSB".into()).into());
    }
    if !(args.min_amplitude.is_finite() && args.min_amplitude >= 0.0) || args.orders == Some(0) {
        return Err(
            Usage("--min-amplitude must be at least 0 and --orders at least 1".into()).into(),
        );
    }
    if !args.table.exists() {
        return Err(Usage(format!(
            "{}: no such file; check the path",
            args.table.display()
        ))
        .into());
    }
    let table = calib_io::table::read_any_table(&args.table)
        .with_context(|| format!("cannot read {}", args.table.display()))?;
    let text = match table {
        calib_io::table::AnyTable::Turn(table) => {
            let map = match args.points {
                Some(n) if n != table.map.len() => table.map.resample_linear(n),
                _ => table.map,
            };
            render(args, &map, Grid::Turn)
        }
        calib_io::table::AnyTable::Range(table) => {
            if args.format == Format::Harmonic {
                return Err(Usage(format!(
                    "{} is a range table ({:.6}° to {:.6}°): a joint that never turned a whole revolution has no \
                     Fourier series (harmonics need the whole turn); export it as a look-up table (e.g. --format lut-f32-rad \
                     or csv)",
                    args.table.display(),
                    table.map.start().to_degrees(),
                    table.map.end().to_degrees()
                ))
                .into());
            }
            let m = &table.map;
            let n = args.points.unwrap_or(m.len());
            // Resampled linearly over the range, both ends kept.
            let values = (0..n)
                .map(|i| {
                    m.eval_linear(m.start() + m.span() * i as f64 / (n - 1) as f64)
                        .unwrap_or(0.0)
                })
                .collect();
            render(
                args,
                &ErrorMap::new(values),
                Grid::Range {
                    lo: m.start().to_degrees(),
                    hi: m.end().to_degrees(),
                },
            )
        }
    }
    .with_context(|| format!("{}", args.table.display()))?;
    match &args.output {
        Some(path) => {
            calib_io::atomic::write_atomic(path, text.as_bytes())?;
            Ok(format!("wrote {}\n", path.display()))
        }
        None => Ok(text),
    }
}

/// The correction at each grid point, arcseconds.
fn corrections(map: &ErrorMap) -> Vec<f64> {
    map.values().iter().map(|e| -e * ARCSEC_PER_RAD).collect()
}

/// `x` with at most 9 decimals, trailing zeros dropped (`117.3`, `0.1`).
fn trimmed(x: f64) -> String {
    let s = format!("{x:.9}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Where the entries of an export lie.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Grid {
    /// Entry i at i·360/N, periodic.
    Turn,
    /// Entry i at lo + i·(hi − lo)/(N − 1), degrees, both ends included.
    Range { lo: f64, hi: f64 },
}

impl Grid {
    fn angle(self, i: usize, n: usize) -> f64 {
        match self {
            Grid::Turn => 360.0 * i as f64 / n as f64,
            Grid::Range { lo, hi } => lo + (hi - lo) * i as f64 / (n - 1) as f64,
        }
    }
    fn step(self, n: usize) -> f64 {
        match self {
            Grid::Turn => 360.0 / n as f64,
            Grid::Range { lo, hi } => (hi - lo) / (n - 1) as f64,
        }
    }
}

/// The export as text (pure). `map` holds the values on `grid` (for a range, its values are not
/// periodic and its mean is the mean over the range).
fn render(args: &Args, map: &ErrorMap, grid: Grid) -> anyhow::Result<String> {
    let n = map.len();
    let c = corrections(map);
    let comment = if args.format == Format::CArray {
        "//"
    } else {
        "#"
    };
    let mut o = String::new();
    let mut head = |line: String| {
        let _ = writeln!(o, "{comment} {line}");
    };
    head(format!(
        "calib {} export of {}",
        env!("CARGO_PKG_VERSION"),
        args.table.display()
    ));
    head(
        "sign: correction = -error (error = reading - true angle); corrected = reading + correction(reading)"
            .into(),
    );
    match grid {
        Grid::Turn => head(format!(
            "grid: entry i at reading i*360/{n} deg (i = 0..{}), 0 at reading 0, step {} deg, periodic; interpolate linearly",
            n - 1,
            360.0 / n as f64
        )),
        Grid::Range { lo, hi } => {
            head(format!(
                "range: {lo:.6} to {hi:.6} deg of the reading (a range table: a joint that never turns a whole revolution)"
            ));
            head(format!(
                "grid: entry i at reading {lo:.6} + i*{}/{} deg (i = 0..{}), both ends included, step {} deg, not periodic; \
                 interpolate linearly inside the range, leave readings outside it uncorrected",
                trimmed(hi - lo),
                n - 1,
                n - 1,
                trimmed(grid.step(n))
            ));
        }
    }
    let codes = |max_code: i64, offset: i64| -> anyhow::Result<(f64, Vec<i64>)> {
        let largest = c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        // The smallest scale that fits: the largest |correction| on the largest code.
        let fits = largest / max_code as f64;
        let scale = args.scale.unwrap_or(if fits > 0.0 { fits } else { 1.0 });
        if largest / scale > max_code as f64 + 0.5 {
            return Err(Usage(format!(
                "the largest |correction| is {largest:.6}″, which at --scale {scale} ″/LSB needs code {:.0}, beyond ±{max_code}; \
                 use --scale {fits:.6e} or larger",
                largest / scale
            ))
            .into());
        }
        Ok((
            scale,
            c.iter()
                .map(|v| (v / scale).round() as i64 + offset)
                .collect(),
        ))
    };
    let mut body = String::new();
    match args.format {
        Format::LutF32Rad => {
            head(format!("units: radians (f32), one per line, {n} lines"));
            for v in &c {
                let _ = writeln!(body, "{:e}", (v / ARCSEC_PER_RAD) as f32);
            }
        }
        Format::LutI16 | Format::LutU16 | Format::LutI8 => {
            let (max_code, offset, kind) = match args.format {
                Format::LutI16 => (i64::from(i16::MAX), 0, "int16"),
                Format::LutU16 => (i64::from(i16::MAX), 32768, "uint16 offset binary"),
                _ => (i64::from(i8::MAX), 0, "int8"),
            };
            let (scale, codes) = codes(max_code, offset)?;
            head(format!("units: {kind} codes, one per line, {n} lines"));
            if offset == 0 {
                head(format!("scale: correction_arcsec = code * {scale:e}"));
            } else {
                head(format!(
                    "scale: correction_arcsec = (code - {offset}) * {scale:e}"
                ));
            }
            for k in codes {
                let _ = writeln!(body, "{k}");
            }
        }
        Format::CArray => {
            head("units: arcseconds (float)".into());
            let _ = writeln!(body, "#define CALIB_CORRECTION_POINTS {n}");
            let _ = writeln!(body, "#define CALIB_CORRECTION_STEP_DEG {:e}", grid.step(n));
            if let Grid::Range { lo, hi } = grid {
                let _ = writeln!(body, "#define CALIB_CORRECTION_START_DEG {lo:e}");
                let _ = writeln!(body, "#define CALIB_CORRECTION_END_DEG {hi:e}");
            }
            let _ = writeln!(
                body,
                "static const float calib_correction_arcsec[CALIB_CORRECTION_POINTS] = {{"
            );
            for chunk in c.chunks(8) {
                let row: Vec<String> = chunk.iter().map(|v| format!("{v:.6}f")).collect();
                let _ = writeln!(body, "    {},", row.join(", "));
            }
            let _ = writeln!(body, "}};");
        }
        Format::Csv => {
            head("units: degrees, arcseconds".into());
            let _ = writeln!(body, "angle_deg,correction_arcsec");
            for (i, v) in c.iter().enumerate() {
                let _ = writeln!(body, "{:.6},{v:.6}", grid.angle(i, n));
            }
        }
        Format::Harmonic => {
            // The correction is −error: same amplitudes, phases turned by 180°.
            let mut hs: Vec<(usize, f64, f64)> = map
                .series()
                .harmonics()
                .iter()
                .map(|h| {
                    let phase = (h.phase + PI).rem_euclid(2.0 * PI);
                    let phase = if phase > PI { phase - 2.0 * PI } else { phase };
                    (h.order, h.amplitude * ARCSEC_PER_RAD, phase * DEG_PER_RAD)
                })
                .collect();
            hs.sort_by(|a, b| b.1.total_cmp(&a.1));
            let keep = match args.orders {
                Some(k) => k.min(hs.len()),
                None => hs.iter().filter(|h| h.1 >= args.min_amplitude).count(),
            };
            let total_ms = c.iter().map(|v| v * v).sum::<f64>() / n as f64;
            let kept_ms = hs[..keep].iter().map(|h| h.1 * h.1 / 2.0).sum::<f64>();
            head("units: amplitude arcseconds, phase degrees; correction(θ) = Σ amplitude·cos(order·θ + phase), θ the reading".into());
            head(format!(
                "kept: {keep} of {} orders, largest first; dropped: {} orders, RMS {:.6} arcsec",
                hs.len(),
                hs.len() - keep,
                (total_ms - kept_ms).max(0.0).sqrt()
            ));
            let _ = writeln!(body, "order,amplitude_arcsec,phase_deg");
            for (order, a, p) in &hs[..keep] {
                let _ = writeln!(body, "{order},{a:.6},{p:.6}");
            }
        }
    }
    o.push_str(&body);
    Ok(o)
}

//! `calib compose`: one table for a table in use followed by the residual calibrated through it.

use crate::exit::Usage;
use crate::json::ComposeJson;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::compose::{CHECK_POINTS_PER_STEP, compose, compose_uncertainty};
use calib_core::{ErrorMap, TableMap};
use calib_io::export::require_whole_revolution;
use calib_io::limits::readable;
use calib_io::table::{Table, read_table};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Compose the table a controller applies with the residual calibrated through it.
///
/// Refining a table in use: the controller corrects readings with T1, a new log of the corrected
/// readings is calibrated (the residual, a function of the corrected reading), and the table to
/// load next is T1 followed by the residual — not T1 plus the residual, which reads the residual
/// at the wrong angle (off by the residual's slope times T1's error: tenths of an arcsecond for
/// errors of hundreds). In calib's terms (error = reading − true angle):
///
///   e₂(r) = e₁(r) + F·e_R(r − e₁(r)),
///
/// at every grid point, both tables interpolated linearly and periodically as `calib apply` and
/// the controllers do. At its grid points the result is exact; between them it departs from
/// applying the two tables in turn by at most the residual's own interpolation error, and the
/// summary says how much it was (checked at 16 points per grid step). Like every table the
/// result has zero mean: the constant removed is printed.
///
/// --factor F takes part of the residual (a partial update, as moteus users refine a table with
/// an incremental factor). Where both tables have u_arcsec, the result's is the root-sum-square
/// √(u₁² + (F·u_R)²), u_R read where the residual is; if only one has it, it is dropped (noted).
///
/// Example: `calib compose calib-out/a.csv recal/a.csv -o a-next.csv`
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The table the controller applies now (T1).
    pub first: PathBuf,
    /// The residual: a table calibrated from readings T1 corrected (a log recorded with T1
    /// loaded, or `calib apply T1` of one).
    pub residual: PathBuf,
    /// The composed table to write.
    #[arg(short, long = "output", value_name = "FILE")]
    pub output: PathBuf,
    /// Print what was composed as JSON (docs/compose.schema.json) instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Replace FILE even if calib did not write it (without it, a file there that no calib
    /// manifest of its folder lists is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
    /// The part of the residual to take: 1 for all of it, less for a partial update.
    #[arg(long, default_value_t = 1.0)]
    pub factor: f64,
    /// Points of the composed table (default: the larger of the two tables' counts).
    #[arg(long)]
    pub points: Option<usize>,
}

/// Runs `calib compose`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    if !(args.factor.is_finite() && args.factor > 0.0 && args.factor <= 2.0) {
        return Err(Usage(format!(
            "--factor {} is not in (0, 2]: 1 takes the whole residual, less a part of it",
            readable(args.factor)
        ))
        .into());
    }
    crate::input::check_points(args.points)?;
    crate::overwrite::check(
        &args.output,
        &format!("-o {}", crate::ui::shown(&args.output)),
    )?;
    let _lock = crate::output::prepare_file(&args.output, "-o")?;
    let first = load(&args.first)?;
    let residual = load(&args.residual)?;
    let points = args
        .points
        .unwrap_or(first.map.len().max(residual.map.len()));
    let done = compose(&first.map, &residual.map, args.factor, points);
    let (u, u_note) = match (&first.u, &residual.u) {
        (Some(u1), Some(ur)) => (
            Some(compose_uncertainty(&first.map, u1, ur, args.factor, points)),
            "u_arcsec: root-sum-square of both tables' (√(u₁² + (F·u_R)²))",
        ),
        (None, None) => (None, ""),
        _ => (
            None,
            "u_arcsec: dropped — only one of the tables has it, and the other's is unknown",
        ),
    };
    calib_io::table::write_table(&args.output, &done.map.clone().into(), u.as_deref())
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    crate::output::record_written([&args.output]);

    let arcsec = |x: f64| x * ARCSEC_PER_RAD;
    let describe = |t: &Table<ErrorMap>, path: &Path| {
        format!(
            "{} ({} points, {:.3}″ peak to peak)",
            path.display(),
            t.map.len(),
            arcsec(t.map.peak_to_peak())
        )
    };
    // What adding the tables would have given, to show why they are composed instead.
    let added = calib_core::ErrorMap::new(
        (0..points)
            .map(|i| {
                let r = done.map.grid_angle(i);
                first.map.eval_linear(r) + args.factor * residual.map.eval_linear(r)
            })
            .collect(),
    );
    let adding_off = added.minus(&done.map).max_abs_arcsec();
    if args.json {
        return crate::json::render(&ComposeJson {
            schema_version: calib_core::report::SCHEMA_VERSION,
            first: args.first.display().to_string(),
            residual: args.residual.display().to_string(),
            factor: args.factor,
            output: args.output.display().to_string(),
            points,
            peak_to_peak_arcsec: arcsec(done.map.peak_to_peak()),
            rms_arcsec: arcsec(done.map.rms()),
            sequential_offset_arcsec: arcsec(done.offset),
            sequential_deviation_arcsec: arcsec(done.deviation),
            adding_off_arcsec: adding_off,
            uncertainty: u.is_some(),
        });
    }
    let mut o = String::new();
    let _ = writeln!(
        o,
        "composed {} then {} (factor {})",
        describe(&first, &args.first),
        describe(&residual, &args.residual),
        readable(args.factor)
    );
    let _ = writeln!(
        o,
        "  e₂(r) = e₁(r) + F·e_R(r − e₁(r)) on {points} points: {:.3}″ peak to peak, {:.3}″ RMS",
        arcsec(done.map.peak_to_peak()),
        arcsec(done.map.rms())
    );
    let _ = writeln!(
        o,
        "  against applying the two in turn: readings {:+.4}″ apart (the mean every table \
         drops), and within {:.4}″ of that between grid points ({} checked per step)",
        arcsec(done.offset),
        arcsec(done.deviation),
        CHECK_POINTS_PER_STEP
    );
    let _ = writeln!(
        o,
        "  adding the tables instead would be off by up to {adding_off:.4}″"
    );
    if !u_note.is_empty() {
        let _ = writeln!(o, "  {u_note}");
    }
    let _ = writeln!(o, "wrote {}", args.output.display());
    Ok(o)
}

/// Reads a table for composition, which needs it over one whole revolution.
fn load(path: &Path) -> anyhow::Result<Table<ErrorMap>> {
    if !path.exists() {
        return Err(Usage(format!("{}: no such table; check the path", path.display())).into());
    }
    let table = read_table(path).with_context(|| format!("cannot read {}", path.display()))?;
    match table.map {
        TableMap::Turn(map) => Ok(Table { map, u: table.u }),
        // A range table cannot be composed periodically.
        range => {
            let why = require_whole_revolution("calib compose", &range)
                .err()
                .map_or_else(|| "not a whole-turn table".to_string(), |e| e.to_string());
            Err(Usage(format!("{}: {why}", path.display())).into())
        }
    }
}

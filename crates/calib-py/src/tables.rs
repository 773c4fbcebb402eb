//! Correction tables (read, write, apply, export, compose) and the simulator.
//!
//! A table crosses into Python as its errors in arcseconds on a uniform grid, its standard
//! uncertainties where known, and its range: none for a whole turn (the grid `i·360°/N`), or the
//! first and last grid readings in degrees (`lo + (hi − lo)·i/(N − 1)`, signed across the
//! reading 0 as the CSV table writes them). Inside, a [`TableMap`] in radians.

use crate::errors::{array_error, check_points, data, usage};
use calib_core::RangeMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::{ErrorMap, TableMap, compose::compose_uncertainty};
use calib_io::export::{ExportOptions, Format, Keep};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// Refuses a table the CLI's table reader would refuse ([`calib_io::table::table_problem`]):
/// an `ArrayError` (a `UsageError` and a `ValueError`) naming the argument and index.
fn check_table_of(
    errors_arcsec: &[f64],
    u_arcsec: Option<&[f64]>,
    range_deg: Option<(f64, f64)>,
) -> PyResult<()> {
    match calib_io::table::table_problem(errors_arcsec, u_arcsec, range_deg) {
        None => Ok(()),
        Some(why) => Err(array_error(why)),
    }
}

/// Checks a table as it is made (`calib.Table`): [`check_table_of`].
#[pyfunction]
#[pyo3(signature = (error_arcsec, u_arcsec=None, range_deg=None))]
pub fn check_table(
    error_arcsec: PyReadonlyArray1<'_, f64>,
    u_arcsec: Option<PyReadonlyArray1<'_, f64>>,
    range_deg: Option<(f64, f64)>,
) -> PyResult<()> {
    let u = u_arcsec.as_ref().map(|u| u.as_slice()).transpose()?;
    check_table_of(error_arcsec.as_slice()?, u, range_deg)
}

/// The errors given in arcseconds as radians, checked as a table's would be.
fn radians_of(errors_arcsec: &[f64]) -> PyResult<Vec<f64>> {
    check_table_of(errors_arcsec, None, None)?;
    Ok(errors_arcsec.iter().map(|e| e / ARCSEC_PER_RAD).collect())
}

/// The whole-turn map of errors given in arcseconds.
fn map_of(errors_arcsec: &[f64]) -> PyResult<ErrorMap> {
    Ok(ErrorMap::new(radians_of(errors_arcsec)?))
}

/// A table's map: a whole turn, or the range `(lo, hi)` (degrees, both ends grid points).
fn table_map(errors_arcsec: &[f64], range_deg: Option<(f64, f64)>) -> PyResult<TableMap> {
    let values = radians_of(errors_arcsec)?;
    let Some((lo, hi)) = range_deg else {
        return Ok(TableMap::Turn(ErrorMap::new(values)));
    };
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(usage(format!(
            "range_deg=({lo}, {hi}) is not a range: give (first, last) grid readings in \
                 degrees, first < last"
        )));
    }
    let step = (hi - lo).to_radians() / (values.len() - 1) as f64;
    RangeMap::new(lo.to_radians(), step, values)
        .map(TableMap::Range)
        .map_err(|e| usage(format!("range_deg=({lo}, {hi}): {e}")))
}

/// Arcseconds of radians.
fn arcsec(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| v * ARCSEC_PER_RAD).collect()
}

/// A table's errors, its uncertainties where it has them (arcseconds), and its range (degrees,
/// `None` for a whole turn).
type Columns<'py> = (
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    Option<(f64, f64)>,
);

/// Reads a correction table of either kind: `(error_arcsec, u_arcsec or None, range_deg or
/// None)`.
#[pyfunction]
pub fn read_table(py: Python<'_>, path: PathBuf) -> PyResult<Columns<'_>> {
    if !path.exists() {
        return Err(usage(format!(
            "{}: no such file; check the path",
            path.display()
        )));
    }
    let table = calib_io::table::read_table(&path).map_err(|e| data(e.to_string()))?;
    Ok((
        PyArray1::from_vec(py, arcsec(table.map.values())),
        table.u.as_ref().map(|u| PyArray1::from_vec(py, arcsec(u))),
        table.map.range_deg(),
    ))
}

/// Writes a correction table, whole-turn or over `range_deg` (atomically: complete or not at
/// all).
#[pyfunction]
#[pyo3(signature = (path, error_arcsec, u_arcsec=None, range_deg=None))]
pub fn write_table(
    path: PathBuf,
    error_arcsec: PyReadonlyArray1<'_, f64>,
    u_arcsec: Option<PyReadonlyArray1<'_, f64>>,
    range_deg: Option<(f64, f64)>,
) -> PyResult<()> {
    let map = table_map(error_arcsec.as_slice()?, range_deg)?;
    let u: Option<Vec<f64>> = u_arcsec
        .map(|u| {
            u.as_slice()
                .map(|u| u.iter().map(|v| v / ARCSEC_PER_RAD).collect())
        })
        .transpose()?;
    let text = calib_io::table::render_table(&map, u.as_deref())
        .map_err(|e| usage(format!("{}: {e}", path.display())))?;
    calib_io::atomic::write_atomic(&path, text.as_bytes())
        .map_err(|e| data(format!("cannot write {}: {e}", path.display())))
}

/// Corrects `readings` (radians) with the table: `r − e(r)`, the table interpolated linearly
/// (periodically for a whole turn); a range table leaves readings outside its range unchanged
/// (what `calib apply` and a controller do).
#[pyfunction]
#[pyo3(signature = (error_arcsec, readings, range_deg=None))]
pub fn correct<'py>(
    py: Python<'py>,
    error_arcsec: PyReadonlyArray1<'py, f64>,
    readings: PyReadonlyArray1<'py, f64>,
    range_deg: Option<(f64, f64)>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let map = table_map(error_arcsec.as_slice()?, range_deg)?;
    let r = readings.as_slice()?;
    // `r − e(r)`; a range map leaves readings outside its range unchanged, as `calib apply`.
    let out: Vec<f64> = py.detach(|| {
        r.iter()
            .map(|&x| map.eval_linear(x).map_or(x, |e| x - e))
            .collect()
    });
    Ok(PyArray1::from_vec(py, out))
}

/// The table in a controller's format, as `calib export` writes it: `(text, header lines)`.
#[pyfunction]
#[pyo3(signature = (error_arcsec, format, *, range_deg=None, points=None, scale=None, orders=None, largest=None, min_amplitude=0.01, moteus_source=0, title="calib correction table".to_string()))]
#[allow(clippy::too_many_arguments)]
pub fn export(
    error_arcsec: PyReadonlyArray1<'_, f64>,
    format: &str,
    range_deg: Option<(f64, f64)>,
    points: Option<usize>,
    scale: Option<f64>,
    orders: Option<Vec<usize>>,
    largest: Option<usize>,
    min_amplitude: f64,
    moteus_source: u8,
    title: String,
) -> PyResult<(String, Vec<String>)> {
    // As `calib export`: every format that needs a whole turn refuses a range.
    let map = table_map(error_arcsec.as_slice()?, range_deg)?;
    let Some(format) = Format::from_name(format) else {
        let names: Vec<&str> = Format::ALL.iter().map(|f| f.name()).collect();
        return Err(usage(format!(
            "format=`{format}` is not a format calib exports; give one of {}",
            names.join(", ")
        )));
    };
    check_points(points)?;
    if scale.is_some_and(|s| !(s > 0.0 && s.is_finite())) {
        return Err(usage(
            "scale must be a positive number of arcseconds per LSB",
        ));
    }
    let keep = match (orders, largest) {
        (Some(_), Some(_)) => return Err(usage("give orders or largest, not both")),
        (Some(o), None) => Keep::Orders(o),
        (None, Some(k)) => Keep::Largest(k),
        (None, None) => Keep::All,
    };
    let opts = ExportOptions {
        points,
        scale_arcsec: scale,
        keep,
        min_amplitude_arcsec: min_amplitude,
        moteus_source,
        ..ExportOptions::new(format, title)
    };
    // The library names the scale by its field, `scale_arcsec`; here it is `scale`.
    let out = calib_io::export::export(&map, &opts).map_err(|e| {
        usage(
            e.to_string()
                .replace("`scale_arcsec = ", "`scale = ")
                .replace("`scale_arcsec` option", "`scale` option"),
        )
    })?;
    Ok((out.text, out.header))
}

/// What [`compose`] returns: the composed errors, their uncertainties where both tables have
/// them, the offset and the deviation (arcseconds).
type Composed<'py> = (
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    f64,
    f64,
);

/// One map for the map already in use followed by the residual calibrated through it
/// (`calib compose`): `(error_arcsec, u_arcsec or None, offset_arcsec, deviation_arcsec)`, the
/// uncertainty `√(u₁² + (F·u_R)²)` where both tables have one (as `calib compose`).
#[pyfunction]
#[pyo3(signature = (first_arcsec, residual_arcsec, factor=1.0, points=None, first_u_arcsec=None, residual_u_arcsec=None))]
pub fn compose<'py>(
    py: Python<'py>,
    first_arcsec: PyReadonlyArray1<'py, f64>,
    residual_arcsec: PyReadonlyArray1<'py, f64>,
    factor: f64,
    points: Option<usize>,
    first_u_arcsec: Option<PyReadonlyArray1<'py, f64>>,
    residual_u_arcsec: Option<PyReadonlyArray1<'py, f64>>,
) -> PyResult<Composed<'py>> {
    let first = map_of(first_arcsec.as_slice()?)?;
    let residual = map_of(residual_arcsec.as_slice()?)?;
    if !factor.is_finite() {
        return Err(usage("factor must be a finite number"));
    }
    check_points(points)?;
    let radians = |u: &[f64]| u.iter().map(|v| v / ARCSEC_PER_RAD).collect::<Vec<_>>();
    let u = match (first_u_arcsec, residual_u_arcsec) {
        (Some(u1), Some(ur)) => Some((radians(u1.as_slice()?), radians(ur.as_slice()?))),
        _ => None,
    };
    let points = points.unwrap_or(first.len().max(residual.len()));
    let c = calib_core::compose::compose(&first, &residual, factor, points);
    let u2 = u.map(|(u1, ur)| compose_uncertainty(&first, &u1, &ur, factor, points));
    Ok((
        PyArray1::from_vec(py, arcsec(c.map.values())),
        u2.map(|u| PyArray1::from_vec(py, arcsec(&u))),
        c.offset * ARCSEC_PER_RAD,
        c.deviation * ARCSEC_PER_RAD,
    ))
}

/// Simulates a scenario (TOML text, or its JSON from a dict): every sample and each sensor's
/// true error table (`points` points).
#[pyfunction]
#[pyo3(signature = (text, is_json, points=36000))]
pub fn simulate<'py>(
    py: Python<'py>,
    text: &str,
    is_json: bool,
    points: usize,
) -> PyResult<Bound<'py, PyDict>> {
    check_points(Some(points))?;
    let source = Path::new("<scenario>");
    let scenario = if is_json {
        let s: calib_core::simulate::Scenario =
            serde_json::from_str(text).map_err(|e| usage(format!("scenario: {e}")))?;
        s.validate().map_err(|e| usage(format!("scenario: {e}")))?;
        s
    } else {
        calib_io::scenario::parse_scenario(text, source).map_err(|e| usage(e.to_string()))?
    };
    let channels = scenario.channels();
    let (t, values, sessions, truth) = py
        .detach(|| {
            let samples = scenario.samples()?;
            let mut t = Vec::with_capacity(samples.len());
            let mut values = vec![Vec::with_capacity(samples.len()); channels.len()];
            let mut sessions = Vec::new();
            for s in samples {
                t.push(s.t);
                for (column, v) in values.iter_mut().zip(&s.values) {
                    column.push(*v);
                }
                if scenario.mark_sessions {
                    sessions.push(s.session.map_or(-1, i64::from));
                }
            }
            let truth = scenario.truth(points)?;
            Ok::<_, calib_core::simulate::ScenarioError>((t, values, sessions, truth))
        })
        .map_err(|e| usage(format!("scenario: {e}")))?;
    let out = PyDict::new(py);
    out.set_item("t", PyArray1::from_vec(py, t))?;
    let columns = PyDict::new(py);
    for (c, column) in channels.iter().zip(values) {
        columns.set_item(&c.name, PyArray1::from_vec(py, column))?;
    }
    out.set_item("channels", columns)?;
    out.set_item(
        "session",
        scenario
            .mark_sessions
            .then(|| PyArray1::from_vec(py, sessions)),
    )?;
    let truths = PyDict::new(py);
    for (name, map) in truth {
        truths.set_item(name, PyArray1::from_vec(py, arcsec(map.values())))?;
    }
    out.set_item("truth", truths)?;
    Ok(out)
}

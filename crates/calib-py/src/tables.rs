//! Correction tables (read, write, apply, export, compose) and the simulator.
//!
//! A table crosses into Python as its errors on the uniform grid `i·360°/N`, arcseconds, and
//! its standard uncertainties where known; inside, an [`ErrorMap`] in radians.

use crate::errors::{check_points, data, usage};
use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_io::export::{ExportOptions, Format, Keep};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// Every export format, by the name `calib export --format` takes.
const FORMATS: [Format; 11] = [
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

/// The map of errors given in arcseconds, checked as a table's would be.
fn map_of(errors_arcsec: &[f64]) -> PyResult<ErrorMap> {
    if errors_arcsec.len() < 2 {
        return Err(usage("a table needs at least 2 points"));
    }
    if let Some(i) = errors_arcsec.iter().position(|e| !e.is_finite()) {
        return Err(usage(format!(
            "the error at grid point {i} is {}, not a finite number",
            errors_arcsec[i]
        )));
    }
    Ok(ErrorMap::new(
        errors_arcsec.iter().map(|e| e / ARCSEC_PER_RAD).collect(),
    ))
}

/// Arcseconds of radians.
fn arcsec(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| v * ARCSEC_PER_RAD).collect()
}

/// A table's errors and, where it has them, uncertainties (arcseconds).
type Columns<'py> = (Bound<'py, PyArray1<f64>>, Option<Bound<'py, PyArray1<f64>>>);

/// Reads a whole-turn correction table: `(error_arcsec, u_arcsec or None)` on its grid.
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
        table.u.map(|u| PyArray1::from_vec(py, arcsec(&u))),
    ))
}

/// Writes a whole-turn correction table (atomically: complete or not at all).
#[pyfunction]
#[pyo3(signature = (path, error_arcsec, u_arcsec=None))]
pub fn write_table(
    path: PathBuf,
    error_arcsec: PyReadonlyArray1<'_, f64>,
    u_arcsec: Option<PyReadonlyArray1<'_, f64>>,
) -> PyResult<()> {
    let map = map_of(error_arcsec.as_slice()?)?;
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
/// and periodically (what `calib apply` and a controller do).
#[pyfunction]
pub fn correct<'py>(
    py: Python<'py>,
    error_arcsec: PyReadonlyArray1<'py, f64>,
    readings: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let map = map_of(error_arcsec.as_slice()?)?;
    let r = readings.as_slice()?;
    let out: Vec<f64> = py.detach(|| r.iter().map(|&x| x - map.eval_linear(x)).collect());
    Ok(PyArray1::from_vec(py, out))
}

/// The table in a controller's format, as `calib export` writes it: `(text, header lines)`.
#[pyfunction]
#[pyo3(signature = (error_arcsec, format, *, points=None, scale=None, orders=None, largest=None, min_amplitude=0.01, moteus_source=0, title="calib correction table".to_string()))]
#[allow(clippy::too_many_arguments)]
pub fn export(
    error_arcsec: PyReadonlyArray1<'_, f64>,
    format: &str,
    points: Option<usize>,
    scale: Option<f64>,
    orders: Option<Vec<usize>>,
    largest: Option<usize>,
    min_amplitude: f64,
    moteus_source: u8,
    title: String,
) -> PyResult<(String, Vec<String>)> {
    let map = map_of(error_arcsec.as_slice()?)?;
    let Some(&format) = FORMATS.iter().find(|f| f.name() == format) else {
        let names: Vec<&str> = FORMATS.iter().map(|f| f.name()).collect();
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
    let out = calib_io::export::export(&map, &opts).map_err(|e| usage(e.to_string()))?;
    Ok((out.text, out.header))
}

/// One map for the map already in use followed by the residual calibrated through it
/// (`calib compose`): `(error_arcsec, offset_arcsec, deviation_arcsec)`.
#[pyfunction]
#[pyo3(signature = (first_arcsec, residual_arcsec, factor=1.0, points=None))]
pub fn compose<'py>(
    py: Python<'py>,
    first_arcsec: PyReadonlyArray1<'py, f64>,
    residual_arcsec: PyReadonlyArray1<'py, f64>,
    factor: f64,
    points: Option<usize>,
) -> PyResult<(Bound<'py, PyArray1<f64>>, f64, f64)> {
    let first = map_of(first_arcsec.as_slice()?)?;
    let residual = map_of(residual_arcsec.as_slice()?)?;
    if !factor.is_finite() {
        return Err(usage("factor must be a finite number"));
    }
    check_points(points)?;
    let points = points.unwrap_or(first.len().max(residual.len()));
    let c = calib_core::compose::compose(&first, &residual, factor, points);
    Ok((
        PyArray1::from_vec(py, arcsec(c.map.values())),
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

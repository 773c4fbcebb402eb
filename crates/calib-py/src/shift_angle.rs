//! The shift-angle method (polygon + autocollimator) on a readings file: `shift_angle`
//! (`calib shift-angle`).

use crate::errors::{data, usage};
use calib_core::Report;
use calib_core::shift_angle::Method;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Cross-calibration of an encoder and a polygon from autocollimator readings (see
/// `calib.shift_angle`).
#[pyfunction]
#[pyo3(signature = (path, *, method="joint", faces=None, budget=None))]
pub fn shift_angle<'py>(
    py: Python<'py>,
    path: PathBuf,
    method: &str,
    faces: Option<usize>,
    budget: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let method = match method {
        "joint" => Method::Joint,
        "paper" => Method::Paper,
        other => {
            return Err(usage(format!(
                "method=`{other}`: give \"joint\" (one constrained fit) or \"paper\" (the \
                 paper's two steps)"
            )));
        }
    };
    for p in std::iter::once(&path).chain(&budget) {
        if !p.exists() {
            return Err(usage(format!(
                "{}: no such file; check the path",
                p.display()
            )));
        }
    }
    let budget = budget
        .as_ref()
        .map(|b| {
            let read = calib_io::budget::read_budget(b).map_err(|e| data(e.to_string()))?;
            calib_core::uncertainty::evaluate(&read)
                .map_err(|e| data(format!("{}: {e}", b.display())))
        })
        .transpose()?;
    let readings =
        calib_io::readings::read_readings(&path, faces).map_err(|e| data(e.to_string()))?;
    let what = path.display().to_string();
    let result = py
        .detach(|| calib_core::shift_angle::calibrate(&readings, method))
        .map_err(|e| data(format!("{what}: {e}")))?;
    calib_io::shift_angle::check_values(&result).map_err(|e| data(format!("{what}: {e}")))?;
    let report = Report::new(
        result.report_section(&readings, budget.as_ref()),
        vec![what],
        None,
        Vec::new(),
    );
    let json = calib_io::report::render_json(&report).map_err(|e| data(e.to_string()))?;
    let out = PyDict::new(py);
    out.set_item("report_json", json)?;
    let p = &result.points;
    let n = p.len();
    let uniform = p
        .iter()
        .enumerate()
        .all(|(i, q)| (q.angle_deg - 360.0 * i as f64 / n as f64).abs() < 1e-6);
    let u: Option<Vec<f64>> = match &budget {
        Some(b) => Some(vec![b.combined_standard_uncertainty; n]),
        None => p.iter().map(|q| q.u_arcsec).collect(),
    };
    let table = PyDict::new(py);
    table.set_item(
        "angle_deg",
        PyArray1::from_vec(py, p.iter().map(|q| q.angle_deg).collect()),
    )?;
    table.set_item(
        "error_arcsec",
        PyArray1::from_vec(py, p.iter().map(|q| q.error_arcsec).collect()),
    )?;
    table.set_item("u_arcsec", u.map(|u| PyArray1::from_vec(py, u)))?;
    table.set_item("range", !uniform)?;
    let tables = PyDict::new(py);
    for name in report.channels.keys() {
        tables.set_item(name, &table)?;
    }
    out.set_item("tables", tables)?;
    let polygon = PyDict::new(py);
    let faces = &result.polygon;
    polygon.set_item(
        "face",
        PyArray1::from_vec(py, faces.iter().map(|f| f.face as i64).collect()),
    )?;
    polygon.set_item(
        "pitch_deviation_arcsec",
        PyArray1::from_vec(py, faces.iter().map(|f| f.pitch_deviation_arcsec).collect()),
    )?;
    out.set_item("polygon", polygon)?;
    Ok(out)
}

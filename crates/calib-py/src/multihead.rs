//! Multi-head self-calibration on arrays and on logs: `multihead`, `multihead_log`
//! (`calib multihead`).

use crate::errors::{check_points, check_readings, data, usage};
use crate::logs::{LogOptions, LogRead, for_each_sample, log_read, open};
use crate::methods::{result, same_length, turn};
use calib_core::multihead::{Head, Method, Multihead, MultiheadCalibration, MultiheadOptions};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The heads (name, nominal angle in degrees) and options, checked as `calib multihead` checks
/// its `--heads`, `--sets` and options.
pub(crate) fn options(
    heads: &[(String, f64)],
    method: &str,
    sets: Option<Vec<Vec<String>>>,
    max_order: Option<usize>,
    points: Option<usize>,
    min_observability: f64,
) -> PyResult<(Vec<Head>, MultiheadOptions)> {
    let mut list: Vec<Head> = Vec::new();
    for (name, deg) in heads {
        if !deg.is_finite() {
            return Err(usage(format!(
                "heads: the nominal angle of `{name}` is {deg}, not a finite number of degrees"
            )));
        }
        if list.iter().any(|h| h.name == *name) {
            return Err(usage(format!(
                "heads names `{name}` twice; name each head once"
            )));
        }
        list.push(Head {
            name: name.clone(),
            nominal: deg.to_radians(),
        });
    }
    if list.len() < 2 {
        return Err(usage(format!(
            "heads names {} head(s); a multi-head calibration needs at least 2",
            list.len()
        )));
    }
    let method = match method {
        "joint" => Method::Joint,
        "eda" => Method::Eda,
        other => {
            return Err(usage(format!(
                "method=`{other}`: give \"joint\" (joint least squares) or \"eda\" (the SelfA \
                 paper's equal-division average)"
            )));
        }
    };
    if sets.is_some() && method != Method::Eda {
        return Err(usage(
            "sets is for method=\"eda\"; the joint method uses every head at once",
        ));
    }
    let sets = sets
        .map(|sets| {
            sets.iter()
                .map(|set| {
                    set.iter()
                        .map(|name| {
                            list.iter().position(|h| h.name == *name).ok_or_else(|| {
                                usage(format!("sets: `{name}` is not one of the heads"))
                            })
                        })
                        .collect::<PyResult<Vec<_>>>()
                })
                .collect::<PyResult<Vec<_>>>()
        })
        .transpose()?;
    if max_order == Some(0) {
        return Err(usage("max_order=0 is outside its range, 1 or more"));
    }
    check_points(points)?;
    if !(0.0..1.0).contains(&min_observability) {
        return Err(usage(format!(
            "min_observability={} is outside its range, 0 to 1 (excluded)",
            calib_io::limits::readable(min_observability)
        )));
    }
    let opts = MultiheadOptions {
        method,
        max_order,
        min_observability,
        points,
        sets,
        ..MultiheadOptions::default()
    };
    Multihead::new(list.clone(), opts.clone()).map_err(|e| usage(e.to_string()))?;
    Ok((list, opts))
}

/// The result dictionary of a multi-head calibration: the table of the scale as the first
/// head reads it.
fn multihead_result<'py>(
    py: Python<'py>,
    cal: &MultiheadCalibration,
    heads: &[Head],
    inputs: Vec<String>,
    warnings: Vec<String>,
    read: LogRead,
) -> PyResult<Bound<'py, PyDict>> {
    let section = cal
        .report_section(heads)
        .with_alignment(read.alignment)
        .with_reading(read.reading)
        .with_time_origin(read.time_origin_s);
    let table = turn(&heads[0].name, &cal.map, Some(&cal.uncertainty.u));
    result(py, section, inputs, warnings, &[table])
}

/// The heads' names joined, for messages.
fn joined(heads: &[Head]) -> String {
    heads
        .iter()
        .map(|h| h.name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Multi-head self-calibration from arrays (see `calib.multihead`).
#[pyfunction]
#[pyo3(signature = (names, readings, nominal_deg, *, method="joint", sets=None, max_order=None, points=None, min_observability=0.01))]
#[allow(clippy::too_many_arguments)]
pub fn multihead<'py>(
    py: Python<'py>,
    names: Vec<String>,
    readings: Vec<PyReadonlyArray1<'py, f64>>,
    nominal_deg: Vec<f64>,
    method: &str,
    sets: Option<Vec<Vec<String>>>,
    max_order: Option<usize>,
    points: Option<usize>,
    min_observability: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let specs: Vec<(String, f64)> = names.into_iter().zip(nominal_deg).collect();
    let (heads, opts) = options(&specs, method, sets, max_order, points, min_observability)?;
    let columns = readings
        .iter()
        .map(|r| r.as_slice())
        .collect::<Result<Vec<_>, _>>()?;
    let n = columns.first().map_or(0, |c| c.len());
    for (h, c) in heads.iter().zip(&columns) {
        same_length(&h.name, c, n)?;
        check_readings(&h.name, c)?;
    }
    let cal = py.detach(|| {
        let mut mh = Multihead::new(heads.clone(), opts).map_err(|e| e.to_string())?;
        let mut row = vec![0.0; columns.len()];
        for i in 0..n {
            for (r, c) in row.iter_mut().zip(&columns) {
                *r = c[i];
            }
            mh.push(&row);
        }
        mh.finish().map_err(|e| e.to_string())
    });
    let cal = cal.map_err(|e| data(format!("the arrays: heads {}: {e}", joined(&heads))))?;
    multihead_result(py, &cal, &heads, vec![], vec![], LogRead::default())
}

/// Multi-head self-calibration of a log's head channels (see `calib.multihead_log`).
#[pyfunction]
#[pyo3(signature = (path, names, nominal_deg, *, method="joint", sets=None, max_order=None, points=None, min_observability=0.01, unit=None, time="header", max_gap=None, time_column=None, time_unit=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn multihead_log<'py>(
    py: Python<'py>,
    path: Bound<'py, PyAny>,
    names: Vec<String>,
    nominal_deg: Vec<f64>,
    method: &str,
    sets: Option<Vec<Vec<String>>>,
    max_order: Option<usize>,
    points: Option<usize>,
    min_observability: f64,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    storage_options: Option<std::collections::HashMap<String, String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let specs: Vec<(String, f64)> = names.into_iter().zip(nominal_deg).collect();
    let (heads, opts) = options(&specs, method, sets, max_order, points, min_observability)?;
    let log = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = crate::logs::LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    let channel_names: Vec<String> = heads.iter().map(|h| h.name.clone()).collect();
    let reader = py.detach(|| open(&input, Some(&channel_names), &log))?;
    let what = path.display().to_string();
    let (cal, reader) = py
        .detach(|| {
            let mut mh = Multihead::new(heads.clone(), opts).map_err(|e| e.to_string())?;
            let reader = for_each_sample(&path, reader, |s| mh.push(s.values))?;
            let cal = mh
                .finish()
                .map_err(|e| format!("{what}: heads {}: {e}", joined(&heads)))?;
            Ok::<_, String>((cal, reader))
        })
        .map_err(data)?;
    multihead_result(
        py,
        &cal,
        &heads,
        vec![what],
        reader.warnings(&path),
        log_read(&reader),
    )
}

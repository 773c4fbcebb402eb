//! The spin-down (TDR) method on arrays and on logs: `tdr`, `tdr_log` (`calib tdr`).

use crate::errors::{check_array, check_points, check_readings, data, usage};
use crate::logs::{LogOptions, LogRead, for_each_sample, log_read, open};
use crate::methods::{result, same_length, turn};
use calib_core::tdr::{MotorOrders, RunKind, Tdr, TdrCalibration, TdrOptions};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The largest `max_order`, `max_drag_order` and `motion_degree` (the CLI's).
const MAX_ORDER: usize = 1000;
const MAX_DRAG_ORDER: usize = 100;
const MAX_DEGREE: usize = 60;

/// The TDR options from the keyword arguments, checked as `calib tdr` checks its options.
pub(crate) fn options(
    max_order: Option<usize>,
    max_drag_order: usize,
    motion_degree: Option<usize>,
    min_revolutions: f64,
    points: Option<usize>,
    (run, pole_pairs, cogging_orders): (&str, Option<usize>, Option<Vec<usize>>),
) -> PyResult<TdrOptions> {
    let (run, motor) = driven_options(run, pole_pairs, cogging_orders)?;
    check_points(points)?;
    if let Some(h) = max_order.filter(|h| !(1..=MAX_ORDER).contains(h)) {
        return Err(usage(format!(
            "max_order={h} is outside its range, 1 to {MAX_ORDER}"
        )));
    }
    if max_drag_order > MAX_DRAG_ORDER {
        return Err(usage(format!(
            "max_drag_order={max_drag_order} is outside its range, 0 to {MAX_DRAG_ORDER}"
        )));
    }
    if let Some(p) = motion_degree.filter(|p| !(1..=MAX_DEGREE).contains(p)) {
        return Err(usage(format!(
            "motion_degree={p} is outside its range, 1 to {MAX_DEGREE}"
        )));
    }
    if !(min_revolutions.is_finite() && min_revolutions >= 1.0) {
        return Err(usage(format!(
            "min_revolutions={} is outside its range, 1 or more",
            calib_io::limits::readable(min_revolutions)
        )));
    }
    Ok(TdrOptions {
        max_order,
        max_drag_order,
        motion_degree,
        points,
        min_revolutions,
        run,
        motor,
        ..TdrOptions::default()
    })
}

/// Checks that `tdr_log`'s `channel` and `ref` are two different channels.
pub(crate) fn tdr_channels(channel: &str, r#ref: Option<&str>) -> PyResult<()> {
    if r#ref == Some(channel) {
        return Err(usage(format!(
            "channel and ref both name `{channel}`: name the encoder to calibrate and a different \
             reference"
        )));
    }
    Ok(())
}

/// The driven run's options (`run`, `pole_pairs`, `cogging_orders`), checked as `calib tdr`
/// checks `--run`, `--pole-pairs` and `--cogging-orders`.
fn driven_options(
    run: &str,
    pole_pairs: Option<usize>,
    cogging_orders: Option<Vec<usize>>,
) -> PyResult<(RunKind, MotorOrders)> {
    let run = match run {
        "auto" => RunKind::Auto,
        "coast" => RunKind::Coast,
        "driven" => RunKind::Driven,
        other => {
            return Err(usage(format!(
                "run={other:?} is not one of \"auto\", \"coast\", \"driven\""
            )));
        }
    };
    let motor = match (pole_pairs, cogging_orders) {
        (Some(_), Some(_)) => {
            return Err(usage(
                "pole_pairs and cogging_orders both given: name the motor's orders one way",
            ));
        }
        (Some(p), None) if !(1..=MAX_ORDER / 6).contains(&p) => {
            return Err(usage(format!(
                "pole_pairs={p} is outside its range, 1 to {}",
                MAX_ORDER / 6
            )));
        }
        (Some(p), None) => MotorOrders::PolePairs(p),
        (None, Some(list)) => {
            if let Some(k) = list.iter().find(|k| !(1..=MAX_ORDER).contains(*k)) {
                return Err(usage(format!(
                    "cogging_orders holds {k}, outside 1 to {MAX_ORDER}"
                )));
            }
            MotorOrders::Orders(list)
        }
        (None, None) => MotorOrders::None,
    };
    Ok((run, motor))
}

/// The result dictionary of a TDR calibration.
fn tdr_result<'py>(
    py: Python<'py>,
    cal: &TdrCalibration,
    (channel, reference, max_drag_order): (&str, Option<&str>, usize),
    inputs: Vec<String>,
    warnings: Vec<String>,
    read: LogRead,
) -> PyResult<Bound<'py, PyDict>> {
    let section = cal
        .report_section(channel, reference, max_drag_order)
        .with_alignment(read.alignment)
        .with_reading(read.reading)
        .with_time_origin(read.time_origin_s);
    let table = turn(channel, &cal.map, Some(&cal.uncertainty.u));
    result(py, section, inputs, warnings, &[table])
}

/// Spin-down self-calibration of one encoder from arrays (see `calib.tdr`).
#[pyfunction]
#[pyo3(signature = (t, readings, r#ref=None, *, name="encoder".to_string(), max_order=None, max_drag_order=16, motion_degree=None, min_revolutions=10.0, points=None, run="auto", pole_pairs=None, cogging_orders=None))]
#[allow(clippy::too_many_arguments)]
pub fn tdr<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    readings: PyReadonlyArray1<'py, f64>,
    r#ref: Option<PyReadonlyArray1<'py, f64>>,
    name: String,
    max_order: Option<usize>,
    max_drag_order: usize,
    motion_degree: Option<usize>,
    min_revolutions: f64,
    points: Option<usize>,
    run: &str,
    pole_pairs: Option<usize>,
    cogging_orders: Option<Vec<usize>>,
) -> PyResult<Bound<'py, PyDict>> {
    let (t, x) = (t.as_slice()?, readings.as_slice()?);
    check_array("t", t, calib_io::limits::Samples::Stamps)?;
    same_length("readings", x, t.len())?;
    check_readings("readings", x)?;
    let r = r#ref.as_ref().map(|r| r.as_slice()).transpose()?;
    if let Some(r) = r {
        same_length("ref", r, t.len())?;
        check_readings("ref", r)?;
    }
    let opts = options(
        max_order,
        max_drag_order,
        motion_degree,
        min_revolutions,
        points,
        (run, pole_pairs, cogging_orders),
    )?;
    let cal = py.detach(|| {
        let mut tdr = Tdr::new(opts);
        for i in 0..t.len() {
            match r {
                Some(r) => tdr.push_with_reference(t[i], x[i], r[i]),
                None => tdr.push(t[i], x[i]),
            }
        }
        tdr.finish()
    });
    let cal = cal.map_err(|e| data(format!("the arrays: channel `{name}`: {e}")))?;
    let reference = r.map(|_| "ref");
    tdr_result(
        py,
        &cal,
        (&name, reference, max_drag_order),
        vec![],
        vec![],
        LogRead::default(),
    )
}

/// Spin-down self-calibration of a log's channel (see `calib.tdr_log`).
#[pyfunction]
#[pyo3(signature = (path, *, channel, r#ref=None, max_order=None, max_drag_order=16, motion_degree=None, min_revolutions=10.0, points=None, unit=None, time="header", max_gap=None, time_column=None, time_unit=None, run="auto", pole_pairs=None, cogging_orders=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn tdr_log<'py>(
    py: Python<'py>,
    path: Bound<'py, PyAny>,
    channel: String,
    r#ref: Option<String>,
    max_order: Option<usize>,
    max_drag_order: usize,
    motion_degree: Option<usize>,
    min_revolutions: f64,
    points: Option<usize>,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    run: &str,
    pole_pairs: Option<usize>,
    cogging_orders: Option<Vec<usize>>,
    storage_options: Option<std::collections::HashMap<String, String>>,
) -> PyResult<Bound<'py, PyDict>> {
    tdr_channels(&channel, r#ref.as_deref())?;
    let opts = options(
        max_order,
        max_drag_order,
        motion_degree,
        min_revolutions,
        points,
        (run, pole_pairs, cogging_orders),
    )?;
    let log = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = crate::logs::LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    let mut names = vec![channel.clone()];
    names.extend(r#ref.clone());
    let reader = py.detach(|| open(&input, Some(&names), &log))?;
    let what = path.display().to_string();
    let with_ref = r#ref.is_some();
    let (cal, reader) = py
        .detach(|| {
            let mut tdr = Tdr::new(opts);
            let reader = for_each_sample(&path, reader, |s| {
                if with_ref {
                    tdr.push_with_reference(s.t, s.values[0], s.values[1]);
                } else {
                    tdr.push(s.t, s.values[0]);
                }
            })?;
            let cal = tdr
                .finish()
                .map_err(|e| format!("{what}: channel `{channel}`: {e}"))?;
            Ok::<_, String>((cal, reader))
        })
        .map_err(data)?;
    tdr_result(
        py,
        &cal,
        (&channel, r#ref.as_deref(), max_drag_order),
        vec![what],
        reader.warnings(&path),
        log_read(&reader),
    )
}

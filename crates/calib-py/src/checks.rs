//! The options of each `*_log` method checked without a log: `calib.map_logs` calls these once,
//! before it sends any log to a worker, so that a bad option is one error at once, naming it,
//! rather than the same failure on every log of a fleet.
//!
//! Each function takes its method's keyword arguments (`path` left out) and runs the checks
//! the method itself runs before it opens the log, through the same functions.

use crate::logs::LogOptions;
use crate::methods::{
    CsrrArgs, csrr_channels, gear_of, latency_of, reference_channels, reference_options,
};
use pyo3::prelude::*;

/// Checks `csrr_log`'s options. A CSV `session` column is not known without the log: sessions
/// are taken as found from the motion, which changes no check.
#[pyfunction]
#[pyo3(signature = (*, a="a".to_string(), b="b".to_string(), r#ref=None, method="joint", max_order=None, points=None, session_tol=None, min_speed=1.0, detect_sessions=false, min_observability=0.01, benchmarks=(0.0, 0.0), latency=None, unit=None, time="header", max_gap=None, time_column=None, time_unit=None))]
#[allow(clippy::too_many_arguments)]
pub fn check_csrr_log(
    a: String,
    b: String,
    r#ref: Option<String>,
    method: &str,
    max_order: Option<usize>,
    points: Option<usize>,
    session_tol: Option<f64>,
    min_speed: f64,
    detect_sessions: bool,
    min_observability: f64,
    benchmarks: (f64, f64),
    latency: Option<Bound<'_, PyAny>>,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
) -> PyResult<()> {
    latency_of(latency.as_ref())?;
    csrr_channels(&a, &b, r#ref.as_deref())?;
    LogOptions::new(unit, time, max_gap, time_column, time_unit, None)?;
    CsrrArgs::new(
        method,
        max_order,
        points,
        session_tol,
        min_speed,
        min_observability,
        benchmarks,
        r#ref.is_some(),
        !detect_sessions,
    )?;
    Ok(())
}

/// Checks `reference_log`'s options.
#[pyfunction]
#[pyo3(signature = (*, dut, r#ref, ref_u=None, points=3600, min_speed=1.0, follow_tol=5.0, bridge_gap=5.0, targets=None, approach=1.0, latency=None, ref_kind="encoder", pole_pairs=None, ref_ratio=None, ref_orders=16, unit=None, time="header", max_gap=None, time_column=None, time_unit=None))]
#[allow(clippy::too_many_arguments)]
pub fn check_reference_log(
    dut: String,
    r#ref: String,
    ref_u: Option<f64>,
    points: usize,
    min_speed: f64,
    follow_tol: f64,
    bridge_gap: f64,
    targets: Option<Bound<'_, PyAny>>,
    approach: f64,
    latency: Option<Bound<'_, PyAny>>,
    ref_kind: &str,
    pole_pairs: Option<u32>,
    ref_ratio: Option<Bound<'_, PyAny>>,
    ref_orders: usize,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
) -> PyResult<()> {
    reference_channels(&dut, &r#ref)?;
    gear_of(ref_ratio.as_ref(), ref_orders)?;
    reference_options(
        ref_u,
        points,
        min_speed,
        follow_tol,
        bridge_gap,
        targets.as_ref(),
        approach,
        (latency.as_ref(), ref_kind, pole_pairs),
    )?;
    LogOptions::new(unit, time, max_gap, time_column, time_unit, None)?;
    Ok(())
}

/// Checks `tdr_log`'s options.
#[pyfunction]
#[pyo3(signature = (*, channel, r#ref=None, max_order=None, max_drag_order=16, motion_degree=None, min_revolutions=10.0, points=None, unit=None, time="header", max_gap=None, time_column=None, time_unit=None, run="auto", pole_pairs=None, cogging_orders=None))]
#[allow(clippy::too_many_arguments)]
pub fn check_tdr_log(
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
) -> PyResult<()> {
    crate::tdr::tdr_channels(&channel, r#ref.as_deref())?;
    crate::tdr::options(
        max_order,
        max_drag_order,
        motion_degree,
        min_revolutions,
        points,
        (run, pole_pairs, cogging_orders),
    )?;
    LogOptions::new(unit, time, max_gap, time_column, time_unit, None)?;
    Ok(())
}

/// Checks `multihead_log`'s options (the heads as `names` and `nominal_deg`, as it takes them).
#[pyfunction]
#[pyo3(signature = (names, nominal_deg, *, method="joint", sets=None, max_order=None, points=None, min_observability=0.01, unit=None, time="header", max_gap=None, time_column=None, time_unit=None))]
#[allow(clippy::too_many_arguments)]
pub fn check_multihead_log(
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
) -> PyResult<()> {
    let specs: Vec<(String, f64)> = names.into_iter().zip(nominal_deg).collect();
    crate::multihead::options(&specs, method, sets, max_order, points, min_observability)?;
    LogOptions::new(unit, time, max_gap, time_column, time_unit, None)?;
    Ok(())
}

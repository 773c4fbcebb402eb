//! The methods on arrays and on logs: `csrr`, `csrr_log`, `reference`, `reference_log`.
//!
//! Each returns a dictionary: `report_json` (report.json as the CLI writes it, without its
//! `command_line`), and `tables`, one per calibrated channel, each its grid (`angle_deg`), errors
//! (`error_arcsec`) and standard uncertainties (`u_arcsec`, or `None`).

use crate::errors::{
    check_array, check_non_negative, check_points, check_range, check_readings, data, usage,
};
use crate::logs::{LogOptions, LogRead, for_each_sample, log_read, open, reopen};
use calib_core::Report;
use calib_core::TableMap;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::csrr::{Csrr, CsrrError, CsrrOptions, Method};
use calib_core::reference_cal::{
    Gear, Latency, Ratio, ReferenceKind, ReferenceOptions, ReferenceRun, Targets,
};
use calib_core::report::ReportSection;
use calib_core::segment::SegmentOptions;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// One output table: the channel's name, its errors on a grid starting at `start` (radians)
/// with `step` between points, and the standard uncertainties (radians) where known.
pub struct OutTable<'a> {
    pub name: &'a str,
    pub start: f64,
    pub step: f64,
    pub errors: &'a [f64],
    pub u: Option<&'a [f64]>,
}

/// The result dictionary of a method: its report (`inputs` as given) and its tables.
pub fn result<'py>(
    py: Python<'py>,
    section: ReportSection,
    inputs: Vec<String>,
    warnings: Vec<String>,
    tables: &[OutTable],
) -> PyResult<Bound<'py, PyDict>> {
    let report = Report::new(section, inputs, None, warnings);
    let json = calib_io::report::render_json(&report).map_err(|e| data(e.to_string()))?;
    let out = PyDict::new(py);
    out.set_item("report_json", json)?;
    let all = PyDict::new(py);
    for t in tables {
        let table = PyDict::new(py);
        let n = t.errors.len();
        let is_range = t.step * n as f64 + 1e-12 < std::f64::consts::TAU;
        let (mut lo, step) = (t.start.to_degrees(), t.step.to_degrees());
        // A range across the reading 0 in its signed form, as the CSV table (never above 360°).
        if is_range && lo + step * (n - 1) as f64 > 360.0 {
            lo -= 360.0;
        }
        let angles: Vec<f64> = (0..n).map(|i| lo + step * i as f64).collect();
        let range_deg = is_range.then(|| (angles[0], angles[n - 1]));
        let arcsec = |v: &[f64]| v.iter().map(|x| x * ARCSEC_PER_RAD).collect::<Vec<_>>();
        table.set_item("angle_deg", PyArray1::from_vec(py, angles))?;
        table.set_item("error_arcsec", PyArray1::from_vec(py, arcsec(t.errors)))?;
        table.set_item("u_arcsec", t.u.map(|u| PyArray1::from_vec(py, arcsec(u))))?;
        table.set_item("range", range_deg)?;
        all.set_item(t.name, table)?;
    }
    out.set_item("tables", all)?;
    Ok(out)
}

/// The whole-turn table of `map` for channel `name`.
pub fn turn<'a>(
    name: &'a str,
    map: &'a calib_core::ErrorMap,
    u: Option<&'a [f64]>,
) -> OutTable<'a> {
    OutTable {
        name,
        start: 0.0,
        step: std::f64::consts::TAU / map.len() as f64,
        errors: map.values(),
        u,
    }
}

/// The samples of a method on arrays: `t` given, or the sample index over `rate_hz`; every
/// array the length of the first.
fn times(t: Option<&[f64]>, n: usize, rate_hz: f64) -> PyResult<Vec<f64>> {
    if !(rate_hz > 0.0 && rate_hz.is_finite()) {
        return Err(usage(
            "rate_hz must be a positive number of samples per second",
        ));
    }
    match t {
        Some(t) if t.len() != n => Err(usage(format!(
            "t has {} samples and the readings {n}: give one time stamp per reading",
            t.len()
        ))),
        Some(t) => {
            check_array("t", t, calib_io::limits::Samples::Stamps)?;
            Ok(t.to_vec())
        }
        None => Ok((0..n).map(|i| i as f64 / rate_hz).collect()),
    }
}

/// Checks that `array` (keyword `name`) has `n` values.
pub fn same_length(name: &str, array: &[f64], n: usize) -> PyResult<()> {
    if array.len() == n {
        return Ok(());
    }
    Err(usage(format!(
        "{name} has {} values and the first array {n}: give one value per sample",
        array.len()
    )))
}

/// The CSRR keyword arguments (the CLI's options of `calib csrr`).
pub(crate) struct CsrrArgs {
    opts: CsrrOptions,
}

impl CsrrArgs {
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        method: &str,
        max_order: Option<usize>,
        points: Option<usize>,
        session_tol: Option<f64>,
        min_speed: f64,
        min_observability: f64,
        benchmarks: (f64, f64),
        reference: bool,
        use_marks: bool,
    ) -> PyResult<Self> {
        let method = match method {
            "joint" => Method::Joint,
            "paper" => Method::Paper,
            other => {
                return Err(usage(format!(
                    "method=`{other}`: give \"joint\" (joint least squares) or \"paper\" (the seed \
                     paper's method)"
                )));
            }
        };
        if let Some(tol) = session_tol {
            check_range("session_tol", tol, 0.0, 180.0, "degrees")?;
        }
        check_range("min_speed", min_speed, 0.0, 360_000.0, "degrees per second")?;
        if !(0.0..1.0).contains(&min_observability) {
            return Err(usage(format!(
                "min_observability={} is outside its range, 0 to 1 (excluded)",
                calib_io::limits::readable(min_observability)
            )));
        }
        check_points(points)?;
        if max_order == Some(0) {
            return Err(usage("max_order must be at least 1"));
        }
        Ok(CsrrArgs {
            opts: CsrrOptions {
                method,
                max_order,
                segments: SegmentOptions {
                    min_speed: min_speed.to_radians(),
                    relative_tol: session_tol.map(f64::to_radians),
                    use_marks,
                    ..SegmentOptions::default()
                },
                points,
                benchmarks: (benchmarks.0.to_radians(), benchmarks.1.to_radians()),
                reference,
                min_observability,
                ..CsrrOptions::default()
            },
        })
    }
}

/// Checks that `csrr_log`'s channels `a`, `b` and `ref` are three different channels.
pub(crate) fn csrr_channels(a: &str, b: &str, r#ref: Option<&str>) -> PyResult<()> {
    if a == b {
        return Err(usage(format!(
            "a and b both name `{a}`: name the two sensors' channels"
        )));
    }
    if let Some(r) = r#ref.filter(|r| *r == a || *r == b) {
        return Err(usage(format!(
            "ref `{r}` is also a calibrated sensor's channel; the reference must be a third \
             encoder on B's shaft (or leave ref out)"
        )));
    }
    Ok(())
}

/// Checks that `reference_log`'s `dut` and `ref` are two different channels.
pub(crate) fn reference_channels(dut: &str, r#ref: &str) -> PyResult<()> {
    if dut == r#ref {
        return Err(usage(format!(
            "dut and ref both name `{dut}`: name the encoder to calibrate and the reference"
        )));
    }
    Ok(())
}

/// `latency`: `"auto"` (or None) or the lag in seconds, within ±10, as `--latency`.
pub(crate) fn latency_of(value: Option<&Bound<'_, PyAny>>) -> PyResult<Latency> {
    let bad = |shown: String| {
        usage(format!(
            "latency={shown}: give \"auto\" or the lag in seconds, within ±10 (e.g. 0.02 for \
             20 ms; 0 for none)"
        ))
    };
    let Some(value) = value else {
        return Ok(Latency::Auto);
    };
    if let Ok(text) = value.extract::<String>() {
        return if text.trim().eq_ignore_ascii_case("auto") {
            Ok(Latency::Auto)
        } else {
            Err(bad(format!("{text:?}")))
        };
    }
    match value.extract::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 10.0 => Ok(Latency::Fixed(v)),
        Ok(v) => Err(bad(v.to_string())),
        Err(_) => Err(bad(value.to_string())),
    }
}

/// `ref_kind` and `pole_pairs`, as `--ref-kind` and `--pole-pairs`.
fn reference_kind(
    ref_kind: &str,
    pole_pairs: Option<u32>,
    points: usize,
) -> PyResult<ReferenceKind> {
    match (ref_kind, pole_pairs) {
        ("encoder", None) => Ok(ReferenceKind::Encoder),
        ("encoder", Some(_)) => Err(usage(
            "pole_pairs is for a commanded reference: give ref_kind=\"commanded\", or leave pole_pairs out",
        )),
        ("commanded", None) => Err(usage(
            "ref_kind=\"commanded\" needs the motor's pole_pairs (moteus: motor.poles / 2; a 42-pole motor has 21)",
        )),
        ("commanded", Some(p)) if p == 0 || points < 8 * p as usize => Err(usage(format!(
            "pole_pairs={p} needs at least 1 and points of at least 8 per pole pair ({})",
            8 * p.max(1) as usize
        ))),
        ("commanded", Some(p)) => Ok(ReferenceKind::Commanded { pole_pairs: p }),
        (other, _) => Err(usage(format!(
            "ref_kind=`{other}`: give \"encoder\" (an encoder on the DUT's shaft) or \"commanded\" \
             (a motor's open-loop commanded angle)"
        ))),
    }
}

/// The message of a CSRR that failed on channels `a` and `b` of `what`.
fn csrr_error(what: &str, a: &str, b: &str, e: &CsrrError) -> String {
    match e {
        CsrrError::NeverMoves { sensor } => {
            let name = if *sensor == 'A' { a } else { b };
            format!("{what}: channel `{name}`: {e}")
        }
        _ => format!("{what}: channels `{a}` and `{b}`: {e}"),
    }
}

/// The result dictionary of a CSRR calibration.
fn csrr_result<'py>(
    py: Python<'py>,
    cal: &calib_core::csrr::Calibration,
    (a, b): (&str, &str),
    reference: Option<&str>,
    inputs: Vec<String>,
    warnings: Vec<String>,
    read: LogRead,
) -> PyResult<Bound<'py, PyDict>> {
    let section = cal
        .report_section((a, b), reference, None)
        .with_alignment(read.alignment)
        .with_reading(read.reading)
        .with_time_origin(read.time_origin_s);
    let (ua, ub) = match &cal.uncertainty {
        Some((ua, ub)) => (Some(ua.u.as_slice()), Some(ub.u.as_slice())),
        None => (None, None),
    };
    result(
        py,
        section,
        inputs,
        warnings,
        &[turn(a, &cal.a, ua), turn(b, &cal.b, ub)],
    )
}

/// CSRR self-calibration of two coaxial sensors from arrays (see `calib.csrr`).
#[pyfunction]
#[pyo3(signature = (a, b, t=None, sessions=None, r#ref=None, *, names=("a".to_string(), "b".to_string()), rate_hz=1000.0, method="joint", max_order=None, points=None, session_tol=None, min_speed=1.0, detect_sessions=false, min_observability=0.01, benchmarks=(0.0, 0.0), latency=None))]
#[allow(clippy::too_many_arguments)]
pub fn csrr<'py>(
    py: Python<'py>,
    a: PyReadonlyArray1<'py, f64>,
    b: PyReadonlyArray1<'py, f64>,
    t: Option<PyReadonlyArray1<'py, f64>>,
    sessions: Option<PyReadonlyArray1<'py, i64>>,
    r#ref: Option<PyReadonlyArray1<'py, f64>>,
    names: (String, String),
    rate_hz: f64,
    method: &str,
    max_order: Option<usize>,
    points: Option<usize>,
    session_tol: Option<f64>,
    min_speed: f64,
    detect_sessions: bool,
    min_observability: f64,
    benchmarks: (f64, f64),
    latency: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let latency = latency_of(latency.as_ref())?;
    let (a, b) = (a.as_slice()?, b.as_slice()?);
    let n = a.len();
    check_readings("a", a)?;
    same_length("b", b, n)?;
    check_readings("b", b)?;
    let t = times(t.as_ref().map(|t| t.as_slice()).transpose()?, n, rate_hz)?;
    let sessions = sessions.as_ref().map(|s| s.as_slice()).transpose()?;
    if let Some(s) = sessions
        && s.len() != n
    {
        return Err(usage(format!(
            "sessions has {} values and the readings {n}: give one session number per sample \
             (negative: in no session)",
            s.len()
        )));
    }
    let r = r#ref.as_ref().map(|r| r.as_slice()).transpose()?;
    if let Some(r) = r {
        same_length("ref", r, n)?;
        check_readings("ref", r)?;
    }
    if names.0 == names.1 {
        return Err(usage(format!(
            "names gives `{}` twice: name the two sensors differently",
            names.0
        )));
    }
    let args = CsrrArgs::new(
        method,
        max_order,
        points,
        session_tol,
        min_speed,
        min_observability,
        benchmarks,
        r.is_some(),
        sessions.is_some() && !detect_sessions,
    )?;
    let cal = py.detach(|| {
        // The arrays are read once per pass (`auto` latency reads them again with the lag
        // removed).
        calib_core::csrr::latency::calibrate(&args.opts, latency, |csrr: &mut Csrr| {
            for i in 0..n {
                let mark = sessions.and_then(|s| u32::try_from(s[i]).ok());
                match r {
                    Some(r) => csrr.push_with_reference(t[i], a[i], b[i], r[i], mark),
                    None => csrr.push(t[i], a[i], b[i], mark),
                }
            }
            Ok::<(), std::convert::Infallible>(())
        })
        .unwrap_or_else(|never| match never {})
    });
    let (na, nb) = (names.0.as_str(), names.1.as_str());
    let cal = cal.map_err(|e| data(csrr_error("the arrays", na, nb, &e)))?;
    let reference = r.map(|_| "ref");
    csrr_result(
        py,
        &cal,
        (na, nb),
        reference,
        vec![],
        vec![],
        LogRead::default(),
    )
}

/// CSRR self-calibration of two channels of a log (see `calib.csrr_log`).
#[pyfunction]
#[pyo3(signature = (path, *, a="a".to_string(), b="b".to_string(), r#ref=None, method="joint", max_order=None, points=None, session_tol=None, min_speed=1.0, detect_sessions=false, min_observability=0.01, benchmarks=(0.0, 0.0), latency=None, unit=None, time="header", max_gap=None, time_column=None, time_unit=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn csrr_log<'py>(
    py: Python<'py>,
    path: Bound<'py, PyAny>,
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
    latency: Option<Bound<'py, PyAny>>,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    storage_options: Option<std::collections::HashMap<String, String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let latency = latency_of(latency.as_ref())?;
    csrr_channels(&a, &b, r#ref.as_deref())?;
    let log = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = crate::logs::LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    let mut names = vec![a.clone(), b.clone()];
    names.extend(r#ref.clone());
    let reader = py.detach(|| open(&input, Some(&names), &log))?;
    let args = CsrrArgs::new(
        method,
        max_order,
        points,
        session_tol,
        min_speed,
        min_observability,
        benchmarks,
        r#ref.is_some(),
        reader.has_session_marks() && !detect_sessions,
    )?;
    let what = path.display().to_string();
    let (cal, reader) = py
        .detach(|| {
            let with_ref = r#ref.is_some();
            let (mut first, mut last) = (Some(reader), None);
            // One reading of the log per pass (`auto` latency reads it again with the lag
            // removed).
            let cal =
                calib_core::csrr::latency::calibrate(&args.opts, latency, |csrr: &mut Csrr| {
                    let reader = match first.take() {
                        Some(reader) => reader,
                        None => reopen(&input, &names, &log)?,
                    };
                    last = Some(for_each_sample(&path, reader, |s| {
                        let v = &s.values;
                        if with_ref {
                            csrr.push_with_reference(s.t, v[0], v[1], v[2], s.session);
                        } else {
                            csrr.push(s.t, v[0], v[1], s.session);
                        }
                    })?);
                    Ok::<(), String>(())
                })?
                .map_err(|e| csrr_error(&what, &a, &b, &e))?;
            Ok::<_, String>((cal, last.expect("the log is read at least once")))
        })
        .map_err(data)?;
    csrr_result(
        py,
        &cal,
        (&a, &b),
        r#ref.as_deref(),
        vec![what],
        reader.warnings(&path),
        log_read(&reader),
    )
}

/// `targets` as a count (an int) or readings in degrees (a sequence of numbers); `None` if it is
/// neither.
fn parse_targets(targets: &Bound<'_, PyAny>) -> Option<PyResult<Targets>> {
    if let Ok(k) = targets.extract::<usize>() {
        return Some(if k == 0 {
            Err(usage("targets: give a count of targets (≥ 1), not 0"))
        } else {
            Ok(Targets::Count(k))
        });
    }
    let angles: Vec<f64> = targets.extract().ok()?;
    Some(if angles.iter().any(|a| !a.is_finite()) {
        Err(usage(
            "targets: every target must be a finite angle in degrees",
        ))
    } else {
        Ok(Targets::Angles(
            angles.into_iter().map(f64::to_radians).collect(),
        ))
    })
}

/// The reference calibration's options from its keyword arguments (`calib reference`'s).
#[allow(clippy::too_many_arguments)]
pub(crate) fn reference_options(
    ref_u: Option<f64>,
    points: usize,
    min_speed: f64,
    follow_tol: f64,
    bridge_gap: f64,
    targets: Option<&Bound<'_, PyAny>>,
    approach: f64,
    (latency, ref_kind, pole_pairs): (Option<&Bound<'_, PyAny>>, &str, Option<u32>),
) -> PyResult<ReferenceOptions> {
    check_points(Some(points))?;
    if let Some(u) = ref_u {
        check_non_negative("ref_u", u, "arcseconds")?;
    }
    check_non_negative("approach", approach, "degrees")?;
    check_range("min_speed", min_speed, 0.0, 360_000.0, "degrees per second")?;
    check_range("follow_tol", follow_tol, 0.0, 180.0, "degrees")?;
    if !(bridge_gap.is_finite() && (0.0..360.0).contains(&bridge_gap)) {
        return Err(usage(format!(
            "bridge_gap={} is outside its range: at least 0 and below 360 degrees",
            calib_io::limits::readable(bridge_gap)
        )));
    }
    let bad = || usage("targets: give a count of targets (≥ 1) or a list of readings in degrees");
    let targets = match targets {
        None => Targets::Count(20),
        Some(t) => parse_targets(t).ok_or_else(bad)??,
    };
    Ok(ReferenceOptions {
        points,
        min_speed: min_speed.to_radians(),
        reference_u: ref_u.unwrap_or(0.0) / ARCSEC_PER_RAD,
        follow_tol: follow_tol.to_radians(),
        approach: approach.to_radians(),
        max_gap: bridge_gap.to_radians(),
        targets,
        latency: latency_of(latency)?,
        reference_kind: reference_kind(ref_kind, pole_pairs, points)?,
    })
}

/// The gear of `ref_ratio` (a number or `"auto"`; `None`: one shaft) and `ref_orders`, as
/// `calib reference --ref-ratio --ref-orders` takes them.
pub(crate) fn gear_of(
    ref_ratio: Option<&Bound<'_, PyAny>>,
    ref_orders: usize,
) -> PyResult<Option<Gear>> {
    let Some(value) = ref_ratio else {
        return Ok(None);
    };
    let ratio = match value.extract::<f64>() {
        Ok(r) => r.to_string().parse::<Ratio>(),
        Err(_) => value
            .extract::<String>()
            .map_err(|_| usage("ref_ratio: give a number or \"auto\""))?
            .parse::<Ratio>(),
    }
    .map_err(|e| usage(format!("ref_ratio: {e}")))?;
    check_range("ref_orders", ref_orders as f64, 0.0, 200.0, "orders")?;
    Ok(Some(Gear {
        ratio,
        reference_orders: ref_orders,
    }))
}

/// The result dictionary of a reference calibration.
fn reference_result<'py>(
    py: Python<'py>,
    cal: &calib_core::reference_cal::ReferenceCalibration,
    (dut, reference, ref_u): (&str, &str, Option<f64>),
    inputs: Vec<String>,
    warnings: Vec<String>,
    read: LogRead,
) -> PyResult<Bound<'py, PyDict>> {
    let section = cal
        .report_section(dut, reference, ref_u)
        .with_alignment(read.alignment)
        .with_reading(read.reading)
        .with_time_origin(read.time_origin_s);
    let values = cal.map.values();
    let (start, step) = match &cal.map {
        TableMap::Turn(m) => (0.0, std::f64::consts::TAU / m.len() as f64),
        TableMap::Range(m) => (m.start(), (m.end() - m.start()) / (m.len() - 1) as f64),
    };
    let mut tables = vec![OutTable {
        name: dut,
        start,
        step,
        errors: values,
        u: Some(&cal.u),
    }];
    if let Some(m) = cal.gear.as_ref().and_then(|g| g.reference_map.as_ref()) {
        tables.push(OutTable {
            name: reference,
            start: 0.0,
            step: std::f64::consts::TAU / m.map.len() as f64,
            errors: m.map.values(),
            u: Some(&m.u),
        });
    }
    result(py, section, inputs, warnings, &tables)
}

/// Cross-calibration against a reference encoder from arrays (see `calib.reference`).
#[pyfunction]
#[pyo3(signature = (dut, r#ref, t=None, *, names=("dut".to_string(), "ref".to_string()), rate_hz=1000.0, ref_u=None, points=3600, min_speed=1.0, follow_tol=5.0, bridge_gap=5.0, targets=None, approach=1.0, latency=None, ref_kind="encoder", pole_pairs=None, ref_ratio=None, ref_orders=16))]
#[allow(clippy::too_many_arguments)]
pub fn reference<'py>(
    py: Python<'py>,
    dut: PyReadonlyArray1<'py, f64>,
    r#ref: PyReadonlyArray1<'py, f64>,
    t: Option<PyReadonlyArray1<'py, f64>>,
    names: (String, String),
    rate_hz: f64,
    ref_u: Option<f64>,
    points: usize,
    min_speed: f64,
    follow_tol: f64,
    bridge_gap: f64,
    targets: Option<Bound<'py, PyAny>>,
    approach: f64,
    latency: Option<Bound<'py, PyAny>>,
    ref_kind: &str,
    pole_pairs: Option<u32>,
    ref_ratio: Option<Bound<'py, PyAny>>,
    ref_orders: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let gear = gear_of(ref_ratio.as_ref(), ref_orders)?;
    let (d, r) = (dut.as_slice()?, r#ref.as_slice()?);
    let n = d.len();
    check_readings("dut", d)?;
    same_length("ref", r, n)?;
    check_readings("ref", r)?;
    let t = times(t.as_ref().map(|t| t.as_slice()).transpose()?, n, rate_hz)?;
    let opts = reference_options(
        ref_u,
        points,
        min_speed,
        follow_tol,
        bridge_gap,
        targets.as_ref(),
        approach,
        (latency.as_ref(), ref_kind, pole_pairs),
    )?;
    let cal = py.detach(|| {
        let mut cal = ReferenceRun::new(opts, gear);
        for i in 0..n {
            cal.push(t[i], d[i], r[i]);
        }
        cal.finish()
    });
    let cal = cal.map_err(|e| {
        data(format!(
            "the arrays: DUT `{}`, reference `{}`: {e}",
            names.0, names.1
        ))
    })?;
    reference_result(
        py,
        &cal,
        (&names.0, &names.1, ref_u),
        vec![],
        vec![],
        LogRead::default(),
    )
}

/// Cross-calibration of a log's DUT channel against its reference channel (see
/// `calib.reference_log`).
#[pyfunction]
#[pyo3(signature = (path, *, dut, r#ref, ref_u=None, points=3600, min_speed=1.0, follow_tol=5.0, bridge_gap=5.0, targets=None, approach=1.0, latency=None, ref_kind="encoder", pole_pairs=None, ref_ratio=None, ref_orders=16, unit=None, time="header", max_gap=None, time_column=None, time_unit=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn reference_log<'py>(
    py: Python<'py>,
    path: Bound<'py, PyAny>,
    dut: String,
    r#ref: String,
    ref_u: Option<f64>,
    points: usize,
    min_speed: f64,
    follow_tol: f64,
    bridge_gap: f64,
    targets: Option<Bound<'py, PyAny>>,
    approach: f64,
    latency: Option<Bound<'py, PyAny>>,
    ref_kind: &str,
    pole_pairs: Option<u32>,
    ref_ratio: Option<Bound<'py, PyAny>>,
    ref_orders: usize,
    unit: Option<&str>,
    time: &str,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    storage_options: Option<std::collections::HashMap<String, String>>,
) -> PyResult<Bound<'py, PyDict>> {
    reference_channels(&dut, &r#ref)?;
    let gear = gear_of(ref_ratio.as_ref(), ref_orders)?;
    let opts = reference_options(
        ref_u,
        points,
        min_speed,
        follow_tol,
        bridge_gap,
        targets.as_ref(),
        approach,
        (latency.as_ref(), ref_kind, pole_pairs),
    )?;
    let log = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = crate::logs::LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    let reader = py.detach(|| open(&input, Some(&[dut.clone(), r#ref.clone()]), &log))?;
    let what = path.display().to_string();
    let (cal, reader) = py
        .detach(|| {
            let mut cal = ReferenceRun::new(opts, gear);
            let reader =
                for_each_sample(&path, reader, |s| cal.push(s.t, s.values[0], s.values[1]))?;
            let cal = cal
                .finish()
                .map_err(|e| format!("{what}: DUT `{dut}`, reference `{}`: {e}", r#ref))?;
            Ok::<_, String>((cal, reader))
        })
        .map_err(data)?;
    reference_result(
        py,
        &cal,
        (&dut, &r#ref, ref_u),
        vec![what],
        reader.warnings(&path),
        log_read(&reader),
    )
}

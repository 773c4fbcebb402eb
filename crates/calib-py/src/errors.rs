//! The package's exceptions and the checks of keyword arguments, with the CLI's messages.

use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

// The classes' module is `calib`, where the package re-exports them: pickle finds a class by its
// module and name, so an error raised in a worker process (a process pool, Dask, Ray) is sent
// back and raised again as the same class.
create_exception!(
    calib,
    CalibError,
    PyException,
    "Base class of calib's errors."
);
create_exception!(
    calib,
    DataError,
    CalibError,
    "The data cannot be calibrated or read (the CLI's exit status 1): the message names the \
     file, line or message, and channel, and what to do."
);
create_exception!(
    calib,
    UsageError,
    CalibError,
    "A bad argument: an unknown channel, an option outside its range, a missing file (the CLI's \
     exit status 2)."
);

/// `ArrayError`: a [`UsageError`] that is also Python's `ValueError` — an array argument that
/// is empty or holds NaN, an infinity or a value out of range, named with its index. Made once,
/// from both bases (an exception class of one base is all `create_exception!` makes).
static ARRAY_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// The `ArrayError` class (see [`ARRAY_ERROR`]).
pub fn array_error_type(py: Python<'_>) -> PyResult<&Bound<'_, PyType>> {
    ARRAY_ERROR
        .get_or_try_init(py, || {
            let bases = PyTuple::new(
                py,
                [py.get_type::<UsageError>(), py.get_type::<PyValueError>()],
            )?;
            let dict = PyDict::new(py);
            dict.set_item("__module__", "calib")?;
            dict.set_item(
                "__doc__",
                "An array argument that is empty or holds NaN, an infinity or a value out of \
                 range (a UsageError and a ValueError): the message names the argument and the \
                 first bad index.",
            )?;
            let class = py
                .get_type::<PyType>()
                .call1(("ArrayError", bases, dict))?
                .cast_into::<PyType>()?;
            Ok(class.unbind())
        })
        .map(|class| class.bind(py))
}

/// Refuses the array `name` of `values` (`kind`) as the log readers refuse such values
/// ([`calib_io::limits::array_problem`]): an `ArrayError` naming it and the first bad index.
pub fn check_array(
    name: &str,
    values: &[f64],
    kind: calib_io::limits::Samples,
) -> Result<(), PyErr> {
    match calib_io::limits::array_problem(name, values, kind) {
        None => Ok(()),
        Some(message) => Err(array_error(message)),
    }
}

/// An `ArrayError` with `message`.
pub fn array_error(message: String) -> PyErr {
    Python::attach(|py| match array_error_type(py) {
        Ok(class) => PyErr::from_type(class.clone(), message),
        Err(e) => e,
    })
}

/// Readings in radians: [`check_array`].
pub fn check_readings(name: &str, values: &[f64]) -> Result<(), PyErr> {
    check_array(name, values, calib_io::limits::Samples::Readings)
}

/// A [`DataError`] with `message`.
pub fn data(message: impl Into<String>) -> PyErr {
    DataError::new_err(message.into())
}

/// A [`UsageError`] with `message`.
pub fn usage(message: impl Into<String>) -> PyErr {
    UsageError::new_err(message.into())
}

/// Checks that `value` of the keyword `name` lies in (`low`, `high`], naming it and its range.
pub fn check_range(name: &str, value: f64, low: f64, high: f64, unit: &str) -> Result<(), PyErr> {
    if value > low && value <= high {
        return Ok(());
    }
    let r = calib_io::limits::readable;
    Err(usage(format!(
        "{name}={} is outside its range: above {} and at most {} {unit}",
        r(value),
        r(low),
        r(high)
    )))
}

/// Checks that `value` of the keyword `name` is a finite number of at least 0.
pub fn check_non_negative(name: &str, value: f64, unit: &str) -> Result<(), PyErr> {
    if value.is_finite() && value >= 0.0 {
        return Ok(());
    }
    Err(usage(format!(
        "{name}={} is outside its range: a finite number of at least 0 {unit}",
        calib_io::limits::readable(value)
    )))
}

/// Checks a table size `points` against the limit every calib table has.
pub fn check_points(points: Option<usize>) -> Result<(), PyErr> {
    use calib_io::limits::MAX_TABLE_POINTS;
    match points {
        Some(p) if !(2..=MAX_TABLE_POINTS).contains(&p) => Err(usage(format!(
            "points={p} is outside its range, 2 to {MAX_TABLE_POINTS}"
        ))),
        _ => Ok(()),
    }
}

//! The package's exceptions and the checks of keyword arguments, with the CLI's messages.

use pyo3::PyErr;
use pyo3::create_exception;
use pyo3::exceptions::PyException;

create_exception!(
    _calib,
    CalibError,
    PyException,
    "Base class of calib's errors."
);
create_exception!(
    _calib,
    DataError,
    CalibError,
    "The data cannot be calibrated or read (the CLI's exit status 1): the message names the \
     file, line or message, and channel, and what to do."
);
create_exception!(
    _calib,
    UsageError,
    CalibError,
    "A bad argument: an unknown channel, an option outside its range, a missing file (the CLI's \
     exit status 2)."
);

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

//! `calib` from Python: the native module `calib._calib` behind the `calib` package
//! (`python/calib/__init__.py`), which wraps its dictionaries and arrays in documented classes.
//!
//! Every function here takes numpy arrays or paths and returns dictionaries of numpy arrays
//! (readings in radians, tables in degrees and arcseconds as calib writes them) and JSON text;
//! the work itself is calib-core's and calib-io's, run with the GIL released.

mod checks;
mod errors;
mod logs;
mod methods;
mod multihead;
mod shift_angle;
mod tables;
mod tdr;

use pyo3::prelude::*;

/// The native part of the `calib` package; use `calib` itself.
#[pymodule]
fn _calib(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("CalibError", py.get_type::<errors::CalibError>())?;
    m.add("DataError", py.get_type::<errors::DataError>())?;
    m.add("UsageError", py.get_type::<errors::UsageError>())?;
    m.add("ArrayError", errors::array_error_type(py)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(logs::read, m)?)?;
    m.add_function(wrap_pyfunction!(logs::inspect, m)?)?;
    m.add_function(wrap_pyfunction!(methods::csrr, m)?)?;
    m.add_function(wrap_pyfunction!(methods::csrr_log, m)?)?;
    m.add_function(wrap_pyfunction!(methods::reference, m)?)?;
    m.add_function(wrap_pyfunction!(methods::reference_log, m)?)?;
    m.add_function(wrap_pyfunction!(multihead::multihead, m)?)?;
    m.add_function(wrap_pyfunction!(multihead::multihead_log, m)?)?;
    m.add_function(wrap_pyfunction!(shift_angle::shift_angle, m)?)?;
    m.add_function(wrap_pyfunction!(tdr::tdr, m)?)?;
    m.add_function(wrap_pyfunction!(tdr::tdr_log, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_csrr_log, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_reference_log, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_tdr_log, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_multihead_log, m)?)?;
    m.add_function(wrap_pyfunction!(tables::read_table, m)?)?;
    m.add_function(wrap_pyfunction!(tables::check_table, m)?)?;
    m.add_function(wrap_pyfunction!(tables::write_table, m)?)?;
    m.add_function(wrap_pyfunction!(tables::correct, m)?)?;
    m.add_function(wrap_pyfunction!(tables::export, m)?)?;
    m.add_function(wrap_pyfunction!(tables::compose, m)?)?;
    m.add_function(wrap_pyfunction!(tables::simulate, m)?)?;
    Ok(())
}

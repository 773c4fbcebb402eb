//! CSV logs: [`CsvReader`] streams a log as [`Sample`](calib_core::Sample)s, [`CsvWriter`]
//! writes one.
//!
//! # Format
//! One header row naming the columns, then one row per sample:
//!
//! ```text
//! t,a,b,session
//! 0.000,359.998,0.012,0
//! 0.001,0.004,0.019,0
//! ```
//!
//! - `t`: time in seconds, finite and strictly increasing from row to row (a row repeating the
//!   one before exactly is dropped as a copy: the `stamps` module). Required.
//! - `session`: optional integer marking each row's CSRR session; negative for rows outside any
//!   session.
//! - every other column is a channel named by its header; readings in the unit given by
//!   [`ReadOptions::unit`](crate::ReadOptions::unit) (degrees by default), wrapped to one
//!   revolution or accumulated, as the sensor gives them.
//!
//! Fields may carry surrounding spaces or tabs, the file may start with a UTF-8 byte order mark,
//! and blank lines are skipped. A field holding the separator or quotes must be quoted as CSV
//! (RFC 4180) quotes it.
//!
//! # Dialects
//! Lab exports are read too ([`dialect`]): `;` or tab separators, metadata lines before the
//! header, and a time column named `time`, `timestamp`, `Time [s]`, `t_ms`, `Zeit [s]`, … (or any
//! name given as [`ReadOptions::time_column`](crate::ReadOptions::time_column)) in s, ms, us or
//! ns (stamps since 1970 in a column that names no unit: the unit their magnitude says).

pub mod dialect;
pub mod direction;
mod fields;
mod reader;
pub mod time_step;
mod writer;

pub(crate) use fields::{
    csv_reader, from_csv, header_names, line_at, line_of, not_a_number, parse_f64, parse_f64_comma,
    wrong_width,
};
pub use reader::CsvReader;
pub use writer::CsvWriter;

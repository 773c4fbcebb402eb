//! Parquet files (pyarrow and pandas, Polars, Spark, data platforms, Foxglove and PlotJuggler
//! exports), read with the `parquet` crate's column readers (no Arrow), row group by row group.
//!
//! Every numeric leaf column is a channel named by its path, nested fields joined by `.`
//! (`pose.x`). Floats and integers of up to 32 bits become doubles, 64-bit integers stay
//! integers; a `TIMESTAMP` column (and the legacy `INT96` stamps Spark and Impala write) is a
//! column of stamps since 1970 ([`ColumnTime::Stamps`]), which the reader takes as the time. A
//! column with nulls is listed and not taken (calib needs a reading in every row: a file of many
//! columns often has a sparse one besides the channels); a null stamp is an error. Strings, booleans, decimals, dates, times of day and lists are listed in
//! [`ColumnSet::structure`] with why they were not taken.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use parquet::basic::{ConvertedType, LogicalType, TimeUnit as PqTimeUnit, Type as Physical};
use parquet::column::reader::{ColumnReader, ColumnReaderImpl, get_column_reader};
use parquet::data_type::DataType;
use parquet::file::reader::{FileReader, SerializedFileReader};
use parquet::schema::types::ColumnDescriptor;

use super::parquet_guards::{CheckedPages, EndChecked};
use super::thrift_walk::{self, Stop};
use super::{Column, ColumnFormat, ColumnSet, ColumnTime, Values};
use crate::csv_log::dialect::TimeUnit;
use crate::limits::{self, MAX_PARQUET_COLUMNS, MAX_PARQUET_FOOTER_BYTES};
use crate::{Error, ReadOptions};

/// The 4 bytes a Parquet file starts and ends with.
const MAGIC: &[u8; 4] = b"PAR1";

/// The most records read from a column in one call (bounded buffers of levels and values).
const BATCH: usize = 64 * 1024;

/// Parquet files.
pub(crate) struct Parquet;

impl ColumnFormat for Parquet {
    fn name(&self) -> &'static str {
        "Parquet"
    }

    fn about(&self) -> &'static str {
        "Parquet files (pyarrow, pandas, Polars, Spark, Foxglove and PlotJuggler exports): numeric \
         columns by path, TIMESTAMP columns as time"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["parquet", "pq"]
    }

    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(MAGIC)
    }

    fn read(&self, path: &Path, _opts: &ReadOptions) -> Result<ColumnSet, Error> {
        read_file(path)
    }
}

/// An [`Error::Data`] naming `path`, and `column` where one is concerned.
fn error(path: &Path, column: Option<&str>, message: String) -> Error {
    Error::Data {
        path: path.to_path_buf(),
        message: match column {
            Some(c) => format!("column `{c}`: {message}"),
            None => message,
        },
    }
}

fn io_error(path: &Path, source: std::io::Error) -> Error {
    Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// What a leaf column is read as.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Doubles (floats, integers of up to 32 bits).
    F64,
    /// Unsigned 32-bit integers stored as INT32 (their bits reinterpreted).
    U32,
    /// 64-bit integers; stamps in this unit where `Some`.
    I64(Option<TimeUnit>),
    /// Unsigned 64-bit integers stored as INT64 (beyond `i64::MAX` an error).
    U64,
    /// INT96 stamps (nanoseconds of the day and a Julian day), as ns since 1970.
    Int96,
}

/// One taken column: where it is in the schema and what it is read into.
struct Taken {
    /// The leaf's index in the schema.
    leaf: usize,
    /// The leaf's path, `.`-joined.
    name: String,
    kind: Kind,
    /// The definition level of a present value (0 for a required column).
    max_def: i16,
    /// The values so far.
    values: Values,
    /// Its rows without a value so far.
    nulls: u64,
    /// Its line in [`ColumnSet::structure`].
    line: usize,
}

/// Reads every numeric column of the Parquet file at `path`.
fn read_file(path: &Path) -> Result<ColumnSet, Error> {
    let mut file = File::open(path).map_err(|e| io_error(path, e))?;
    let file_len = check_footer(path, &mut file)?;
    let headers = file.try_clone().map_err(|e| io_error(path, e))?;
    let reader = SerializedFileReader::new(EndChecked(file)).map_err(|e| {
        error(
            path,
            None,
            format!("not a readable Parquet file: {}", one_line(&e)),
        )
    })?;
    let meta = reader.metadata();
    let schema = meta.file_metadata().schema_descr();
    let leaves = schema.columns();
    if leaves.len() > MAX_PARQUET_COLUMNS {
        return Err(error(
            path,
            None,
            format!(
                "{} columns, more than the {MAX_PARQUET_COLUMNS} calib reads from one file; \
                 write the channels you need to a file of their own",
                leaves.len()
            ),
        ));
    }
    let rows = u64::try_from(meta.file_metadata().num_rows()).unwrap_or(0);
    let mut set = ColumnSet::default();
    set.structure.push(format!(
        "Parquet file, {} rows in {} row groups, {} columns{}",
        rows,
        meta.num_row_groups(),
        leaves.len(),
        meta.file_metadata()
            .created_by()
            .map(|w| format!(", written by {w}"))
            .unwrap_or_default()
    ));
    let mut taken = Vec::new();
    for (leaf, column) in leaves.iter().enumerate() {
        let name = column.path().string();
        let described = describe(column);
        match kind_of(column) {
            Ok(kind) => {
                set.structure
                    .push(format!("`{name}`: {described} → channel `{name}`"));
                taken.push(Taken {
                    nulls: 0,
                    line: set.structure.len() - 1,
                    leaf,
                    name,
                    kind,
                    max_def: column.max_def_level(),
                    values: match kind {
                        Kind::F64 | Kind::U32 => Values::F64(Vec::new()),
                        _ => Values::I64(Vec::new()),
                    },
                });
            }
            Err(why) => set
                .structure
                .push(format!("`{name}`: {described} — not taken: {why}")),
        }
    }
    // Every taken column holds `rows` values of 8 bytes: what the file states must fit what a
    // file of its length can decompress to before anything is allocated.
    let stated = rows.saturating_mul(8).saturating_mul(taken.len() as u64);
    if stated > limits::decompressed_limit(file_len) {
        return Err(error(
            path,
            None,
            format!(
                "states {rows} rows of {} numeric columns ({stated} bytes), more than a file of \
                 {file_len} bytes can hold; the file is damaged",
                taken.len()
            ),
        ));
    }
    for group in 0..meta.num_row_groups() {
        let row_group = reader.get_row_group(group).map_err(|e| {
            error(
                path,
                None,
                format!("row group {group} cannot be read: {}", one_line(&e)),
            )
        })?;
        let group_rows = usize::try_from(row_group.metadata().num_rows()).unwrap_or(0);
        for column in &mut taken {
            // The crate asserts (panics) on a negative start or length of a column chunk: a
            // damaged footer's numbers are checked here first (found by fuzzing).
            let meta = row_group.metadata().column(column.leaf);
            let start = meta
                .dictionary_page_offset()
                .unwrap_or(meta.data_page_offset());
            let len = meta.compressed_size();
            let end = u64::try_from(start)
                .ok()
                .zip(u64::try_from(len).ok())
                .and_then(|(s, l)| s.checked_add(l));
            if end.is_none_or(|end| end > file_len) {
                return Err(error(
                    path,
                    Some(&column.name),
                    format!(
                        "row group {group}: the column's chunk is stated at byte {start}, \
                         {len} bytes long, outside the file of {file_len} bytes; the file is \
                         damaged"
                    ),
                ));
            }
            if let Err(why) = check_page_headers(&headers, start as u64, len as u64) {
                return Err(error(
                    path,
                    Some(&column.name),
                    format!("row group {group}: {why}; the file is damaged"),
                ));
            }
            let pages = row_group.get_column_page_reader(column.leaf).map_err(|e| {
                error(
                    path,
                    Some(&column.name),
                    format!("row group {group}: {}", one_line(&e)),
                )
            })?;
            let descr = meta.column_descr_ptr();
            let chunk =
                get_column_reader(descr.clone(), Box::new(CheckedPages::new(pages, &descr)));
            let before = column.values.len();
            read_chunk(chunk, column, group_rows).map_err(|message| {
                error(
                    path,
                    Some(&column.name),
                    format!("row group {group}: {message}"),
                )
            })?;
            let read = column.values.len() - before;
            if read != group_rows {
                return Err(error(
                    path,
                    Some(&column.name),
                    format!(
                        "row group {group} states {group_rows} rows but holds {read}; the file \
                         is damaged"
                    ),
                ));
            }
        }
    }
    for t in taken.iter().filter(|t| t.nulls > 0) {
        let line = &mut set.structure[t.line];
        if let Some(at) = line.find(" → channel") {
            line.truncate(at);
        }
        line.push_str(&format!(
            " — not taken: {} of {rows} rows are null (calib needs a reading in every row)",
            t.nulls
        ));
    }
    set.columns = taken
        .into_iter()
        .filter(|t| t.nulls == 0)
        .map(|t| Column {
            time: match t.kind {
                Kind::I64(Some(unit)) => ColumnTime::Stamps(unit),
                Kind::Int96 => ColumnTime::Stamps(TimeUnit::Ns),
                _ => ColumnTime::Unknown,
            },
            name: t.name,
            unit: None,
            values: t.values,
        })
        .collect();
    Ok(set)
}

/// Checks the footer's stated length against the file's length and
/// [`MAX_PARQUET_FOOTER_BYTES`] before the crate reads it; returns the file's length.
fn check_footer(path: &Path, file: &mut File) -> Result<u64, Error> {
    let len = file.metadata().map_err(|e| io_error(path, e))?.len();
    let damaged = |what: String| {
        error(
            path,
            None,
            format!("{what}; the file is not a whole Parquet file (cut short, or damaged)"),
        )
    };
    if len < 12 {
        return Err(damaged(format!("{len} bytes long")));
    }
    let mut tail = [0u8; 8];
    file.seek(SeekFrom::End(-8))
        .and_then(|_| file.read_exact(&mut tail))
        .map_err(|e| io_error(path, e))?;
    if &tail[4..] != MAGIC {
        return Err(damaged("it does not end in `PAR1`".to_string()));
    }
    let footer = u64::from(u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]));
    if footer > len - 12 || footer > MAX_PARQUET_FOOTER_BYTES {
        return Err(damaged(format!(
            "its footer states {footer} bytes of metadata in a file of {len} bytes"
        )));
    }
    let mut metadata = vec![0u8; footer as usize];
    file.seek(SeekFrom::End(-8 - footer as i64))
        .and_then(|_| file.read_exact(&mut metadata))
        .map_err(|e| io_error(path, e))?;
    match thrift_walk::walk_struct(&metadata, 0, true) {
        Ok(_) => {}
        Err(Stop::Short) => return Err(damaged("its footer ends inside its metadata".to_string())),
        Err(Stop::Damaged(why)) => return Err(damaged(format!("its footer's metadata: {why}"))),
    }
    file.rewind().map_err(|e| io_error(path, e))?;
    Ok(len)
}

/// Walks the page headers of the column chunk of `len` bytes at `start` ([`thrift_walk`]), page
/// by page, before the crate reads them. A header the chunk ends inside is left to the crate,
/// which reports it.
fn check_page_headers(mut file: &File, start: u64, len: u64) -> Result<(), String> {
    /// `compressed_page_size` in Parquet's `PageHeader`.
    const COMPRESSED_SIZE: i16 = 3;
    let end = start + len;
    let (mut at, mut want) = (start, 4096u64);
    while at < end {
        let n = want.min(end - at);
        let mut buf = vec![0u8; n as usize];
        file.seek(SeekFrom::Start(at))
            .and_then(|_| file.read_exact(&mut buf))
            .map_err(|e| format!("cannot read the page header at byte {at}: {e}"))?;
        match thrift_walk::walk_struct(&buf, COMPRESSED_SIZE, at + n == end) {
            Ok((header, Some(size))) if size >= 0 => {
                at = at.saturating_add(header as u64).saturating_add(size as u64);
                want = 4096;
            }
            Ok(_) => return Err(format!("the page header at byte {at} states no page size")),
            Err(Stop::Short) if at + n < end => want = want.saturating_mul(4),
            Err(Stop::Short) => return Ok(()),
            Err(Stop::Damaged(why)) => return Err(format!("the page header at byte {at}: {why}")),
        }
    }
    Ok(())
}

/// The crate's message for `e`, on one line.
fn one_line(e: &parquet::errors::ParquetError) -> String {
    e.to_string().replace('\n', " ")
}

/// How a leaf column is read, or why it is not taken.
fn kind_of(column: &ColumnDescriptor) -> Result<Kind, String> {
    if column.max_rep_level() > 0 {
        return Err("a list (repeated values per row)".to_string());
    }
    let logical = column.logical_type_ref();
    let converted = column.converted_type();
    match (column.physical_type(), logical) {
        (_, Some(LogicalType::Decimal(_))) => Err("a decimal".to_string()),
        (_, Some(LogicalType::Date)) => Err("a date".to_string()),
        (_, Some(LogicalType::Time(_))) => Err("a time of day".to_string()),
        (Physical::INT64, Some(LogicalType::Timestamp(t))) => Ok(Kind::I64(Some(match t.unit {
            PqTimeUnit::MILLIS => TimeUnit::Ms,
            PqTimeUnit::MICROS => TimeUnit::Us,
            PqTimeUnit::NANOS => TimeUnit::Ns,
        }))),
        (Physical::INT64, None) if converted == ConvertedType::TIMESTAMP_MILLIS => {
            Ok(Kind::I64(Some(TimeUnit::Ms)))
        }
        (Physical::INT64, None) if converted == ConvertedType::TIMESTAMP_MICROS => {
            Ok(Kind::I64(Some(TimeUnit::Us)))
        }
        (_, _) if matches!(converted, ConvertedType::DECIMAL) => Err("a decimal".to_string()),
        (_, _)
            if matches!(
                converted,
                ConvertedType::DATE | ConvertedType::TIME_MILLIS | ConvertedType::TIME_MICROS
            ) =>
        {
            Err("a date or time of day".to_string())
        }
        (Physical::INT32, Some(LogicalType::Integer(i))) if !i.is_signed && i.bit_width == 32 => {
            Ok(Kind::U32)
        }
        (Physical::INT32, None) if converted == ConvertedType::UINT_32 => Ok(Kind::U32),
        (Physical::INT32, _) => Ok(Kind::F64),
        (Physical::INT64, Some(LogicalType::Integer(i))) if !i.is_signed => Ok(Kind::U64),
        (Physical::INT64, None) if converted == ConvertedType::UINT_64 => Ok(Kind::U64),
        (Physical::INT64, _) => Ok(Kind::I64(None)),
        (Physical::INT96, _) => Ok(Kind::Int96),
        (Physical::FLOAT | Physical::DOUBLE, _) => Ok(Kind::F64),
        (Physical::BOOLEAN, _) => Err("booleans".to_string()),
        (Physical::FIXED_LEN_BYTE_ARRAY, Some(LogicalType::Float16)) => {
            Err("16-bit floats".to_string())
        }
        (Physical::BYTE_ARRAY | Physical::FIXED_LEN_BYTE_ARRAY, _) => {
            Err("strings or bytes".to_string())
        }
    }
}

/// A leaf column's type as `calib inspect` lists it: `double`, `int64 TIMESTAMP(ns)`.
fn describe(column: &ColumnDescriptor) -> String {
    let physical = column.physical_type().to_string().to_lowercase();
    let logical = match column.logical_type_ref() {
        Some(LogicalType::Timestamp(t)) => format!(
            " TIMESTAMP({}{})",
            match t.unit {
                PqTimeUnit::MILLIS => "ms",
                PqTimeUnit::MICROS => "us",
                PqTimeUnit::NANOS => "ns",
            },
            if t.is_adjusted_to_u_t_c { ", UTC" } else { "" }
        ),
        Some(LogicalType::Integer(i)) => {
            format!(" {}INT{}", if i.is_signed { "" } else { "U" }, i.bit_width)
        }
        Some(other) => format!(" {other:?}").to_uppercase(),
        None => String::new(),
    };
    let optional = if column.max_def_level() > 0 {
        ", optional"
    } else {
        ""
    };
    format!("{physical}{logical}{optional}")
}

/// Reads one column chunk of `rows` rows onto `column`'s values.
/// A null is counted in `column.nulls` and held as NaN or 0 (the column is then not taken); in a
/// column of stamps it is an error.
fn read_chunk(chunk: ColumnReader, column: &mut Taken, rows: usize) -> Result<(), String> {
    let max_def = column.max_def;
    let kind = column.kind;
    let nulls = &mut column.nulls;
    let mut problem = None;
    let mut null = |row: usize| {
        if matches!(kind, Kind::I64(Some(_)) | Kind::Int96) {
            problem.get_or_insert(format!(
                "row {row} has no time stamp (null); every row needs one"
            ));
        }
        *nulls += 1;
    };
    match (chunk, &mut column.values) {
        (ColumnReader::DoubleColumnReader(r), Values::F64(out)) => {
            read_values(r, rows, max_def, |i, present| {
                out.push(present.unwrap_or_else(|| {
                    null(i);
                    f64::NAN
                }))
            })?;
        }
        (ColumnReader::FloatColumnReader(r), Values::F64(out)) => {
            read_values(r, rows, max_def, |i, present| {
                out.push(present.map_or_else(
                    || {
                        null(i);
                        f64::NAN
                    },
                    f64::from,
                ))
            })?;
        }
        (ColumnReader::Int32ColumnReader(r), Values::F64(out)) => {
            read_values(r, rows, max_def, |i, present| {
                out.push(match present {
                    Some(v) if kind == Kind::U32 => f64::from(v as u32),
                    Some(v) => f64::from(v),
                    None => {
                        null(i);
                        f64::NAN
                    }
                })
            })?;
        }
        (ColumnReader::Int64ColumnReader(r), Values::I64(out)) => {
            let mut beyond = None;
            read_values(r, rows, max_def, |i, present| match present {
                Some(v) if kind == Kind::U64 && v < 0 => {
                    beyond.get_or_insert(format!(
                        "value {} at row {i} is beyond the range calib reads (an unsigned 64-bit \
                         integer above 2⁶³)",
                        v as u64
                    ));
                }
                Some(v) => out.push(v),
                None => {
                    null(i);
                    out.push(0);
                }
            })?;
            if let Some(beyond) = beyond {
                return Err(beyond);
            }
        }
        (ColumnReader::Int96ColumnReader(r), Values::I64(out)) => {
            read_values(r, rows, max_def, |i, present| match present {
                Some(v) => out.push(v.to_nanos()),
                None => {
                    null(i);
                    out.push(0);
                }
            })?;
        }
        _ => return Err("its stored type does not match its schema".to_string()),
    }
    problem.map_or(Ok(()), Err)
}

/// Reads `rows` records of a flat column through `reader`, calling `each(row, value)` for every
/// row in order with `None` where the value is null.
fn read_values<T: DataType>(
    mut reader: ColumnReaderImpl<T>,
    rows: usize,
    max_def: i16,
    mut each: impl FnMut(usize, Option<T::T>),
) -> Result<(), String> {
    let mut row = 0usize;
    let mut values = Vec::new();
    let mut defs = Vec::new();
    while row < rows {
        values.clear();
        defs.clear();
        let want = (rows - row).min(BATCH);
        let (records, read, _) = reader
            .read_records(
                want,
                if max_def > 0 { Some(&mut defs) } else { None },
                None,
                &mut values,
            )
            .map_err(|e| one_line(&e))?;
        if records == 0 {
            break;
        }
        if max_def == 0 {
            for v in values.iter().take(read) {
                each(row, Some(v.clone()));
                row += 1;
            }
        } else {
            let mut next = values.iter().take(read);
            for &d in defs.iter().take(records) {
                let value = if d == max_def {
                    next.next().cloned()
                } else {
                    None
                };
                each(row, value);
                row += 1;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata")
            .join(name)
    }

    fn read(name: &str) -> ColumnSet {
        Parquet
            .read(&fixture(name), &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    fn column<'a>(set: &'a ColumnSet, name: &str) -> &'a Column {
        set.columns
            .iter()
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("no channel {name} in {:?}", set.structure))
    }

    fn f64s(c: &Column) -> &[f64] {
        match &c.values {
            Values::F64(v) => v,
            Values::I64(_) => panic!("{} holds integers", c.name),
        }
    }

    fn i64s(c: &Column) -> &[i64] {
        match &c.values {
            Values::I64(v) => v,
            Values::F64(_) => panic!("{} holds doubles", c.name),
        }
    }

    /// 2025-12-01T00:00:00Z, the fixtures' first stamp (`make_fixture.py`).
    const START_NS: i64 = 1_764_547_200_000_000_000;

    #[test]
    fn pyarrow_columns_with_a_timestamp_across_row_groups() {
        let set = read("parquet/quick.parquet");
        let names: Vec<&str> = set.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["stamp", "a", "b"]);
        let stamp = column(&set, "stamp");
        assert_eq!(stamp.time, ColumnTime::Stamps(TimeUnit::Ns));
        let ns = i64s(stamp);
        assert_eq!(ns.len(), 3301, "4 row groups of up to 1000 rows");
        assert_eq!((ns[0], ns[3300]), (START_NS, START_NS + 16_500_000_000));
        // The first row of the simulator's CSV, exact.
        assert_eq!(f64s(column(&set, "a"))[0], 0.29229999999999995);
        assert_eq!(f64s(column(&set, "b"))[0], 0.28612499999999996);
        assert_eq!(column(&set, "a").time, ColumnTime::Unknown);
        assert!(set.structure[0].starts_with("Parquet file, 3301 rows in 4 row groups, 3 columns"));
    }

    #[test]
    fn same_values_as_the_hdf5_fixture() {
        #[cfg(feature = "hdf5")]
        {
            let pq = read("parquet/quick.parquet");
            let h5 = super::super::hdf5::Hdf5
                .read(&fixture("hdf5/quick.h5"), &ReadOptions::default())
                .expect("quick.h5");
            for (p, h) in [("a", "enc/a"), ("b", "enc/b")] {
                assert_eq!(f64s(column(&pq, p)), f64s(column(&h5, h)));
            }
        }
    }

    /// BYTE_STREAM_SPLIT pages, joined by `parquet_guards` before the crate decodes them, give
    /// pyarrow's values exactly, on data pages v1 (levels with a length prefix) and v2.
    #[test]
    fn byte_stream_split_pages_on_both_page_versions() {
        for name in ["parquet/split_v1.parquet", "parquet/split_v2.parquet"] {
            let set = read(name);
            let i: Vec<f64> = (0..200).map(f64::from).collect();
            let expect = |f: fn(f64) -> f64| i.iter().map(|&i| f(i)).collect::<Vec<_>>();
            assert_eq!(f64s(column(&set, "t")), expect(|i| i / 100.0), "{name}");
            assert_eq!(f64s(column(&set, "d")), expect(|i| i / 4.0 - 7.0), "{name}");
            assert_eq!(f64s(column(&set, "f")), expect(|i| i / 2.0), "{name}");
            assert_eq!(f64s(column(&set, "i32")), expect(|i| i - 100.0), "{name}");
            assert_eq!(
                i64s(column(&set, "i64")),
                (0..200).map(|i| 3 * i).collect::<Vec<_>>()
            );
            assert!(
                set.structure
                    .iter()
                    .any(|l| l.contains("`gaps`") && l.contains("40 of 200 rows are null")),
                "{name}: {:?}",
                set.structure
            );
        }
    }

    #[test]
    fn types_nulls_and_what_is_left() {
        let set = read("parquet/shapes.parquet");
        let t = column(&set, "t_us");
        assert_eq!(t.time, ColumnTime::Stamps(TimeUnit::Us));
        assert_eq!(i64s(t)[49], START_NS / 1000 + 49_000);
        assert_eq!(f64s(column(&set, "f32"))[3], 1.5);
        assert_eq!(f64s(column(&set, "u16"))[49], 49.0);
        assert_eq!(
            f64s(column(&set, "u32"))[1],
            2_147_483_649.0,
            "uint32 above 2^31"
        );
        assert_eq!(i64s(column(&set, "i64"))[0], -25);
        assert_eq!(i64s(column(&set, "u64"))[1], (1 << 40) + 1);
        assert!(set.columns.iter().all(|c| c.name != "gaps"));
        assert_eq!(
            f64s(column(&set, "pose.x"))[30],
            30.0,
            "a struct's field by path"
        );
        assert_eq!(i64s(column(&set, "pose.n"))[30], 30);
        let structure = set.structure.join("\n");
        for left in [
            "`gaps`: double, optional — not taken: 8 of 50 rows are null (calib needs a reading \
             in every row)",
            "`xs.list.element`: double, optional — not taken: a list (repeated values per row)",
            "`label`: byte_array STRING, optional — not taken: strings or bytes",
            "`ok`: boolean, optional — not taken: booleans",
        ] {
            assert!(structure.contains(left), "{left} in\n{structure}");
        }
        assert!(
            structure.contains("`t_us`: int64 TIMESTAMP(us, UTC), optional → channel `t_us`"),
            "{structure}"
        );
    }

    #[test]
    fn int96_stamps_are_nanoseconds_since_1970() {
        let set = read("parquet/legacy.parquet");
        let t = column(&set, "t");
        assert_eq!(t.time, ColumnTime::Stamps(TimeUnit::Ns));
        assert_eq!(i64s(t)[..2], [START_NS, START_NS + 1_000_000]);
    }

    #[test]
    fn damaged_files_are_errors_naming_the_file() {
        let bytes = std::fs::read(fixture("parquet/quick.parquet")).expect("fixture");
        let dir = tempfile::tempdir().expect("temp dir");
        let mut huge_footer = bytes.clone();
        let n = huge_footer.len();
        huge_footer[n - 8..n - 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let mut flipped = bytes.clone();
        for i in (4..flipped.len() - 8).step_by(89) {
            flipped[i] ^= 0xa5;
        }
        let cases: Vec<(&str, Vec<u8>, Option<&str>)> = vec![
            ("magic only", b"PAR1".to_vec(), Some("4 bytes long")),
            (
                "cut short",
                bytes[..n / 2].to_vec(),
                Some("does not end in `PAR1`"),
            ),
            (
                "huge footer",
                huge_footer,
                Some("footer states 4294967295 bytes"),
            ),
            ("bytes flipped", flipped, None),
        ];
        for (what, data, says) in cases {
            let path = dir.path().join("bad.parquet");
            std::fs::write(&path, &data).expect("write");
            match Parquet.read(&path, &ReadOptions::default()) {
                Err(e) => {
                    let text = e.to_string();
                    assert!(text.contains("bad.parquet"), "{what}: {text}");
                    if let Some(says) = says {
                        assert!(text.contains(says), "{what}: {text}");
                    }
                }
                Ok(_) => assert!(says.is_none(), "{what} read without error"),
            }
        }
    }
}

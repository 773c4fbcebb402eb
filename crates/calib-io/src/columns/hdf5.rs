//! HDF5 files (h5py, pandas' `PyTables`, LabVIEW and DAQ exports) and MATLAB v7.3 MAT-files,
//! which are HDF5 behind a 512-byte header, read with the pure-Rust `rust-hdf5` crate.
//!
//! Every numeric dataset of one or two dimensions is taken, named by its path without the
//! leading `/` (`enc/a`): a 1-D dataset (or a 2-D one with a side of 1) is one channel, a 2-D
//! dataset one channel per index of its shorter side (`m[0]`, `m[1]`, …; the first dimension is
//! the samples when both are equal). MATLAB stores a matrix transposed, so a 5×N MATLAB matrix is
//! an N×5 dataset and its rows are `M[0]` … `M[4]` either way. Floats and integers of up to 32
//! bits become doubles, 64-bit integers stay integers (stamps in ns since 1970). A string
//! attribute `unit`/`units` (any case) is the channel's unit. Everything else — strings,
//! compound records, 3-D arrays, MATLAB cells, `char` and `logical` arrays — is listed in
//! [`ColumnSet::structure`] with why it was not taken.

use std::path::Path;

use rust_hdf5::{DatatypeMessage, H5Dataset, H5File, Hdf5Error};

use super::{Column, ColumnFormat, ColumnSet, ColumnTime, Values};
use crate::limits::{self, MAX_HDF5_DATASETS};
use crate::{Error, ReadOptions};

/// The 8-byte signature every HDF5 superblock starts with.
const SIGNATURE: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

/// The text a MATLAB v7.3 MAT-file's 128-byte header starts with.
const MAT73_TEXT: &[u8] = b"MATLAB 7.3 MAT-file";

/// HDF5 files: the superblock's signature at the start (a file with a user block is found by its
/// extension).
pub(crate) struct Hdf5;

/// MATLAB v7.3 MAT-files (`save -v7.3`, `hdf5storage`): HDF5 after a 512-byte header.
pub(crate) struct MatV73;

impl ColumnFormat for Hdf5 {
    fn name(&self) -> &'static str {
        "HDF5"
    }

    fn about(&self) -> &'static str {
        "HDF5 files (h5py, PyTables, DAQ exports): numeric datasets by path"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["h5", "hdf5", "hdf", "he5"]
    }

    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(SIGNATURE)
    }

    fn read(&self, path: &Path, _opts: &ReadOptions) -> Result<ColumnSet, Error> {
        read_file(path, false)
    }
}

impl ColumnFormat for MatV73 {
    fn name(&self) -> &'static str {
        "MATLAB v7.3"
    }

    fn about(&self) -> &'static str {
        "MATLAB v7.3 MAT-files (`save -v7.3`): numeric variables, which are HDF5 datasets"
    }

    fn extensions(&self) -> &'static [&'static str] {
        // `.mat` is found by its header: v4 and v5 files share the extension.
        &[]
    }

    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(MAT73_TEXT) || is_v73_header(head)
    }

    fn read(&self, path: &Path, _opts: &ReadOptions) -> Result<ColumnSet, Error> {
        read_file(path, true)
    }
}

/// Whether a 128-byte MAT-file header (text, subsystem offset, version, endian mark) states
/// version 0x0200, which MATLAB writes for v7.3 whatever its text says.
fn is_v73_header(head: &[u8]) -> bool {
    if head.len() < 128 || !head.starts_with(b"MATLAB") {
        return false;
    }
    matches!(
        &head[124..128],
        [0x00, 0x02, b'I', b'M'] | [0x02, 0x00, b'M', b'I']
    )
}

/// An [`Error::Data`] naming `path`, and `dataset` where one is concerned.
fn error(path: &Path, dataset: Option<&str>, message: String) -> Error {
    Error::Data {
        path: path.to_path_buf(),
        message: match dataset {
            Some(d) => format!("dataset `{d}`: {message}"),
            None => message,
        },
    }
}

/// Reads every numeric dataset of the HDF5 file (or MATLAB v7.3 file) at `path`.
fn read_file(path: &Path, matlab: bool) -> Result<ColumnSet, Error> {
    let file_len = std::fs::metadata(path)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    // A reader of a recording needs no lock: best effort, so that a file on a file system
    // without locks (NFS) or held by a writer still opens.
    let file = H5File::options()
        .best_effort_locking()
        .open(path)
        .map_err(|e| {
            error(
                path,
                None,
                format!("not a readable HDF5 file: {}", crate_message(&e)),
            )
        })?;
    let mut names = file.dataset_names();
    if names.len() > MAX_HDF5_DATASETS {
        return Err(error(
            path,
            None,
            format!(
                "{} datasets, more than the {MAX_HDF5_DATASETS} calib reads from one file; \
                 export the channels you need into a file of their own",
                names.len()
            ),
        ));
    }
    names.sort();
    let mut set = ColumnSet::default();
    set.structure.push(if matlab {
        format!(
            "MATLAB v7.3 MAT-file (HDF5 after a {}-byte header), {} variables",
            file.userblock_size(),
            names.len()
        )
    } else {
        format!("HDF5 file, {} datasets", names.len())
    });
    // The stated sizes of all taken datasets together: what they would hold in memory.
    let mut budget = limits::decompressed_limit(file_len);
    for name in &names {
        let shown = name.trim_start_matches('/');
        if matlab && (shown.starts_with("#refs#/") || shown == "#subsystem#") {
            // The contents of MATLAB cells and objects, reached only through references.
            continue;
        }
        let ds = file.dataset(name).map_err(|e| {
            error(
                path,
                Some(shown),
                format!("cannot be opened: {}", crate_message(&e)),
            )
        })?;
        match plan(&ds, matlab) {
            Err(why) => set
                .structure
                .push(format!("`{shown}`: {} — not taken: {why}", describe(&ds))),
            Ok(plan) => {
                let bytes = (ds.total_elements() as u64).saturating_mul(plan.size);
                if bytes > budget {
                    return Err(error(
                        path,
                        Some(shown),
                        format!(
                            "states {} values of {} bytes ({bytes} bytes), more than a file of \
                             {file_len} bytes can hold (at most {} bytes in all); the file is \
                             damaged",
                            ds.total_elements(),
                            plan.size,
                            limits::decompressed_limit(file_len),
                        ),
                    ));
                }
                // Each chunk is decompressed into a buffer of the size its stated dimensions
                // give, allocated before a byte is inflated: a damaged layout can state a chunk
                // far larger than the dataset (found by fuzzing: 111 GB in an 11 kB file).
                let chunk = ds.chunk_dims().map_or(0, |dims| {
                    dims.iter()
                        .try_fold(plan.size, |b, &d| b.checked_mul(d as u64))
                        .unwrap_or(u64::MAX)
                });
                if chunk > budget {
                    return Err(error(
                        path,
                        Some(shown),
                        format!(
                            "states chunks of {chunk} bytes, more than a file of {file_len} bytes \
                             can hold (at most {} bytes in all); the file is damaged",
                            limits::decompressed_limit(file_len),
                        ),
                    ));
                }
                budget -= bytes;
                let unit = unit_of(&ds);
                let first = set.columns.len();
                split(path, shown, &ds, &plan, unit, &mut set.columns)?;
                let taken: Vec<&str> = set.columns[first..]
                    .iter()
                    .map(|c| c.name.as_str())
                    .collect();
                set.structure.push(format!(
                    "`{shown}`: {} → {}",
                    describe(&ds),
                    channels_line(&taken)
                ));
            }
        }
    }
    Ok(set)
}

/// The crate's message for `e`, on one line.
fn crate_message(e: &Hdf5Error) -> String {
    e.to_string().replace('\n', " ")
}

/// How a dataset is read: its element type and how its values form channels.
struct Plan {
    /// The stored element's size in bytes.
    size: u64,
    /// Read as 64-bit integers (else as doubles).
    integer64: bool,
    /// Samples × channels (the channels along the shorter side), and whether the channels are
    /// the dataset's first dimension (rows in the file's row-major order).
    samples: usize,
    channels: usize,
    channels_are_rows: bool,
    /// Name each channel `name[i]` (false for one channel).
    indexed: bool,
}

/// How `ds` is read, or why it is not taken.
fn plan(ds: &H5Dataset, matlab: bool) -> Result<Plan, String> {
    let datatype = ds
        .datatype()
        .map_err(|e| format!("its type cannot be read ({})", crate_message(&e)))?;
    if matlab {
        if let Some(class) = string_attr(ds, "MATLAB_class") {
            match class.as_str() {
                "double" | "single" | "int8" | "uint8" | "int16" | "uint16" | "int32"
                | "uint32" | "int64" | "uint64" => {}
                other => return Err(format!("MATLAB class `{other}`, not numbers")),
            }
        }
        if ds
            .attr_names()
            .unwrap_or_default()
            .iter()
            .any(|a| a == "MATLAB_empty")
        {
            return Err("an empty MATLAB array".to_string());
        }
    }
    let (size, integer64) = match datatype {
        DatatypeMessage::FloatingPoint { size: 4 | 8, .. } => {
            (u64::from(size_of(&datatype)), false)
        }
        DatatypeMessage::FixedPoint {
            size: 1 | 2 | 4, ..
        } => (u64::from(size_of(&datatype)), false),
        DatatypeMessage::FixedPoint { size: 8, .. } => (8, true),
        DatatypeMessage::FloatingPoint { size, .. } => {
            return Err(format!("{}-bit floating point", size * 8));
        }
        _ => return Err("not numbers".to_string()),
    };
    let shape = ds.shape();
    let (samples, channels, channels_are_rows, indexed) = match shape[..] {
        [] => return Err("a single value".to_string()),
        [n] => (n, 1, false, false),
        [r, 1] => (r, 1, false, false),
        [1, c] => (c, 1, true, false),
        [r, c] if r >= c => (r, c, false, true),
        [r, c] => (c, r, true, true),
        _ => return Err(format!("{} dimensions (calib takes 1 or 2)", shape.len())),
    };
    if samples == 0 {
        return Err("no values".to_string());
    }
    Ok(Plan {
        size,
        integer64,
        samples,
        channels,
        channels_are_rows,
        indexed,
    })
}

/// The element size a numeric datatype states.
fn size_of(datatype: &DatatypeMessage) -> u32 {
    match datatype {
        DatatypeMessage::FloatingPoint { size, .. } | DatatypeMessage::FixedPoint { size, .. } => {
            *size
        }
        _ => 0,
    }
}

/// Reads `ds` and appends its channels, named after `name`, to `out`.
fn split(
    path: &Path,
    name: &str,
    ds: &H5Dataset,
    plan: &Plan,
    unit: Option<String>,
    out: &mut Vec<Column>,
) -> Result<(), Error> {
    let read_error = |e: Hdf5Error| {
        error(
            path,
            Some(name),
            format!("cannot be read: {}", crate_message(&e)),
        )
    };
    let all = if plan.integer64 {
        Values::I64(ds.read_numeric_as::<i64>().map_err(read_error)?)
    } else {
        match ds.datatype() {
            Ok(DatatypeMessage::FixedPoint { .. }) => Values::F64(
                ds.read_numeric_as::<i64>()
                    .map_err(read_error)?
                    .into_iter()
                    .map(|v| v as f64)
                    .collect(),
            ),
            _ => Values::F64(ds.read_numeric_as::<f64>().map_err(read_error)?),
        }
    };
    if all.len() != plan.samples * plan.channels {
        return Err(error(
            path,
            Some(name),
            format!(
                "holds {} values where its shape states {}; the file is damaged",
                all.len(),
                plan.samples * plan.channels
            ),
        ));
    }
    for i in 0..plan.channels {
        let values = match &all {
            Values::F64(v) => Values::F64(pick(v, plan, i)),
            Values::I64(v) => Values::I64(pick(v, plan, i)),
        };
        out.push(Column {
            name: if plan.indexed {
                format!("{name}[{i}]")
            } else {
                name.to_string()
            },
            unit: unit.clone(),
            values,
            time: ColumnTime::Unknown,
        });
    }
    Ok(())
}

/// Channel `i` of the row-major values `all`, laid out as `plan` says.
fn pick<T: Copy>(all: &[T], plan: &Plan, i: usize) -> Vec<T> {
    if plan.channels == 1 {
        all.to_vec()
    } else if plan.channels_are_rows {
        all[i * plan.samples..(i + 1) * plan.samples].to_vec()
    } else {
        all.iter().skip(i).step_by(plan.channels).copied().collect()
    }
}

/// The unit a dataset's `unit` or `units` attribute (any case) states.
fn unit_of(ds: &H5Dataset) -> Option<String> {
    let names = ds.attr_names().ok()?;
    let name = names
        .iter()
        .find(|n| n.eq_ignore_ascii_case("unit") || n.eq_ignore_ascii_case("units"))?;
    string_attr(ds, name)
        .map(|u| u.trim().to_string())
        .filter(|u| !u.is_empty())
}

/// The value of the string attribute `name` of `ds`, if it has one.
fn string_attr(ds: &H5Dataset, name: &str) -> Option<String> {
    ds.attr(name).ok()?.read_string().ok()
}

/// A dataset's type and shape as `calib inspect` lists them: `float64 [1000×3], deflate`.
fn describe(ds: &H5Dataset) -> String {
    let kind = match ds.datatype() {
        Ok(DatatypeMessage::FloatingPoint { size, .. }) => format!("float{}", size * 8),
        Ok(DatatypeMessage::FixedPoint { size, signed, .. }) => {
            format!("{}int{}", if signed { "" } else { "u" }, size * 8)
        }
        Ok(DatatypeMessage::FixedString { .. }) | Ok(DatatypeMessage::VarLenString { .. }) => {
            "string".to_string()
        }
        Ok(DatatypeMessage::Enum { .. }) => "enum".to_string(),
        Ok(DatatypeMessage::Compound { .. }) => "compound".to_string(),
        Ok(DatatypeMessage::Reference { .. }) => "references".to_string(),
        Ok(_) => "other type".to_string(),
        Err(_) => "unreadable type".to_string(),
    };
    let shape: Vec<String> = ds.shape().iter().map(usize::to_string).collect();
    let mut text = format!("{kind} [{}]", shape.join("×"));
    let filters: Vec<&str> = ds
        .filters()
        .unwrap_or_default()
        .iter()
        .map(|f| match f.id {
            1 => "deflate",
            2 => "shuffle",
            3 => "fletcher32",
            4 => "szip",
            5 => "nbit",
            6 => "scaleoffset",
            32000 => "lzf",
            _ => "filter",
        })
        .collect();
    if !filters.is_empty() {
        text.push_str(", ");
        text.push_str(&filters.join("+"));
    }
    text
}

/// The channels a dataset became, as one line: `channel \`a\`` or `channels \`m[0]\` … \`m[2]\``.
fn channels_line(names: &[&str]) -> String {
    match names {
        [one] => format!("channel `{one}`"),
        [first, .., last] => format!("{} channels `{first}` … `{last}`", names.len()),
        [] => "no channel".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/hdf5")
            .join(name)
    }

    fn read(format: &dyn ColumnFormat, name: &str) -> ColumnSet {
        format
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

    /// The figures of `calib simulate testdata/scenarios/quick.toml`'s CSV the fixtures were
    /// written from (its first row and its last stamp), exact: every writer stores the doubles
    /// it was given.
    const A0: f64 = 0.29229999999999995;
    const B0: f64 = 0.28612499999999996;

    #[test]
    fn h5py_datasets_are_channels_by_path_with_their_units() {
        let set = read(&Hdf5, "quick.h5");
        let names: Vec<&str> = set.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["enc/a", "enc/b", "t"]);
        let (a, b, t) = (
            column(&set, "enc/a"),
            column(&set, "enc/b"),
            column(&set, "t"),
        );
        assert_eq!(a.unit.as_deref(), Some("deg"), "attribute `unit`");
        assert_eq!(b.unit.as_deref(), Some("deg"), "attribute `units`");
        assert_eq!(t.unit.as_deref(), Some("s"));
        assert_eq!(f64s(a).len(), 3301);
        assert_eq!((f64s(a)[0], f64s(b)[0]), (A0, B0));
        assert_eq!(f64s(t)[3300], 16.5);
        assert!(set.columns.iter().all(|c| c.time == ColumnTime::Unknown));
        let structure = set.structure.join("\n");
        assert!(
            structure.contains("`enc/a`: float64 [3301], shuffle+deflate → channel `enc/a`"),
            "{structure}"
        );
        assert!(
            structure.contains("`notes`: string [2] — not taken: not numbers"),
            "{structure}"
        );
    }

    #[test]
    fn matlab_v73_rows_of_a_matrix_are_channels() {
        let head = std::fs::read(fixture("quick_v73.mat")).expect("fixture");
        assert!(MatV73.sniff(&head[..SNIFF]));
        assert!(
            !Hdf5.sniff(&head[..SNIFF]),
            "the signature is at 512, past the sniffed bytes"
        );
        let set = read(&MatV73, "quick_v73.mat");
        let names: Vec<&str> = set.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["enc[0]", "enc[1]", "t"]);
        let h5 = read(&Hdf5, "quick.h5");
        assert_eq!(f64s(column(&set, "enc[0]")), f64s(column(&h5, "enc/a")));
        assert_eq!(f64s(column(&set, "enc[1]")), f64s(column(&h5, "enc/b")));
        assert_eq!(f64s(column(&set, "t")), f64s(column(&h5, "t")));
        assert!(
            set.structure[0].starts_with("MATLAB v7.3 MAT-file (HDF5 after a 512-byte header)")
        );
        let structure = set.structure.join("\n");
        assert!(
            structure.contains("`label`: uint16 [5×1] — not taken: MATLAB class `char`"),
            "{structure}"
        );
    }

    const SNIFF: usize = super::super::SNIFF_BYTES;

    #[test]
    fn shapes_types_and_what_is_left() {
        let set = read(&Hdf5, "shapes.h5");
        // 3×40 float32: three channels of 40 samples along the short side.
        for i in 0..3 {
            let m = f64s(column(&set, &format!("m[{i}]")));
            assert_eq!(m.len(), 40);
            assert_eq!(m[5], 5.0 * (i + 1) as f64);
        }
        let be = f64s(column(&set, "be_i16"));
        assert_eq!((be[0], be[39]), (-20.0, 19.0), "big-endian int16");
        assert_eq!(
            column(&set, "u64").values,
            Values::I64((0..40).map(|i| (1 << 40) + i).collect()),
            "64-bit integers stay integers"
        );
        for i in 0..12 {
            assert_eq!(
                f64s(column(&set, &format!("many/c{i:02}")))[2],
                2.0 * i as f64
            );
        }
        let structure = set.structure.join("\n");
        for left in [
            "`cube`: float64 [2×3×4] — not taken: 3 dimensions (calib takes 1 or 2)",
            "`scalar`: float64 [] — not taken: a single value",
            "`records`: compound [4] — not taken: not numbers",
        ] {
            assert!(structure.contains(left), "{left} in\n{structure}");
        }
    }

    #[test]
    fn sniffs_the_signature_and_v73_headers_only() {
        assert!(Hdf5.sniff(b"\x89HDF\r\n\x1a\n\0\0\0\0"));
        assert!(!Hdf5.sniff(b"\x89HDF\r\n"));
        let mut v5 = [b' '; 128];
        v5[..19].copy_from_slice(b"MATLAB 5.0 MAT-file");
        v5[124..].copy_from_slice(&[0x00, 0x01, b'I', b'M']);
        assert!(!MatV73.sniff(&v5), "a v5 header is the MATLAB reader's");
        let mut v73 = v5;
        v73[..19].copy_from_slice(b"MATLAB 7.0 MAT-file");
        v73[124..].copy_from_slice(&[0x00, 0x02, b'I', b'M']);
        assert!(MatV73.sniff(&v73), "version 0x0200 whatever the text");
        assert!(!MatV73.sniff(b"MATLAB 5.0"));
    }

    #[test]
    fn damaged_files_are_errors_naming_the_file() {
        let bytes = std::fs::read(fixture("quick.h5")).expect("fixture");
        let dir = tempfile::tempdir().expect("temp dir");
        let mut cases: Vec<(&str, Vec<u8>)> = vec![
            ("signature only", bytes[..8].to_vec()),
            ("first half", bytes[..bytes.len() / 2].to_vec()),
            ("superblock only", bytes[..96].to_vec()),
        ];
        // Every 97th byte past the superblock flipped.
        let mut flipped = bytes.clone();
        for i in (100..flipped.len()).step_by(97) {
            flipped[i] ^= 0x5a;
        }
        cases.push(("bytes flipped", flipped));
        for (what, data) in cases {
            let path = dir.path().join("bad.h5");
            std::fs::write(&path, &data).expect("write");
            match Hdf5.read(&path, &ReadOptions::default()) {
                Err(e) => assert!(e.to_string().contains("bad.h5"), "{what}: {e}"),
                // A flip inside the compressed data of a chunk can go unnoticed by deflate only
                // if it still decodes; then the values differ, which is not this test's concern.
                Ok(_) => assert_eq!(what, "bytes flipped", "{what} read without error"),
            }
        }
    }
}

//! MATLAB `.mat` files of Level 4 (v4) and Level 5 (v5, and v7, its compressed form), as
//! MATLAB, Simulink, dSPACE, Octave and `scipy.io.savemat` write them.
//!
//! # Format
//!
//! MathWorks, "MAT-File Format". **v4** has no file header: matrices follow one another, each a
//! 20-byte header of five `i32` — the type `MOPT` (M: 0 little-endian, 1 big-endian IEEE; O: 0;
//! P: 0 double, 1 single, 2 int32, 3 int16, 4 uint16, 5 uint8; T: 0 numeric, 1 text, 2 sparse),
//! rows, columns, `imagf` (1: complex) and the name's length — then the name (usually ending in
//! a NUL; some writers leave it out), then the values column by column (and as many imaginary
//! ones if complex). **v5** starts with a 128-byte header (text, subsystem offset, version
//! `0x0100`, `IM` or `MI` for the byte order), then data elements: a tag (type and length; a
//! small element packs both into 4 bytes and its data into the next 4) and data padded to 8
//! bytes. A variable is an `miMATRIX` (array flags and class, dimensions, name, real part,
//! imaginary part; for a struct the field names and then each field's `miMATRIX`), or an
//! `miCOMPRESSED` element holding one, zlib-compressed. **v7.3** files are HDF5 inside (their
//! header says `MATLAB 7.3 MAT-file`): not this format.
//!
//! # What calib takes
//!
//! Every real numeric variable of two or more values: a vector is the channel `name`; a matrix
//! gives one channel per row or column along its short side, `name[i]` (0-based), its samples
//! along the long side (a MATLAB-saved `5 × 26213` log is five channels of 26213 samples); the
//! fields of a 1 × 1 struct are `name.field`. Text, cells, sparse, complex and logical arrays,
//! scalars, objects and struct arrays are listed, not taken.
//!
//! Hand-written rather than the `matfile` crate (0.5): that reads v5 only (not the v4 files
//! MATLAB's `-v4` and many lab scripts write), skips struct fields, and allocates what a
//! variable's header states; here every length is checked against the file, and compressed
//! variables are inflated with a cap on their size, before anything is allocated.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use flate2::read::ZlibDecoder;

use super::binary::{Cursor, Endian, Fail, Kind, as_variant, extend, read_file};
use super::{Column, ColumnFormat, ColumnSet, ColumnTime, Values};
use crate::limits::{self, MAX_CSV_COLUMNS, MAX_DECOMPRESSION_RATIO};
use crate::{Error, ReadOptions};

/// MATLAB `.mat`, the [`ColumnFormat`].
pub(crate) struct Mat;

impl ColumnFormat for Mat {
    fn name(&self) -> &'static str {
        "MATLAB"
    }

    fn about(&self) -> &'static str {
        "MATLAB .mat v4 and v5/v7 (MATLAB, Simulink, dSPACE, scipy): vectors `name`, a \
         matrix's rows or columns `name[i]`, struct fields `name.field` (v7.3 is HDF5)"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["mat"]
    }

    fn sniff(&self, head: &[u8]) -> bool {
        v5_endian(head).is_some() || v4_header(head).is_some_and(|h| name_looks_valid(h, head))
    }

    fn read(&self, path: &Path, _opts: &ReadOptions) -> Result<ColumnSet, Error> {
        read_file(path, read_mat)
    }
}

/// What to do about a damaged file.
const RESAVE: &str = "the file is damaged or cut short; save the variables again (MATLAB \
                      `save FILE -v7`, or `scipy.io.savemat`)";
/// Bytes of a v5 file's header.
const V5_HEADER: u64 = 128;
/// The longest variable name calib accepts in a v4 header (MATLAB's are at most 63 characters;
/// other writers' a few hundred).
const MAX_V4_NAME: i32 = 4096;
/// How deep structs may nest (MATLAB logs nest two or three levels; the limit keeps a crafted
/// file from recursing without end).
const MAX_DEPTH: usize = 16;

/// v5 data types.
const MI_INT8: u32 = 1;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;

/// Reads a v4 or v5 file of `len` bytes.
fn read_mat(r: &mut (impl Read + Seek), len: u64) -> Result<ColumnSet, Fail> {
    let mut head = vec![0; len.min(V5_HEADER) as usize];
    r.read_exact(&mut head)?;
    r.seek(SeekFrom::Start(0))?;
    if let Some(endian) = v5_endian(&head) {
        return read_v5(r, len, &head, endian);
    }
    if v4_header(&head).is_some() {
        return read_v4(r, len);
    }
    Err(Fail::Bad(if head.starts_with(b"MATLAB 7.3") {
        "a MATLAB v7.3 MAT-file, which is HDF5 inside; read it as HDF5, or save it again as \
         v7 (`save FILE -v7`)"
            .into()
    } else {
        format!(
            "not a MATLAB v4 or v5 MAT-file: it starts with {}; save the variables with MATLAB \
             `save FILE -v7` (or `-v4`) or `scipy.io.savemat`",
            limits::shown_bytes(&head[..head.len().min(20)])
        )
    }))
}

/// The byte order of a v5 header (`MATLAB 5.0 MAT-file`, version `0x0100`, `IM` or `MI`).
fn v5_endian(head: &[u8]) -> Option<Endian> {
    if head.len() < V5_HEADER as usize || !head.starts_with(b"MATLAB 5.0 MAT-file") {
        return None;
    }
    match (&head[124..126], &head[126..128]) {
        ([0, 1], b"IM") => Some(Endian::Little),
        ([1, 0], b"MI") => Some(Endian::Big),
        _ => None,
    }
}

/// A v4 matrix header.
#[derive(Debug, Clone, Copy, PartialEq)]
struct V4Header {
    endian: Endian,
    /// P: the precision of the values.
    kind: Kind,
    /// T: 0 numeric, 1 text, 2 sparse.
    form: i32,
    rows: u64,
    cols: u64,
    complex: bool,
    name_len: u64,
}

/// The v4 matrix header at the start of `h`, if its 20 bytes are one: a type `MOPT` whose M
/// says the byte order it is read in, O 0, P and T known, sizes not negative, a name.
fn v4_header(h: &[u8]) -> Option<V4Header> {
    let h = h.get(..20)?;
    [Endian::Little, Endian::Big]
        .into_iter()
        .find_map(|endian| {
            let mut c = Cursor::new(h, endian);
            let [ty, rows, cols, imagf, name_len] = [(); 5].map(|_| c.i32().unwrap_or(-1));
            let m = if endian == Endian::Little { 0 } else { 1 };
            let kind = match ty / 10 % 10 {
                0 => Kind::F64,
                1 => Kind::F32,
                2 => Kind::I32,
                3 => Kind::I16,
                4 => Kind::U16,
                5 => Kind::U8,
                _ => return None,
            };
            let ok = (0..5000).contains(&ty)
                && ty / 1000 == m
                && ty / 100 % 10 == 0
                && ty % 10 <= 2
                && rows >= 0
                && cols >= 0
                && (0..=1).contains(&imagf)
                && (1..=MAX_V4_NAME).contains(&name_len);
            ok.then_some(V4Header {
                endian,
                kind,
                form: ty % 10,
                rows: rows as u64,
                cols: cols as u64,
                complex: imagf == 1,
                name_len: name_len as u64,
            })
        })
}

/// Whether the name after a v4 header, as far as `head` holds it, is printable ASCII ending
/// in at most one NUL: with the header's checks, enough that no CSV, text or other binary
/// format is taken for v4.
fn name_looks_valid(h: V4Header, head: &[u8]) -> bool {
    let name = &head[20..head.len().min(20 + h.name_len as usize)];
    let text = name.strip_suffix(&[0]).unwrap_or(name);
    !text.is_empty() && text.iter().all(|b| b.is_ascii_graphic())
}

/// The name of a v4 precision.
fn v4_type(kind: Kind) -> &'static str {
    match kind {
        Kind::F64 => "double",
        Kind::F32 => "single",
        Kind::I32 => "int32",
        Kind::I16 => "int16",
        Kind::U16 => "uint16",
        _ => "uint8",
    }
}

/// Reads a v4 file: matrices one after another.
fn read_v4(r: &mut (impl Read + Seek), len: u64) -> Result<ColumnSet, Fail> {
    let mut out = Out::default();
    let mut endians = Vec::new();
    let mut at = 0;
    let mut k = 0;
    let mut buf = Vec::new();
    while at < len {
        let bad = |what: String| Fail::Bad(format!("matrix {k} (at byte {at}): {what}; {RESAVE}"));
        if len - at < 20 {
            return Err(bad(format!(
                "{} bytes are left, fewer than a matrix header's 20",
                len - at
            )));
        }
        let mut head = [0; 20];
        r.read_exact(&mut head)?;
        let h = v4_header(&head).ok_or_else(|| {
            bad(format!(
                "{} is not a MATLAB v4 matrix header",
                limits::shown_bytes(&head)
            ))
        })?;
        if !endians.contains(&h.endian) {
            endians.push(h.endian);
        }
        let left = len - at - 20;
        if h.name_len > left {
            return Err(bad(format!(
                "its name is {} bytes long, but only {left} are left",
                h.name_len
            )));
        }
        buf.clear();
        r.by_ref().take(h.name_len).read_to_end(&mut buf)?;
        let name = c_string(&buf);
        let bad = |what: String| {
            Fail::Bad(format!(
                "matrix {k} `{name}` (at byte {at}): {what}; {RESAVE}"
            ))
        };
        let left = left - h.name_len;
        let values = h.rows.saturating_mul(h.cols);
        let bytes = values
            .saturating_mul(h.kind.size() as u64)
            .saturating_mul(if h.complex { 2 } else { 1 });
        if bytes > left {
            return Err(bad(format!(
                "{} × {} {} values{} need {bytes} bytes, but only {left} are left",
                h.rows,
                h.cols,
                v4_type(h.kind),
                if h.complex { " (complex)" } else { "" }
            )));
        }
        let shape = format!("{} × {} {}", h.rows, h.cols, v4_type(h.kind));
        let refused = match (h.form, h.complex) {
            (1, _) => Some("text is not readings"),
            (2, _) => Some("sparse matrices are not read; save it full (`full(x)`)"),
            (_, true) => Some("complex values are not readings"),
            _ => None,
        };
        if let Some(why) = refused {
            out.refuse(&name, &shape, why);
            r.seek(SeekFrom::Current(bytes as i64))?;
        } else {
            // Within the file (checked above), so no larger than what it holds.
            buf.resize(bytes as usize, 0);
            r.read_exact(&mut buf)?;
            let stored = (h.kind, h.endian, buf.as_slice());
            out.matrix(&name, &shape, (h.rows, h.cols), stored, false)
                .map_err(bad)?;
        }
        at += 20 + h.name_len + bytes;
        k += 1;
    }
    let order: Vec<&str> = endians.iter().map(|e| e.name()).collect();
    out.structure.insert(
        0,
        format!(
            "MATLAB v4 MAT-file (Level 1.0), {}, {k} matri{}",
            if order.is_empty() {
                "empty".to_string()
            } else {
                order.join(" and ")
            },
            if k == 1 { "x" } else { "ces" }
        ),
    );
    out.finish()
}

/// A name stored as bytes, up to its first NUL.
fn c_string(bytes: &[u8]) -> String {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..end]).into_owned()
}

/// Reads a v5 file: the header, then variables.
fn read_v5(
    r: &mut (impl Read + Seek),
    len: u64,
    head: &[u8],
    endian: Endian,
) -> Result<ColumnSet, Fail> {
    let mut out = Out::default();
    let text = String::from_utf8_lossy(&head[..116]);
    out.structure.push(format!(
        "MATLAB v5 MAT-file, {} (`{}`)",
        endian.name(),
        text.trim_end_matches(['\0', ' '])
    ));
    let mut at = V5_HEADER;
    let mut k = 0;
    let mut buf = Vec::new();
    r.seek(SeekFrom::Start(at))?;
    while at < len {
        let bad =
            |what: String| Fail::Bad(format!("variable {k} (at byte {at}): {what}; {RESAVE}"));
        if len - at < 8 {
            return Err(bad(format!(
                "{} bytes are left, fewer than a data element's 8-byte tag",
                len - at
            )));
        }
        let mut tag = [0; 8];
        r.read_exact(&mut tag)?;
        let mut c = Cursor::new(&tag, endian);
        let (ty, n) = (c.u32().unwrap_or(0), c.u32().unwrap_or(0));
        let left = len - at - 8;
        if u64::from(n) > left {
            return Err(bad(format!(
                "it says it is {n} bytes long, but only {left} are left"
            )));
        }
        // Within the file (checked above), so no larger than what it holds.
        buf.resize(n as usize, 0);
        r.read_exact(&mut buf)?;
        match ty {
            MI_MATRIX => matrix(&buf, endian, None, 0, &mut out, "").map_err(&bad)?,
            MI_COMPRESSED => {
                let (inner, data) = inflate(&buf, endian).map_err(&bad)?;
                if inner != MI_MATRIX {
                    out.structure.push(format!(
                        "variable {k}: a compressed data element of type {inner}, not a \
                         variable: left out"
                    ));
                } else {
                    matrix(&data, endian, None, 0, &mut out, " (compressed)").map_err(bad)?;
                }
            }
            _ => out.structure.push(format!(
                "variable {k}: a data element of type {ty}, not a variable: left out"
            )),
        }
        // Elements are padded to 8 bytes; compressed ones are not.
        let pad = if ty == MI_COMPRESSED {
            0
        } else {
            (8 - u64::from(n) % 8) % 8
        };
        at = (at + 8 + u64::from(n) + pad).min(len);
        r.seek(SeekFrom::Start(at))?;
        k += 1;
    }
    out.finish()
}

/// The data element of an `miCOMPRESSED` element, inflated: its type and bytes. Its stated
/// length is checked against [`MAX_DECOMPRESSION_RATIO`] times the compressed length before
/// any of it is kept, and only what the stream really holds is allocated.
fn inflate(compressed: &[u8], endian: Endian) -> Result<(u32, Vec<u8>), String> {
    let mut z = ZlibDecoder::new(compressed);
    let mut tag = [0; 8];
    z.read_exact(&mut tag)
        .map_err(|e| format!("its compressed data does not inflate ({e})"))?;
    let mut c = Cursor::new(&tag, endian);
    let (ty, n) = (c.u32()?, c.u32()?);
    let limit = limits::decompressed_limit(compressed.len() as u64);
    if u64::from(n) > limit {
        return Err(format!(
            "its {} compressed bytes say they hold {n}, more than {MAX_DECOMPRESSION_RATIO} \
             times as many",
            compressed.len()
        ));
    }
    let mut data = Vec::new();
    z.take(u64::from(n))
        .read_to_end(&mut data)
        .map_err(|e| format!("its compressed data does not inflate ({e})"))?;
    if data.len() as u64 != u64::from(n) {
        return Err(format!(
            "its compressed data inflates to {} bytes, its tag says {n}",
            data.len()
        ));
    }
    Ok((ty, data))
}

/// A v5 data element: its type and data (the padding after it passed over).
fn element<'a>(c: &mut Cursor<'a>, what: &str) -> Result<(u32, &'a [u8]), String> {
    let fail = |e: String| format!("its {what}: {e}");
    let first = c.u32().map_err(fail)?;
    if first >> 16 != 0 {
        // The small element format: length in the upper half, data in the next 4 bytes.
        let n = (first >> 16) as usize;
        if n > 4 {
            return Err(fail(format!(
                "a small data element of {n} bytes, where at most 4 fit"
            )));
        }
        let data = c.take(4).map_err(fail)?;
        return Ok((first & 0xFFFF, &data[..n]));
    }
    let n = c.u32().map_err(fail)?;
    let data = c.take(u64::from(n)).map_err(fail)?;
    c.skip_up_to((8 - n as usize % 8) % 8);
    Ok((first, data))
}

/// The number type of a v5 data type.
fn mi_kind(ty: u32) -> Option<Kind> {
    Some(match ty {
        1 => Kind::I8,
        2 => Kind::U8,
        3 => Kind::I16,
        4 => Kind::U16,
        5 => Kind::I32,
        6 => Kind::U32,
        7 => Kind::F32,
        9 => Kind::F64,
        12 => Kind::I64,
        13 => Kind::U64,
        _ => return None,
    })
}

/// The name of a v5 array class.
fn class_name(class: u32) -> &'static str {
    match class {
        1 => "cell",
        2 => "struct",
        3 => "object",
        4 => "char",
        5 => "sparse",
        6 => "double",
        7 => "single",
        8 => "int8",
        9 => "uint8",
        10 => "int16",
        11 => "uint16",
        12 => "int32",
        13 => "uint32",
        14 => "int64",
        15 => "uint64",
        16 => "function handle",
        _ => "opaque",
    }
}

/// Reads an `miMATRIX`'s data into `out`: a numeric array as channels, a struct's fields
/// (named `name.field`) one by one, anything else as a line saying why it is not taken.
/// `field` names a struct field (whose own name is empty); `note` is added to its line.
fn matrix(
    data: &[u8],
    endian: Endian,
    field: Option<&str>,
    depth: usize,
    out: &mut Out,
    note: &str,
) -> Result<(), String> {
    let mut c = Cursor::new(data, endian);
    let (ty, flags) = element(&mut c, "array flags")?;
    if ty != MI_UINT32 || flags.len() != 8 {
        return Err(format!(
            "array flags of type {ty} and {} bytes, not 8 bytes of miUINT32",
            flags.len()
        ));
    }
    let flags = Cursor::new(flags, endian).u32()?;
    let class = flags & 0xFF;
    let (complex, logical) = (flags & 0x800 != 0, flags & 0x200 != 0);
    let (ty, dims) = element(&mut c, "dimensions")?;
    if ty != MI_INT32 || dims.len() < 8 || dims.len() % 4 != 0 {
        return Err(format!(
            "dimensions of type {ty} and {} bytes, not two or more miINT32",
            dims.len()
        ));
    }
    let mut dc = Cursor::new(dims, endian);
    let dims: Vec<u64> = (0..dims.len() / 4)
        .map(|_| dc.i32().map(|d| u64::try_from(d).unwrap_or(u64::MAX)))
        .collect::<Result<_, _>>()?;
    if dims.contains(&u64::MAX) {
        return Err("a negative dimension".into());
    }
    let (ty, name) = element(&mut c, "name")?;
    if ty != MI_INT8 && !name.is_empty() {
        return Err(format!("a name of type {ty}, not miINT8"));
    }
    let name = match field {
        Some(f) => f.to_owned(),
        None => c_string(name),
    };
    let within = |e: String| format!("variable `{name}`: {e}");
    let shape = format!(
        "{} {}{note}",
        dims.iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(" × "),
        class_name(class)
    );
    let count = dims.iter().try_fold(1u64, |n, &d| n.checked_mul(d));
    match class {
        6..=15 => {
            let (ty, real) = element(&mut c, "values").map_err(within)?;
            let kind = mi_kind(ty)
                .ok_or_else(|| within(format!("values of data type {ty}, not numbers")))?;
            let size = kind.size();
            let stored = (real.len() / size) as u64;
            if real.len() % size != 0 || Some(stored) != count {
                return Err(within(format!(
                    "its dimensions {} make {} values, its data holds {} bytes of {}",
                    dims.iter()
                        .map(u64::to_string)
                        .collect::<Vec<_>>()
                        .join(" × "),
                    count.map_or("too many".to_string(), |n| n.to_string()),
                    real.len(),
                    kind.name()
                )));
            }
            let long: Vec<u64> = dims.iter().copied().filter(|&d| d > 1).collect();
            let why = if complex {
                Some("complex values are not readings")
            } else if logical {
                Some("true/false values are not readings")
            } else if long.len() > 2 {
                Some("an array of three or more dimensions; calib reads vectors and matrices")
            } else {
                None
            };
            if let Some(why) = why {
                out.refuse(&name, &shape, why);
                return Ok(());
            }
            let (rows, cols) = (dims[0], stored / dims[0].max(1));
            out.matrix(
                &name,
                &shape,
                (rows, cols),
                (kind, endian, real),
                class >= 14,
            )
            .map_err(within)?;
        }
        2 => {
            let (ty, len) = element(&mut c, "field name length").map_err(within)?;
            let field_len = match (ty, len.len()) {
                (MI_INT32, 4) => Cursor::new(len, endian).i32().unwrap_or(0),
                _ => 0,
            };
            let (_, names) = element(&mut c, "field names").map_err(within)?;
            if field_len <= 0 || names.len() % field_len as usize != 0 {
                return Err(within(format!(
                    "field names of {} bytes in fields of {field_len}",
                    names.len()
                )));
            }
            let names: Vec<String> = names.chunks(field_len as usize).map(c_string).collect();
            if count != Some(1) {
                out.refuse(
                    &name,
                    &shape,
                    "a struct array; calib reads the fields of a 1 × 1 struct",
                );
                return Ok(());
            }
            if depth >= MAX_DEPTH {
                out.refuse(&name, &shape, "structs nested more than 16 deep");
                return Ok(());
            }
            out.structure.push(format!(
                "`{name}`: {shape} of fields {}",
                limits::listed(&names)
            ));
            for f in &names {
                let (ty, data) = element(&mut c, &format!("field `{f}`")).map_err(within)?;
                if ty != MI_MATRIX {
                    return Err(within(format!(
                        "field `{f}` of data type {ty}, not miMATRIX"
                    )));
                }
                matrix(
                    data,
                    endian,
                    Some(&format!("{name}.{f}")),
                    depth + 1,
                    out,
                    "",
                )?;
            }
        }
        _ => {
            let why = match class {
                1 => {
                    "cell arrays are not read; store the signals as numeric arrays or a struct of them"
                }
                3 => "objects are not read",
                4 => "text is not readings",
                5 => "sparse arrays are not read; save it full (`full(x)`)",
                _ => "not numbers",
            };
            out.refuse(&name, &shape, why);
        }
    }
    Ok(())
}

/// The columns and structure lines gathered so far.
#[derive(Debug, Default)]
struct Out {
    columns: Vec<Column>,
    structure: Vec<String>,
}

impl Out {
    fn refuse(&mut self, name: &str, shape: &str, why: &str) {
        self.structure
            .push(format!("`{name}`: {shape}: not taken: {why}"));
    }

    /// A `rows × cols` array of `kind` stored column-major in `bytes` as channels: a vector
    /// as `name`, a matrix as `name[i]` along its short side; `wide` keeps them as 64-bit
    /// integers (a MATLAB `int64` or `uint64` array, whatever type stores it). Each channel is
    /// decoded straight from the bytes, with no copy of the whole matrix.
    fn matrix(
        &mut self,
        name: &str,
        shape: &str,
        (rows, cols): (u64, u64),
        (kind, endian, bytes): (Kind, Endian, &[u8]),
        wide: bool,
    ) -> Result<(), String> {
        let size = kind.size();
        let count = (rows * cols) as usize;
        if count < 2 {
            self.refuse(name, shape, "one value or none, not a channel");
            return Ok(());
        }
        let (rows, cols) = (rows as usize, cols as usize);
        let (channels, samples) = if rows == 1 || cols == 1 {
            (1, count)
        } else {
            (rows.min(cols), rows.max(cols))
        };
        if self.columns.len() + channels > MAX_CSV_COLUMNS {
            self.refuse(
                name,
                shape,
                &format!("{channels} channels, more than the {MAX_CSV_COLUMNS} of any log"),
            );
            return Ok(());
        }
        if channels == 1 {
            self.structure
                .push(format!("`{name}`: {shape} → `{name}`, {samples} samples"));
        } else {
            self.structure.push(format!(
                "`{name}`: {shape} → {} `{name}[0]` … `{name}[{}]`, {samples} samples each",
                if rows >= cols { "columns" } else { "rows" },
                channels - 1
            ));
        }
        for i in 0..channels {
            // Value (i, j) is at j·rows + i: a column is contiguous, a row strided.
            let (start, stride) = if channels == 1 || rows >= cols {
                (i * samples * size, size)
            } else {
                (i * size, rows * size)
            };
            let mut values = kind.empty(samples);
            extend(&mut values, kind, endian, &bytes[start..], stride, samples)
                .map_err(|e| format!("its values cannot be decoded ({e:?})"))?;
            let channel = if channels == 1 {
                name.to_owned()
            } else {
                format!("{name}[{i}]")
            };
            self.push(channel, as_variant(values, wide));
        }
        Ok(())
    }

    fn push(&mut self, name: String, values: Values) {
        self.columns.push(Column {
            name,
            unit: None,
            values,
            time: ColumnTime::Unknown,
        });
    }

    fn finish(self) -> Result<ColumnSet, Fail> {
        Ok(ColumnSet {
            columns: self.columns,
            structure: self.structure,
        })
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use flate2::Compression;
    use flate2::write::ZlibEncoder;

    use super::*;

    fn read(bytes: &[u8]) -> Result<ColumnSet, String> {
        read_mat(&mut std::io::Cursor::new(bytes), bytes.len() as u64).map_err(|e| match e {
            Fail::Io(e) => format!("io: {e}"),
            Fail::Bad(m) => m,
        })
    }

    fn column<'a>(set: &'a ColumnSet, name: &str) -> &'a Column {
        set.columns
            .iter()
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("no `{name}` in {:?}", set.structure))
    }

    fn f64s(set: &ColumnSet, name: &str) -> Vec<f64> {
        match &column(set, name).values {
            Values::F64(v) => v.clone(),
            other => panic!("{other:?}"),
        }
    }

    fn bytes32(big: bool, xs: &[i32]) -> Vec<u8> {
        xs.iter()
            .flat_map(|x| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect()
    }

    /// A v4 matrix: header, name (as given: with its NUL, or without as some writers leave it),
    /// values.
    fn v4(big: bool, p: i32, t: i32, rows: i32, cols: i32, name: &str, data: &[u8]) -> Vec<u8> {
        let m = i32::from(big);
        let mut out = bytes32(
            big,
            &[m * 1000 + p * 10 + t, rows, cols, 0, name.len() as i32],
        );
        out.extend(name.as_bytes());
        out.extend(data);
        out
    }

    fn doubles(big: bool, xs: &[f64]) -> Vec<u8> {
        xs.iter()
            .flat_map(|x| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect()
    }

    #[test]
    fn v4_matrices_give_rows_or_columns_along_their_short_side() {
        // 3 × 4 double, as the real recording is laid out (rows are channels): column-major.
        let m: Vec<f64> = (0..4)
            .flat_map(|j| (0..3).map(move |i| (10 * i + j) as f64))
            .collect();
        let mut file = v4(false, 0, 0, 3, 4, "data_1", &doubles(false, &m));
        // 4 × 2 int16: columns are channels.
        let ints: Vec<u8> = [1i16, 2, 3, 4, -1, -2, -3, -4]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        file.extend(v4(false, 3, 0, 4, 2, "k\0", &ints));
        file.extend(v4(
            false,
            0,
            0,
            1,
            4,
            "t\0",
            &doubles(false, &[0.0, 0.1, 0.2, 0.3]),
        ));
        file.extend(v4(
            false,
            0,
            1,
            1,
            2,
            "note\0",
            &doubles(false, &[104.0, 105.0]),
        ));
        file.extend(v4(false, 0, 0, 1, 1, "fs\0", &doubles(false, &[1000.0])));
        let set = read(&file).unwrap();
        assert_eq!(f64s(&set, "data_1[0]"), [0.0, 1.0, 2.0, 3.0]);
        assert_eq!(f64s(&set, "data_1[2]"), [20.0, 21.0, 22.0, 23.0]);
        assert_eq!(f64s(&set, "k[1]"), [-1.0, -2.0, -3.0, -4.0]);
        assert_eq!(f64s(&set, "t"), [0.0, 0.1, 0.2, 0.3]);
        assert_eq!(set.columns.len(), 6);
        assert_eq!(
            set.structure,
            [
                "MATLAB v4 MAT-file (Level 1.0), little-endian, 5 matrices",
                "`data_1`: 3 × 4 double → rows `data_1[0]` … `data_1[2]`, 4 samples each",
                "`k`: 4 × 2 int16 → columns `k[0]` … `k[1]`, 4 samples each",
                "`t`: 1 × 4 double → `t`, 4 samples",
                "`note`: 1 × 2 double: not taken: text is not readings",
                "`fs`: 1 × 1 double: not taken: one value or none, not a channel",
            ]
        );
    }

    #[test]
    fn v4_big_endian_and_every_precision() {
        let mut file = v4(true, 1, 0, 2, 1, "s\0", &[0x3F, 0xC0, 0, 0, 0xC0, 0, 0, 0]);
        file.extend(v4(true, 2, 0, 1, 2, "i\0", &bytes32(true, &[-7, 70_000])));
        file.extend(v4(true, 4, 0, 1, 2, "u\0", &[0xFF, 0xFF, 0, 1]));
        file.extend(v4(true, 5, 0, 1, 2, "b\0", &[255, 3]));
        let set = read(&file).unwrap();
        assert_eq!(f64s(&set, "s"), [1.5, -2.0]);
        assert_eq!(f64s(&set, "i"), [-7.0, 70_000.0]);
        assert_eq!(f64s(&set, "u"), [65535.0, 1.0]);
        assert_eq!(f64s(&set, "b"), [255.0, 3.0]);
        assert!(set.structure[0].contains("big-endian"));
    }

    /// A v5 data element: tag, data, padding to 8 (the small format where `data` fits in 4).
    fn el(big: bool, ty: u32, data: &[u8]) -> Vec<u8> {
        let u32b = |x: u32| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        };
        let mut out = Vec::new();
        if !data.is_empty() && data.len() <= 4 {
            out.extend(u32b(((data.len() as u32) << 16) | ty));
            out.extend(data);
            out.resize(8, 0);
            return out;
        }
        out.extend(u32b(ty));
        out.extend(u32b(data.len() as u32));
        out.extend(data);
        out.resize(out.len().div_ceil(8) * 8, 0);
        out
    }

    /// An `miMATRIX` element: flags (class and extra bits), dimensions, name, then `rest`.
    fn mx(big: bool, class: u32, extra: u32, dims: &[i32], name: &str, rest: &[u8]) -> Vec<u8> {
        let u32b = |x: u32| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        };
        let mut flags = u32b(class | extra).to_vec();
        flags.extend([0; 4]);
        let mut body = el(big, MI_UINT32, &flags);
        body.extend(el(big, MI_INT32, &bytes32(big, dims)));
        body.extend(el(big, MI_INT8, name.as_bytes()));
        body.extend(rest);
        el(big, MI_MATRIX, &body)
    }

    fn header(big: bool) -> Vec<u8> {
        let mut h = b"MATLAB 5.0 MAT-file, written by a test".to_vec();
        h.resize(116, b' ');
        h.extend([0; 8]);
        h.extend(if big {
            [1, 0, b'M', b'I']
        } else {
            [0, 1, b'I', b'M']
        });
        h
    }

    fn compressed(big: bool, element: &[u8]) -> Vec<u8> {
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(element).unwrap();
        let data = z.finish().unwrap();
        let u32b = |x: u32| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        };
        let mut out = u32b(MI_COMPRESSED).to_vec();
        out.extend(u32b(data.len() as u32));
        out.extend(data);
        out
    }

    /// A v5 file of every kind of variable, in byte order `big`.
    fn v5_file(big: bool) -> Vec<u8> {
        let mut file = header(big);
        // A double vector stored as uint8, as MATLAB stores small integers.
        file.extend(mx(big, 6, 0, &[1, 5], "t", &el(big, 2, &[0, 1, 2, 3, 4])));
        // A 2 × 3 int64 matrix, compressed: rows are channels.
        let big_ints: Vec<u8> = [1i64 << 60, -1, 2, -2, 3, -3]
            .iter()
            .flat_map(|x| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        file.extend(compressed(
            big,
            &mx(big, 14, 0, &[2, 3], "n", &el(big, 12, &big_ints)),
        ));
        // A struct {a: single column vector, deep: {x: int16 vector}, s: char}.
        let field = |name: &[u8]| {
            let mut f = name.to_vec();
            f.resize(8, 0);
            f
        };
        let mut names = field(b"a");
        names.extend(field(b"deep"));
        names.extend(field(b"s"));
        let singles: Vec<u8> = [0.5f32, 1.5]
            .iter()
            .flat_map(|x| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        let i16s: Vec<u8> = [-3i16, 4]
            .iter()
            .flat_map(|x| {
                if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        let mut deep_rest = el(big, MI_INT32, &bytes32(big, &[8]));
        deep_rest.extend(el(big, MI_INT8, &field(b"x")));
        deep_rest.extend(mx(big, 10, 0, &[1, 2], "", &el(big, 3, &i16s)));
        let mut rest = el(big, MI_INT32, &bytes32(big, &[8]));
        rest.extend(el(big, MI_INT8, &names));
        rest.extend(mx(big, 7, 0, &[2, 1], "", &el(big, 7, &singles)));
        rest.extend(mx(big, 2, 0, &[1, 1], "", &deep_rest));
        rest.extend(mx(big, 4, 0, &[1, 2], "", &el(big, 4, &[0, b'h', 0, b'i'])));
        file.extend(mx(big, 2, 0, &[1, 1], "run", &rest));
        // Listed, not taken: a cell, a logical vector, a complex vector, a 3-D array.
        file.extend(mx(big, 1, 0, &[1, 0], "c", &[]));
        file.extend(mx(big, 9, 0x200, &[1, 2], "ok", &el(big, 2, &[1, 0])));
        file.extend(mx(
            big,
            6,
            0x800,
            &[1, 2],
            "z",
            &[el(big, 2, &[1, 2]), el(big, 2, &[3, 4])].concat(),
        ));
        file.extend(mx(big, 9, 0, &[2, 2, 2], "cube", &el(big, 2, &[1; 8])));
        file
    }

    #[test]
    fn v5_variables_of_every_kind_in_either_byte_order() {
        for big in [false, true] {
            let set = read(&v5_file(big)).unwrap();
            assert_eq!(f64s(&set, "t"), [0.0, 1.0, 2.0, 3.0, 4.0]);
            assert_eq!(
                column(&set, "n[0]").values,
                Values::I64(vec![1 << 60, 2, 3])
            );
            assert_eq!(column(&set, "n[1]").values, Values::I64(vec![-1, -2, -3]));
            assert_eq!(f64s(&set, "run.a"), [0.5, 1.5]);
            assert_eq!(f64s(&set, "run.deep.x"), [-3.0, 4.0]);
            let names: Vec<&str> = set.columns.iter().map(|c| c.name.as_str()).collect();
            assert_eq!(names, ["t", "n[0]", "n[1]", "run.a", "run.deep.x"]);
            let text = set.structure.join("\n");
            for line in [
                "`n`: 2 × 3 int64 (compressed) → rows `n[0]` … `n[1]`, 3 samples each",
                "`run`: 1 × 1 struct of fields a, deep, s",
                "`run.s`: 1 × 2 char: not taken: text is not readings",
                "`c`: 1 × 0 cell: not taken: cell arrays are not read",
                "`ok`: 1 × 2 uint8: not taken: true/false values",
                "`z`: 1 × 2 double: not taken: complex values",
                "`cube`: 2 × 2 × 2 uint8: not taken: an array of three or more dimensions",
            ] {
                assert!(text.contains(line), "{line} not in\n{text}");
            }
            assert!(set.structure[0].starts_with(if big {
                "MATLAB v5 MAT-file, big-endian (`MATLAB 5.0 MAT-file, written by a test`)"
            } else {
                "MATLAB v5 MAT-file, little-endian"
            }));
        }
    }

    #[test]
    fn sniffing_takes_v4_and_v5_but_not_v7_3_or_text() {
        let v4_head = v4(false, 0, 0, 5, 26213, "data_1", &[]);
        assert!(Mat.sniff(&v4_head));
        assert!(Mat.sniff(&v4(true, 0, 0, 1, 2, "x\0", &[])));
        assert!(Mat.sniff(&header(false)));
        let mut v73 = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".to_vec();
        v73.resize(116, b' ');
        v73.extend([0; 8]);
        v73.extend([0, 2, b'I', b'M']);
        assert!(!Mat.sniff(&v73));
        let err = read(&v73).unwrap_err();
        assert!(err.contains("v7.3") && err.contains("HDF5"), "{err}");
        assert!(!Mat.sniff(b"t,a,b\n0,1,2\n0.005,1,2\n"));
        assert!(!Mat.sniff(&[0; 128]));
        assert!(!Mat.sniff(&v4(false, 0, 0, 1, 2, "a b\0", &[])));
    }

    #[test]
    fn hostile_sizes_fail_naming_the_variable() {
        // A v4 matrix of 2^31 − 1 × 2^31 − 1 values in a 30-byte file.
        let huge = v4(false, 0, 0, i32::MAX, i32::MAX, "big\0", &[0; 8]);
        let err = read(&huge).unwrap_err();
        assert!(
            err.contains("matrix 0 `big`") && err.contains("only 8 are left"),
            "{err}"
        );
        // A v4 name longer than the file.
        let mut name = v4(false, 0, 0, 1, 2, "x\0", &[]);
        name[16..20].copy_from_slice(&4000i32.to_le_bytes());
        assert!(read(&name).unwrap_err().contains("name is 4000 bytes long"));
        // A v5 element longer than the file.
        let mut long = v5_file(false);
        long[132..136].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = read(&long).unwrap_err();
        assert!(
            err.contains("variable 0 (at byte 128)") && err.contains("bytes long"),
            "{err}"
        );
        // Dimensions that do not match the data.
        let mut file = header(false);
        file.extend(mx(false, 6, 0, &[1000, 1000], "m", &el(false, 9, &[0; 16])));
        let err = read(&file).unwrap_err();
        assert!(
            err.contains("`m`") && err.contains("make 1000000 values"),
            "{err}"
        );
        // A compressed variable claiming 4 GiB inside a few bytes.
        let mut inner = 14u32.to_le_bytes().to_vec();
        inner.extend(u32::MAX.to_le_bytes());
        let mut file = header(false);
        file.extend(compressed(false, &inner));
        let err = read(&file).unwrap_err();
        assert!(err.contains("more than 1000 times"), "{err}");
        // Compressed bytes that are not zlib.
        let mut file = header(false);
        file.extend(15u32.to_le_bytes());
        file.extend(8u32.to_le_bytes());
        file.extend([0xFF; 8]);
        assert!(read(&file).unwrap_err().contains("does not inflate"));
        // Structs nested without end are refused at depth 16, not recursed into.
        let mut nested = mx(false, 6, 0, &[1, 2], "", &el(false, 2, &[1, 2]));
        for _ in 0..40 {
            let mut rest = el(false, MI_INT32, &bytes32(false, &[8]));
            rest.extend(el(false, MI_INT8, b"f\0\0\0\0\0\0\0"));
            rest.extend(nested);
            nested = mx(false, 2, 0, &[1, 1], "", &rest);
        }
        let mut file = header(false);
        file.extend(nested);
        // The outermost element's name is empty: name it.
        let set = read(&file).unwrap();
        assert!(set.columns.is_empty());
        assert!(
            set.structure
                .join("\n")
                .contains("nested more than 16 deep")
        );
        // Every cut of a good file fails or reads, never panics.
        let good = v5_file(false);
        for n in 0..good.len() {
            let _ = read(&good[..n]);
        }
        let good = v4(
            false,
            0,
            0,
            2,
            2,
            "m\0",
            &doubles(false, &[1.0, 2.0, 3.0, 4.0]),
        );
        for n in 0..good.len() {
            let _ = read(&good[..n]);
        }
    }

    /// The files `testdata/mat/make_fixture.py` wrote with scipy.
    fn fixture(name: &str) -> ColumnSet {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/mat")
            .join(name);
        Mat.read(&path, &ReadOptions::default()).unwrap()
    }

    #[test]
    fn the_scipy_fixtures_read_as_written() {
        let v4 = fixture("quick_v4.mat");
        let v5 = fixture("quick_v5.mat");
        for set in [&v4, &v5] {
            for (i, name) in ["t", "a", "b"].into_iter().enumerate() {
                let vector = f64s(set, name);
                assert_eq!(vector.len(), 3301);
                // The matrix's row i is the vector: rows are channels along the long side.
                assert_eq!(f64s(set, &format!("data_1[{i}]")), vector, "{name}");
            }
            assert_eq!(f64s(set, "t")[1], 0.005);
            assert_eq!(f64s(set, "a")[0], 0.29229999999999995);
        }
        for name in ["t", "a", "b"] {
            assert_eq!(f64s(&v4, name), f64s(&v5, name));
        }
        assert_eq!(f64s(&v5, "info.index")[3300], 3300.0);
        assert_eq!(
            v4.structure,
            [
                "MATLAB v4 MAT-file (Level 1.0), little-endian, 5 matrices",
                "`data_1`: 3 × 3301 double → rows `data_1[0]` … `data_1[2]`, 3301 samples each",
                "`t`: 1 × 3301 double → `t`, 3301 samples",
                "`a`: 1 × 3301 double → `a`, 3301 samples",
                "`b`: 1 × 3301 double → `b`, 3301 samples",
                "`note`: 1 × 23 uint8: not taken: text is not readings",
            ]
        );
        let text = v5.structure.join("\n");
        for line in [
            "`data_1`: 3 × 3301 double (compressed) → rows `data_1[0]` … `data_1[2]`",
            "`note`: 1 × 23 char (compressed): not taken: text is not readings",
            "`info`: 1 × 1 struct (compressed) of fields rate_hz, index",
            "`info.rate_hz`: 1 × 1 double: not taken: one value or none",
            "`info.index`: 1 × 3301 int32 → `info.index`, 3301 samples",
        ] {
            assert!(text.contains(line), "{line} not in\n{text}");
        }
    }
}

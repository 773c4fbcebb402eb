//! LabVIEW TDMS files, as NI hardware, LabVIEW, DIAdem and `nptdms` write them.
//!
//! # Format
//!
//! NI, "TDMS File Format Internal Structure": a file is a run of segments, each a 28-byte lead-in
//! (`TDSm`; a table-of-contents mask: metadata, new object list, raw data, interleaved,
//! big-endian, DAQmx; the version, 4712 or 4713; the segment's length after the lead-in; where
//! its raw data starts), then metadata, then raw data. The metadata lists objects by path (`/`,
//! `/'group'`, `/'group'/'channel'`), each with a raw-data index (type, count of values) and
//! properties. A segment may only say what changed: without metadata it repeats the previous
//! segment's list; without a new object list its objects update or extend that list; a raw-data
//! index of `0x00000000` repeats the object's previous index, `0xFFFFFFFF` means no data here.
//! The raw data is one or more chunks, each holding every listed channel's values: one
//! channel's after another, or interleaved value by value.
//!
//! # What calib takes
//!
//! Every channel of integers, floats or time stamps, named `group/channel`; its `unit_string`
//! as the unit; `wf_increment` with `wf_start_time` (+ `wf_start_offset`) as a waveform's time;
//! a time-stamp channel as stamps in ns since 1970. Strings, booleans, complex and extended
//! floats, and DAQmx raw data (whose scaling lives in NI-DAQmx) are listed, not taken.
//!
//! Hand-written rather than the `tdms` crate (0.3, which its author calls a work in progress):
//! every length the file states is checked against the file before anything is read or
//! allocated, a segment cut short by a crash reads up to its last whole chunk, and each error
//! names the segment and the channel.

use std::collections::HashMap;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::binary::{Cursor, DecodeError, Endian, Fail, Kind, extend, read_file};
use super::{Column, ColumnFormat, ColumnSet, ColumnTime, Values};
use crate::csv_log::dialect::TimeUnit;
use crate::limits::{self, MAX_CSV_COLUMNS, readable};
use crate::{Error, ReadOptions};

/// LabVIEW TDMS, the [`ColumnFormat`].
pub(crate) struct Tdms;

impl ColumnFormat for Tdms {
    fn name(&self) -> &'static str {
        "TDMS"
    }

    fn about(&self) -> &'static str {
        "LabVIEW TDMS (NI test benches, LabVIEW, DIAdem): channels `group/channel`"
    }

    fn extensions(&self) -> &'static [&'static str] {
        &["tdms"]
    }

    fn sniff(&self, head: &[u8]) -> bool {
        head.starts_with(b"TDSm")
    }

    fn read(&self, path: &Path, _opts: &ReadOptions) -> Result<ColumnSet, Error> {
        read_file(path, read_tdms)
    }
}

const TOC_META: u32 = 1 << 1;
const TOC_NEW_OBJ_LIST: u32 = 1 << 2;
const TOC_RAW: u32 = 1 << 3;
const TOC_INTERLEAVED: u32 = 1 << 5;
const TOC_BIG_ENDIAN: u32 = 1 << 6;
const TOC_DAQMX: u32 = 1 << 7;
/// Bytes of a segment's lead-in.
const LEAD_IN: u64 = 28;
/// A segment's length when the writer never finished it (LabVIEW stopped mid-write).
const UNFINISHED: u64 = u64::MAX;
/// Raw-data index: the object has no data in this segment.
const NO_DATA: u32 = 0xFFFF_FFFF;
/// Raw-data index: as the object's previous one.
const AS_BEFORE: u32 = 0;
/// Raw-data index headers of DAQmx data (format-changing and digital-line scalers).
const DAQMX_INDEX: [u32; 2] = [0x0000_1269, 0x0000_126A];
/// Seconds from LabVIEW's epoch (1904-01-01 UTC) to 1970-01-01.
const EPOCH_1904_S: i64 = 2_082_844_800;
/// Raw data read at a time: whole chunks up to this many bytes (one chunk if it is larger).
const BATCH_BYTES: u64 = 8 << 20;
/// What to do about a damaged file.
const REPAIR: &str = "the file is damaged; save it again from LabVIEW (or run NI's TDMS \
                      Defragment on it), or export the channels to CSV";

/// A TDMS data type.
#[derive(Debug, Clone, Copy, PartialEq)]
enum DataType {
    Num(Kind),
    /// 16 bytes: seconds since 1904 and fractions of 2⁻⁶⁴ s.
    Stamp,
    Bool,
    Str,
    DaqMx,
    /// A type calib does not take: its name and size (`None`: unknown).
    Other(&'static str, Option<u64>),
}

impl DataType {
    fn from_code(code: u32) -> DataType {
        match code {
            1 => DataType::Num(Kind::I8),
            2 => DataType::Num(Kind::I16),
            3 => DataType::Num(Kind::I32),
            4 => DataType::Num(Kind::I64),
            5 => DataType::Num(Kind::U8),
            6 => DataType::Num(Kind::U16),
            7 => DataType::Num(Kind::U32),
            8 => DataType::Num(Kind::U64),
            9 | 0x19 => DataType::Num(Kind::F32),
            10 | 0x1A => DataType::Num(Kind::F64),
            0x44 => DataType::Stamp,
            0x21 => DataType::Bool,
            0x20 => DataType::Str,
            0xFFFF_FFFF => DataType::DaqMx,
            0 => DataType::Other("void", Some(0)),
            11 | 0x1B => DataType::Other("extended float", Some(16)),
            0x08_000C => DataType::Other("complex single", Some(8)),
            0x10_000D => DataType::Other("complex double", Some(16)),
            0x4F => DataType::Other("fixed point", None),
            _ => DataType::Other("unknown", None),
        }
    }

    /// Bytes per value; `None` for strings (their index states their size) and unknown types.
    fn size(self) -> Option<u64> {
        match self {
            DataType::Num(k) => Some(k.size() as u64),
            DataType::Stamp => Some(16),
            DataType::Bool => Some(1),
            DataType::Str | DataType::DaqMx => None,
            DataType::Other(_, size) => size,
        }
    }

    fn name(self) -> &'static str {
        match self {
            DataType::Num(k) => k.name(),
            DataType::Stamp => "timestamp",
            DataType::Bool => "boolean",
            DataType::Str => "string",
            DataType::DaqMx => "DAQmx raw",
            DataType::Other(name, _) => name,
        }
    }
}

/// Where an object's values are in a segment's chunk.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Index {
    /// `count` values of `ty`, `bytes` in all.
    Data {
        ty: DataType,
        count: u64,
        bytes: u64,
    },
    /// DAQmx raw data: buffers scaled by NI-DAQmx, not read.
    DaqMx,
}

/// A property's value, as far as calib uses it.
#[derive(Debug, Clone, PartialEq)]
enum Prop {
    Num(f64),
    Str(String),
    /// Seconds since 1904 and fractions of 2⁻⁶⁴ s.
    Stamp(i64, u64),
    Other,
}

/// What has been read of a channel.
#[derive(Debug)]
enum Data {
    /// No values yet.
    None,
    /// Values of one type.
    Taken { ty: DataType, values: Values },
    /// Not taken, and why.
    Refused { ty: DataType, why: String },
}

/// A TDMS object: the file, a group or a channel.
#[derive(Debug)]
struct Object {
    /// `group/channel` for a channel, the group's name for a group, `` for the file.
    name: String,
    group: Option<String>,
    is_channel: bool,
    props: Vec<(String, Prop)>,
    /// The last raw-data index the file gave it.
    last: Option<Index>,
    data: Data,
}

impl Object {
    fn prop(&self, name: &str) -> Option<&Prop> {
        self.props
            .iter()
            .rev()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p)
    }

    fn set_prop(&mut self, name: String, value: Prop) {
        match self.props.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = value,
            None => self.props.push((name, value)),
        }
    }

    /// Leaves the channel out, keeping the first reason given.
    fn refuse(&mut self, ty: DataType, why: String) {
        if !matches!(self.data, Data::Refused { .. }) {
            self.data = Data::Refused { ty, why };
        }
    }
}

/// Everything read so far.
#[derive(Debug, Default)]
struct State {
    objects: Vec<Object>,
    by_path: HashMap<String, usize>,
    channels: usize,
    /// The objects of the current segment in order, with their index where they have data.
    list: Vec<(usize, Option<Index>)>,
    notes: Vec<String>,
    segments: u64,
    versions: Vec<u32>,
    endians: Vec<Endian>,
}

/// A segment, for messages.
struct Segment {
    number: u64,
    at: u64,
}

impl Segment {
    fn bad(&self, what: impl std::fmt::Display) -> Fail {
        Fail::Bad(format!(
            "TDMS segment {} (at byte {}): {what}; {REPAIR}",
            self.number, self.at
        ))
    }
}

/// Reads every segment of a TDMS file of `len` bytes.
fn read_tdms(r: &mut (impl Read + Seek), len: u64) -> Result<ColumnSet, Fail> {
    let mut st = State::default();
    let mut at = 0;
    let mut buf = Vec::new();
    while at < len {
        let seg = Segment {
            number: st.segments,
            at,
        };
        st.segments += 1;
        if len - at < LEAD_IN {
            return Err(seg.bad(format_args!(
                "{} bytes are left, fewer than a segment's {LEAD_IN}-byte lead-in (the file is cut short)",
                len - at
            )));
        }
        r.seek(SeekFrom::Start(at))?;
        let mut lead = [0; LEAD_IN as usize];
        r.read_exact(&mut lead)?;
        if &lead[..4] != b"TDSm" {
            return Err(seg.bad(format_args!(
                "starts with {} instead of `TDSm`",
                limits::shown_bytes(&lead[..4])
            )));
        }
        let toc = u32::from_le_bytes([lead[4], lead[5], lead[6], lead[7]]);
        let endian = if toc & TOC_BIG_ENDIAN != 0 {
            Endian::Big
        } else {
            Endian::Little
        };
        let mut c = Cursor::new(&lead[8..], endian);
        let (version, next, raw_offset) = (
            c.u32().map_err(|e| seg.bad(e))?,
            c.u64().map_err(|e| seg.bad(e))?,
            c.u64().map_err(|e| seg.bad(e))?,
        );
        if !st.versions.contains(&version) {
            st.versions.push(version);
        }
        if !st.endians.contains(&endian) {
            st.endians.push(endian);
        }
        let body = at + LEAD_IN;
        let left = len - body;
        let (seg_len, cut) = if next == UNFINISHED {
            st.notes.push(format!(
                "segment {} was never finished (LabVIEW stopped writing): read up to the end of the file",
                seg.number
            ));
            (left, true)
        } else if next > left {
            return Err(seg.bad(format_args!(
                "says it is {next} bytes long after its lead-in, but the file ends {left} bytes \
                 into it (a copy cut short?)"
            )));
        } else {
            (next, false)
        };
        if raw_offset > seg_len {
            return Err(seg.bad(format_args!(
                "says its raw data starts {raw_offset} bytes into a segment of {seg_len}"
            )));
        }
        if toc & TOC_META != 0 {
            buf.clear();
            r.by_ref().take(raw_offset).read_to_end(&mut buf)?;
            read_metadata(&mut st, &buf, endian, toc, &seg)?;
        } else if st.segments == 1 {
            return Err(seg.bad("the first segment has no metadata, so no channels"));
        }
        if toc & TOC_RAW != 0 {
            let raw = (body + raw_offset, seg_len - raw_offset);
            read_raw(&mut st, r, raw, endian, toc, cut, &seg)?;
        }
        at = body + seg_len;
    }
    Ok(finish(st))
}

/// A string: a u32 length, then UTF-8.
fn string(c: &mut Cursor, what: &str) -> Result<String, String> {
    let n = c.u32().map_err(|e| format!("{what}: {e}"))?;
    let bytes = c
        .take(u64::from(n))
        .map_err(|e| format!("{what} of {n} bytes: {e}"))?;
    Ok(String::from_utf8_lossy(bytes).into_owned())
}

/// The group and channel of an object path (`/`, `/'group'`, `/'group'/'channel'`; a quote
/// inside a name is doubled).
fn parse_path(path: &str) -> Option<Vec<String>> {
    let mut parts = Vec::new();
    let mut rest = path.strip_prefix('/')?;
    while !rest.is_empty() {
        let mut chars = rest.strip_prefix('\'')?.char_indices();
        let mut name = String::new();
        let end = loop {
            let (i, ch) = chars.next()?;
            if ch != '\'' {
                name.push(ch);
                continue;
            }
            match chars.clone().next() {
                Some((_, '\'')) => {
                    chars.next();
                    name.push('\'');
                }
                _ => break i + 1,
            }
        };
        parts.push(name);
        rest = &rest.strip_prefix('\'')?[end..];
        if !rest.is_empty() {
            rest = rest.strip_prefix('/')?;
            if rest.is_empty() {
                return None;
            }
        }
    }
    (parts.len() <= 2).then_some(parts)
}

/// Reads a segment's metadata, updating the objects and the segment's object list.
fn read_metadata(
    st: &mut State,
    meta: &[u8],
    endian: Endian,
    toc: u32,
    seg: &Segment,
) -> Result<(), Fail> {
    let mut c = Cursor::new(meta, endian);
    let count = c
        .u32()
        .map_err(|e| seg.bad(format_args!("the number of objects: {e}")))?;
    if toc & TOC_NEW_OBJ_LIST != 0 {
        st.list.clear();
    }
    for k in 0..count {
        let path = string(&mut c, "an object's path")
            .map_err(|e| seg.bad(format_args!("object {k} of {count}: {e}")))?;
        let id = object(st, &path, seg)?;
        let name = st.objects[id].name.clone();
        let obj_bad = |e: String| seg.bad(format_args!("object `{name}`: {e}"));
        let header = c
            .u32()
            .map_err(|e| obj_bad(format!("raw data index: {e}")))?;
        let index = match header {
            NO_DATA => None,
            AS_BEFORE => Some(st.objects[id].last.ok_or_else(|| {
                obj_bad(
                    "its raw data index says \"as before\", but no segment before gave one".into(),
                )
            })?),
            h if DAQMX_INDEX.contains(&h) => {
                skip_daqmx_index(&mut c, h).map_err(|e| obj_bad(format!("DAQmx index: {e}")))?;
                Some(Index::DaqMx)
            }
            _ => Some(data_index(&mut c).map_err(|e| obj_bad(format!("raw data index: {e}")))?),
        };
        if index.is_some() {
            st.objects[id].last = index;
        }
        match st.list.iter_mut().find(|(o, _)| *o == id) {
            Some(slot) => slot.1 = index,
            None => st.list.push((id, index)),
        }
        let props = c
            .u32()
            .map_err(|e| obj_bad(format!("number of properties: {e}")))?;
        for _ in 0..props {
            let (name, value) = property(&mut c).map_err(&obj_bad)?;
            st.objects[id].set_prop(name, value);
        }
    }
    Ok(())
}

/// The object of `path`, added if new.
fn object(st: &mut State, path: &str, seg: &Segment) -> Result<usize, Fail> {
    if let Some(&id) = st.by_path.get(path) {
        return Ok(id);
    }
    let parts = parse_path(path).ok_or_else(|| {
        seg.bad(format_args!(
            "object path {} is not `/`, `/'group'` or `/'group'/'channel'`",
            limits::shown_bytes(path.as_bytes())
        ))
    })?;
    let is_channel = parts.len() == 2;
    if is_channel {
        st.channels += 1;
        if st.channels > MAX_CSV_COLUMNS {
            return Err(seg.bad(format_args!(
                "more than {MAX_CSV_COLUMNS} channels, more than any log holds"
            )));
        }
    }
    st.objects.push(Object {
        name: parts.join("/"),
        group: parts.first().cloned(),
        is_channel,
        props: Vec::new(),
        last: None,
        data: Data::None,
    });
    let id = st.objects.len() - 1;
    st.by_path.insert(path.to_owned(), id);
    Ok(id)
}

/// A raw-data index after its length: type, dimension, count, and for strings their size.
fn data_index(c: &mut Cursor) -> Result<Index, String> {
    let code = c.u32()?;
    let ty = DataType::from_code(code);
    let dimension = c.u32()?;
    if dimension != 1 {
        return Err(format!(
            "array dimension {dimension}; TDMS 2.0 allows only 1"
        ));
    }
    let count = c.u64()?;
    let bytes = match ty {
        DataType::Str => c.u64()?,
        DataType::DaqMx => return Err("DAQmx raw data type under a plain index".into()),
        _ => {
            let size = ty.size().ok_or_else(|| {
                format!(
                    "data type {code:#x} ({}), whose size calib does not know",
                    ty.name()
                )
            })?;
            count
                .checked_mul(size)
                .ok_or_else(|| format!("{count} values of {size} bytes overflow"))?
        }
    };
    Ok(Index::Data { ty, count, bytes })
}

/// Passes over a DAQmx raw-data index (its scalers and raw data widths).
fn skip_daqmx_index(c: &mut Cursor, header: u32) -> Result<(), String> {
    let _type = c.u32()?;
    let _dimension = c.u32()?;
    let _chunk = c.u64()?;
    let scalers = c.u32()?;
    let scaler_bytes = if header == DAQMX_INDEX[0] { 20 } else { 17 };
    c.take(u64::from(scalers) * scaler_bytes)?;
    let widths = c.u32()?;
    c.take(u64::from(widths) * 4)?;
    Ok(())
}

/// A property: name, type, value.
fn property(c: &mut Cursor) -> Result<(String, Prop), String> {
    let name = string(c, "a property's name")?;
    let code = c.u32().map_err(|e| format!("property `{name}`: {e}"))?;
    let value = prop_value(c, DataType::from_code(code))
        .map_err(|e| format!("property `{name}` of type {code:#x}: {e}"))?;
    Ok((name, value))
}

fn prop_value(c: &mut Cursor, ty: DataType) -> Result<Prop, String> {
    Ok(match ty {
        DataType::Num(Kind::I64) => Prop::Num(c.i64()? as f64),
        DataType::Num(Kind::U64) => Prop::Num(c.u64()? as f64),
        DataType::Num(Kind::F64) => Prop::Num(c.f64()?),
        DataType::Num(k) => {
            let endian = c.endian();
            let mut v = k.empty(1);
            extend(&mut v, k, endian, c.take(k.size() as u64)?, k.size(), 1)
                .map_err(|e| format!("{e:?}"))?;
            match v {
                Values::F64(v) => Prop::Num(v.first().copied().unwrap_or(f64::NAN)),
                Values::I64(v) => Prop::Num(v.first().map_or(f64::NAN, |&x| x as f64)),
            }
        }
        DataType::Bool => Prop::Num(f64::from(c.u8()?)),
        DataType::Str => Prop::Str(string(c, "the value")?),
        DataType::Stamp => {
            let (secs, frac) = stamp(c)?;
            Prop::Stamp(secs, frac)
        }
        DataType::Other(_, Some(size)) => {
            c.take(size)?;
            Prop::Other
        }
        DataType::Other(name, None) => {
            return Err(format!("a {name} value, whose size calib does not know"));
        }
        DataType::DaqMx => return Err("a DAQmx raw value, which no property can be".into()),
    })
}

/// A time stamp: seconds since 1904 and fractions of 2⁻⁶⁴ s (fractions first in a
/// little-endian segment, seconds first in a big-endian one).
fn stamp(c: &mut Cursor) -> Result<(i64, u64), String> {
    Ok(match c.endian() {
        Endian::Little => {
            let frac = c.u64()?;
            (c.i64()?, frac)
        }
        Endian::Big => {
            let secs = c.i64()?;
            (secs, c.u64()?)
        }
    })
}

/// A TDMS time stamp in ns since 1970, to the nearest ns, if an `i64` holds it (1678 to 2262).
/// Rounded, not truncated: writers store a whole number of µs or ns as the fraction below it
/// (nptdms writes 15 ms as 0.01499999999… s).
fn stamp_ns(secs: i64, frac: u64) -> Option<i64> {
    let ns_of_frac = ((u128::from(frac) * 1_000_000_000 + (1 << 63)) >> 64) as i64;
    secs.checked_sub(EPOCH_1904_S)?
        .checked_mul(1_000_000_000)?
        .checked_add(ns_of_frac)
}

/// A channel with data in a segment: its object, type, count of values and bytes.
#[derive(Debug, Clone, Copy)]
struct Listed {
    id: usize,
    ty: DataType,
    count: u64,
    bytes: u64,
}

/// Reads a segment's raw data (`len` bytes at `start`) into its channels.
fn read_raw(
    st: &mut State,
    r: &mut (impl Read + Seek),
    (start, len): (u64, u64),
    endian: Endian,
    toc: u32,
    cut: bool,
    seg: &Segment,
) -> Result<(), Fail> {
    let with_data: Vec<(usize, Index)> = st
        .list
        .iter()
        .filter_map(|&(id, ix)| ix.map(|ix| (id, ix)))
        .collect();
    let daqmx = toc & TOC_DAQMX != 0 || with_data.iter().any(|(_, ix)| *ix == Index::DaqMx);
    let mut chans = Vec::with_capacity(with_data.len());
    for (id, ix) in with_data {
        match ix {
            Index::DaqMx => st.objects[id].refuse(
                DataType::DaqMx,
                "DAQmx raw data, whose scaling to physical units NI-DAQmx keeps; log scaled \
                 data instead (DAQmx logging mode \"Log and Read\"), or convert the file in \
                 LabVIEW or DIAdem"
                    .into(),
            ),
            Index::Data { ty, .. } if daqmx => st.objects[id].refuse(
                ty,
                "its segments hold DAQmx raw data too, which calib does not read".into(),
            ),
            Index::Data { ty, count, bytes } => chans.push(Listed {
                id,
                ty,
                count,
                bytes,
            }),
        }
    }
    if daqmx {
        return Ok(());
    }
    let mut chunk: u64 = 0;
    for ch in &chans {
        chunk = chunk
            .checked_add(ch.bytes)
            .ok_or_else(|| seg.bad("its channels' sizes overflow"))?;
        start_channel(&mut st.objects[ch.id], ch.ty, seg)?;
    }
    let interleaved = toc & TOC_INTERLEAVED != 0;
    if interleaved {
        if let Some(ch) = chans.iter().find(|ch| ch.ty.size().is_none()) {
            return Err(seg.bad(format_args!(
                "channel `{}` holds {} values in interleaved data, where every value needs a fixed size",
                st.objects[ch.id].name,
                ch.ty.name()
            )));
        }
        if let Some(ch) = chans.iter().find(|ch| ch.count != chans[0].count) {
            return Err(seg.bad(format_args!(
                "interleaved data, but channel `{}` has {} values per chunk and `{}` {}",
                st.objects[ch.id].name, ch.count, st.objects[chans[0].id].name, chans[0].count
            )));
        }
    }
    if chunk == 0 {
        if len > 0 {
            st.notes.push(format!(
                "segment {}: {len} bytes of raw data, but its channels list no values; left out",
                seg.number
            ));
        }
        return Ok(());
    }
    let whole = len / chunk;
    let rest = len % chunk;
    let listed = || {
        chans
            .iter()
            .map(|ch| {
                format!(
                    "`{}` {} × {}",
                    st.objects[ch.id].name,
                    ch.count,
                    ch.ty.name()
                )
            })
            .collect::<Vec<_>>()
    };
    if whole == 0 && !cut {
        return Err(seg.bad(format_args!(
            "holds {len} bytes of raw data, less than one chunk of its channels ({chunk} bytes: {})",
            limits::listed(&listed())
        )));
    }
    if rest != 0 {
        st.notes.push(if cut {
            format!(
                "segment {} is cut short: its last {rest} bytes, part of a chunk, are left out",
                seg.number
            )
        } else {
            format!(
                "segment {}: {rest} bytes after its last whole chunk of {chunk} are left out",
                seg.number
            )
        });
    }
    for ch in &chans {
        if let Data::Taken { values, .. } = &mut st.objects[ch.id].data {
            // Bounded by the file: `whole` chunks of at least `count` values each are in it.
            let more = usize::try_from(ch.count.saturating_mul(whole)).unwrap_or(0);
            match values {
                Values::F64(v) => v.reserve(more),
                Values::I64(v) => v.reserve(more),
            }
        }
    }
    let chunk_len = usize::try_from(chunk).map_err(|_| seg.bad("a chunk larger than memory"))?;
    // An interleaved row: one value of each channel.
    let row: usize = chans
        .iter()
        .map(|ch| ch.ty.size().unwrap_or(0) as usize)
        .sum();
    let per_batch = (BATCH_BYTES / chunk).max(1);
    r.seek(SeekFrom::Start(start))?;
    let mut buf = Vec::new();
    let mut done = 0;
    while done < whole {
        let k = per_batch.min(whole - done);
        buf.resize(chunk_len * k as usize, 0);
        r.read_exact(&mut buf)?;
        for bytes in buf.chunks_exact(chunk_len) {
            let mut off = 0;
            for ch in &chans {
                let count = ch.count as usize;
                let obj = &mut st.objects[ch.id];
                if interleaved {
                    take_values(obj, ch.ty, endian, &bytes[off..], row, count);
                    off += ch.ty.size().unwrap_or(0) as usize;
                } else {
                    let n = ch.bytes as usize;
                    let size = ch.ty.size().unwrap_or(1) as usize;
                    take_values(obj, ch.ty, endian, &bytes[off..off + n], size, count);
                    off += n;
                }
            }
        }
        done += k;
    }
    Ok(())
}

/// Sets up a channel for values of `ty` (or refuses it, saying why), the first time it has
/// data; a later segment must give the same type.
fn start_channel(obj: &mut Object, ty: DataType, seg: &Segment) -> Result<(), Fail> {
    match &obj.data {
        Data::None => {
            obj.data = match ty {
                DataType::Num(k) => Data::Taken {
                    ty,
                    values: k.empty(0),
                },
                DataType::Stamp => Data::Taken {
                    ty,
                    values: Values::I64(Vec::new()),
                },
                DataType::Str => Data::Refused {
                    ty,
                    why: "strings are not readings".into(),
                },
                DataType::Bool => Data::Refused {
                    ty,
                    why: "true/false values are not readings".into(),
                },
                _ => Data::Refused {
                    ty,
                    why: format!("{} values are not read", ty.name()),
                },
            };
            Ok(())
        }
        Data::Taken { ty: first, .. } if *first != ty => Err(seg.bad(format_args!(
            "channel `{}` changes from {} to {} values; calib reads a channel of one type",
            obj.name,
            first.name(),
            ty.name()
        ))),
        _ => Ok(()),
    }
}

/// Appends `count` values of a channel, value `i` at `bytes[i·stride..]`; a value it cannot
/// keep leaves the channel out, saying why.
fn take_values(
    obj: &mut Object,
    ty: DataType,
    endian: Endian,
    bytes: &[u8],
    stride: usize,
    count: usize,
) {
    let Data::Taken { values, .. } = &mut obj.data else {
        return;
    };
    let result = match ty {
        DataType::Num(k) => extend(values, k, endian, bytes, stride, count).map_err(|e| match e {
            DecodeError::U64TooLarge(x) => {
                format!("u64 value {x} is beyond the 64-bit signed integers calib keeps")
            }
            DecodeError::Mismatch => "its values do not fit its chunk".into(),
        }),
        DataType::Stamp => stamps(values, endian, bytes, stride, count),
        _ => Ok(()),
    };
    if let Err(why) = result {
        obj.data = Data::Refused { ty, why };
    }
}

/// Appends time stamps as ns since 1970.
fn stamps(
    out: &mut Values,
    endian: Endian,
    bytes: &[u8],
    stride: usize,
    count: usize,
) -> Result<(), String> {
    let Values::I64(out) = out else {
        return Err("its values do not fit its chunk".into());
    };
    for i in 0..count {
        let row = bytes
            .get(i * stride..i * stride + 16)
            .ok_or("its values do not fit its chunk")?;
        let (secs, frac) = stamp(&mut Cursor::new(row, endian))?;
        out.push(stamp_ns(secs, frac).ok_or_else(|| {
            format!(
                "time stamp {secs} s since 1904 is beyond the years 1678–2262 that ns since 1970 hold"
            )
        })?);
    }
    Ok(())
}

/// A channel's waveform time from its properties, or why its `wf_increment` is not one.
fn waveform(obj: &Object) -> Result<Option<ColumnTime>, String> {
    let Some(Prop::Num(increment)) = obj.prop("wf_increment") else {
        return Ok(None);
    };
    if !(increment.is_finite() && *increment > 0.0) {
        return Err(format!(
            "its wf_increment {increment} is not a positive step"
        ));
    }
    if let Some(Prop::Str(unit)) = obj.prop("wf_xunit_string") {
        if !unit.trim().is_empty() && unit.trim() != "s" {
            return Err(format!(
                "its waveform's x axis is in `{unit}`, not in seconds (a spectrum?)"
            ));
        }
    }
    let start = match obj.prop("wf_start_time") {
        // LabVIEW's zero time (1904-01-01 00:00) is a waveform with no start.
        Some(Prop::Stamp(0, 0)) | None => 0,
        Some(Prop::Stamp(secs, frac)) => stamp_ns(*secs, *frac).ok_or_else(|| {
            format!("its wf_start_time ({secs} s since 1904) is beyond the years 1678–2262")
        })?,
        Some(_) => return Err("its wf_start_time is not a time stamp".into()),
    };
    let offset_ns = match obj.prop("wf_start_offset") {
        Some(Prop::Num(o)) if o.is_finite() && o.abs() < 9e9 => (o * 1e9).round() as i64,
        Some(Prop::Num(o)) => return Err(format!("its wf_start_offset {o} s is out of range")),
        _ => 0,
    };
    Ok(Some(ColumnTime::Waveform {
        start_ns: start.saturating_add(offset_ns),
        increment_s: *increment,
    }))
}

/// The columns and the lines `calib inspect` shows.
fn finish(st: State) -> ColumnSet {
    let mut structure = vec![format!(
        "TDMS version {}, {} segment{}, {}",
        st.versions
            .iter()
            .map(u32::to_string)
            .collect::<Vec<_>>()
            .join(" and "),
        st.segments,
        if st.segments == 1 { "" } else { "s" },
        st.endians
            .iter()
            .map(|e| e.name())
            .collect::<Vec<_>>()
            .join(" and ")
    )];
    let mut columns = Vec::new();
    let mut groups: Vec<(String, Vec<String>)> = Vec::new();
    let mut refused = Vec::new();
    for obj in st.objects {
        let Some(group) = obj.group.clone() else {
            continue;
        };
        let at = match groups.iter().position(|(g, _)| *g == group) {
            Some(at) => at,
            None => {
                groups.push((group.clone(), Vec::new()));
                groups.len() - 1
            }
        };
        if !obj.is_channel {
            continue;
        }
        let short = obj.name[group.len() + 1..].to_owned();
        let unit = match obj.prop("unit_string") {
            Some(Prop::Str(u)) if !u.trim().is_empty() => Some(u.trim().to_owned()),
            _ => None,
        };
        match obj.data {
            Data::None => groups[at].1.push(format!("`{short}` (no values)")),
            Data::Refused { ty, ref why } => {
                groups[at]
                    .1
                    .push(format!("`{short}` ({}, not taken)", ty.name()));
                refused.push(format!("`{}`: not taken: {why}", obj.name));
            }
            Data::Taken { ty, ref values } => {
                let time = if ty == DataType::Stamp {
                    Some(ColumnTime::Stamps(TimeUnit::Ns))
                } else {
                    waveform(&obj).unwrap_or_else(|why| {
                        refused.push(format!(
                            "`{}`: read without its waveform time: {why}",
                            obj.name
                        ));
                        None
                    })
                };
                let mut about = vec![ty.name().to_owned(), format!("{} values", values.len())];
                if let Some(u) = &unit {
                    about.push(format!("unit `{u}`"));
                }
                if let Some(ColumnTime::Waveform { increment_s, .. }) = time {
                    about.push(format!("waveform at {} Hz", readable(1.0 / increment_s)));
                }
                if ty == DataType::Stamp {
                    about.push("time stamps".into());
                }
                groups[at]
                    .1
                    .push(format!("`{short}` ({})", about.join(", ")));
                if values.len() > 0 {
                    columns.push(Column {
                        name: obj.name,
                        unit,
                        values: match obj.data {
                            Data::Taken { values, .. } => values,
                            _ => Values::F64(Vec::new()),
                        },
                        time: time.unwrap_or(ColumnTime::Unknown),
                    });
                }
            }
        }
    }
    for (group, chans) in groups {
        structure.push(if chans.is_empty() {
            format!("group `{group}`: no channels")
        } else {
            format!("group `{group}`: {}", chans.join(", "))
        });
    }
    structure.extend(refused);
    structure.extend(st.notes);
    ColumnSet { columns, structure }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A property value for [`obj`].
    enum P {
        Str(&'static str),
        F64(f64),
        Stamp(i64, u64),
    }

    /// A raw-data index for [`obj`].
    enum Ix {
        No,
        AsBefore,
        Data(u32, u64),
        Str(u64, u64),
        DaqMx,
    }

    /// Bytes in one byte order, as NI's writers lay them out.
    struct W {
        big: bool,
        out: Vec<u8>,
    }

    impl W {
        fn new(big: bool) -> W {
            W {
                big,
                out: Vec::new(),
            }
        }
        fn u32(&mut self, x: u32) {
            self.out.extend(if self.big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            });
        }
        fn u64(&mut self, x: u64) {
            self.out.extend(if self.big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            });
        }
        fn str(&mut self, s: &str) {
            self.u32(s.len() as u32);
            self.out.extend(s.as_bytes());
        }
        fn stamp(&mut self, secs: i64, frac: u64) {
            if self.big {
                self.out.extend(secs.to_be_bytes());
                self.out.extend(frac.to_be_bytes());
            } else {
                self.out.extend(frac.to_le_bytes());
                self.out.extend(secs.to_le_bytes());
            }
        }
    }

    /// One object of a segment's metadata.
    fn obj(w: &mut W, path: &str, ix: Ix, props: &[(&str, P)]) {
        w.str(path);
        match ix {
            Ix::No => w.u32(NO_DATA),
            Ix::AsBefore => w.u32(AS_BEFORE),
            Ix::Data(code, count) => {
                w.u32(20);
                w.u32(code);
                w.u32(1);
                w.u64(count);
            }
            Ix::Str(count, bytes) => {
                w.u32(28);
                w.u32(0x20);
                w.u32(1);
                w.u64(count);
                w.u64(bytes);
            }
            Ix::DaqMx => {
                w.u32(DAQMX_INDEX[0]);
                w.u32(0xFFFF_FFFF);
                w.u32(1);
                w.u64(4);
                w.u32(1);
                w.out.extend([0; 20]);
                w.u32(1);
                w.u32(4);
            }
        }
        w.u32(props.len() as u32);
        for (name, value) in props {
            w.str(name);
            match value {
                P::Str(s) => {
                    w.u32(0x20);
                    w.str(s);
                }
                P::F64(x) => {
                    w.u32(10);
                    w.out.extend(if w.big {
                        x.to_be_bytes()
                    } else {
                        x.to_le_bytes()
                    });
                }
                P::Stamp(secs, frac) => {
                    w.u32(0x44);
                    w.stamp(*secs, *frac);
                }
            }
        }
    }

    /// A segment: lead-in, metadata of `count` objects (written by `objects`), raw data.
    fn segment(toc: u32, count: u32, objects: impl FnOnce(&mut W), raw: &[u8]) -> Vec<u8> {
        let big = toc & TOC_BIG_ENDIAN != 0;
        let mut meta = W::new(big);
        if toc & TOC_META != 0 {
            meta.u32(count);
            objects(&mut meta);
        }
        let mut w = W::new(big);
        w.out.extend(b"TDSm");
        w.out.extend(toc.to_le_bytes());
        w.u32(4713);
        w.u64((meta.out.len() + raw.len()) as u64);
        w.u64(meta.out.len() as u64);
        w.out.extend(meta.out);
        w.out.extend(raw);
        w.out
    }

    fn read(bytes: &[u8]) -> Result<ColumnSet, String> {
        read_tdms(&mut std::io::Cursor::new(bytes), bytes.len() as u64).map_err(|e| match e {
            Fail::Io(e) => format!("io: {e}"),
            Fail::Bad(m) => m,
        })
    }

    fn le(values: &[f64]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    fn column<'a>(set: &'a ColumnSet, name: &str) -> &'a Column {
        set.columns
            .iter()
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("no `{name}` in {:?}", set.structure))
    }

    const ALL: u32 = TOC_META | TOC_NEW_OBJ_LIST | TOC_RAW;

    #[test]
    fn a_segment_without_metadata_repeats_the_one_before() {
        let start = EPOCH_1904_S + 1_700_000_000;
        let mut raw = le(&[1.0, 2.0, 3.0]);
        raw.extend([5i16, -6, 7].iter().flat_map(|v| v.to_le_bytes()));
        let mut file = segment(
            ALL,
            4,
            |w| {
                obj(w, "/", Ix::No, &[("name", P::Str("run"))]);
                obj(w, "/'g'", Ix::No, &[]);
                obj(
                    w,
                    "/'g'/'a'",
                    Ix::Data(10, 3),
                    &[
                        ("unit_string", P::Str("deg")),
                        ("wf_increment", P::F64(0.001)),
                        ("wf_start_time", P::Stamp(start, 1 << 63)),
                        ("wf_start_offset", P::F64(0.25)),
                    ],
                );
                obj(w, "/'g'/'b'", Ix::Data(2, 3), &[]);
            },
            &raw,
        );
        // Two more chunks of the same layout, in a segment with raw data only.
        let mut raw2 = le(&[4.0, 5.0, 6.0]);
        raw2.extend([8i16, 9, 10].iter().flat_map(|v| v.to_le_bytes()));
        raw2.extend(le(&[7.0, 8.0, 9.0]));
        raw2.extend([11i16, 12, 13].iter().flat_map(|v| v.to_le_bytes()));
        file.extend(segment(TOC_RAW, 0, |_| {}, &raw2));
        let set = read(&file).unwrap();
        let a = column(&set, "g/a");
        assert_eq!(a.values, Values::F64((1..=9).map(f64::from).collect()));
        assert_eq!(a.unit.as_deref(), Some("deg"));
        assert_eq!(
            a.time,
            ColumnTime::Waveform {
                start_ns: 1_700_000_000_750_000_000,
                increment_s: 0.001
            }
        );
        let b = column(&set, "g/b");
        assert_eq!(
            b.values,
            Values::F64(vec![5.0, -6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0])
        );
        assert_eq!((b.unit.clone(), b.time), (None, ColumnTime::Unknown));
        assert_eq!(
            set.structure,
            [
                "TDMS version 4713, 2 segments, little-endian",
                "group `g`: `a` (f64, 9 values, unit `deg`, waveform at 1000 Hz), `b` (i16, 9 values)"
            ]
        );
    }

    #[test]
    fn incremental_metadata_updates_and_extends_the_object_list() {
        let mut file = segment(
            ALL,
            2,
            |w| {
                obj(w, "/'g'/'a'", Ix::Data(10, 2), &[]);
                obj(w, "/'g'/'b'", Ix::Data(10, 2), &[]);
            },
            &le(&[1.0, 2.0, 10.0, 20.0]),
        );
        // a as before, b without data here, c new: the list is a, b, c; data of a and c.
        let mut raw = le(&[3.0, 4.0]);
        raw.extend([100i32, 200].iter().flat_map(|v| v.to_le_bytes()));
        file.extend(segment(
            TOC_META | TOC_RAW,
            3,
            |w| {
                obj(w, "/'g'/'a'", Ix::AsBefore, &[]);
                obj(w, "/'g'/'b'", Ix::No, &[]);
                obj(
                    w,
                    "/'g'/'c'",
                    Ix::Data(3, 2),
                    &[("unit_string", P::Str("rad"))],
                );
            },
            &raw,
        ));
        // A new list of b alone, its index as before.
        file.extend(segment(
            ALL,
            1,
            |w| obj(w, "/'g'/'b'", Ix::AsBefore, &[]),
            &le(&[30.0, 40.0]),
        ));
        let set = read(&file).unwrap();
        let values = |n| column(&set, n).values.clone();
        assert_eq!(values("g/a"), Values::F64(vec![1.0, 2.0, 3.0, 4.0]));
        assert_eq!(values("g/b"), Values::F64(vec![10.0, 20.0, 30.0, 40.0]));
        assert_eq!(values("g/c"), Values::F64(vec![100.0, 200.0]));
        assert_eq!(column(&set, "g/c").unit.as_deref(), Some("rad"));
    }

    #[test]
    fn interleaved_big_endian_values_and_time_stamps() {
        let t0 = EPOCH_1904_S + 1_000;
        let mut raw = W::new(true);
        for (i, (a, b)) in [(1u16, 0.5f32), (65535, -1.5)].into_iter().enumerate() {
            raw.out.extend(a.to_be_bytes());
            raw.stamp(t0 + i as i64, 1 << 62);
            raw.out.extend(b.to_be_bytes());
        }
        let toc = ALL | TOC_INTERLEAVED | TOC_BIG_ENDIAN;
        let file = segment(
            toc,
            3,
            |w| {
                obj(w, "/'h'/'a'", Ix::Data(6, 2), &[]);
                obj(w, "/'h'/'t'", Ix::Data(0x44, 2), &[]);
                obj(w, "/'h'/'b'", Ix::Data(9, 2), &[]);
            },
            &raw.out,
        );
        let set = read(&file).unwrap();
        assert_eq!(column(&set, "h/a").values, Values::F64(vec![1.0, 65535.0]));
        assert_eq!(column(&set, "h/b").values, Values::F64(vec![0.5, -1.5]));
        let t = column(&set, "h/t");
        assert_eq!(
            t.values,
            Values::I64(vec![1_000_250_000_000, 1_001_250_000_000])
        );
        assert_eq!(t.time, ColumnTime::Stamps(TimeUnit::Ns));
        assert!(
            set.structure[0].ends_with("big-endian"),
            "{:?}",
            set.structure
        );
    }

    #[test]
    fn every_integer_type_is_read_and_64_bit_ones_stay_exact() {
        let mut raw = vec![0xFF_u8]; // i8 -1
        raw.extend((-300i16).to_le_bytes());
        raw.extend((-70_000i32).to_le_bytes());
        raw.extend((i64::MIN + 1).to_le_bytes());
        raw.push(200); // u8
        raw.extend(60_000u16.to_le_bytes());
        raw.extend(4_000_000_000u32.to_le_bytes());
        raw.extend((1u64 << 62).to_le_bytes());
        let file = segment(
            ALL,
            8,
            |w| {
                for code in 1..=8 {
                    obj(w, &format!("/'i'/'{code}'"), Ix::Data(code, 1), &[]);
                }
            },
            &raw,
        );
        let set = read(&file).unwrap();
        let got: Vec<Values> = set.columns.iter().map(|c| c.values.clone()).collect();
        assert_eq!(
            got,
            [
                Values::F64(vec![-1.0]),
                Values::F64(vec![-300.0]),
                Values::F64(vec![-70_000.0]),
                Values::I64(vec![i64::MIN + 1]),
                Values::F64(vec![200.0]),
                Values::F64(vec![60_000.0]),
                Values::F64(vec![4e9]),
                Values::I64(vec![1 << 62]),
            ]
        );
    }

    #[test]
    fn strings_and_daqmx_data_are_listed_not_taken() {
        let mut raw = Vec::new();
        raw.extend(1u32.to_le_bytes());
        raw.extend(3u32.to_le_bytes());
        raw.extend(b"abc");
        raw.extend(le(&[1.5]));
        let mut file = segment(
            ALL,
            2,
            |w| {
                obj(w, "/'g'/'s'", Ix::Str(2, 11), &[]);
                obj(w, "/'g'/'x'", Ix::Data(10, 1), &[]);
            },
            &raw,
        );
        file.extend(segment(
            ALL | TOC_DAQMX,
            1,
            |w| obj(w, "/'d'/'volts'", Ix::DaqMx, &[]),
            &[0; 16],
        ));
        let set = read(&file).unwrap();
        assert_eq!(set.columns.len(), 1);
        assert_eq!(column(&set, "g/x").values, Values::F64(vec![1.5]));
        let text = set.structure.join("\n");
        assert!(
            text.contains("`g/s`: not taken: strings are not readings"),
            "{text}"
        );
        assert!(
            text.contains("`d/volts`: not taken: DAQmx raw data"),
            "{text}"
        );
        assert!(text.contains("`s` (string, not taken)"), "{text}");
    }

    #[test]
    fn an_unfinished_segment_is_read_up_to_its_last_whole_chunk() {
        let mut file = segment(
            ALL,
            1,
            |w| obj(w, "/'g'/'a'", Ix::Data(10, 2), &[]),
            &le(&[1.0, 2.0, 3.0, 4.0, 5.0]),
        );
        file[12..20].copy_from_slice(&UNFINISHED.to_le_bytes());
        let set = read(&file).unwrap();
        assert_eq!(
            column(&set, "g/a").values,
            Values::F64(vec![1.0, 2.0, 3.0, 4.0])
        );
        let text = set.structure.join("\n");
        assert!(text.contains("never finished"), "{text}");
        assert!(
            text.contains("its last 8 bytes, part of a chunk, are left out"),
            "{text}"
        );
    }

    #[test]
    fn hostile_lengths_fail_naming_the_segment_and_object() {
        let good = segment(
            ALL,
            1,
            |w| obj(w, "/'g'/'a'", Ix::Data(10, 2), &[]),
            &le(&[1.0, 2.0]),
        );
        // A segment length beyond the file.
        let mut long = good.clone();
        long[12..20].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let err = read(&long).unwrap_err();
        assert!(
            err.contains("segment 0 (at byte 0)") && err.contains("file ends"),
            "{err}"
        );
        // Raw data said to start beyond the segment.
        let mut far = good.clone();
        far[20..28].copy_from_slice(&(1u64 << 40).to_le_bytes());
        assert!(read(&far).unwrap_err().contains("raw data starts"));
        // A channel claiming 10^15 values.
        let huge = segment(
            ALL,
            1,
            |w| obj(w, "/'g'/'a'", Ix::Data(10, 1_000_000_000_000_000), &[]),
            &le(&[1.0, 2.0]),
        );
        let err = read(&huge).unwrap_err();
        assert!(
            err.contains("less than one chunk") && err.contains("`g/a`"),
            "{err}"
        );
        // A count whose size overflows.
        let overflow = segment(
            ALL,
            1,
            |w| obj(w, "/'g'/'a'", Ix::Data(10, u64::MAX / 2), &[]),
            &[],
        );
        assert!(read(&overflow).unwrap_err().contains("overflow"));
        // A property string longer than the metadata.
        let mut prop = segment(
            ALL,
            1,
            |w| {
                obj(
                    w,
                    "/'g'/'a'",
                    Ix::Data(10, 1),
                    &[("unit_string", P::Str("deg"))],
                )
            },
            &le(&[1.0]),
        );
        let at = prop.windows(3).position(|w| w == b"deg").unwrap() - 4;
        prop[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let err = read(&prop).unwrap_err();
        assert!(
            err.contains("object `g/a`") && err.contains("property `unit_string`"),
            "{err}"
        );
        // "As before" with nothing before; a second segment that is not one.
        let before = segment(ALL, 1, |w| obj(w, "/'g'/'a'", Ix::AsBefore, &[]), &[]);
        assert!(read(&before).unwrap_err().contains("no segment before"));
        let mut junk = good.clone();
        junk.extend(b"PK\x03\x04 and more than twenty-eight bytes of a zip");
        let err = read(&junk).unwrap_err();
        assert!(
            err.contains("segment 1") && err.contains("instead of `TDSm`"),
            "{err}"
        );
        // Every cut of a good file fails or reads, never panics.
        for n in 0..good.len() {
            let _ = read(&good[..n]);
        }
    }

    #[test]
    fn object_paths_are_unquoted() {
        assert_eq!(parse_path("/"), Some(vec![]));
        assert_eq!(
            parse_path("/'it''s'/'a/b'"),
            Some(vec!["it's".to_string(), "a/b".to_string()])
        );
        for bad in ["", "g", "/'g", "/'g'x", "/'g'/", "/'a'/'b'/'c'"] {
            assert_eq!(parse_path(bad), None, "{bad}");
        }
    }

    /// The files `testdata/tdms/make_fixture.py` wrote with nptdms.
    fn fixture(name: &str) -> ColumnSet {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../testdata/tdms")
            .join(name);
        Tdms.read(&path, &ReadOptions::default()).unwrap()
    }

    #[test]
    fn the_nptdms_fixtures_read_as_written() {
        let wave = fixture("waveform.tdms");
        let timed = fixture("timed.tdms");
        let names = |set: &ColumnSet| {
            set.columns
                .iter()
                .map(|c| c.name.clone())
                .collect::<Vec<_>>()
        };
        assert_eq!(names(&wave), ["Encoders/a", "Encoders/b"]);
        assert_eq!(names(&timed), ["Run/t", "Run/a", "Run/b"]);
        for name in ["a", "b"] {
            let w = column(&wave, &format!("Encoders/{name}"));
            let t = column(&timed, &format!("Run/{name}"));
            assert_eq!(w.values.len(), 3301);
            // The same numbers, read from one file's three segments and the other's two.
            assert_eq!(w.values, t.values);
            assert_eq!(
                (w.unit.as_deref(), t.unit.as_deref()),
                (Some("deg"), Some("deg"))
            );
            assert_eq!(
                w.time,
                ColumnTime::Waveform {
                    start_ns: 1_700_000_000_000_000_000,
                    increment_s: 0.005
                }
            );
        }
        let Values::F64(a) = &column(&wave, "Encoders/a").values else {
            panic!("a is f64")
        };
        // quick.csv's first reading of a, 0.2923°, as the CSV wrote it.
        assert_eq!(a[0], 0.29229999999999995);
        // t = 0, 0.005, … s after 2023-11-14 22:13:20 UTC, as ns since 1970.
        let t = column(&timed, "Run/t");
        assert_eq!(t.time, ColumnTime::Stamps(TimeUnit::Ns));
        let Values::I64(stamps) = &t.values else {
            panic!("stamps are i64")
        };
        assert_eq!(stamps.len(), 3301);
        for (i, &s) in stamps.iter().enumerate() {
            assert_eq!(
                s,
                1_700_000_000_000_000_000 + i as i64 * 5_000_000,
                "sample {i}"
            );
        }
        assert_eq!(
            wave.structure,
            [
                "TDMS version 4712, 3 segments, little-endian",
                "group `Encoders`: `a` (f64, 3301 values, unit `deg`, waveform at 200 Hz), \
                 `b` (f64, 3301 values, unit `deg`, waveform at 200 Hz)",
                "group `Notes`: `operator` (string, not taken)",
                "`Notes/operator`: not taken: strings are not readings",
            ]
        );
    }
}

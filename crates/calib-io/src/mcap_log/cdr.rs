//! Hand-written decoders of the joint-state messages calib reads: ROS 2
//! `sensor_msgs/msg/JointState` and `control_msgs/msg/DynamicJointState` in CDR, ROS 1
//! `sensor_msgs/JointState` in the ROS 1 wire format, and the `std_msgs` scalars (CDR or ROS 1).
//!
//! **CDR** (OMG CDR as ROS 2 `rmw` writes it): a 4-byte encapsulation header (`00 01`
//! little-endian, `00 00` big-endian, then two option bytes), then the fields, each aligned to its
//! own size counted from the end of that header. Strings are a `u32` length that includes the
//! trailing NUL, then the bytes and the NUL; sequences are a `u32` count then the elements.
//!
//! **ROS 1** (what `mcap convert` makes of a ROS 1 bag: message encoding `ros1`, schema encoding
//! `ros1msg`): no encapsulation header, little-endian, no alignment padding at all; strings are a
//! `u32` length *without* a NUL, then the bytes; the header starts with `uint32 seq` and its stamp
//! is `uint32 secs, uint32 nsecs`.
//!
//! ```text
//! JointState        = Header header { [uint32 seq (ROS 1)] Time stamp { sec; nanosec }; string frame_id }
//!                     string[] name; float64[] position; float64[] velocity; float64[] effort
//! DynamicJointState = Header header; string[] joint_names;
//!                     InterfaceValue[] interface_values { string[] interface_names; float64[] values }
//! ```
//!
//! A DynamicJointState's channels are its `joint_names`; each joint's reading is the value of its
//! `position` interface (a joint without one carries no reading in that message).
//!
//! The decoder borrows from the message and allocates nothing for JointState: it checks every
//! length against the bytes that remain before using it, so a corrupt length can neither panic
//! nor make it allocate. It is hand-written rather than serde-based because it is the hot loop of
//! reading a log (see `benches/ingest_mcap.rs`), and because comparing a message's `name` block
//! byte for byte with the first message's is how the reader checks cheaply that the joints did
//! not change.

use std::fmt;

/// Bytes of the encapsulation header; alignment is counted from its end.
pub(super) const ORIGIN: usize = 4;

/// What is wrong with a CDR message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum CdrError {
    /// The encapsulation header names a representation other than plain CDR.
    Encapsulation([u8; 2]),
    /// The message ends before a field.
    Truncated {
        /// The field being read.
        field: &'static str,
        /// Byte offset of the field in the message.
        offset: usize,
        /// Bytes the message has.
        len: usize,
    },
    /// A length or count claims more bytes than the message has left.
    LengthTooLarge {
        /// The string or sequence.
        field: &'static str,
        /// The length or count read.
        count: u32,
        /// Bytes left in the message after it.
        remaining: usize,
    },
    /// A DynamicJointState's counts disagree: joints and their interface values, or an
    /// interface's names and values.
    Mismatch {
        /// Names counted.
        names: usize,
        /// Values counted.
        values: usize,
    },
    /// The message names more joints than [`MAX_JOINTS`](crate::limits::MAX_JOINTS).
    TooManyJoints {
        /// The count the message gives.
        count: usize,
    },
    /// A joint name is not UTF-8.
    NameNotUtf8 {
        /// Index of the name in `name`.
        index: usize,
    },
}

impl fmt::Display for CdrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            // The first bytes of a zstd frame (28 b5 2f fd): a compressed payload.
            CdrError::Encapsulation([0x28, 0xb5]) => f.write_str(
                "the message is zstd-compressed (it starts with the zstd magic 28 b5 2f fd), \
                 not CDR; a bag whose messages are compressed says so in its metadata.yaml \
                 (compression_format: zstd, compression_mode: MESSAGE): restore that file, or \
                 read the bag directory rather than the .db3 file alone",
            ),
            CdrError::TooManyJoints { count } => write!(
                f,
                "the message names {count} joints, more than the {} calib reads in one \
                 message; the message is damaged",
                crate::limits::MAX_JOINTS
            ),
            CdrError::Encapsulation(h) => write!(
                f,
                "unsupported CDR encapsulation {:02x} {:02x}; calib reads plain CDR \
                 (00 00 big-endian or 00 01 little-endian), which ROS 2 writes by default",
                h[0], h[1]
            ),
            CdrError::Truncated { field, offset, len } => write!(
                f,
                "the CDR message is truncated: `{field}` at byte {offset} lies beyond \
                 its {len} bytes"
            ),
            CdrError::LengthTooLarge {
                field,
                count,
                remaining,
            } => write!(
                f,
                "the CDR message is truncated or corrupt: `{field}` claims {count} \
                 entries or bytes but only {remaining} bytes remain"
            ),
            CdrError::Mismatch { names, values } => write!(
                f,
                "the DynamicJointState message has {names} names but {values} values; the \
                 publisher must give one value per name"
            ),
            CdrError::NameNotUtf8 { index } => {
                write!(
                    f,
                    "joint name {index} of the JointState message is not UTF-8"
                )
            }
        }
    }
}

/// The wire formats of joint-state messages calib reads (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum JointFormat {
    /// `sensor_msgs/msg/JointState`, CDR.
    Cdr,
    /// `sensor_msgs/JointState`, ROS 1 wire format.
    Ros1,
    /// `control_msgs/msg/DynamicJointState`, CDR: the `position` interface of each joint.
    Dynamic,
}

/// A bounds-checked reader of CDR (or, `packed`, ROS 1) primitives.
pub(super) struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
    pub(super) big_endian: bool,
    /// Where alignment is counted from: the end of the CDR encapsulation header.
    origin: usize,
    /// ROS 1: no alignment padding, strings without their NUL.
    packed: bool,
}

impl<'a> Cursor<'a> {
    pub(super) fn cdr(buf: &'a [u8], pos: usize, big_endian: bool) -> Self {
        Cursor {
            buf,
            pos,
            big_endian,
            origin: ORIGIN,
            packed: false,
        }
    }

    pub(super) fn align(&mut self, n: usize) {
        if self.packed {
            return;
        }
        let rel = self.pos - self.origin;
        self.pos = self.origin + rel.div_ceil(n) * n;
    }

    pub(super) fn remaining(&self) -> usize {
        self.buf.len().saturating_sub(self.pos)
    }

    pub(super) fn take(&mut self, n: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        let bytes = self
            .pos
            .checked_add(n)
            .and_then(|end| self.buf.get(self.pos..end))
            .ok_or(CdrError::Truncated {
                field,
                offset: self.pos,
                len: self.buf.len(),
            })?;
        self.pos += n;
        Ok(bytes)
    }

    pub(super) fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        self.align(4);
        let b: [u8; 4] = self.take(4, field)?.try_into().unwrap_or_default();
        Ok(if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }

    /// A sequence count, checked against the bytes left: each element takes at least
    /// `min_size` bytes.
    pub(super) fn count(
        &mut self,
        field: &'static str,
        min_size: usize,
    ) -> Result<usize, CdrError> {
        let count = self.u32(field)?;
        let remaining = self.remaining();
        if (count as usize).saturating_mul(min_size) > remaining {
            return Err(CdrError::LengthTooLarge {
                field,
                count,
                remaining,
            });
        }
        Ok(count as usize)
    }

    /// A string's bytes without the trailing NUL.
    pub(super) fn string(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let len = self.count(field, 1)?;
        let bytes = self.take(len, field)?;
        // The length counts the NUL; tolerate writers that omit it (or write length 0). ROS 1
        // strings have none.
        Ok(bytes.strip_suffix(&[0]).unwrap_or(bytes))
    }

    /// A `float64[]`: the raw element bytes, `8 × count` of them.
    fn f64_seq(&mut self, field: &'static str) -> Result<&'a [u8], CdrError> {
        let count = self.count(field, 8)?;
        if count == 0 {
            // No padding follows the count of an empty sequence.
            return Ok(&[]);
        }
        self.align(8);
        // Re-check after the alignment padding.
        let remaining = self.remaining();
        if count * 8 > remaining {
            return Err(CdrError::LengthTooLarge {
                field,
                count: count as u32,
                remaining,
            });
        }
        self.take(count * 8, field)
    }

    fn f64_at(&self, b: &[u8]) -> f64 {
        let b: [u8; 8] = b.try_into().unwrap_or_default();
        if self.big_endian {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    }

    /// The header stamp `(sec, nanosec)` and `frame_id` of a ROS 2 or (`packed`) ROS 1 header.
    fn header(&mut self) -> Result<(i64, u32), CdrError> {
        let sec = if self.packed {
            self.u32("header.seq")?;
            // ROS 1 `time`: unsigned seconds.
            i64::from(self.u32("header.stamp.secs")?)
        } else {
            i64::from(self.u32("header.stamp.sec")? as i32)
        };
        let nanosec = self.u32("header.stamp.nanosec")?;
        self.string("header.frame_id")?;
        Ok((sec, nanosec))
    }
}

/// The CDR encapsulation header's byte order: `true` for big-endian.
pub(super) fn encapsulation(data: &[u8]) -> Result<bool, CdrError> {
    let header = data.get(..ORIGIN).ok_or(CdrError::Truncated {
        field: "encapsulation header",
        offset: 0,
        len: data.len(),
    })?;
    match [header[0], header[1]] {
        [0, 0] => Ok(true),
        [0, 1] => Ok(false),
        other => Err(CdrError::Encapsulation(other)),
    }
}

/// Where a message's joint positions are.
#[derive(Debug, Clone)]
enum Positions<'a> {
    /// `float64[] position`: the raw elements.
    Raw(&'a [u8]),
    /// DynamicJointState: each joint's `position` interface value, NaN where it has none.
    Interfaces(Vec<f64>),
}

/// Where one `position` element lies in a JointState message: its offset, and the message's byte
/// order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Place {
    pub at: usize,
    pub big_endian: bool,
}

impl Place {
    /// The position in `data`, a message of the layout this place was found in.
    pub fn read(self, data: &[u8]) -> f64 {
        let b: [u8; 8] = data[self.at..self.at + 8].try_into().unwrap_or_default();
        if self.big_endian {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    }

    /// Overwrites the position in `data` with `value`; every other byte stays as it was.
    pub fn write(self, data: &mut [u8], value: f64) {
        data[self.at..self.at + 8].copy_from_slice(&if self.big_endian {
            value.to_be_bytes()
        } else {
            value.to_le_bytes()
        });
    }
}

/// A decoded joint-state message (JointState in CDR or ROS 1, or DynamicJointState), borrowing
/// from the message.
#[derive(Debug, Clone)]
pub(crate) struct JointState<'a> {
    /// `header.stamp.sec`.
    pub sec: i64,
    /// `header.stamp.nanosec`.
    pub nanosec: u32,
    /// Number of joint names.
    pub name_count: usize,
    /// The serialized `name` sequence after its count, padding included. Its start is 4-aligned
    /// whatever `frame_id` is, so two messages with the same names normally have equal blocks.
    pub name_block: &'a [u8],
    /// The whole message, and where `name_block` starts in it.
    data: &'a [u8],
    name_start: usize,
    positions: Positions<'a>,
    /// Where the raw `position` elements start in the message.
    positions_at: usize,
    big_endian: bool,
    packed: bool,
}

impl<'a> JointState<'a> {
    /// Decodes a CDR `sensor_msgs/msg/JointState`, checking every field including `velocity`
    /// and `effort`.
    #[cfg(test)]
    pub fn parse(data: &'a [u8]) -> Result<Self, CdrError> {
        Self::parse_as(data, JointFormat::Cdr)
    }

    /// Decodes a message of this format, checking every field.
    pub fn parse_as(data: &'a [u8], format: JointFormat) -> Result<Self, CdrError> {
        let mut c = match format {
            JointFormat::Cdr | JointFormat::Dynamic => {
                Cursor::cdr(data, ORIGIN, encapsulation(data)?)
            }
            JointFormat::Ros1 => Cursor {
                buf: data,
                pos: 0,
                big_endian: false,
                origin: 0,
                packed: true,
            },
        };
        let (sec, nanosec) = c.header()?;
        // Each name takes at least its 4-byte length.
        let name_count = c.count("name", 4)?;
        if name_count > crate::limits::MAX_JOINTS {
            return Err(CdrError::TooManyJoints { count: name_count });
        }
        let name_start = c.pos;
        for _ in 0..name_count {
            c.string("name")?;
        }
        let name_block = &data[name_start..c.pos];
        let (positions, positions_at) = if format == JointFormat::Dynamic {
            (
                Positions::Interfaces(interface_positions(&mut c, name_count)?),
                0,
            )
        } else {
            let raw = c.f64_seq("position")?;
            let at = c.pos - raw.len();
            c.f64_seq("velocity")?;
            c.f64_seq("effort")?;
            (Positions::Raw(raw), at)
        };
        Ok(JointState {
            sec,
            nanosec,
            name_count,
            name_block,
            data,
            name_start,
            positions,
            positions_at,
            big_endian: c.big_endian,
            packed: c.packed,
        })
    }

    /// The index of the joint named `name`, if the message has it.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.names().position(|n| n.is_ok_and(|n| n == name))
    }

    /// Where `position[index]` lies in the message; `None` if the message has no such position
    /// (a DynamicJointState has no `position` array).
    pub fn place(&self, index: usize) -> Option<Place> {
        (matches!(self.positions, Positions::Raw(_)) && index < self.position_count()).then_some(
            Place {
                at: self.positions_at + 8 * index,
                big_endian: self.big_endian,
            },
        )
    }

    /// Where the `position` elements lie in the message (empty for a DynamicJointState).
    pub fn positions_span(&self) -> std::ops::Range<usize> {
        match &self.positions {
            Positions::Raw(raw) => self.positions_at..self.positions_at + raw.len(),
            Positions::Interfaces(_) => 0..0,
        }
    }

    /// Overwrites `position[index]` of `data` — the message this was parsed from, or a copy of
    /// it — with `value` in the message's byte order; every other byte stays as it was. `false`
    /// (and `data` untouched) if the message has no such position.
    #[cfg(test)]
    pub fn set_position(&self, data: &mut [u8], index: usize, value: f64) -> bool {
        match self.place(index) {
            Some(place) if data.len() == self.data.len() => {
                place.write(data, value);
                true
            }
            _ => false,
        }
    }

    /// The joint names, in order.
    pub fn names(&self) -> impl Iterator<Item = Result<&'a str, CdrError>> + 'a {
        let mut c = Cursor {
            buf: self.data,
            pos: self.name_start,
            big_endian: self.big_endian,
            origin: if self.packed { 0 } else { ORIGIN },
            packed: self.packed,
        };
        (0..self.name_count).map(move |index| {
            let bytes = c.string("name")?;
            std::str::from_utf8(bytes).map_err(|_| CdrError::NameNotUtf8 { index })
        })
    }

    /// Number of `position` entries (of joints, for a DynamicJointState).
    pub fn position_count(&self) -> usize {
        match &self.positions {
            Positions::Raw(raw) => raw.len() / 8,
            Positions::Interfaces(v) => v.len(),
        }
    }

    /// The positions, radians; NaN for a DynamicJointState joint without a `position`
    /// interface.
    pub fn positions(&self) -> impl Iterator<Item = f64> + '_ {
        let big_endian = self.big_endian;
        let (raw, interfaces): (&[u8], &[f64]) = match &self.positions {
            Positions::Raw(raw) => (raw, &[]),
            Positions::Interfaces(v) => (&[], v),
        };
        raw.chunks_exact(8)
            .map(move |b| {
                let b: [u8; 8] = b.try_into().unwrap_or_default();
                if big_endian {
                    f64::from_be_bytes(b)
                } else {
                    f64::from_le_bytes(b)
                }
            })
            .chain(interfaces.iter().copied())
    }
}

/// The `position` interface value of each of `joints` joints from a DynamicJointState's
/// `interface_values` (NaN where a joint has no `position` interface).
fn interface_positions(c: &mut Cursor<'_>, joints: usize) -> Result<Vec<f64>, CdrError> {
    // Each entry holds at least its two 4-byte counts.
    let count = c.count("interface_values", 8)?;
    if count != joints {
        return Err(CdrError::Mismatch {
            names: joints,
            values: count,
        });
    }
    let mut positions = vec![f64::NAN; count];
    for position in &mut positions {
        let names = c.count("interface_values.interface_names", 4)?;
        let mut at = None;
        for k in 0..names {
            if c.string("interface_values.interface_names")? == b"position" {
                at = Some(k);
            }
        }
        let values = c.f64_seq("interface_values.values")?;
        if values.len() / 8 != names {
            return Err(CdrError::Mismatch {
                names,
                values: values.len() / 8,
            });
        }
        if let Some(k) = at {
            *position = c.f64_at(&values[8 * k..8 * k + 8]);
        }
    }
    Ok(positions)
}

/// Encodes JointStates with fixed names, little-endian, rewriting only the stamp and positions of
/// one buffer per message: the names, `frame_id` (empty) and the empty `velocity` and `effort`
/// never change, so they are serialized once.
#[derive(Debug, Clone)]
pub(crate) struct JointStateEncoder {
    buf: Vec<u8>,
    positions_at: usize,
    count: usize,
}

impl JointStateEncoder {
    /// An encoder for messages carrying these joint names.
    pub fn new<'n>(names: impl IntoIterator<Item = &'n str>) -> Self {
        let mut w = Writer {
            buf: vec![0, 1, 0, 0],
        };
        w.u32(0); // stamp.sec
        w.u32(0); // stamp.nanosec
        w.string(""); // frame_id
        let names: Vec<&str> = names.into_iter().collect();
        w.u32(names.len() as u32);
        for name in &names {
            w.string(name);
        }
        w.u32(names.len() as u32);
        if !names.is_empty() {
            w.align(8);
        }
        let positions_at = w.buf.len();
        w.buf.resize(positions_at + 8 * names.len(), 0);
        w.u32(0); // velocity
        w.u32(0); // effort
        JointStateEncoder {
            buf: w.buf,
            positions_at,
            count: names.len(),
        }
    }

    /// The message for this stamp and these positions (as many as names; extra ones are not
    /// written, missing ones keep their previous value — the caller checks the count).
    pub fn encode(&mut self, sec: i32, nanosec: u32, positions: &[f64]) -> &[u8] {
        self.buf[4..8].copy_from_slice(&sec.to_le_bytes());
        self.buf[8..12].copy_from_slice(&nanosec.to_le_bytes());
        let slots =
            self.buf[self.positions_at..self.positions_at + 8 * self.count].chunks_exact_mut(8);
        for (slot, p) in slots.zip(positions) {
            slot.copy_from_slice(&p.to_le_bytes());
        }
        &self.buf
    }
}

/// A little-endian CDR serializer, for the encoder's template and for tests.
struct Writer {
    buf: Vec<u8>,
}

impl Writer {
    fn align(&mut self, n: usize) {
        let rel = self.buf.len() - ORIGIN;
        self.buf.resize(ORIGIN + rel.div_ceil(n) * n, 0);
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
}

/// The `std_msgs` scalar messages calib reads: one number (`data`) per message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Scalar {
    Float64,
    Float32,
    Int64,
    Int32,
    UInt32,
    UInt16,
}

impl Scalar {
    /// The scalar type of a ROS message type name (`std_msgs/msg/Float64`, or the ROS 1 style
    /// `std_msgs/Float64` that older converters write).
    pub(crate) fn of_type(name: &str) -> Option<Self> {
        let base = name
            .strip_prefix("std_msgs/msg/")
            .or_else(|| name.strip_prefix("std_msgs/"))?;
        Some(match base {
            "Float64" => Scalar::Float64,
            "Float32" => Scalar::Float32,
            "Int64" => Scalar::Int64,
            "Int32" => Scalar::Int32,
            "UInt32" => Scalar::UInt32,
            "UInt16" => Scalar::UInt16,
            _ => return None,
        })
    }

    /// The value of a message of this type in `message_encoding`: `ros1` (the ROS 1 wire
    /// format: the value alone, little-endian) or CDR.
    pub(crate) fn decode_in(self, data: &[u8], message_encoding: &str) -> Result<f64, CdrError> {
        if message_encoding != "ros1" {
            return self.decode(data);
        }
        let size = self.size();
        let mut c = Cursor::cdr(data, 0, false);
        c.packed = true;
        let bytes = c.take(size, "data")?;
        let mut b = [0u8; 8];
        b[..size].copy_from_slice(bytes);
        Ok(self.value(b))
    }

    fn size(self) -> usize {
        match self {
            Scalar::Float64 | Scalar::Int64 => 8,
            Scalar::Float32 | Scalar::Int32 | Scalar::UInt32 => 4,
            Scalar::UInt16 => 2,
        }
    }

    /// The value of little-endian bytes of this type (padded to 8).
    fn value(self, b: [u8; 8]) -> f64 {
        let (lo4, lo2) = ([b[0], b[1], b[2], b[3]], [b[0], b[1]]);
        match self {
            Scalar::Float64 => f64::from_le_bytes(b),
            Scalar::Int64 => i64::from_le_bytes(b) as f64,
            Scalar::Float32 => f64::from(f32::from_le_bytes(lo4)),
            Scalar::Int32 => f64::from(i32::from_le_bytes(lo4)),
            Scalar::UInt32 => f64::from(u32::from_le_bytes(lo4)),
            Scalar::UInt16 => f64::from(u16::from_le_bytes(lo2)),
        }
    }

    /// The value of a CDR message of this type. The one field lies right after the
    /// encapsulation header, which is aligned for any size; integers are returned exactly as
    /// `f64` (an `int64` beyond 2⁵³ is rounded, far beyond any encoder's count).
    pub(crate) fn decode(self, data: &[u8]) -> Result<f64, CdrError> {
        let size = self.size();
        let mut c = Cursor::cdr(data, ORIGIN, encapsulation(data)?);
        let bytes = c.take(size, "data")?;
        let mut b = [0u8; 8];
        if c.big_endian {
            b[8 - size..].copy_from_slice(bytes);
            b.reverse();
        } else {
            b[..size].copy_from_slice(bytes);
        }
        Ok(self.value(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names<'a>(js: &JointState<'a>) -> Vec<&'a str> {
        js.names().map(|n| n.unwrap()).collect()
    }

    /// Each scalar type in both byte orders, as `rmw` serializes `std_msgs` messages: the
    /// encapsulation header, then `data`.
    #[test]
    fn scalars_decode_in_both_byte_orders() {
        let le = |bytes: &[u8]| [&[0u8, 1, 0, 0][..], bytes].concat();
        let be = |bytes: &[u8]| [&[0u8, 0, 0, 0][..], bytes].concat();
        let cases: [(Scalar, Vec<u8>, Vec<u8>, f64); 6] = [
            (
                Scalar::Float64,
                le(&1.25f64.to_le_bytes()),
                be(&1.25f64.to_be_bytes()),
                1.25,
            ),
            (
                Scalar::Float32,
                le(&(-0.5f32).to_le_bytes()),
                be(&(-0.5f32).to_be_bytes()),
                -0.5,
            ),
            (
                Scalar::Int64,
                le(&(-3i64).to_le_bytes()),
                be(&(-3i64).to_be_bytes()),
                -3.0,
            ),
            (
                Scalar::Int32,
                le(&(-70000i32).to_le_bytes()),
                be(&(-70000i32).to_be_bytes()),
                -70000.0,
            ),
            (
                Scalar::UInt32,
                le(&4_000_000_000u32.to_le_bytes()),
                be(&4_000_000_000u32.to_be_bytes()),
                4e9,
            ),
            (
                Scalar::UInt16,
                le(&65535u16.to_le_bytes()),
                be(&65535u16.to_be_bytes()),
                65535.0,
            ),
        ];
        for (kind, little, big, want) in cases {
            assert_eq!(kind.decode(&little), Ok(want), "{kind:?} little-endian");
            assert_eq!(kind.decode(&big), Ok(want), "{kind:?} big-endian");
            assert!(matches!(
                kind.decode(&little[..little.len() - 1]),
                Err(CdrError::Truncated { field: "data", .. })
            ));
        }
        assert_eq!(Scalar::of_type("std_msgs/msg/UInt16"), Some(Scalar::UInt16));
        assert_eq!(Scalar::of_type("std_msgs/Float64"), Some(Scalar::Float64));
        assert_eq!(Scalar::of_type("std_msgs/msg/String"), None);
        assert!(matches!(
            Scalar::Float64.decode(&[0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]),
            Err(CdrError::Encapsulation([0, 3]))
        ));
    }

    #[test]
    fn encoder_output_decodes_back() {
        for joints in [vec![], vec!["a"], vec!["a", "bb", "ccc", "dddd"]] {
            let mut enc = JointStateEncoder::new(joints.iter().copied());
            let positions: Vec<f64> = (0..joints.len()).map(|i| i as f64 - 0.25).collect();
            let data = enc.encode(-3, 999_999_999, &positions).to_vec();
            let js = JointState::parse(&data).unwrap();
            assert_eq!((js.sec, js.nanosec), (-3, 999_999_999));
            assert_eq!(names(&js), joints);
            assert_eq!(js.positions().collect::<Vec<_>>(), positions);
        }
    }

    #[test]
    fn every_truncation_and_corruption_is_an_error_not_a_panic() {
        let mut enc = JointStateEncoder::new(["a", "b"]);
        let data = enc.encode(1, 2, &[0.5, 1.5]).to_vec();
        for n in 0..data.len() {
            assert!(JointState::parse(&data[..n]).is_err(), "cut at {n}");
        }
        // Every single-byte change either decodes or fails cleanly.
        for at in 0..data.len() {
            for value in [0x00, 0x7f, 0xff] {
                let mut bad = data.clone();
                bad[at] = value;
                if let Ok(js) = JointState::parse(&bad) {
                    let _ = js.names().count();
                    let _ = js.positions().count();
                }
            }
        }
    }

    #[test]
    fn set_position_rewrites_eight_bytes_and_nothing_else() {
        let mut enc = JointStateEncoder::new(["a", "bb", "c"]);
        let data = enc.encode(7, 8, &[0.5, 1.5, 2.5]).to_vec();
        let js = JointState::parse(&data).unwrap();
        assert_eq!(js.joint("bb"), Some(1));
        assert_eq!(js.joint("b"), None);
        let mut out = data.clone();
        assert!(js.set_position(&mut out, 1, -4.25));
        assert!(!js.set_position(&mut out, 3, 0.0));
        let changed: Vec<usize> = (0..data.len()).filter(|&i| data[i] != out[i]).collect();
        assert!(!changed.is_empty() && changed.len() <= 8, "{changed:?}");
        let back = JointState::parse(&out).unwrap();
        assert_eq!(back.positions().collect::<Vec<_>>(), [0.5, -4.25, 2.5]);
        assert_eq!(
            (back.sec, back.nanosec, back.name_block),
            (7, 8, js.name_block)
        );
    }

    /// ROS 1: no encapsulation header and no padding (a 3-byte `frame_id` leaves the names
    /// and positions off every boundary), the header with `seq`, unsigned seconds.
    /// A ROS 1 scalar is its value alone, little-endian: what a bag (or `mcap convert`) holds.
    #[test]
    fn ros1_scalars_have_no_header() {
        let cases: [(Scalar, Vec<u8>, f64); 3] = [
            (Scalar::Float64, 1.25f64.to_le_bytes().to_vec(), 1.25),
            (Scalar::Int32, (-7i32).to_le_bytes().to_vec(), -7.0),
            (Scalar::UInt16, 65535u16.to_le_bytes().to_vec(), 65535.0),
        ];
        for (kind, bytes, want) in cases {
            assert_eq!(kind.decode_in(&bytes, "ros1"), Ok(want), "{kind:?}");
            assert!(kind.decode_in(&bytes[..1], "ros1").is_err(), "{kind:?}");
        }
        // The same bytes as CDR lack the encapsulation header's 4 bytes first.
        assert_ne!(
            Scalar::Float64.decode_in(&1.25f64.to_le_bytes(), "cdr"),
            Ok(1.25)
        );
    }

    #[test]
    fn ros1_joint_state_is_packed() {
        let mut b = Vec::new();
        for v in [7u32, 3_000_000_000, 5, 3] {
            b.extend(v.to_le_bytes());
        }
        b.extend(b"enc");
        b.extend(2u32.to_le_bytes());
        b.extend(1u32.to_le_bytes());
        b.extend(b"a");
        b.extend(2u32.to_le_bytes());
        b.extend(b"bb");
        b.extend(2u32.to_le_bytes());
        b.extend(0.5f64.to_le_bytes());
        b.extend((-1.5f64).to_le_bytes());
        b.extend(0u32.to_le_bytes());
        b.extend(0u32.to_le_bytes());
        let js = JointState::parse_as(&b, JointFormat::Ros1).unwrap();
        assert_eq!((js.sec, js.nanosec), (3_000_000_000, 5));
        assert_eq!(names(&js), ["a", "bb"]);
        assert_eq!(js.positions().collect::<Vec<_>>(), [0.5, -1.5]);
        let mut out = b.clone();
        assert!(js.set_position(&mut out, 1, 2.0));
        let back = JointState::parse_as(&out, JointFormat::Ros1).unwrap();
        assert_eq!(back.positions().collect::<Vec<_>>(), [0.5, 2.0]);
        for n in 0..b.len() {
            assert!(
                JointState::parse_as(&b[..n], JointFormat::Ros1).is_err(),
                "{n}"
            );
        }
    }

    /// DynamicJointState: each joint's `position` interface, wherever it is among the
    /// interfaces; NaN for a joint without one; counts that disagree are errors.
    #[test]
    fn dynamic_joint_state_reads_the_position_interface() {
        let message = |interfaces: &[&[(&str, f64)]]| {
            let mut w = Writer {
                buf: vec![0, 1, 0, 0],
            };
            w.u32(1);
            w.u32(2);
            w.string("base");
            w.u32(interfaces.len() as u32);
            for k in 0..interfaces.len() {
                w.string(["j1", "j2", "j3"][k]);
            }
            w.u32(interfaces.len() as u32);
            for joint in interfaces {
                w.u32(joint.len() as u32);
                for (name, _) in *joint {
                    w.string(name);
                }
                w.u32(joint.len() as u32);
                if !joint.is_empty() {
                    w.align(8);
                }
                for (_, v) in *joint {
                    w.buf.extend(v.to_le_bytes());
                }
            }
            w.buf
        };
        let data = message(&[
            &[("position", 1.25), ("velocity", 9.0)],
            &[("effort", 3.0), ("position", -0.5)],
            &[("velocity", 2.0)],
        ]);
        let js = JointState::parse_as(&data, JointFormat::Dynamic).unwrap();
        assert_eq!((js.sec, js.nanosec), (1, 2));
        assert_eq!(names(&js), ["j1", "j2", "j3"]);
        let p: Vec<f64> = js.positions().collect();
        assert_eq!(&p[..2], [1.25, -0.5]);
        assert!(p[2].is_nan());
        assert!(!js.set_position(&mut data.clone(), 0, 0.0));
        for n in 0..data.len() {
            assert!(
                JointState::parse_as(&data[..n], JointFormat::Dynamic).is_err(),
                "{n}"
            );
        }
    }

    #[test]
    fn big_endian_and_foreign_encapsulations() {
        // Big-endian by hand: stamp 1 s 2 ns, frame_id "", one name "x", position [1.0].
        let mut be = vec![0, 0, 0, 0];
        be.extend(1u32.to_be_bytes());
        be.extend(2u32.to_be_bytes());
        be.extend(1u32.to_be_bytes());
        be.extend([0, 0, 0, 0]); // "" + padding
        be.extend(1u32.to_be_bytes());
        be.extend(2u32.to_be_bytes());
        be.extend([b'x', 0, 0, 0]); // "x" + padding to 8
        be.extend(1u32.to_be_bytes());
        be.extend(1f64.to_be_bytes());
        be.extend(0u32.to_be_bytes());
        be.extend(0u32.to_be_bytes());
        let js = JointState::parse(&be).unwrap();
        assert_eq!((js.sec, js.nanosec), (1, 2));
        assert_eq!(names(&js), ["x"]);
        assert_eq!(js.positions().collect::<Vec<_>>(), [1.0]);
        be[1] = 3;
        assert_eq!(
            JointState::parse(&be).unwrap_err(),
            CdrError::Encapsulation([0, 3])
        );
    }
}

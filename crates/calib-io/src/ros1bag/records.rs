//! The records of a ROS 1 bag (format 2.0), parsed from bytes: a record is a header (a `u32`
//! length, then fields `u32 length` + `name=value`) and data (a `u32` length, then the bytes).
//! Every length is checked against the bytes that remain before it is used, so a corrupt
//! length can neither panic nor drive an allocation.

use std::fmt;

/// The first line of a bag of format 2.0, the one calib reads.
pub(crate) const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The first bytes of a bag of any format version (`#ROSBAG V1.2`, `#ROSBAG V2.0`).
pub(crate) const MAGIC_PREFIX: &[u8] = b"#ROSBAG V";

/// The `op` of each kind of record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Op {
    /// A message: header `conn`, `time`; data the serialized message.
    MessageData,
    /// The bag header, first record of the file: `index_pos`, `conn_count`, `chunk_count`.
    BagHeader,
    /// A chunk's index of one connection: `ver`, `conn`, `count`; data `(time, offset)` pairs.
    IndexData,
    /// A chunk: `compression`, `size`; data the (compressed) connection and message records.
    Chunk,
    /// Where a chunk lies and what it holds: `ver`, `chunk_pos`, `start_time`, `end_time`,
    /// `count`; data `(conn, count)` pairs.
    ChunkInfo,
    /// A connection: `conn`, `topic`; data more fields (`type`, `md5sum`,
    /// `message_definition`, optional `callerid` and `latching`).
    Connection,
}

impl Op {
    fn of(code: u8) -> Option<Self> {
        Some(match code {
            0x02 => Op::MessageData,
            0x03 => Op::BagHeader,
            0x04 => Op::IndexData,
            0x05 => Op::Chunk,
            0x06 => Op::ChunkInfo,
            0x07 => Op::Connection,
            _ => return None,
        })
    }

    /// How an error names the record.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Op::MessageData => "message data",
            Op::BagHeader => "bag header",
            Op::IndexData => "index data",
            Op::Chunk => "chunk",
            Op::ChunkInfo => "chunk info",
            Op::Connection => "connection",
        }
    }
}

/// Why bytes are not a record.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum RecordError {
    /// The bytes end inside the record (a file or chunk cut short).
    Cut,
    /// The record is malformed: what is wrong.
    Bad(String),
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::Cut => f.write_str("the record is cut short"),
            RecordError::Bad(m) => f.write_str(m),
        }
    }
}

/// A record's header fields (or a connection record's data, which has the same form), checked
/// to be well formed when made.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fields<'a> {
    bytes: &'a [u8],
}

impl<'a> Fields<'a> {
    /// The fields of `bytes`: each a `u32` length and `name=value` of that length.
    pub(crate) fn parse(bytes: &'a [u8]) -> Result<Self, String> {
        let mut rest = bytes;
        let mut at = 0usize;
        while !rest.is_empty() {
            let (field, tail) = split_len(rest).ok_or_else(|| {
                format!(
                    "the header's field at byte {at} claims more bytes than the header holds; \
                     the record is damaged"
                )
            })?;
            if !field.contains(&b'=') {
                return Err(format!(
                    "the header's field at byte {at} ({}) has no `=`; the record is damaged",
                    crate::limits::shown_bytes(&field[..field.len().min(40)])
                ));
            }
            at += 4 + field.len();
            rest = tail;
        }
        Ok(Fields { bytes })
    }

    /// Fields [`parse`](Self::parse) accepted before.
    pub(crate) fn checked(bytes: &'a [u8]) -> Self {
        Fields { bytes }
    }

    /// The value of the field `name`, if the header has it (the first, if it has several).
    pub(crate) fn get(&self, name: &str) -> Option<&'a [u8]> {
        let mut rest = self.bytes;
        while let Some((field, tail)) = split_len(rest) {
            if let Some(value) = field
                .strip_prefix(name.as_bytes())
                .and_then(|v| v.strip_prefix(b"="))
            {
                return Some(value);
            }
            rest = tail;
        }
        None
    }

    /// The record's `op`.
    pub(crate) fn op(&self) -> Result<Op, String> {
        match self.get("op") {
            Some(&[code]) => Op::of(code).ok_or_else(|| {
                format!("the record's op is 0x{code:02x}, not one of a ROS 1 bag (0x02–0x07)")
            }),
            Some(v) => Err(format!(
                "the record's op field is {} bytes long, not 1",
                v.len()
            )),
            None => Err("the record's header has no op field".into()),
        }
    }

    /// The required field `name`, exactly `N` bytes.
    fn fixed<const N: usize>(&self, name: &str) -> Result<[u8; N], String> {
        let value = self
            .get(name)
            .ok_or_else(|| format!("the record's header has no `{name}` field"))?;
        value.try_into().map_err(|_| {
            format!(
                "the `{name}` field is {} bytes long, not {N}; the record is damaged",
                value.len()
            )
        })
    }

    /// The required `u32` field `name`.
    pub(crate) fn u32(&self, name: &str) -> Result<u32, String> {
        self.fixed::<4>(name).map(u32::from_le_bytes)
    }

    /// The required `u64` field `name`.
    pub(crate) fn u64(&self, name: &str) -> Result<u64, String> {
        self.fixed::<8>(name).map(u64::from_le_bytes)
    }

    /// The required time field `name` (`u32` seconds, `u32` nanoseconds) in nanoseconds.
    pub(crate) fn time(&self, name: &str) -> Result<u64, String> {
        self.fixed::<8>(name).map(time_ns)
    }

    /// The required text field `name`.
    pub(crate) fn text(&self, name: &str) -> Result<&'a str, String> {
        let value = self
            .get(name)
            .ok_or_else(|| format!("the record's header has no `{name}` field"))?;
        std::str::from_utf8(value).map_err(|_| format!("the `{name}` field is not UTF-8 text"))
    }
}

/// A ROS 1 time (`u32` seconds, `u32` nanoseconds, little-endian) in nanoseconds.
pub(crate) fn time_ns(b: [u8; 8]) -> u64 {
    let sec = u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    let nsec = u64::from(u32::from_le_bytes([b[4], b[5], b[6], b[7]]));
    sec * 1_000_000_000 + nsec
}

/// A `u32` length and that many bytes at the start of `bytes`, and what follows; `None` if the
/// bytes end first.
fn split_len(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    let (len, rest) = bytes.split_first_chunk::<4>()?;
    let len = usize::try_from(u32::from_le_bytes(*len)).ok()?;
    (len <= rest.len()).then(|| rest.split_at(len))
}

/// A record inside a buffer (a decompressed chunk).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Record<'a> {
    pub(crate) fields: Fields<'a>,
    pub(crate) data: &'a [u8],
    /// Where the record's data starts in the buffer.
    pub(crate) data_at: usize,
    /// Where the next record starts.
    pub(crate) end: usize,
}

/// The record at `at` in `buf`.
pub(crate) fn record_at(buf: &[u8], at: usize) -> Result<Record<'_>, RecordError> {
    let rest = buf.get(at..).ok_or(RecordError::Cut)?;
    let (header, tail) = split_len(rest).ok_or(RecordError::Cut)?;
    let (data, _) = split_len(tail).ok_or(RecordError::Cut)?;
    let fields = Fields::parse(header).map_err(RecordError::Bad)?;
    let data_at = at + 8 + header.len();
    Ok(Record {
        fields,
        data,
        data_at,
        end: data_at + data.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A header of `fields` as a bag holds it.
    pub(crate) fn header(fields: &[(&str, &[u8])]) -> Vec<u8> {
        let mut out = Vec::new();
        for (name, value) in fields {
            let len = (name.len() + 1 + value.len()) as u32;
            out.extend_from_slice(&len.to_le_bytes());
            out.extend_from_slice(name.as_bytes());
            out.push(b'=');
            out.extend_from_slice(value);
        }
        out
    }

    /// A record: its header and data, each with its length.
    fn record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
        let h = header(fields);
        let mut out = (h.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(&h);
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(data);
        out
    }

    #[test]
    fn a_message_record_gives_its_fields_and_data() {
        let time = [7u8, 0, 0, 0, 0x40, 0x42, 0x0f, 0]; // 7 s + 1 000 000 ns
        let mut buf = record(&[("op", &[2]), ("conn", &3u32.to_le_bytes())], b"xx");
        buf.extend(record(
            &[("op", &[2]), ("conn", &9u32.to_le_bytes()), ("time", &time)],
            b"hello",
        ));
        let first = record_at(&buf, 0).unwrap();
        assert_eq!(first.fields.op(), Ok(Op::MessageData));
        assert_eq!(first.fields.u32("conn"), Ok(3));
        assert!(first.fields.time("time").unwrap_err().contains("no `time`"));
        assert_eq!(first.data, b"xx");
        let second = record_at(&buf, first.end).unwrap();
        assert_eq!(second.fields.u32("conn"), Ok(9));
        assert_eq!(second.fields.time("time"), Ok(7_001_000_000));
        assert_eq!(second.data, b"hello");
        assert_eq!(&buf[second.data_at..second.end], b"hello");
        assert_eq!(second.end, buf.len());
        assert_eq!(record_at(&buf, second.end).unwrap_err(), RecordError::Cut);
    }

    #[test]
    fn values_may_hold_equals_signs_and_names_prefix_others() {
        let h = header(&[("topics", b"x"), ("topic", b"/a=b"), ("op", &[7])]);
        let f = Fields::parse(&h).unwrap();
        assert_eq!(f.text("topic"), Ok("/a=b"));
        assert_eq!(f.text("topics"), Ok("x"));
        assert_eq!(f.op(), Ok(Op::Connection));
    }

    #[test]
    fn every_cut_is_found_and_no_length_is_trusted() {
        let buf = record(
            &[("op", &[5]), ("size", &10u32.to_le_bytes())],
            b"abcdefghij",
        );
        for n in 0..buf.len() {
            assert_eq!(
                record_at(&buf[..n], 0).unwrap_err(),
                RecordError::Cut,
                "{n}"
            );
        }
        // A header length of 4 GiB in a few bytes.
        let huge = [0xff, 0xff, 0xff, 0xff, 1, 2, 3];
        assert_eq!(record_at(&huge, 0).unwrap_err(), RecordError::Cut);
        // A field claiming more than the header holds, a field without `=`.
        let mut bad = 9u32.to_le_bytes().to_vec();
        bad.extend_from_slice(&[200, 0, 0, 0, b'o', b'p', b'=', 2, 0]);
        bad.extend_from_slice(&0u32.to_le_bytes());
        let RecordError::Bad(m) = record_at(&bad, 0).unwrap_err() else {
            panic!("not bad");
        };
        assert!(m.contains("field at byte 0"), "{m}");
        let no_eq = record(&[], b"");
        let mut no_eq = no_eq[..4].to_vec();
        no_eq[0] = 6;
        no_eq.extend_from_slice(&[2, 0, 0, 0, b'o', b'p']);
        no_eq.extend_from_slice(&0u32.to_le_bytes());
        let RecordError::Bad(m) = record_at(&no_eq, 0).unwrap_err() else {
            panic!("not bad");
        };
        assert!(m.contains("no `=`"), "{m}");
    }

    #[test]
    fn ops_and_widths_are_checked() {
        let h = header(&[("op", &[9]), ("conn", &[1, 2])]);
        let f = Fields::parse(&h).unwrap();
        assert!(f.op().unwrap_err().contains("0x09"));
        assert!(f.u32("conn").unwrap_err().contains("2 bytes long, not 4"));
        assert!(f.u64("index_pos").unwrap_err().contains("no `index_pos`"));
        let h = header(&[("index_pos", &4200u64.to_le_bytes()), ("t", &[0xff])]);
        let f = Fields::parse(&h).unwrap();
        assert_eq!(f.u64("index_pos"), Ok(4200));
        assert!(f.text("t").unwrap_err().contains("UTF-8"));
        assert_eq!(
            time_ns([0xff; 8]),
            4_294_967_295 * 1_000_000_000 + 4_294_967_295
        );
    }
}

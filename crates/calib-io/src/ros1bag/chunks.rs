//! A ROS 1 bag's chunks: their data decompressed (`none`, `bz2`, `lz4`) within the size their
//! header declares, and the message records inside listed in time order.

use std::io::Read;

use super::records::{Op, RecordError, record_at};
use crate::limits::MAX_ROS1_CHUNK_BYTES;

/// How a chunk's data is compressed (its header's `compression` field).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Compression {
    None,
    /// bzip2, one stream (what `rosbag record --bz2` writes).
    Bz2,
    /// LZ4, one frame of the LZ4 frame format (`rosbag record --lz4`, the `roslz4` library).
    Lz4,
}

impl Compression {
    /// The compression a chunk header names.
    pub(crate) fn of(name: &str) -> Result<Self, String> {
        match name {
            "none" => Ok(Compression::None),
            "bz2" => Ok(Compression::Bz2),
            "lz4" => Ok(Compression::Lz4),
            other => Err(format!(
                "the chunk's compression is `{}`, not one of a ROS 1 bag (none, bz2, lz4); \
                 the chunk is damaged",
                other.escape_debug()
            )),
        }
    }
}

/// The uncompressed size a chunk header declares (its `size` field), checked against
/// [`MAX_ROS1_CHUNK_BYTES`] before anything is allocated for it.
pub(crate) fn declared_size(size: u32) -> Result<usize, String> {
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    if size > MAX_ROS1_CHUNK_BYTES {
        return Err(format!(
            "the chunk declares {size} bytes uncompressed, more than the {MAX_ROS1_CHUNK_BYTES} \
             calib holds for one chunk (`rosbag record` closes chunks at 768 KiB by default); \
             the chunk header is damaged, or the bag was recorded with a huge `--chunksize`: \
             rewrite it with `rosbag compress` or `rosbag filter`"
        ));
    }
    Ok(size)
}

/// Decompresses a chunk's data, read from `input` (the data's bytes, compressed), into `out`:
/// at most `size` bytes (what the header declares), an error if the data gives more or fewer.
/// On an error `out` holds what could be decompressed, which the reader uses from a chunk the
/// end of the file cut short.
pub(crate) fn decompress(
    input: impl Read,
    compression: Compression,
    size: usize,
    out: &mut Vec<u8>,
) -> Result<(), String> {
    out.clear();
    // Grown as the data gives bytes: a small damaged chunk declaring 100 MB allocates little.
    out.reserve(size.min(1 << 20));
    let limit = size as u64 + 1;
    let read = match compression {
        Compression::None => input.take(limit).read_to_end(out),
        Compression::Bz2 => bzip2::read::BzDecoder::new(input)
            .take(limit)
            .read_to_end(out),
        Compression::Lz4 => lz4::Decoder::new(input).and_then(|d| d.take(limit).read_to_end(out)),
    };
    let name = match compression {
        Compression::None => "",
        Compression::Bz2 => "bz2 ",
        Compression::Lz4 => "lz4 ",
    };
    read.map_err(|e| format!("the chunk's {name}data cannot be decompressed ({e})"))?;
    if out.len() > size {
        return Err(format!(
            "the chunk's {name}data holds more than the {size} bytes its header declares; the \
             chunk is damaged"
        ));
    }
    if out.len() < size {
        return Err(format!(
            "the chunk's {name}data holds {} bytes, fewer than the {size} its header declares; \
             the chunk is damaged",
            out.len()
        ));
    }
    Ok(())
}

/// A message record in a decompressed chunk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Entry {
    /// The record's `time`, ns: when the recorder received it.
    pub(crate) time: u64,
    /// Its connection's ID (`conn`).
    pub(crate) conn: u32,
    /// Where its data lies in the chunk.
    pub(crate) start: usize,
    pub(crate) end: usize,
}

/// The records of a decompressed chunk `buf`: each message record's [`Entry`] into `entries`,
/// each connection record handed to `connection`.
/// `complete`: `buf` is the whole chunk; otherwise (a chunk cut short) its last, incomplete
/// record ends the list. The entries are then put in time order, records of equal times in
/// their order in the chunk. The error gives the byte of the chunk where it is.
pub(crate) fn entries(
    buf: &[u8],
    complete: bool,
    mut connection: impl FnMut(super::records::Fields<'_>, &[u8]) -> Result<(), String>,
    entries: &mut Vec<Entry>,
) -> Result<(), (usize, String)> {
    entries.clear();
    let mut at = 0;
    while at < buf.len() {
        let record = match record_at(buf, at) {
            Ok(record) => record,
            Err(RecordError::Cut) if !complete => break,
            Err(RecordError::Cut) => {
                return Err((
                    at,
                    "the record runs past the end of the chunk; the chunk is damaged".into(),
                ));
            }
            Err(RecordError::Bad(m)) => return Err((at, m)),
        };
        let fields = record.fields;
        match fields.op().map_err(|m| (at, m))? {
            Op::MessageData => {
                let conn = fields.u32("conn").map_err(|m| (at, m))?;
                let time = fields.time("time").map_err(|m| (at, m))?;
                entries.push(Entry {
                    time,
                    conn,
                    start: record.data_at,
                    end: record.end,
                });
            }
            Op::Connection => connection(fields, record.data).map_err(|m| (at, m))?,
            other => {
                return Err((
                    at,
                    format!(
                        "a {} record inside a chunk, which holds only messages and \
                         connections; the chunk is damaged",
                        other.name()
                    ),
                ));
            }
        }
        at = record.end;
    }
    if !entries.is_sorted_by_key(|e| e.time) {
        entries.sort_by_key(|e| e.time);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
        let mut h = Vec::new();
        for (name, value) in fields {
            h.extend_from_slice(&((name.len() + 1 + value.len()) as u32).to_le_bytes());
            h.extend_from_slice(name.as_bytes());
            h.push(b'=');
            h.extend_from_slice(value);
        }
        let mut out = (h.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(&h);
        out.extend_from_slice(&(data.len() as u32).to_le_bytes());
        out.extend_from_slice(data);
        out
    }

    fn message(conn: u32, sec: u32, data: &[u8]) -> Vec<u8> {
        let mut time = sec.to_le_bytes().to_vec();
        time.extend_from_slice(&0u32.to_le_bytes());
        record(
            &[("op", &[2]), ("conn", &conn.to_le_bytes()), ("time", &time)],
            data,
        )
    }

    #[test]
    fn messages_come_in_time_order_equal_times_as_recorded() {
        let mut buf = record(&[("op", &[7]), ("conn", &5u32.to_le_bytes())], b"");
        for (sec, data) in [(3, b"c"), (1, b"a"), (3, b"d"), (2, b"b")] {
            buf.extend(message(5, sec, data));
        }
        let mut seen = 0;
        let mut list = Vec::new();
        entries(
            &buf,
            true,
            |f, _| {
                seen += f.u32("conn")?;
                Ok(())
            },
            &mut list,
        )
        .unwrap();
        assert_eq!(seen, 5);
        let got: Vec<&[u8]> = list.iter().map(|e| &buf[e.start..e.end]).collect();
        assert_eq!(got, [b"a", b"b", b"c", b"d"]);
        // A cut chunk gives the whole records before the cut; a whole one refuses it.
        let cut = &buf[..buf.len() - 1];
        entries(cut, false, |_, _| Ok(()), &mut list).unwrap();
        assert_eq!(list.len(), 3);
        let (at, m) = entries(cut, true, |_, _| Ok(()), &mut list).unwrap_err();
        assert!(at > 0 && m.contains("past the end"), "{at} {m}");
        assert!(list.iter().all(|e| e.conn == 5));
        // A record that has no place in a chunk.
        let info = record(&[("op", &[6])], b"");
        let (at, m) = entries(&info, true, |_, _| Ok(()), &mut list).unwrap_err();
        assert!(
            at == 0 && m.contains("chunk info record inside a chunk"),
            "{m}"
        );
    }

    #[test]
    fn each_compression_decompresses_to_the_declared_size_and_no_more() {
        let plain: Vec<u8> = (0..5000u32).flat_map(|i| (i % 251).to_le_bytes()).collect();
        let mut bz = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::best());
        bz.write_all(&plain).unwrap();
        let bz = bz.finish().unwrap();
        let mut lz = lz4::EncoderBuilder::new().build(Vec::new()).unwrap();
        lz.write_all(&plain).unwrap();
        let (lz, done) = lz.finish();
        done.unwrap();
        let mut out = Vec::new();
        for (compression, data) in [
            (Compression::None, &plain),
            (Compression::Bz2, &bz),
            (Compression::Lz4, &lz),
        ] {
            decompress(data.as_slice(), compression, plain.len(), &mut out).unwrap();
            assert_eq!(out, plain, "{compression:?}");
            // Declared one byte short: refused after one byte more, never more memory.
            let m =
                decompress(data.as_slice(), compression, plain.len() - 1, &mut out).unwrap_err();
            assert!(m.contains("more than"), "{compression:?}: {m}");
            assert_eq!(out.len(), plain.len());
            // Cut in half: fewer bytes, and what came out kept.
            let half = &data[..data.len() / 2];
            let m = decompress(half, compression, plain.len(), &mut out).unwrap_err();
            assert!(m.contains("decompressed") || m.contains("fewer"), "{m}");
            assert!(
                out.len() < plain.len() && plain.starts_with(&out),
                "{compression:?}"
            );
        }
        assert!(decompress(&b"garbage"[..], Compression::Bz2, 10, &mut out).is_err());
        assert!(decompress(&b"garbage"[..], Compression::Lz4, 10, &mut out).is_err());
        assert!(Compression::of("zstd").unwrap_err().contains("`zstd`"));
        assert!(
            declared_size(u32::MAX)
                .unwrap_err()
                .contains("declares 4294967295 bytes")
        );
    }
}

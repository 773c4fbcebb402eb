//! What calib puts between the `parquet` crate and a damaged or hostile file: places where the
//! crate (59.3.3; 60.2 alike) trusts what the file states and panics or hangs, found by fuzzing
//! `parquet_reader`. Written by hand because the crate offers no option for them.
//!
//! - [`CheckedPages`], a data page in a dictionary encoding with no dictionary page before it:
//!   the crate `expect`s the dictionary's decoder (a panic); a dictionary page stating more
//!   values than its bytes hold: the crate allocates the stated count first (7 GB for a 4 kB
//!   file). Both are errors here.
//! - [`CheckedPages`], BYTE_STREAM_SPLIT pages: the crate's decoder (apache/arrow-rs#11121, open)
//!   takes its stride from the page's bytes and its count from the page header, and indexes past
//!   the page — a panic — when a header states more values than the bytes hold. The encoding is
//!   simple enough to undo here with the bounds it needs: a page of `n` values of `w` bytes holds
//!   `w` streams of `n` bytes, byte `j` of value `i` at `i + j·n`; the joined page holds the
//!   `⌊bytes / w⌋` whole values the streams give, value after value, which is PLAIN. The crate's
//!   PLAIN decoder refuses a page shorter than its header states with an error, not a panic.
//! - [`CheckedPages`], run and block headers (ULEB128 integers) of levels, dictionary indices
//!   and DELTA_BINARY_PACKED values: the crate asserts (panics) on one longer than 10 bytes; the
//!   headers are walked here first ([`check_hybrid`], [`check_delta`]).
//! - [`EndChecked`]: the crate skips an unknown Thrift field of a page header by copying its
//!   stated length from the reader, and takes a short copy as done; a header stating a list of
//!   2³¹ doubles then costs 2³¹ reads at the end of the file (26 s to minutes for a 1 kB file).
//!   A read at the end of the file is an error here, which ends the skip at once.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};

use bytes::Bytes;
use parquet::basic::{Encoding, Type as Physical};
use parquet::column::page::{Page, PageMetadata, PageReader};
use parquet::errors::{ParquetError, Result};
use parquet::file::reader::{ChunkReader, Length};
use parquet::schema::types::ColumnDescriptor;

/// A column chunk's pages, checked and with BYTE_STREAM_SPLIT data pages turned into PLAIN ones
/// (see the module's documentation).
pub(super) struct CheckedPages {
    pages: Box<dyn PageReader>,
    /// Whether the chunk's dictionary page has been read.
    dictionary: bool,
    /// Bytes per value of the column's physical type (INT96 included); 0 for other types.
    size: usize,
    /// Bytes per value where BYTE_STREAM_SPLIT applies (4 or 8); 0 where calib leaves the page
    /// alone.
    width: usize,
    max_def: i16,
    max_rep: i16,
}

impl CheckedPages {
    pub(super) fn new(pages: Box<dyn PageReader>, column: &ColumnDescriptor) -> Self {
        CheckedPages {
            pages,
            dictionary: false,
            size: match column.physical_type() {
                Physical::INT32 | Physical::FLOAT => 4,
                Physical::INT64 | Physical::DOUBLE => 8,
                Physical::INT96 => 12,
                _ => 0,
            },
            width: match column.physical_type() {
                Physical::INT32 | Physical::FLOAT => 4,
                Physical::INT64 | Physical::DOUBLE => 8,
                _ => 0,
            },
            max_def: column.max_def_level(),
            max_rep: column.max_rep_level(),
        }
    }

    /// `page`, checked, and joined if it is a BYTE_STREAM_SPLIT data page of a fixed-width
    /// number.
    fn check(&mut self, page: Page) -> Result<Page> {
        let (buf, values_at, count) = match &page {
            Page::DictionaryPage {
                buf, num_values, ..
            } => {
                // The crate sizes the dictionary by its stated count before decoding it: a count
                // the page's bytes cannot hold (PLAIN values of `size` bytes) asked for 7 GB.
                let stated = (*num_values as usize).saturating_mul(self.size);
                if stated > buf.len() {
                    return Err(ParquetError::General(format!(
                        "a dictionary page states {num_values} values ({stated} bytes) in {} \
                         bytes",
                        buf.len()
                    )));
                }
                self.dictionary = true;
                return Ok(page);
            }
            Page::DataPage {
                buf,
                num_values,
                def_level_encoding,
                rep_level_encoding,
                ..
            } => {
                let mut at = 0;
                for (max, encoding) in [
                    (self.max_rep, *rep_level_encoding),
                    (self.max_def, *def_level_encoding),
                ] {
                    if max > 0 {
                        let len = v1_levels_len(&buf[at..], encoding, max, *num_values)?;
                        if encoding == Encoding::RLE {
                            check_hybrid(&buf[at + 4..at + len], bits(max), *num_values as usize)?;
                        }
                        at += len;
                    }
                }
                (buf, at, *num_values as usize)
            }
            Page::DataPageV2 {
                buf,
                num_values,
                def_levels_byte_len,
                rep_levels_byte_len,
                ..
            } => {
                let (rep, def) = (*rep_levels_byte_len as usize, *def_levels_byte_len as usize);
                if rep + def > buf.len() {
                    return Err(ParquetError::General(format!(
                        "a data page states {} bytes of levels in a page of {} bytes",
                        rep + def,
                        buf.len()
                    )));
                }
                let n = *num_values as usize;
                if self.max_rep > 0 {
                    check_hybrid(&buf[..rep], bits(self.max_rep), n)?;
                }
                if self.max_def > 0 {
                    check_hybrid(&buf[rep..rep + def], bits(self.max_def), n)?;
                }
                (buf, rep + def, n)
            }
        };
        let values = &buf[values_at..];
        #[allow(deprecated)]
        match page.encoding() {
            Encoding::PLAIN_DICTIONARY | Encoding::RLE_DICTIONARY => {
                if !self.dictionary {
                    return Err(ParquetError::General(format!(
                        "a data page in {} encoding with no dictionary page before it",
                        page.encoding()
                    )));
                }
                // The indices' bit width, then their runs; a width over 32 the crate refuses.
                if let Some((&width, indices)) = values.split_first() {
                    if width <= 32 {
                        check_hybrid(indices, usize::from(width), count)?;
                    }
                }
            }
            Encoding::DELTA_BINARY_PACKED => check_delta(values)?,
            Encoding::BYTE_STREAM_SPLIT if self.width > 0 => {
                let plain = joined(buf, values_at, self.width);
                return Ok(as_plain(page, plain));
            }
            _ => {}
        }
        Ok(page)
    }
}

/// `page`, a data page, holding `buf` in PLAIN encoding instead of its own.
fn as_plain(page: Page, buf: Bytes) -> Page {
    match page {
        Page::DataPage {
            num_values,
            def_level_encoding,
            rep_level_encoding,
            statistics,
            ..
        } => Page::DataPage {
            buf,
            num_values,
            encoding: Encoding::PLAIN,
            def_level_encoding,
            rep_level_encoding,
            statistics,
        },
        Page::DataPageV2 {
            num_values,
            num_nulls,
            num_rows,
            def_levels_byte_len,
            rep_levels_byte_len,
            is_compressed,
            statistics,
            ..
        } => Page::DataPageV2 {
            buf,
            num_values,
            encoding: Encoding::PLAIN,
            num_nulls,
            num_rows,
            def_levels_byte_len,
            rep_levels_byte_len,
            is_compressed,
            statistics,
        },
        other => other,
    }
}

/// The bits a level up to `max_level` takes.
fn bits(max_level: i16) -> usize {
    (u16::BITS - (max_level as u16).leading_zeros()) as usize
}

/// The most bytes of a ULEB128 integer the crate reads; a longer one makes it panic (an assert
/// in `BitReader::get_vlq_int`, found by fuzzing).
const MAX_ULEB128_BYTES: usize = 10;

/// The ULEB128 integer at `*at` in `stream`, moving `*at` past it; `Ok(None)` where the stream
/// ends inside it (the crate's decoder then reports the end itself).
fn uleb128(stream: &[u8], at: &mut usize) -> Result<Option<u64>> {
    let mut value = 0u64;
    for (i, &byte) in stream.get(*at..).unwrap_or(&[]).iter().enumerate() {
        if i == MAX_ULEB128_BYTES {
            return Err(ParquetError::General(format!(
                "a run or block header longer than {MAX_ULEB128_BYTES} bytes at byte {} of its \
                 data",
                *at
            )));
        }
        value |= u64::from(byte & 0x7f)
            .checked_shl(7 * i as u32)
            .unwrap_or(0);
        if byte & 0x80 == 0 {
            *at += i + 1;
            return Ok(Some(value));
        }
    }
    Ok(None)
}

/// Walks the run headers of an RLE/bit-packed hybrid stream (levels, dictionary indices) of
/// `width`-bit values over its first `count` values, so that the crate meets no header it
/// panics on. A bit-packed run of `g` groups holds `8g` values in `g·width` bytes; an RLE run
/// one value in `⌈width/8⌉` bytes.
fn check_hybrid(stream: &[u8], width: usize, count: usize) -> Result<()> {
    let (mut at, mut left) = (0usize, count);
    while left > 0 && at < stream.len() {
        let Some(header) = uleb128(stream, &mut at)? else {
            break;
        };
        let run = usize::try_from(header >> 1).unwrap_or(usize::MAX);
        if header & 1 == 1 {
            at = at.saturating_add(run.saturating_mul(width));
            left = left.saturating_sub(run.saturating_mul(8));
        } else {
            at = at.saturating_add(width.div_ceil(8));
            left = left.saturating_sub(run);
        }
    }
    Ok(())
}

/// Walks the headers of a DELTA_BINARY_PACKED stream (its own header, then each block's minimum
/// delta and miniblocks' bit widths), as [`check_hybrid`] does for runs.
fn check_delta(stream: &[u8]) -> Result<()> {
    let mut at = 0;
    let mut header = [0u64; 4];
    for field in &mut header {
        let Some(value) = uleb128(stream, &mut at)? else {
            return Ok(());
        };
        *field = value;
    }
    let [block, minis, total, _first] = header;
    if minis == 0 || block % minis != 0 {
        return Ok(()); // refused by the crate
    }
    let per_mini = usize::try_from(block / minis).unwrap_or(usize::MAX);
    let minis = usize::try_from(minis).unwrap_or(usize::MAX);
    let mut left = usize::try_from(total.saturating_sub(1)).unwrap_or(usize::MAX);
    while left > 0 && at < stream.len() {
        if uleb128(stream, &mut at)?.is_none() {
            break;
        }
        let Some(widths) = stream.get(at..at.saturating_add(minis)) else {
            break;
        };
        at += minis;
        for &width in widths {
            if left == 0 {
                break;
            }
            at = at.saturating_add(usize::from(width).saturating_mul(per_mini) / 8);
            left = left.saturating_sub(per_mini);
        }
    }
    Ok(())
}

/// The length of a data page v1's levels at the start of `buf` (RLE: a 4-byte length, then the
/// runs; the deprecated BIT_PACKED: `num_values` levels of the bits `max_level` needs).
fn v1_levels_len(buf: &[u8], encoding: Encoding, max_level: i16, num_values: u32) -> Result<usize> {
    let len = match encoding {
        Encoding::RLE => buf
            .get(..4)
            .map(|b| 4 + u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize),
        #[allow(deprecated)]
        Encoding::BIT_PACKED => Some((num_values as usize * bits(max_level)).div_ceil(8)),
        other => {
            return Err(ParquetError::General(format!(
                "levels in {other} encoding, which Parquet does not define"
            )));
        }
    };
    len.filter(|&len| len <= buf.len())
        .ok_or_else(|| ParquetError::General("a data page too short for its levels".to_string()))
}

/// `buf` with its bytes from `start` on, `width` streams of equal length, joined value by value.
/// Bytes after the last whole value (a damaged page) are dropped.
fn joined(buf: &Bytes, start: usize, width: usize) -> Bytes {
    let streams = &buf[start..];
    let n = streams.len() / width;
    let mut out = Vec::with_capacity(start + n * width);
    out.extend_from_slice(&buf[..start]);
    for i in 0..n {
        out.extend((0..width).map(|j| streams[i + j * n]));
    }
    Bytes::from(out)
}

/// A Parquet file whose readers refuse to read past its end (see the module's documentation).
pub(super) struct EndChecked(pub(super) File);

/// A reader for which reading at its end is an error, not `Ok(0)`.
pub(super) struct NoReadPastEnd<R>(R);

impl<R: Read> Read for NoReadPastEnd<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        match self.0.read(buf)? {
            0 if !buf.is_empty() => Err(io::Error::new(
                io::ErrorKind::UnexpectedEof,
                "the file ends inside a page header",
            )),
            n => Ok(n),
        }
    }
}

impl Length for EndChecked {
    fn len(&self) -> u64 {
        self.0.len()
    }
}

impl ChunkReader for EndChecked {
    type T = NoReadPastEnd<BufReader<File>>;

    fn get_read(&self, start: u64) -> Result<Self::T> {
        let mut file = self.0.try_clone()?;
        file.seek(SeekFrom::Start(start))?;
        Ok(NoReadPastEnd(BufReader::new(file)))
    }

    fn get_bytes(&self, start: u64, length: usize) -> Result<Bytes> {
        self.0.get_bytes(start, length)
    }
}

impl Iterator for CheckedPages {
    type Item = Result<Page>;

    fn next(&mut self) -> Option<Self::Item> {
        self.get_next_page().transpose()
    }
}

impl PageReader for CheckedPages {
    fn get_next_page(&mut self) -> Result<Option<Page>> {
        self.pages
            .get_next_page()?
            .map(|p| self.check(p))
            .transpose()
    }

    fn peek_next_page(&mut self) -> Result<Option<PageMetadata>> {
        self.pages.peek_next_page()
    }

    fn skip_next_page(&mut self) -> Result<()> {
        self.pages.skip_next_page()
    }

    fn at_record_boundary(&mut self) -> Result<bool> {
        self.pages.at_record_boundary()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two doubles split into 8 streams of 2 bytes come back value by value after the levels.
    #[test]
    fn streams_join_into_values_after_the_levels() {
        let values = [1.5f64, -2.25];
        let mut page = vec![9u8, 9];
        for j in 0..8 {
            page.extend(values.iter().map(|v| v.to_le_bytes()[j]));
        }
        page.push(7); // a stray byte after the last whole value
        let out = joined(&Bytes::from(page), 2, 8);
        assert_eq!(&out[..2], &[9, 9]);
        let back: Vec<f64> = out[2..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(back, values);
    }

    /// A run header of 11 bytes is refused wherever it is met, before the crate asserts on it;
    /// well-formed runs and a stream ending inside a header pass.
    #[test]
    fn overlong_run_headers_are_errors() {
        let mut long = vec![0x80u8; 10];
        long.push(0x01);
        // An RLE run of 3 values of 8 bits, then the long header.
        let mut stream = vec![3 << 1, 7];
        stream.extend(&long);
        assert!(
            check_hybrid(&stream, 8, 3).is_ok(),
            "the long header lies past the values"
        );
        assert!(check_hybrid(&stream, 8, 4).is_err());
        // A bit-packed run of one group of 8 one-bit values (1 byte), then an RLE run.
        assert!(check_hybrid(&[0b11, 0xff, 2 << 1, 1], 1, 10).is_ok());
        assert!(
            check_hybrid(&[0x80, 0x80], 1, 10).is_ok(),
            "ends inside a header"
        );
        // DELTA_BINARY_PACKED: block 128, 4 miniblocks, 5 values, first 0; then a long delta.
        let mut delta = vec![0x80, 0x01, 4, 5, 0];
        delta.extend(&long);
        assert!(check_delta(&delta).is_err());
        assert!(
            check_delta(&[0x80, 0x01, 4, 1, 0]).is_ok(),
            "one value: no block"
        );
    }

    #[test]
    fn a_read_at_the_end_is_an_error() {
        let mut r = NoReadPastEnd(&[1u8, 2][..]);
        let mut buf = [0u8; 4];
        assert_eq!(r.read(&mut buf).unwrap(), 2);
        assert_eq!(r.read(&mut []).unwrap(), 0);
        let err = r.read(&mut buf).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::UnexpectedEof);
    }

    #[test]
    fn levels_longer_than_the_page_are_an_error() {
        assert!(v1_levels_len(&[200, 0, 0, 0, 1], Encoding::RLE, 1, 3).is_err());
        assert_eq!(
            v1_levels_len(&[1, 0, 0, 0, 5], Encoding::RLE, 1, 3).unwrap(),
            5
        );
        assert!(v1_levels_len(&[1, 0], Encoding::RLE, 1, 3).is_err());
    }
}

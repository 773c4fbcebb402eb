//! What calib puts between the `parquet` crate and a damaged or hostile file: places where the
//! crate (59.3.3; 60.2 alike) trusts what the file states and panics or hangs, found by fuzzing
//! `parquet_reader`. Written by hand because the crate offers no option for them.
//!
//! - [`CheckedPages`], a data page in a dictionary encoding with no dictionary page before it:
//!   the crate `expect`s the dictionary's decoder (a panic); here it is an error.
//! - [`CheckedPages`], BYTE_STREAM_SPLIT pages: the crate's decoder (apache/arrow-rs#11121, open)
//!   takes its stride from the page's bytes and its count from the page header, and indexes past
//!   the page — a panic — when a header states more values than the bytes hold. The encoding is
//!   simple enough to undo here with the bounds it needs: a page of `n` values of `w` bytes holds
//!   `w` streams of `n` bytes, byte `j` of value `i` at `i + j·n`; the joined page holds the
//!   `⌊bytes / w⌋` whole values the streams give, value after value, which is PLAIN. The crate's
//!   PLAIN decoder refuses a page shorter than its header states with an error, not a panic.
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
    /// Bytes per value of the column's physical type; 0 where calib leaves the page alone.
    width: usize,
    max_def: i16,
    max_rep: i16,
}

impl CheckedPages {
    pub(super) fn new(pages: Box<dyn PageReader>, column: &ColumnDescriptor) -> Self {
        CheckedPages {
            pages,
            dictionary: false,
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
        if let Page::DictionaryPage { .. } = page {
            self.dictionary = true;
            return Ok(page);
        }
        #[allow(deprecated)]
        let by_dictionary = matches!(
            page.encoding(),
            Encoding::PLAIN_DICTIONARY | Encoding::RLE_DICTIONARY
        );
        if by_dictionary && !self.dictionary {
            return Err(ParquetError::General(format!(
                "a data page in {} encoding with no dictionary page before it",
                page.encoding()
            )));
        }
        if self.width == 0 || page.encoding() != Encoding::BYTE_STREAM_SPLIT {
            return Ok(page);
        }
        match page {
            Page::DataPage {
                buf,
                num_values,
                encoding: _,
                def_level_encoding,
                rep_level_encoding,
                statistics,
            } => {
                let mut levels = 0;
                if self.max_rep > 0 {
                    levels += v1_levels_len(
                        &buf[levels..],
                        rep_level_encoding,
                        self.max_rep,
                        num_values,
                    )?;
                }
                if self.max_def > 0 {
                    levels += v1_levels_len(
                        &buf[levels..],
                        def_level_encoding,
                        self.max_def,
                        num_values,
                    )?;
                }
                Ok(Page::DataPage {
                    buf: joined(&buf, levels, self.width),
                    num_values,
                    encoding: Encoding::PLAIN,
                    def_level_encoding,
                    rep_level_encoding,
                    statistics,
                })
            }
            Page::DataPageV2 {
                buf,
                num_values,
                encoding: _,
                num_nulls,
                num_rows,
                def_levels_byte_len,
                rep_levels_byte_len,
                is_compressed,
                statistics,
            } => {
                let levels = def_levels_byte_len as usize + rep_levels_byte_len as usize;
                if levels > buf.len() {
                    return Err(ParquetError::General(format!(
                        "a data page states {levels} bytes of levels in a page of {} bytes",
                        buf.len()
                    )));
                }
                Ok(Page::DataPageV2 {
                    buf: joined(&buf, levels, self.width),
                    num_values,
                    encoding: Encoding::PLAIN,
                    num_nulls,
                    num_rows,
                    def_levels_byte_len,
                    rep_levels_byte_len,
                    is_compressed,
                    statistics,
                })
            }
            other => Ok(other),
        }
    }
}

/// The length of a data page v1's levels at the start of `buf` (RLE: a 4-byte length, then the
/// runs; the deprecated BIT_PACKED: `num_values` levels of the bits `max_level` needs).
fn v1_levels_len(buf: &[u8], encoding: Encoding, max_level: i16, num_values: u32) -> Result<usize> {
    let len = match encoding {
        Encoding::RLE => buf
            .get(..4)
            .map(|b| 4 + u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize),
        #[allow(deprecated)]
        Encoding::BIT_PACKED => {
            let bits = (u16::BITS - (max_level as u16).leading_zeros()) as usize;
            Some((num_values as usize * bits).div_ceil(8))
        }
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

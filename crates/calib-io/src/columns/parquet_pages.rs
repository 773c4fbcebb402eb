//! The pages of a Parquet column chunk as calib hands them to the `parquet` crate's column
//! reader: BYTE_STREAM_SPLIT data pages joined here into PLAIN ones.
//!
//! Written by hand because the crate's own BYTE_STREAM_SPLIT decoder (59.3 and 60.2,
//! apache/arrow-rs#11121, open) takes its stride from the page's bytes and its count from the
//! page header, and indexes past the page — a panic — when a damaged or hostile header states
//! more values than the bytes hold (found by fuzzing `parquet_reader`). The encoding is simple
//! enough to undo here with the bounds it needs: a page of `n` values of `w` bytes holds `w`
//! streams of `n` bytes, byte `j` of value `i` at `i + j·n`; the joined page holds the
//! `⌊bytes / w⌋` whole values the streams give, value after value, which is PLAIN. The crate's
//! PLAIN decoder refuses a page shorter than its header states with an error, not a panic.

use bytes::Bytes;
use parquet::basic::{Encoding, Type as Physical};
use parquet::column::page::{Page, PageMetadata, PageReader};
use parquet::errors::{ParquetError, Result};
use parquet::schema::types::ColumnDescriptor;

/// A column chunk's pages with BYTE_STREAM_SPLIT data pages turned into PLAIN ones.
pub(super) struct JoinedStreams {
    pages: Box<dyn PageReader>,
    /// Bytes per value of the column's physical type; 0 where calib leaves the page alone.
    width: usize,
    max_def: i16,
    max_rep: i16,
}

impl JoinedStreams {
    pub(super) fn new(pages: Box<dyn PageReader>, column: &ColumnDescriptor) -> Self {
        JoinedStreams {
            pages,
            width: match column.physical_type() {
                Physical::INT32 | Physical::FLOAT => 4,
                Physical::INT64 | Physical::DOUBLE => 8,
                _ => 0,
            },
            max_def: column.max_def_level(),
            max_rep: column.max_rep_level(),
        }
    }

    /// `page`, joined if it is a BYTE_STREAM_SPLIT data page of a fixed-width number.
    fn join(&self, page: Page) -> Result<Page> {
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

impl Iterator for JoinedStreams {
    type Item = Result<Page>;

    fn next(&mut self) -> Option<Self::Item> {
        self.get_next_page().transpose()
    }
}

impl PageReader for JoinedStreams {
    fn get_next_page(&mut self) -> Result<Option<Page>> {
        self.pages
            .get_next_page()?
            .map(|p| self.join(p))
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
    fn levels_longer_than_the_page_are_an_error() {
        assert!(v1_levels_len(&[200, 0, 0, 0, 1], Encoding::RLE, 1, 3).is_err());
        assert_eq!(
            v1_levels_len(&[1, 0, 0, 0, 5], Encoding::RLE, 1, 3).unwrap(),
            5
        );
        assert!(v1_levels_len(&[1, 0], Encoding::RLE, 1, 3).is_err());
    }
}

//! A walk over Thrift compact-protocol data (a Parquet footer, a page header) that checks what
//! the `parquet` crate does not: that every list, set and map states no more elements than the
//! bytes left can hold.
//!
//! Written by hand because the crate (59.3.3) skips an unknown field's list element by element
//! whatever its stated size, and a boolean element takes it no bytes to skip: a 4 kB file whose
//! footer states a list of 2³¹ booleans kept it busy for 5 s (found by fuzzing
//! `parquet_reader`), a bound set by the integer's width rather than by the file. In the
//! compact protocol every element of a list takes at least one byte (a boolean element is a
//! byte, unlike a boolean field), so a size above the bytes left is damage, refused here before
//! the crate reads the data.

/// How deep structures may nest, as the crate allows.
const MAX_DEPTH: usize = 64;

/// The compact protocol's type codes used below.
const STOP: u8 = 0;
const BOOL_TRUE: u8 = 1;
const BOOL_FALSE: u8 = 2;
const BYTE: u8 = 3;
const I16: u8 = 4;
const I32: u8 = 5;
const I64: u8 = 6;
const DOUBLE: u8 = 7;
const BINARY: u8 = 8;
const LIST: u8 = 9;
const SET: u8 = 10;
const MAP: u8 = 11;
const STRUCT: u8 = 12;
const UUID: u8 = 13;

/// Why a walk stopped: the data ended first (more bytes may follow), or it is damaged.
#[derive(Debug, PartialEq)]
pub(super) enum Stop {
    /// The bytes end inside the structure.
    Short,
    /// What is wrong.
    Damaged(String),
}

/// Walks one struct at the start of `data`; returns its length in bytes and the value of its
/// field `wanted` if that is an integer. `whole`: `data` holds everything there is (a footer),
/// not the first part of a longer stream (a page header read in part), where a collection
/// larger than the bytes read asks for more ([`Stop::Short`]).
pub(super) fn walk_struct(
    data: &[u8],
    wanted: i16,
    whole: bool,
) -> Result<(usize, Option<i64>), Stop> {
    let mut walk = Walk { data, at: 0, whole };
    let value = walk.fields(0, wanted)?;
    Ok((walk.at, value))
}

struct Walk<'a> {
    data: &'a [u8],
    at: usize,
    whole: bool,
}

impl Walk<'_> {
    fn byte(&mut self) -> Result<u8, Stop> {
        let b = *self.data.get(self.at).ok_or(Stop::Short)?;
        self.at += 1;
        Ok(b)
    }

    fn skip(&mut self, n: usize) -> Result<(), Stop> {
        if n > self.data.len() - self.at {
            return Err(Stop::Short);
        }
        self.at += n;
        Ok(())
    }

    /// A ULEB128 integer (at most 10 bytes).
    fn varint(&mut self) -> Result<u64, Stop> {
        let mut value = 0u64;
        for i in 0..10 {
            let b = self.byte()?;
            value |= u64::from(b & 0x7f).checked_shl(7 * i).unwrap_or(0);
            if b & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(Stop::Damaged("an integer longer than 10 bytes".to_string()))
    }

    /// A zigzag integer's value.
    fn zigzag(&mut self) -> Result<i64, Stop> {
        let v = self.varint()?;
        Ok((v >> 1) as i64 ^ -((v & 1) as i64))
    }

    /// Elements of a collection: `n` of at least one byte each must fit the bytes left.
    fn elements(&mut self, n: u64, per: u64) -> Result<(), Stop> {
        let left = (self.data.len() - self.at) as u64;
        if n.saturating_mul(per) > left {
            if !self.whole {
                return Err(Stop::Short);
            }
            return Err(Stop::Damaged(format!(
                "a list states {n} elements with {left} bytes left"
            )));
        }
        Ok(())
    }

    /// The fields of a struct up to its stop; the value of field `wanted` if an integer.
    fn fields(&mut self, depth: usize, wanted: i16) -> Result<Option<i64>, Stop> {
        if depth > MAX_DEPTH {
            return Err(Stop::Damaged(format!(
                "structures nested deeper than {MAX_DEPTH}"
            )));
        }
        let (mut id, mut found) = (0i16, None);
        loop {
            let head = self.byte()?;
            let ty = head & 0x0f;
            if ty == STOP {
                return Ok(found);
            }
            id = match head >> 4 {
                0 => i16::try_from(self.zigzag()?).unwrap_or(i16::MIN),
                delta => id.wrapping_add(i16::from(delta)),
            };
            match ty {
                BOOL_TRUE | BOOL_FALSE => {}
                I16 | I32 | I64 if id == wanted => found = Some(self.zigzag()?),
                _ => self.value(ty, depth + 1)?,
            }
        }
    }

    /// One value of type `ty` (a collection's element: booleans are a byte).
    fn value(&mut self, ty: u8, depth: usize) -> Result<(), Stop> {
        match ty {
            BOOL_TRUE | BOOL_FALSE | BYTE => self.skip(1),
            I16 | I32 | I64 => self.varint().map(drop),
            DOUBLE => self.skip(8),
            UUID => self.skip(16),
            BINARY => {
                let n = self.varint()?;
                self.skip(usize::try_from(n).unwrap_or(usize::MAX))
            }
            LIST | SET => {
                let head = self.byte()?;
                let n = match head >> 4 {
                    15 => self.varint()?,
                    n => u64::from(n),
                };
                self.elements(n, 1)?;
                let element = head & 0x0f;
                for _ in 0..n {
                    self.value(element, depth + 1)?;
                }
                Ok(())
            }
            MAP => {
                let n = self.varint()?;
                if n == 0 {
                    return Ok(());
                }
                let kinds = self.byte()?;
                self.elements(n, 2)?;
                for _ in 0..n {
                    self.value(kinds >> 4, depth + 1)?;
                    self.value(kinds & 0x0f, depth + 1)?;
                }
                Ok(())
            }
            STRUCT => self.fields(depth, i16::MIN).map(drop),
            other => Err(Stop::Damaged(format!("an unknown Thrift type {other}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_struct_is_walked_to_its_stop_with_the_field_asked_for() {
        // Field 1: i32 -3 (zigzag 5); field 3: i32 1000 (zigzag 2000); a list of two bools;
        // a binary of 2 bytes; stop.
        let data = [
            0x15, 5, 0x25, 0xd0, 0x0f, 0x19, 0x21, 1, 2, 0x18, 2, b'a', b'b', 0, 99,
        ];
        assert_eq!(walk_struct(&data, 3, true), Ok((14, Some(1000))));
        assert_eq!(walk_struct(&data[..6], 3, true), Err(Stop::Short));
    }

    #[test]
    fn a_list_larger_than_its_bytes_is_damage() {
        // Field 1: a list of 2^31 booleans (size as a varint after the 0xF nibble).
        let data = [0x19, 0xf1, 0x80, 0x80, 0x80, 0x80, 0x08, 1, 0];
        assert!(
            matches!(walk_struct(&data, 3, true), Err(Stop::Damaged(m)) if m.contains("2147483648"))
        );
        assert_eq!(walk_struct(&data, 3, false), Err(Stop::Short));
    }
}

//! Bytes of the binary column formats (TDMS, MATLAB): a bounds-checked cursor of either byte
//! order, and arrays of numbers decoded into [`Values`].
//!
//! Every read is checked against what is left, so a length a file states can never index past
//! its bytes; the caller adds what was being read to the message.

use super::Values;

/// The byte order of a file, or of one of its parts (a TDMS segment, a MATLAB v4 matrix).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    /// Least significant byte first (x86, ARM as run).
    Little,
    /// Most significant byte first.
    Big,
}

impl Endian {
    /// `little-endian` or `big-endian`, for `calib inspect`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Endian::Little => "little-endian",
            Endian::Big => "big-endian",
        }
    }
}

/// A position in bytes, reading numbers in one byte order.
#[derive(Debug, Clone)]
pub(crate) struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    endian: Endian,
}

macro_rules! read_number {
    ($name:ident, $t:ty) => {
        /// The next number, in the cursor's byte order.
        pub(crate) fn $name(&mut self) -> Result<$t, String> {
            let a = self.array()?;
            Ok(match self.endian {
                Endian::Little => <$t>::from_le_bytes(a),
                Endian::Big => <$t>::from_be_bytes(a),
            })
        }
    };
}

impl<'a> Cursor<'a> {
    pub(crate) fn new(bytes: &'a [u8], endian: Endian) -> Self {
        Cursor {
            bytes,
            pos: 0,
            endian,
        }
    }

    /// The byte order numbers are read in.
    pub(crate) fn endian(&self) -> Endian {
        self.endian
    }

    /// Bytes left.
    pub(crate) fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// The next `n` bytes, or what is missing.
    pub(crate) fn take(&mut self, n: u64) -> Result<&'a [u8], String> {
        let left = self.left();
        match usize::try_from(n) {
            Ok(n) if n <= left => {
                let out = &self.bytes[self.pos..self.pos + n];
                self.pos += n;
                Ok(out)
            }
            _ => Err(format!(
                "needs {n} bytes at byte {}, but only {left} are left",
                self.pos
            )),
        }
    }

    /// Up to `n` bytes passed over (fewer where fewer are left): padding at the end of a part.
    pub(crate) fn skip_up_to(&mut self, n: usize) {
        self.pos += n.min(self.left());
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let bytes = self.take(N as u64)?;
        let mut a = [0; N];
        a.copy_from_slice(bytes);
        Ok(a)
    }

    read_number!(u8, u8);
    read_number!(u32, u32);
    read_number!(i32, i32);
    read_number!(u64, u64);
    read_number!(i64, i64);
    read_number!(f64, f64);
}

/// A number type as stored in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
}

impl Kind {
    /// Bytes per value.
    pub(crate) fn size(self) -> usize {
        match self {
            Kind::I8 | Kind::U8 => 1,
            Kind::I16 | Kind::U16 => 2,
            Kind::I32 | Kind::U32 | Kind::F32 => 4,
            Kind::I64 | Kind::U64 | Kind::F64 => 8,
        }
    }

    /// The name `calib inspect` gives it (`f64`, `i16`, …).
    pub(crate) fn name(self) -> &'static str {
        match self {
            Kind::I8 => "i8",
            Kind::I16 => "i16",
            Kind::I32 => "i32",
            Kind::I64 => "i64",
            Kind::U8 => "u8",
            Kind::U16 => "u16",
            Kind::U32 => "u32",
            Kind::U64 => "u64",
            Kind::F32 => "f32",
            Kind::F64 => "f64",
        }
    }

    /// Whether values of this kind are kept as [`Values::I64`] (64-bit integers, which an `f64`
    /// does not hold exactly).
    pub(crate) fn is_wide(self) -> bool {
        matches!(self, Kind::I64 | Kind::U64)
    }

    /// An empty [`Values`] of the variant this kind is kept in.
    pub(crate) fn empty(self, capacity: usize) -> Values {
        if self.is_wide() {
            Values::I64(Vec::with_capacity(capacity))
        } else {
            Values::F64(Vec::with_capacity(capacity))
        }
    }
}

/// Why [`extend`] could not decode.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum DecodeError {
    /// A `u64` value beyond `i64::MAX`, which [`Values::I64`] cannot hold.
    U64TooLarge(u64),
    /// `out` is of the other variant than `kind` is kept in, or `bytes` is too short: a bug of
    /// the caller, reported rather than a panic.
    Mismatch,
}

/// Appends `count` values of `kind` to `out`, value `i` at `bytes[i·stride..]` (`stride` is
/// the kind's size for contiguous values, a row's width for interleaved ones).
pub(crate) fn extend(
    out: &mut Values,
    kind: Kind,
    endian: Endian,
    bytes: &[u8],
    stride: usize,
    count: usize,
) -> Result<(), DecodeError> {
    let size = kind.size();
    let needed = match count {
        0 => Some(0),
        n => (n - 1)
            .checked_mul(stride)
            .and_then(|b| b.checked_add(size)),
    };
    if stride < size || needed.is_none_or(|n| n > bytes.len()) {
        return Err(DecodeError::Mismatch);
    }
    let rows = bytes.chunks(stride).take(count);
    use Endian::{Big, Little};
    match (out, kind, endian) {
        (Values::F64(v), Kind::I8, _) => v.extend(rows.map(|c| f64::from(c[0] as i8))),
        (Values::F64(v), Kind::U8, _) => v.extend(rows.map(|c| f64::from(c[0]))),
        (Values::F64(v), Kind::I16, Little) => {
            v.extend(rows.map(|c| f64::from(i16::from_le_bytes(first(c)))))
        }
        (Values::F64(v), Kind::I16, Big) => {
            v.extend(rows.map(|c| f64::from(i16::from_be_bytes(first(c)))))
        }
        (Values::F64(v), Kind::U16, Little) => {
            v.extend(rows.map(|c| f64::from(u16::from_le_bytes(first(c)))))
        }
        (Values::F64(v), Kind::U16, Big) => {
            v.extend(rows.map(|c| f64::from(u16::from_be_bytes(first(c)))))
        }
        (Values::F64(v), Kind::I32, Little) => {
            v.extend(rows.map(|c| f64::from(i32::from_le_bytes(first(c)))))
        }
        (Values::F64(v), Kind::I32, Big) => {
            v.extend(rows.map(|c| f64::from(i32::from_be_bytes(first(c)))))
        }
        (Values::F64(v), Kind::U32, Little) => {
            v.extend(rows.map(|c| f64::from(u32::from_le_bytes(first(c)))))
        }
        (Values::F64(v), Kind::U32, Big) => {
            v.extend(rows.map(|c| f64::from(u32::from_be_bytes(first(c)))))
        }
        (Values::F64(v), Kind::F32, Little) => {
            v.extend(rows.map(|c| f64::from(f32::from_le_bytes(first(c)))))
        }
        (Values::F64(v), Kind::F32, Big) => {
            v.extend(rows.map(|c| f64::from(f32::from_be_bytes(first(c)))))
        }
        (Values::F64(v), Kind::F64, Little) => v.extend(rows.map(|c| f64::from_le_bytes(first(c)))),
        (Values::F64(v), Kind::F64, Big) => v.extend(rows.map(|c| f64::from_be_bytes(first(c)))),
        (Values::I64(v), Kind::I64, Little) => v.extend(rows.map(|c| i64::from_le_bytes(first(c)))),
        (Values::I64(v), Kind::I64, Big) => v.extend(rows.map(|c| i64::from_be_bytes(first(c)))),
        (Values::I64(v), Kind::U64, endian) => {
            v.reserve(count);
            for c in rows {
                let x = match endian {
                    Little => u64::from_le_bytes(first(c)),
                    Big => u64::from_be_bytes(first(c)),
                };
                v.push(i64::try_from(x).map_err(|_| DecodeError::U64TooLarge(x))?);
            }
        }
        _ => return Err(DecodeError::Mismatch),
    }
    Ok(())
}

/// The first `N` bytes of `row` (checked by [`extend`] to be there).
fn first<const N: usize>(row: &[u8]) -> [u8; N] {
    let mut a = [0; N];
    a.copy_from_slice(&row[..N]);
    a
}

/// `values` kept as the other variant where `wide` says which one the column's type needs: a
/// MATLAB `int64` array stored in a narrower type, or a `double` one stored as 64-bit integers.
pub(crate) fn as_variant(values: Values, wide: bool) -> Values {
    match (values, wide) {
        (Values::F64(v), true) => Values::I64(v.into_iter().map(|x| x as i64).collect()),
        (Values::I64(v), false) => Values::F64(v.into_iter().map(|x| x as f64).collect()),
        (values, _) => values,
    }
}

/// Why a columnar file could not be read: the system, or its content (a message naming where).
#[derive(Debug)]
pub(crate) enum Fail {
    /// Reading the file failed.
    Io(std::io::Error),
    /// Its content is not what its format says.
    Bad(String),
}

impl From<std::io::Error> for Fail {
    fn from(e: std::io::Error) -> Self {
        Fail::Io(e)
    }
}

/// Opens `path` and reads it with `read` (given the file and its length), its failures as the
/// crate's errors naming the file.
pub(crate) fn read_file<T>(
    path: &std::path::Path,
    read: impl FnOnce(&mut std::fs::File, u64) -> Result<T, Fail>,
) -> Result<T, crate::Error> {
    let io = |source| crate::Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    read(&mut file, len).map_err(|e| match e {
        Fail::Io(source) => io(source),
        Fail::Bad(message) => crate::Error::Data {
            path: path.to_path_buf(),
            message,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cursor_refuses_to_read_past_the_end() {
        let mut c = Cursor::new(&[1, 0, 0, 0, 2], Endian::Little);
        assert_eq!(c.u32(), Ok(1));
        let err = c.u32().unwrap_err();
        assert!(
            err.contains("needs 4 bytes at byte 4, but only 1 are left"),
            "{err}"
        );
        assert!(c.take(u64::MAX).is_err());
        let mut c = Cursor::new(&[0, 0, 0, 1], Endian::Big);
        assert_eq!(c.i32(), Ok(1));
    }

    #[test]
    fn interleaved_values_are_read_by_stride() {
        // Rows of (i16, f32) big-endian: 1, 0.5 then -2, 1.5.
        let mut bytes = Vec::new();
        for (i, f) in [(1i16, 0.5f32), (-2, 1.5)] {
            bytes.extend(i.to_be_bytes());
            bytes.extend(f.to_be_bytes());
        }
        let mut ints = Kind::I16.empty(2);
        extend(&mut ints, Kind::I16, Endian::Big, &bytes, 6, 2).unwrap();
        assert_eq!(ints, Values::F64(vec![1.0, -2.0]));
        let mut floats = Kind::F32.empty(2);
        extend(&mut floats, Kind::F32, Endian::Big, &bytes[2..], 6, 2).unwrap();
        assert_eq!(floats, Values::F64(vec![0.5, 1.5]));
        // One row too many is refused, not read past the end.
        assert_eq!(
            extend(&mut floats, Kind::F32, Endian::Big, &bytes[2..], 6, 3),
            Err(DecodeError::Mismatch)
        );
    }

    #[test]
    fn sixty_four_bit_integers_stay_exact() {
        let big = (1i64 << 60) + 1;
        let mut v = Kind::I64.empty(1);
        extend(&mut v, Kind::I64, Endian::Little, &big.to_le_bytes(), 8, 1).unwrap();
        assert_eq!(v, Values::I64(vec![big]));
        let mut v = Kind::U64.empty(1);
        assert_eq!(
            extend(
                &mut v,
                Kind::U64,
                Endian::Little,
                &u64::MAX.to_le_bytes(),
                8,
                1
            ),
            Err(DecodeError::U64TooLarge(u64::MAX))
        );
    }
}

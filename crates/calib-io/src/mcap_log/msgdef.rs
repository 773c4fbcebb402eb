//! Numeric fields of any ROS 2 message, found through the message definition the file carries.
//!
//! An MCAP file written by rosbag2 stores each topic's message definition in its schema record
//! (encoding `ros2msg`): the type's fields, one `TYPE NAME` per line, then the definitions of the
//! types it uses, each after a line of `=` and a `MSG: package/Type` line:
//!
//! ```text
//! std_msgs/Header header
//! float64 position
//! float64[3] currents
//! ================================================================================
//! MSG: std_msgs/Header
//! builtin_interfaces/Time stamp
//! string frame_id
//! ...
//! ```
//!
//! [`Definition::parse`] reads that text (comments, constants `TYPE NAME=VALUE` and default values
//! are skipped; arrays `T[]`, `T[N]`, `T[<=N]` and bounded strings `string<=N` are understood);
//! [`Definition::plan`] turns channel paths such as `position`, `state.position` or
//! `currents[1]` into a [`Plan`], which walks each CDR message with the alignment rules of
//! `rmw` (every primitive aligned to its size from the end of the encapsulation header; a
//! sequence is a `u32` count, then its elements, aligned only if there is one; a fixed array
//! has no count; strings are a `u32` length with the NUL, then the bytes) and reads the numeric
//! values the paths name. Fields before and between them are skipped by their lengths, arrays
//! of primitives in one step.
//!
//! If the message type's first field is `std_msgs/Header header`, its stamp is read too, so
//! that the channel can be timed by `header.stamp` as JointState is.

use std::fmt;

use super::cdr::{CdrError, Cursor, ORIGIN, encapsulation};

/// The deepest nesting of message types walked: far beyond any real message (a few levels).
const MAX_DEPTH: usize = 64;

/// A primitive ROS type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Primitive {
    Bool,
    Byte,
    Char,
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
    String,
    WString,
}

impl Primitive {
    fn of(name: &str) -> Option<Self> {
        // Bounded strings `string<=N` are strings on the wire.
        let name = name.split("<=").next().unwrap_or(name);
        Some(match name {
            "bool" => Primitive::Bool,
            "byte" => Primitive::Byte,
            "char" => Primitive::Char,
            "int8" => Primitive::Int8,
            "uint8" => Primitive::UInt8,
            "int16" => Primitive::Int16,
            "uint16" => Primitive::UInt16,
            "int32" => Primitive::Int32,
            "uint32" => Primitive::UInt32,
            "int64" => Primitive::Int64,
            "uint64" => Primitive::UInt64,
            "float32" => Primitive::Float32,
            "float64" => Primitive::Float64,
            "string" => Primitive::String,
            "wstring" => Primitive::WString,
            _ => return None,
        })
    }

    /// Bytes of a numeric value on the wire; `None` for strings.
    fn size(self) -> Option<usize> {
        Some(match self {
            Primitive::Bool
            | Primitive::Byte
            | Primitive::Char
            | Primitive::Int8
            | Primitive::UInt8 => 1,
            Primitive::Int16 | Primitive::UInt16 => 2,
            Primitive::Int32 | Primitive::UInt32 | Primitive::Float32 => 4,
            Primitive::Int64 | Primitive::UInt64 | Primitive::Float64 => 8,
            Primitive::String | Primitive::WString => return None,
        })
    }

    /// The value of its `size()` bytes (in the message's byte order) as `f64`; 64-bit
    /// integers beyond 2⁵³ are rounded.
    fn value(self, b: &[u8], big_endian: bool) -> f64 {
        let mut le = [0u8; 8];
        le[..b.len()].copy_from_slice(b);
        if big_endian {
            le[..b.len()].reverse();
        }
        let [b0, b1, b2, b3, ..] = le;
        match self {
            Primitive::Bool | Primitive::Byte | Primitive::Char | Primitive::UInt8 => f64::from(b0),
            Primitive::Int8 => f64::from(b0 as i8),
            Primitive::Int16 => f64::from(i16::from_le_bytes([b0, b1])),
            Primitive::UInt16 => f64::from(u16::from_le_bytes([b0, b1])),
            Primitive::Int32 => f64::from(i32::from_le_bytes([b0, b1, b2, b3])),
            Primitive::UInt32 => f64::from(u32::from_le_bytes([b0, b1, b2, b3])),
            Primitive::Float32 => f64::from(f32::from_le_bytes([b0, b1, b2, b3])),
            Primitive::Int64 => i64::from_le_bytes(le) as f64,
            Primitive::UInt64 => u64::from_le_bytes(le) as f64,
            Primitive::Float64 => f64::from_le_bytes(le),
            Primitive::String | Primitive::WString => f64::NAN,
        }
    }
}

/// A field's type without its array part.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Base {
    Primitive(Primitive),
    /// Index into [`Definition::types`].
    Message(usize),
}

/// How many values a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Array {
    One,
    /// `T[N]`: N values, no count on the wire.
    Fixed(usize),
    /// `T[]` or `T[<=N]`: a `u32` count, then the values.
    Sequence,
}

#[derive(Debug, Clone)]
struct Field {
    name: String,
    base: Base,
    array: Array,
}

#[derive(Debug, Clone)]
struct MessageType {
    name: String,
    fields: Vec<Field>,
}

/// A parsed message definition: the message type (index 0) and the types it uses.
#[derive(Debug, Clone)]
pub(crate) struct Definition {
    types: Vec<MessageType>,
}

/// `package/Type` of `package/msg/Type` (or of `package/Type`).
fn normalized(name: &str) -> String {
    name.replacen("/msg/", "/", 1)
}

fn package(name: &str) -> &str {
    name.split('/').next().unwrap_or("")
}

impl Definition {
    /// Parses the definition text of `type_name` (`package/msg/Type`); the error says which
    /// line is wrong and why.
    pub(crate) fn parse(type_name: &str, text: &str) -> Result<Self, String> {
        // Sections: the message itself, then `MSG: name` blocks, split by lines of `=`.
        let mut sections: Vec<(String, Vec<(usize, &str)>)> =
            vec![(normalized(type_name), Vec::new())];
        for (n, line) in text.lines().enumerate() {
            let trimmed = line.trim();
            if trimmed.len() >= 3 && trimmed.chars().all(|c| c == '=') {
                sections.push((String::new(), Vec::new()));
                continue;
            }
            let last = sections.len() - 1;
            if let Some(name) = trimmed.strip_prefix("MSG:") {
                sections[last].0 = normalized(name.trim());
                continue;
            }
            sections[last].1.push((n + 1, line));
        }
        if sections.len() > crate::limits::MAX_MESSAGE_TYPES {
            return Err(format!(
                "it holds {} message types, more than the {} calib reads; the message \
                 definition is damaged",
                sections.len(),
                crate::limits::MAX_MESSAGE_TYPES
            ));
        }
        if let Some((_, lines)) = sections.iter().skip(1).find(|(name, _)| name.is_empty()) {
            let at = lines.first().map_or(0, |(n, _)| *n);
            return Err(format!(
                "a definition after a `===` line has no `MSG: package/Type` line (near line {at})"
            ));
        }
        let names: Vec<String> = sections.iter().map(|(name, _)| name.clone()).collect();
        let mut types = Vec::with_capacity(sections.len());
        for (name, lines) in &sections {
            let mut fields = Vec::new();
            for &(n, line) in lines {
                let line = line.split('#').next().unwrap_or("").trim();
                if line.is_empty() {
                    continue;
                }
                let mut words = line.split_whitespace();
                let (Some(kind), Some(field)) = (words.next(), words.next()) else {
                    return Err(format!(
                        "line {n} `{line}` is not `TYPE NAME`; the message definition is damaged"
                    ));
                };
                // Constants (`TYPE NAME=VALUE`) take no room in a message.
                if field.contains('=') || words.next().is_some_and(|w| w.starts_with('=')) {
                    continue;
                }
                let (base, array) = match kind.find('[') {
                    Some(at) => {
                        let inner = kind[at + 1..].strip_suffix(']').ok_or_else(|| {
                            format!("line {n}: type `{kind}` has an unclosed `[`")
                        })?;
                        let array = if inner.is_empty() || inner.starts_with("<=") {
                            Array::Sequence
                        } else {
                            match inner.parse() {
                                Ok(0) | Err(_) => {
                                    return Err(format!(
                                        "line {n}: array size `{inner}` of `{kind}` is not a \
                                         number above 0"
                                    ));
                                }
                                Ok(size) => Array::Fixed(size),
                            }
                        };
                        (&kind[..at], array)
                    }
                    None => (kind, Array::One),
                };
                let base = match Primitive::of(base) {
                    Some(p) => Base::Primitive(p),
                    None => Base::Message(resolve_type(base, name, &names).ok_or_else(|| {
                        format!(
                            "line {n}: field `{field}` has type `{base}`, whose definition the \
                             text does not include"
                        )
                    })?),
                };
                fields.push(Field {
                    name: field.to_string(),
                    base,
                    array,
                });
            }
            types.push(MessageType {
                name: name.clone(),
                fields,
            });
        }
        let definition = Definition { types };
        let mut checked = vec![false; definition.types.len()];
        definition.check_nesting(0, &mut Vec::new(), &mut checked)?;
        Ok(definition)
    }

    /// A type that contains itself cannot be walked (nor be a ROS message), and one nested
    /// deeper than [`MAX_DEPTH`] is refused before a walk could exhaust the stack. Each type is
    /// checked once (`checked`), so a type used by many fields costs nothing more.
    fn check_nesting(
        &self,
        t: usize,
        stack: &mut Vec<usize>,
        checked: &mut [bool],
    ) -> Result<(), String> {
        if stack.contains(&t) {
            return Err(format!(
                "type `{}` contains itself; the message definition is damaged",
                self.types[t].name
            ));
        }
        if stack.len() >= MAX_DEPTH {
            return Err(format!(
                "types are nested more than {MAX_DEPTH} deep; the message definition is damaged"
            ));
        }
        if checked[t] {
            return Ok(());
        }
        stack.push(t);
        for f in &self.types[t].fields {
            if let Base::Message(u) = f.base {
                self.check_nesting(u, stack, checked)?;
            }
        }
        stack.pop();
        checked[t] = true;
        Ok(())
    }

    /// The walk that reads the values of `paths` (`a.b`, `a[2].b`, …), in this order; the
    /// error names the path and what the type offers there.
    pub(crate) fn plan(&self, paths: &[String]) -> Result<Plan, String> {
        let mut want = Want::default();
        for (slot, path) in paths.iter().enumerate() {
            self.add(&mut want, 0, path, path, slot)?;
        }
        let fields = &self.types[0].fields;
        let header = fields.first().is_some_and(|f| {
            f.name == "header"
                && f.array == Array::One
                && matches!(f.base, Base::Message(t) if self.types[t].name == "std_msgs/Header")
        });
        if header {
            let n = paths.len();
            self.add(&mut want, 0, "header.stamp.sec", "header.stamp.sec", n)?;
            self.add(
                &mut want,
                0,
                "header.stamp.nanosec",
                "header.stamp.nanosec",
                n + 1,
            )?;
        }
        Ok(Plan {
            definition: self.clone(),
            want,
            slots: paths.len(),
            header,
        })
    }

    /// Adds `rest` of `path` below type `t` to `want`.
    fn add(
        &self,
        want: &mut Want,
        t: usize,
        rest: &str,
        path: &str,
        slot: usize,
    ) -> Result<(), String> {
        let ty = &self.types[t];
        let (segment, tail) = match rest.split_once('.') {
            Some((s, tail)) => (s, Some(tail)),
            None => (rest, None),
        };
        let (name, index) = match segment.split_once('[') {
            Some((name, i)) => {
                let i = i
                    .strip_suffix(']')
                    .and_then(|i| i.parse::<usize>().ok())
                    .ok_or_else(|| format!("`{path}`: `{segment}` is not `NAME[INDEX]`"))?;
                (name, Some(i))
            }
            None => (segment, None),
        };
        let Some(k) = ty.fields.iter().position(|f| f.name == name) else {
            let names: Vec<&str> = ty.fields.iter().map(|f| f.name.as_str()).collect();
            return Err(format!(
                "`{path}`: {} has no field `{name}` (its fields: {})",
                ty.name,
                names.join(", ")
            ));
        };
        let field = &ty.fields[k];
        let node = want.field(k);
        let node = match (field.array, index) {
            (Array::One, None) => node,
            (Array::One, Some(_)) => {
                return Err(format!(
                    "`{path}`: field `{name}` of {} is not an array",
                    ty.name
                ));
            }
            (Array::Fixed(n), Some(i)) if i >= n => {
                return Err(format!(
                    "`{path}`: field `{name}` of {} has {n} elements, so index {i} is beyond it",
                    ty.name
                ));
            }
            (_, Some(i)) => node.element(i),
            (_, None) => {
                return Err(format!(
                    "`{path}`: field `{name}` of {} is an array; name one element as \
                     `{name}[INDEX]`",
                    ty.name
                ));
            }
        };
        match (&field.base, tail) {
            (Base::Message(u), Some(tail)) => self.add(node, *u, tail, path, slot),
            (Base::Primitive(p), None) if p.size().is_some() => {
                node.slots.push(slot);
                Ok(())
            }
            (Base::Primitive(_), None) => Err(format!(
                "`{path}`: field `{name}` of {} is a string, not a number",
                ty.name
            )),
            (Base::Primitive(_), Some(_)) => Err(format!(
                "`{path}`: field `{name}` of {} is a number and has no fields",
                ty.name
            )),
            (Base::Message(u), None) => {
                let names: Vec<&str> = self.types[*u]
                    .fields
                    .iter()
                    .map(|f| f.name.as_str())
                    .collect();
                Err(format!(
                    "`{path}`: field `{name}` is a {}; name one of its fields ({})",
                    self.types[*u].name,
                    names.join(", ")
                ))
            }
        }
    }
}

/// The index of the type a field names: `package/Type` or `package/msg/Type`, or a bare
/// `Type` of the enclosing type's package (or, as ROS 1's `Header`, the one type of that name).
fn resolve_type(name: &str, enclosing: &str, names: &[String]) -> Option<usize> {
    let wanted = if name.contains('/') {
        normalized(name)
    } else {
        format!("{}/{name}", package(enclosing))
    };
    names.iter().position(|n| *n == wanted).or_else(|| {
        let suffix = format!("/{name}");
        let mut found = names
            .iter()
            .enumerate()
            .filter(|(_, n)| n.ends_with(&suffix));
        match (found.next(), found.next()) {
            (Some((i, _)), None) if !name.contains('/') => Some(i),
            _ => None,
        }
    })
}

/// What a walk reads below one value: channel slots of a numeric value, fields of a message,
/// elements of an array (each in increasing index order).
#[derive(Debug, Clone, Default)]
struct Want {
    slots: Vec<usize>,
    fields: Vec<(usize, Want)>,
    elements: Vec<(usize, Want)>,
}

impl Want {
    fn field(&mut self, k: usize) -> &mut Want {
        child(&mut self.fields, k)
    }

    fn element(&mut self, i: usize) -> &mut Want {
        child(&mut self.elements, i)
    }
}

fn child(list: &mut Vec<(usize, Want)>, k: usize) -> &mut Want {
    let at = match list.binary_search_by_key(&k, |(i, _)| *i) {
        Ok(at) => at,
        Err(at) => {
            list.insert(at, (k, Want::default()));
            at
        }
    };
    &mut list[at].1
}

/// The compiled walk of one topic's messages (see the [module docs](self)).
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    definition: Definition,
    want: Want,
    /// Number of paths.
    slots: usize,
    /// The message starts with `std_msgs/Header header`: its stamp follows the paths' values.
    header: bool,
}

/// What is wrong with a message walked by a [`Plan`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum WalkError {
    Cdr(CdrError),
    /// An element the path names is beyond the array in this message.
    Missing {
        field: String,
        index: usize,
        len: usize,
    },
    WString {
        field: String,
    },
}

impl From<CdrError> for WalkError {
    fn from(e: CdrError) -> Self {
        WalkError::Cdr(e)
    }
}

impl fmt::Display for WalkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WalkError::Cdr(e) => e.fmt(f),
            WalkError::Missing { field, index, len } => write!(
                f,
                "field `{field}` has {len} elements in this message, so element {index} is \
                 missing; every message must carry the channel"
            ),
            WalkError::WString { field } => write!(
                f,
                "field `{field}` is a wstring, which calib cannot skip; name a field before it"
            ),
        }
    }
}

impl Plan {
    /// Reads the values of the paths from a CDR message into `out` (one per path), and returns
    /// the header stamp `(sec, nanosec)` if the message has a header.
    pub(crate) fn read(
        &self,
        data: &[u8],
        out: &mut [f64],
    ) -> Result<Option<(i64, u32)>, WalkError> {
        let mut c = Cursor::cdr(data, ORIGIN, encapsulation(data)?);
        let mut values = vec![f64::NAN; self.slots + 2];
        self.message(&mut c, 0, Some(&self.want), &mut values)?;
        out.copy_from_slice(&values[..self.slots]);
        Ok(self
            .header
            .then(|| (values[self.slots] as i64, values[self.slots + 1] as u32)))
    }

    fn message(
        &self,
        c: &mut Cursor<'_>,
        t: usize,
        want: Option<&Want>,
        out: &mut [f64],
    ) -> Result<(), WalkError> {
        let fields = &self.definition.types[t].fields;
        if fields.is_empty() {
            // `rosidl` gives a message without fields one `uint8` member, so that it has a size.
            c.take(1, "message field")?;
            return Ok(());
        }
        let mut wanted = want
            .map(|w| w.fields.as_slice())
            .unwrap_or_default()
            .iter()
            .peekable();
        for (k, field) in fields.iter().enumerate() {
            let w = wanted.next_if(|(i, _)| *i == k).map(|(_, w)| w);
            self.field(c, field, w, out)?;
        }
        Ok(())
    }

    fn field(
        &self,
        c: &mut Cursor<'_>,
        field: &Field,
        want: Option<&Want>,
        out: &mut [f64],
    ) -> Result<(), WalkError> {
        let count = match field.array {
            Array::One => return self.value(c, field, want, out),
            Array::Fixed(n) => n,
            Array::Sequence => c.count("message field", 0)?,
        };
        // Every element takes at least this many bytes: a count beyond the bytes left is a
        // damaged message (or definition), refused before it could drive a long loop.
        let least = field_min_size(&field.base);
        if count.saturating_mul(least) > c.remaining() {
            return Err(WalkError::Cdr(CdrError::LengthTooLarge {
                field: "message field",
                count: u32::try_from(count).unwrap_or(u32::MAX),
                remaining: c.remaining(),
            }));
        }
        let elements = want.map(|w| w.elements.as_slice()).unwrap_or_default();
        if let Some((i, _)) = elements.iter().find(|(i, _)| *i >= count) {
            return Err(WalkError::Missing {
                field: field.name.clone(),
                index: *i,
                len: count,
            });
        }
        if let (Base::Primitive(p), true) = (&field.base, elements.is_empty())
            && let Some(size) = p.size()
        {
            // Skipped whole: aligned once (only if there is an element), then its bytes.
            if count > 0 {
                c.align(size);
                c.take(count.saturating_mul(size), "message field")?;
            }
            return Ok(());
        }
        let mut wanted = elements.iter().peekable();
        for i in 0..count {
            let w = wanted.next_if(|(k, _)| *k == i).map(|(_, w)| w);
            self.value(c, field, w, out)?;
        }
        Ok(())
    }

    fn value(
        &self,
        c: &mut Cursor<'_>,
        field: &Field,
        want: Option<&Want>,
        out: &mut [f64],
    ) -> Result<(), WalkError> {
        match field.base {
            Base::Message(t) => self.message(c, t, want, out),
            Base::Primitive(Primitive::String) => {
                c.string("message field")?;
                Ok(())
            }
            Base::Primitive(Primitive::WString) => Err(WalkError::WString {
                field: field.name.clone(),
            }),
            Base::Primitive(p) => {
                let size = p.size().unwrap_or(1);
                c.align(size);
                let bytes = c.take(size, "message field")?;
                if let Some(w) = want {
                    let v = p.value(bytes, c.big_endian);
                    for &slot in &w.slots {
                        out[slot] = v;
                    }
                }
                Ok(())
            }
        }
    }
}

/// The least bytes an element of this type takes, to check an array's count against the bytes
/// left.
fn field_min_size(base: &Base) -> usize {
    match base {
        Base::Primitive(p) => p.size().unwrap_or(4),
        // Every message type takes at least one byte (ROS 2 gives an empty one a dummy byte).
        Base::Message(_) => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MOTOR: &str = "\
# A motor's state.
std_msgs/Header header
float64 position  # rad
int32 MODE_IDLE=0
uint8 mode 1
float32[3] currents
Sample[] history
string note
int16 raw

================================================================================
MSG: my_robot/Sample
uint16 count
float64 value
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

    /// A little-endian CDR message of `MOTOR`, written by hand with its padding.
    fn motor(note: &str, history: &[(u16, f64)]) -> Vec<u8> {
        let mut b = vec![0u8, 1, 0, 0];
        let pad = |b: &mut Vec<u8>, n: usize| {
            while (b.len() - 4) % n != 0 {
                b.push(0);
            }
        };
        b.extend(5i32.to_le_bytes());
        b.extend(7u32.to_le_bytes());
        b.extend(3u32.to_le_bytes());
        b.extend(b"ab\0");
        pad(&mut b, 8);
        b.extend(1.5f64.to_le_bytes());
        b.push(2); // mode
        pad(&mut b, 4);
        for v in [0.25f32, -0.5, 0.75] {
            b.extend(v.to_le_bytes());
        }
        b.extend((history.len() as u32).to_le_bytes());
        for &(count, value) in history {
            pad(&mut b, 2);
            b.extend(count.to_le_bytes());
            pad(&mut b, 8);
            b.extend(value.to_le_bytes());
        }
        pad(&mut b, 4);
        b.extend((note.len() as u32 + 1).to_le_bytes());
        b.extend(note.as_bytes());
        b.push(0);
        pad(&mut b, 2);
        b.extend((-300i16).to_le_bytes());
        b
    }

    fn read(paths: &[&str], data: &[u8]) -> (Vec<f64>, Option<(i64, u32)>) {
        let d = Definition::parse("my_robot/msg/Motor", MOTOR).unwrap();
        let paths: Vec<String> = paths.iter().map(|p| p.to_string()).collect();
        let plan = d.plan(&paths).unwrap();
        let mut out = vec![0.0; paths.len()];
        let stamp = plan.read(data, &mut out).unwrap();
        (out, stamp)
    }

    #[test]
    fn fields_are_read_through_every_kind_of_field_before_them() {
        let data = motor("hello", &[(1, 10.0), (2, 20.0)]);
        let (v, stamp) = read(
            &[
                "raw",
                "position",
                "currents[1]",
                "history[1].value",
                "mode",
                "history[0].count",
            ],
            &data,
        );
        assert_eq!(v, [-300.0, 1.5, -0.5, 20.0, 2.0, 1.0]);
        assert_eq!(stamp, Some((5, 7)));
        // Other string and sequence lengths move everything after them.
        let data = motor("", &[]);
        assert_eq!(read(&["raw"], &data).0, [-300.0]);
        // An element the message does not have.
        let d = Definition::parse("my_robot/msg/Motor", MOTOR).unwrap();
        let plan = d.plan(&["history[2].value".to_string()]).unwrap();
        let data = motor("x", &[(1, 1.0)]);
        let err = plan.read(&data, &mut [0.0]).unwrap_err();
        assert!(err.to_string().contains("1 elements"), "{err}");
        // Every cut is an error, not a panic.
        for n in 0..data.len() {
            assert!(plan.read(&data[..n], &mut [0.0]).is_err(), "{n}");
        }
    }

    #[test]
    fn bad_paths_and_definitions_are_errors_saying_why() {
        let d = Definition::parse("my_robot/msg/Motor", MOTOR).unwrap();
        let err = |p: &str| d.plan(&[p.to_string()]).unwrap_err();
        assert!(err("speed").contains("no field `speed` (its fields: header, position"));
        assert!(err("note").contains("string"));
        assert!(err("currents").contains("`currents[INDEX]`"));
        assert!(err("currents[3]").contains("3 elements"));
        assert!(err("header.stamp").contains("builtin_interfaces/Time"));
        assert!(err("position.x").contains("no fields"));
        let bad = Definition::parse("a/msg/B", "float64 x\nfoo/Bar y\n").unwrap_err();
        assert!(bad.contains("line 2") && bad.contains("`foo/Bar`"), "{bad}");
        let bad = Definition::parse("a/msg/B", "float64\n").unwrap_err();
        assert!(bad.contains("line 1"), "{bad}");
        let bad = Definition::parse("a/msg/B", "float64[x] v\n").unwrap_err();
        assert!(bad.contains("not a number"), "{bad}");
        let bad = Definition::parse("a/msg/B", "float64[0] v\n").unwrap_err();
        assert!(bad.contains("above 0"), "{bad}");
        // A type without fields (std_msgs/Empty) takes its one dummy byte.
        let d = Definition::parse("a/msg/B", "uint8 a\nE e\nuint8 b\n===\nMSG: a/E\n").unwrap();
        let plan = d.plan(&["b".to_string()]).unwrap();
        let mut out = [0.0];
        plan.read(&[0, 1, 0, 0, 1, 0, 7], &mut out).unwrap();
        assert_eq!(out, [7.0]);
        let bad = Definition::parse("a/msg/B", "B inner\n").unwrap_err();
        assert!(bad.contains("contains itself"), "{bad}");
        // Forty types each holding the next twice: checked once per type, not 2⁴⁰ times.
        let mut text = String::from("T0 a\nT0 b\n");
        for k in 0..40 {
            text.push_str(&format!("===\nMSG: a/T{k}\nT{} a\nT{} b\n", k + 1, k + 1));
        }
        text.push_str("===\nMSG: a/T40\nuint8 x\n");
        let d = Definition::parse("a/msg/B", &text).unwrap();
        // A count or fixed size beyond the message is an error, not a long loop.
        let plan = d.plan(&[format!("{}x", "a.".repeat(41))]).unwrap();
        assert!(plan.read(&[0, 1, 0, 0, 1], &mut [0.0]).is_err());
        let d = Definition::parse("a/msg/B", "uint8[4000000000] big\nuint8 x\n").unwrap();
        let plan = d.plan(&["x".to_string()]).unwrap();
        assert!(plan.read(&[0, 1, 0, 0, 1, 2], &mut [0.0]).is_err());
    }
}

//! C and C++ arrays, read back: SimpleFOC's `uint16_t calibrationLut[N] = {…};` (what
//! `printLUT()` prints and `--format simplefoc` writes), the `float` table of releases before PR
//! #75 (`--format simplefoc-float`), and calib's `c-array`.
//!
//! The first array initialised in the file (`TYPE NAME[SIZE] = { v, v, … };`, comments skipped)
//! is the table, and a second array of the table's type after it is refused, naming the lines of
//! both (two `printLUT()` outputs pasted together: which one is on the controller?); `SIZE` may be a number, a `#define`d name or empty, and must match the entries
//! where given. SimpleFOC entries are decoded as the driver does (`decodeOffsetU16` in `f32`,
//! [`crate::export::simplefoc::decode`]; floats as the `f32` the compiler makes of them) and hold
//! the error, radians; calib's `c-array` holds the correction, arcseconds.
//! `printLUT()`'s `zero_electric_angle` and `sensor_direction` lines are reported as notes: they
//! are the motor's settings, not part of the table.

use super::{at, check_count, data, refuse_range};
use crate::Error;
use crate::export::Format;
use crate::export::simplefoc::decode;
use calib_core::angle::ARCSEC_PER_RAD;
use std::path::Path;

/// The errors (radians) of the first array in `text`, and notes.
pub(super) fn parse(
    text: &str,
    path: &Path,
    format: Format,
) -> Result<(Vec<f64>, Vec<String>), Error> {
    let code = strip_comments(text);
    if let Some(offset) = code.find("CALIB_CORRECTION_START_DEG") {
        return Err(refuse_range(path, line_at(&code, offset)));
    }
    let Some(array) = first_array(&code) else {
        return Err(data(
            path,
            format!(
                "no array initialiser (`TYPE NAME[N] = {{ … }};`) found; `format = {}` reads {}",
                format.name(),
                expected(format)
            ),
        ));
    };
    let line = line_at(&code, array.open);
    let right = is_of(format, &array.declaration);
    let words: Vec<&str> = array.declaration.split_whitespace().collect();
    let is_u16 = words.contains(&"uint16_t");
    let is_float = words.contains(&"float");
    if !right {
        let hint = if is_float && format == Format::Simplefoc {
            " — a float table is SimpleFOC's before PR #75: `format = simplefoc-float`"
        } else if is_u16 {
            " — a uint16_t table is current SimpleFOC's: `format = simplefoc`"
        } else {
            ""
        };
        return Err(at(
            path,
            line,
            format!(
                "`{}` is not the array `format = {}` reads ({}){hint}",
                array.declaration.trim(),
                format.name(),
                expected(format)
            ),
        ));
    }
    // A second table of the same type: refused, whatever its entries.
    let mut from = array.close + 1;
    while let Some(next) = first_array(&code[from..]) {
        if is_of(format, &next.declaration) {
            return Err(at(
                path,
                line_at(&code, from + next.open),
                format!(
                    "the file holds two tables, `{}` on line {line} and `{}` on line {}; calib \
                     cannot tell which one the controller holds (two outputs pasted \
                     together?): keep one table in the file",
                    array.declaration.trim(),
                    next.declaration.trim(),
                    line_at(&code, from + next.open)
                ),
            ));
        }
        from += next.close + 1;
    }
    let values = read_entries(&code, &array, format, path, &mut Lines::new(&code))?;
    if let Some(size) = declared_size(&code, &array.declaration) {
        match size {
            Ok(n) if n == values.len() => {}
            Ok(n) => {
                return Err(at(
                    path,
                    line,
                    format!(
                        "the array is declared with {n} entries but holds {}; a table cut short \
                         or pasted twice cannot be read",
                        values.len()
                    ),
                ));
            }
            Err(name) => {
                return Err(at(
                    path,
                    line,
                    format!(
                        "the array's size `{name}` is neither a number nor #defined in the file"
                    ),
                ));
            }
        }
    }
    let mut notes = vec![match format {
        Format::Simplefoc => format!(
            "SimpleFOC uint16_t table of {} entries, decoded as (code - 32767)/10430.2191955 rad: \
             the error, subtracted by CalibratedSensor",
            values.len()
        ),
        Format::SimplefocFloat => format!(
            "SimpleFOC float table of {} entries (releases before PR #75): the error in radians, \
             subtracted by CalibratedSensor",
            values.len()
        ),
        _ => format!(
            "calib c-array of {} entries: the correction in arcseconds",
            values.len()
        ),
    }];
    for setting in ["zero_electric_angle", "sensor_direction"] {
        if let Some(value) = assignment(&code, setting) {
            notes.push(format!(
                "{setting} = {value} (the motor's setting, printed beside the table; not part of it)"
            ));
        }
    }
    Ok((values, notes))
}

/// Whether an array of `declaration` is of the type `format` reads: `uint16_t` for SimpleFOC's,
/// `float` for the others.
fn is_of(format: Format, declaration: &str) -> bool {
    let words: Vec<&str> = declaration.split_whitespace().collect();
    match format {
        Format::Simplefoc => words.contains(&"uint16_t"),
        _ => words.contains(&"float"),
    }
}

/// The entries of `array` decoded as `format` reads them (see the module docs), each checked
/// against [`crate::limits::MAX_TABLE_POINTS`] as it is counted. `lines` gives each entry's line
/// for messages.
fn read_entries(
    code: &str,
    array: &Array,
    format: Format,
    path: &Path,
    lines: &mut Lines<'_>,
) -> Result<Vec<f64>, Error> {
    let mut values = Vec::new();
    for (token, offset) in entries(code, array.open + 1, array.close) {
        let line = lines.at(offset);
        check_count(path, line, values.len())?;
        let value = match format {
            Format::Simplefoc => token
                .parse::<u16>()
                .map(|c| f64::from(decode(c)))
                .map_err(|_| format!("`{token}` is not a uint16_t code (0 to 65535)")),
            _ => token
                .trim_end_matches(['f', 'F'])
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .map(|v| match format {
                    Format::CArray => -f64::from(v) / ARCSEC_PER_RAD,
                    _ => f64::from(v),
                })
                .ok_or_else(|| format!("`{token}` is not a finite float")),
        };
        values.push(value.map_err(|m| at(path, line, m))?);
    }
    Ok(values)
}

/// What `format` reads, for messages.
fn expected(format: Format) -> &'static str {
    match format {
        Format::Simplefoc => {
            "SimpleFOC's `uint16_t calibrationLut[N] = {…};` as printLUT() prints it"
        }
        Format::SimplefocFloat => "the `float NAME[N] = {…};` of SimpleFOC releases before PR #75",
        _ => "calib's `static const float calib_correction_arcsec[N] = {…};`",
    }
}

/// An array initialiser: its declaration (`uint16_t calibrationLut[200] =`) and the offsets of
/// its braces.
struct Array {
    declaration: String,
    open: usize,
    close: usize,
}

/// The first `{` whose declaration (since the previous `;`, `{` or `}`) has `[` and `=`, with
/// its closing `}`.
fn first_array(code: &str) -> Option<Array> {
    let mut start = 0;
    for (i, c) in code.char_indices() {
        match c {
            ';' | '}' => start = i + 1,
            '{' => {
                let declaration = &code[start..i];
                if declaration.contains('[') && declaration.contains('=') {
                    let close = i + code[i..].find('}')?;
                    // Lines of the preprocessor before the declaration are not part of it.
                    let declaration = declaration
                        .lines()
                        .filter(|l| !l.trim_start().starts_with('#'))
                        .collect::<Vec<_>>()
                        .join(" ");
                    return Some(Array {
                        declaration,
                        open: i,
                        close,
                    });
                }
                start = i + 1;
            }
            _ => {}
        }
    }
    None
}

/// The entries between `from` and `to`, each with its offset: comma-separated, a trailing comma
/// allowed.
fn entries(code: &str, from: usize, to: usize) -> impl Iterator<Item = (&str, usize)> {
    let mut offset = from;
    code[from..to].split(',').filter_map(move |part| {
        let at = offset + (part.len() - part.trim_start().len());
        offset += part.len() + 1;
        let token = part.trim();
        (!token.is_empty()).then_some((token, at))
    })
}

/// The declared size: `None` for `[]`, `Ok(n)` for a number or a `#define`d name, `Err(name)`
/// for a name not defined.
fn declared_size(code: &str, declaration: &str) -> Option<Result<usize, String>> {
    let inside = declaration.split_once('[')?.1.split_once(']')?.0.trim();
    if inside.is_empty() {
        return None;
    }
    if let Ok(n) = inside.parse() {
        return Some(Ok(n));
    }
    let defined = code.lines().find_map(|l| {
        let mut words = l.split_whitespace();
        (words.next() == Some("#define") && words.next() == Some(inside))
            .then(|| words.next().and_then(|v| v.parse().ok()))
            .flatten()
    });
    Some(defined.ok_or_else(|| inside.to_string()))
}

/// The value assigned to `name` (`… name = VALUE;`), if the file has one.
fn assignment(code: &str, name: &str) -> Option<String> {
    let start = code.find(&format!("{name} ="))? + name.len() + 2;
    let end = start + code[start..].find(';')?;
    Some(code[start..end].trim().to_string())
}

/// 1-based line of byte `offset`.
fn line_at(code: &str, offset: usize) -> usize {
    code[..offset].matches('\n').count() + 1
}

/// The lines of the entries, counted as they are walked: each byte between two entries is
/// looked at once, so a table of `n` entries costs `O(n)` however they are laid out. (Counting
/// from the file's start for each entry cost `O(n²)`: 100,000 entries one a line took over a
/// minute.)
struct Lines<'a> {
    code: &'a str,
    /// The offset counted up to, and its 1-based line.
    offset: usize,
    line: usize,
    /// Bytes looked at so far (what the tests bound).
    scanned: usize,
}

impl<'a> Lines<'a> {
    fn new(code: &'a str) -> Self {
        Lines {
            code,
            offset: 0,
            line: 1,
            scanned: 0,
        }
    }

    /// The 1-based line of byte `offset`, which is at or after the previous call's.
    fn at(&mut self, offset: usize) -> usize {
        let passed = &self.code[self.offset..offset];
        self.scanned += passed.len();
        self.line += passed.matches('\n').count();
        self.offset = offset;
        self.line
    }
}

/// `text` with `//` and `/* */` comments replaced by spaces (line ends kept, so offsets and
/// lines stay those of the file).
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, chars.peek()) {
            ('/', Some('/')) => {
                out.push(' ');
                for c in chars.by_ref() {
                    if c == '\n' {
                        out.push('\n');
                        break;
                    }
                    out.push(' ');
                }
            }
            ('/', Some('*')) => {
                chars.next();
                out.push_str("  ");
                let mut last = ' ';
                for c in chars.by_ref() {
                    out.push(if c == '\n' { '\n' } else { ' ' });
                    if last == '*' && c == '/' {
                        break;
                    }
                    last = c;
                }
            }
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A SimpleFOC table of `n` codes, one a line, as printLUT() prints it.
    fn one_a_line(n: usize) -> String {
        let mut text = format!("uint16_t calibrationLut[{n}] = {{\n");
        for k in 0..n {
            text += &format!("  {},\n", 32767 + (k % 7) as u16);
        }
        text + "};\n"
    }

    /// The lines of the entries are counted by looking at each byte once: the work grows as the
    /// table, not as its square (a count from the start for each entry made 100,000 entries
    /// take over a minute).
    #[test]
    fn entry_lines_cost_one_look_at_each_byte() {
        for n in [1_000, 10_000] {
            let code = strip_comments(&one_a_line(n));
            let array = first_array(&code).unwrap();
            let mut lines = Lines::new(&code);
            let values = read_entries(
                &code,
                &array,
                Format::Simplefoc,
                Path::new("t.h"),
                &mut lines,
            )
            .unwrap();
            assert_eq!(values.len(), n);
            assert!(
                lines.scanned <= code.len(),
                "{} of {}",
                lines.scanned,
                code.len()
            );
            // The last entry is on line n + 1 (the declaration on line 1).
            assert_eq!(lines.line, n + 1);
        }
        // Errors still name the entry's line.
        let mut text = one_a_line(5);
        text = text.replace("  32770,", "  x,");
        let e = parse(&text, Path::new("t.h"), Format::Simplefoc)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 5") && e.contains("`x`"), "{e}");
    }
}

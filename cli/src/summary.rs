//! The compact tables of the stdout summaries: columns aligned by characters (not bytes, so
//! `″` and `°` line up), numbers right-aligned.

use std::fmt::Write;

/// A text table with a header row.
pub struct TextTable {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    min_widths: Vec<usize>,
    indented: bool,
    align_first: bool,
}

impl TextTable {
    /// A table with these column headers.
    pub fn new(header: &[&str]) -> Self {
        TextTable {
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
            min_widths: Vec::new(),
            indented: true,
            align_first: false,
        }
    }
    /// The table without the two-space indent of its lines.
    pub fn flush_left(mut self) -> Self {
        self.indented = false;
        self
    }
    /// The table with its first column right-aligned too when it holds numbers (by default it
    /// names the rows and is left-aligned).
    pub fn align_first_column(mut self) -> Self {
        self.align_first = true;
        self
    }
    /// The table with columns at least these widths (characters), so that its layout stays put
    /// from run to run while its cells fit; a wider cell widens its column.
    pub fn min_widths(mut self, widths: &[usize]) -> Self {
        self.min_widths = widths.to_vec();
        self
    }
    /// Adds a row.
    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }
    /// The table, each line indented by two spaces (unless [`TextTable::flush_left`]), columns
    /// two apart; a column whose cells all start like a number (or `—`, `∞`) is right-aligned
    /// (except the first, unless [`TextTable::align_first_column`]), others left-aligned.
    pub fn render(&self) -> String {
        let n = self.header.len();
        let width = |c: usize| {
            std::iter::once(&self.header)
                .chain(&self.rows)
                .filter_map(|r| r.get(c))
                .map(|s| s.chars().count())
                .max()
                .unwrap_or(0)
                .max(self.min_widths.get(c).copied().unwrap_or(0))
        };
        let widths: Vec<usize> = (0..n).map(width).collect();
        let number_like = |cell: &str| {
            let first = cell.split_whitespace().next().unwrap_or("");
            first == "—"
                || first == "∞"
                || first
                    .trim_end_matches(['″', '°', '%'])
                    .parse::<f64>()
                    .is_ok()
        };
        let right: Vec<bool> = (0..n)
            .map(|c| {
                (c > 0 || self.align_first)
                    && self
                        .rows
                        .iter()
                        .filter_map(|r| r.get(c))
                        .all(|cell| cell.is_empty() || number_like(cell))
            })
            .collect();
        let mut o = String::new();
        for row in std::iter::once(&self.header).chain(&self.rows) {
            let mut line = String::new();
            for (c, w) in widths.iter().enumerate() {
                let cell = row.get(c).map_or("", |s| s.as_str());
                let pad = w - cell.chars().count();
                if right[c] {
                    let _ = write!(line, "  {}{cell}", " ".repeat(pad));
                } else {
                    let _ = write!(line, "  {cell}{}", " ".repeat(pad));
                }
            }
            let line = if self.indented { &line } else { &line[2..] };
            let _ = writeln!(o, "{}", line.trim_end());
        }
        o
    }
}

/// `key   value` lines, keys padded to one width, indented by two spaces.
pub fn key_values(rows: &[(&str, String)]) -> String {
    let w = rows.iter().map(|r| r.0.chars().count()).max().unwrap_or(0);
    let mut o = String::new();
    for (k, v) in rows {
        let _ = writeln!(o, "  {k}{}  {v}", " ".repeat(w - k.chars().count()));
    }
    o
}

/// The closing lines of every method's summary: warnings, then what was written and what to
/// open next.
pub fn ending(
    warnings: &[String],
    dir: &std::path::Path,
    files: &[String],
    look_at: &str,
) -> String {
    let mut o = String::new();
    for w in warnings {
        let _ = writeln!(o, "\nwarning: {w}");
    }
    let _ = writeln!(
        o,
        "\nwrote {} and report.html into {}",
        files.join(", "),
        dir.display()
    );
    let _ = writeln!(
        o,
        "next: open {} — {look_at}",
        dir.join("report.html").display()
    );
    o
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimum_widths_hold_until_a_cell_is_wider() {
        let mut t = TextTable::new(&["head", "angle"]).min_widths(&[6, 8]);
        t.row(vec!["h1".into(), "0.5".into()]);
        assert_eq!(t.render(), "  head       angle\n  h1           0.5\n");
        t.row(vec!["a_long_name".into(), "1.25".into()]);
        assert_eq!(
            t.render(),
            "  head            angle\n  h1                0.5\n  a_long_name      1.25\n"
        );
    }

    #[test]
    fn columns_align_by_characters() {
        let mut t = TextTable::new(&["channel", "p-p", "table"]);
        t.row(vec!["a".into(), "51.127″".into(), "out/a.csv".into()]);
        t.row(vec![
            "long_name".into(),
            "3.1″".into(),
            "out/long_name.csv".into(),
        ]);
        let text = t.render();
        let lines: Vec<&str> = text.lines().collect();
        let col = |l: &str| l.chars().position(|c| c == '″');
        assert_eq!(col(lines[1]), col(lines[2]), "{text}");
        assert!(lines[0].starts_with("  channel"));
    }
}

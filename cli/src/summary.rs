//! The compact tables of the stdout summaries: columns aligned by characters (not bytes, so
//! `″` and `°` line up), numbers right-aligned.

use std::fmt::Write;

/// A text table with a header row.
pub struct TextTable {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl TextTable {
    /// A table with these column headers.
    pub fn new(header: &[&str]) -> Self {
        TextTable {
            header: header.iter().map(|h| h.to_string()).collect(),
            rows: Vec::new(),
        }
    }
    /// Adds a row.
    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }
    /// The table, each line indented by two spaces, columns two apart; a column whose cells all
    /// start like a number is right-aligned (except the first), others left-aligned.
    pub fn render(&self) -> String {
        let n = self.header.len();
        let width = |c: usize| {
            std::iter::once(&self.header)
                .chain(&self.rows)
                .filter_map(|r| r.get(c))
                .map(|s| s.chars().count())
                .max()
                .unwrap_or(0)
        };
        let widths: Vec<usize> = (0..n).map(width).collect();
        let number_like = |cell: &str| {
            let first = cell.split_whitespace().next().unwrap_or("");
            first == "—"
                || first
                    .trim_end_matches(['″', '°', '%'])
                    .parse::<f64>()
                    .is_ok()
        };
        let right: Vec<bool> = (0..n)
            .map(|c| {
                c > 0
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

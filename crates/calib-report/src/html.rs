//! The HTML page of a [`Document`]: one file, inline SVG and CSS, no scripts, no external
//! resources.

use crate::{Document, Figure, Item, PlotError, Table};
use std::collections::HashSet;
use std::fmt::Write;

const STYLE: &str = "
body { font-family: 'DejaVu Sans', Verdana, sans-serif; color: #1d1d1d; max-width: 1060px;
       margin: 1.5em auto; padding: 0 1em; line-height: 1.4; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.8em 0 1.2em; font-size: 0.92em; }
caption { text-align: left; font-weight: bold; padding-bottom: 0.3em; }
th, td { border: 1px solid #d4d4d4; padding: 0.25em 0.6em; vertical-align: top; }
th { background: #f2f2f2; text-align: left; }
td { font-variant-numeric: tabular-nums; }
td.num { text-align: right; white-space: nowrap; }
table.provenance td { font-family: 'DejaVu Sans Mono', monospace; word-break: break-all; }
.warnings { background: #fff4e5; border-left: 4px solid #d55e00; padding: 0.5em 1em; }
figure { margin: 1em 0 1.5em; }
figure svg { max-width: 100%; height: auto; display: block; }
figcaption { font-size: 0.92em; color: #444; margin-top: 0.3em; }
nav ol { columns: 2; font-size: 0.95em; }
";

/// HTML text with `<`, `>`, `&` and quotes escaped.
pub(crate) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '&' => out.push_str("&amp;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A figure id as an HTML id and file stem: letters, digits, `-` and `_` only.
fn clean_id(id: &str) -> String {
    let s: String = id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect();
    if s.is_empty() { "plot".into() } else { s }
}

/// The figures with ids made safe and unique (`-2`, `-3`, … appended to repeats).
pub(crate) fn unique_ids<'a>(
    figures: impl Iterator<Item = &'a Figure>,
) -> Vec<(String, &'a Figure)> {
    let mut seen = HashSet::new();
    figures
        .map(|f| {
            let base = clean_id(&f.id);
            let mut id = base.clone();
            let mut k = 2;
            while !seen.insert(id.clone()) {
                id = format!("{base}-{k}");
                k += 1;
            }
            (id, f)
        })
        .collect()
}

/// Whether a cell reads as a number (then it is right-aligned).
fn numeric(cell: &str) -> bool {
    let t = cell.trim_end_matches(['″', '°', '%', ' ']);
    !t.is_empty() && t.parse::<f64>().is_ok()
}

fn table(o: &mut String, t: &Table) {
    let _ = writeln!(
        o,
        "<table>\n<caption>{}</caption>\n<tr>",
        escape(&t.caption)
    );
    for c in &t.columns {
        let _ = write!(o, "<th>{}</th>", escape(c));
    }
    o.push_str("</tr>\n");
    for row in &t.rows {
        o.push_str("<tr>");
        for cell in row {
            let class = if numeric(cell) { " class=\"num\"" } else { "" };
            let _ = write!(o, "<td{class}>{}</td>", escape(cell));
        }
        o.push_str("</tr>\n");
    }
    o.push_str("</table>\n");
}

/// The page.
pub(crate) fn render(doc: &Document) -> Result<String, PlotError> {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>",
        escape(&doc.title),
        escape(&doc.title)
    );
    let p = &doc.provenance;
    let _ = writeln!(
        o,
        "<table class=\"provenance\">\n<caption>Provenance</caption>\n\
         <tr><th>calib version</th><td>{}</td></tr>\n<tr><th>method</th><td>{}</td></tr>\n\
         <tr><th>inputs</th><td>{}</td></tr>",
        escape(&p.calib_version),
        escape(&p.method),
        escape(&p.inputs.join(", "))
    );
    if let Some(cmd) = &p.command_line {
        let _ = writeln!(o, "<tr><th>command line</th><td>{}</td></tr>", escape(cmd));
    }
    o.push_str("</table>\n");
    if !doc.warnings.is_empty() {
        o.push_str("<div class=\"warnings\"><strong>Warnings</strong>\n<ul>\n");
        for w in &doc.warnings {
            let _ = writeln!(o, "<li>{}</li>", escape(w));
        }
        o.push_str("</ul></div>\n");
    }
    o.push_str("<nav><ol>\n");
    for (i, s) in doc.sections.iter().enumerate() {
        let _ = writeln!(
            o,
            "<li><a href=\"#section-{}\">{}</a></li>",
            i + 1,
            escape(&s.heading)
        );
    }
    o.push_str("</ol></nav>\n");
    let ids = unique_ids(doc.figures());
    let mut ids = ids.iter().map(|(id, _)| id);
    for (i, s) in doc.sections.iter().enumerate() {
        let _ = writeln!(
            o,
            "<section id=\"section-{}\">\n<h2>{}</h2>",
            i + 1,
            escape(&s.heading)
        );
        for item in &s.items {
            match item {
                Item::Text(t) => {
                    let _ = writeln!(o, "<p>{}</p>", escape(t));
                }
                Item::Table(t) => table(&mut o, t),
                Item::Figure(f) => {
                    let id = ids.next().map_or("plot", |s| s.as_str());
                    let svg = f.to_svg()?;
                    // plotters writes no ids of its own, so the figure's id is the only one.
                    let svg = svg.replacen(
                        "<svg ",
                        &format!("<svg role=\"img\" aria-label=\"{}\" ", escape(&f.title)),
                        1,
                    );
                    let _ = writeln!(
                        o,
                        "<figure id=\"fig-{id}\">\n{svg}<figcaption>{}</figcaption>\n</figure>",
                        escape(&f.caption)
                    );
                }
            }
        }
        o.push_str("</section>\n");
    }
    let _ = writeln!(
        o,
        "<footer><p>Written by calib {}. Errors are reading − true angle; corrections are \
         −error.</p></footer>\n</body>\n</html>",
        escape(&p.calib_version)
    );
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Axis, Chart};

    #[test]
    fn text_is_escaped() {
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }

    #[test]
    fn repeated_ids_become_unique() {
        let f = Figure::new(
            "a map",
            "t",
            "c",
            Chart::new(Axis::linear("x"), Axis::linear("y")),
        );
        let figs = [f.clone(), f.clone(), f];
        let ids: Vec<String> = unique_ids(figs.iter()).into_iter().map(|p| p.0).collect();
        assert_eq!(ids, ["a-map", "a-map-2", "a-map-3"]);
    }

    #[test]
    fn numbers_are_recognised() {
        assert!(numeric("12.5″") && numeric("-3") && numeric("45.0°"));
        assert!(!numeric("order 3") && !numeric("—") && !numeric(""));
    }
}

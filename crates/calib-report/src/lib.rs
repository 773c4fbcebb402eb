//! `calib-report`: the report a person reads — a [`Document`] of sections holding plots and
//! tables, written as one self-contained HTML file (inline SVG, no scripts, no network) and, on
//! request, each plot as a standalone SVG and PNG.
//!
//! A method command builds its document from its results with the plot builders of [`plots`]
//! (error map, zoom on one period, harmonic spectrum, session timeline, `|Y|` chart, bar chart)
//! and [`Table`]s, then hands it to the writer that also writes the correction tables and
//! `report.json`:
//!
//! ```
//! use calib_report::{Document, Provenance, Section, Table, plots};
//! use calib_core::{ErrorMap, FourierSeries, Harmonic};
//!
//! let series = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(3, 20.0, 0.0)], 3);
//! let map = ErrorMap::from_series(&series, 3600);
//! let mut doc = Document::new("Calibration of `a`", Provenance {
//!     calib_version: "0.1.0".into(),
//!     method: "example".into(),
//!     inputs: vec!["run.csv".into()],
//!     command_line: Some("calib example run.csv".into()),
//! });
//! doc.push(Section::new("Sensor a")
//!     .figure(plots::error_map("a-map", "a", &plots::MapLayers::of(&map)))
//!     .table(Table::new("Summary", &["quantity", "value"]).row(["peak to peak (″)", "40.0"])));
//! let html = doc.to_html()?;
//! assert!(html.contains("<svg") && html.contains("reading of a (°)"));
//! # Ok::<(), calib_report::PlotError>(())
//! ```
//!
//! Plots are drawn with plotters and the embedded DejaVu Sans font, so nothing depends on system
//! font or graphics packages.
#![deny(missing_docs)]

pub mod binning;
pub mod chart;
mod html;
pub mod iso230;
pub mod plots;
pub mod trace;

pub use chart::{Axis, Chart, Colour, Figure, Level, Mark, PlotError, Scale, Series, Span};

use plotters::style::FontStyle;
use std::sync::OnceLock;

/// Registers the embedded fonts with plotters (once per process); every drawing needs them.
pub(crate) fn register_fonts() -> Result<(), PlotError> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for (style, bytes) in [
            (FontStyle::Normal, dejavu::sans::regular()),
            (FontStyle::Bold, dejavu::sans::bold()),
        ] {
            plotters::style::register_font("sans-serif", style, bytes)
                .map_err(|_| "the embedded DejaVu Sans font is invalid".to_string())?;
        }
        Ok(())
    })
    .clone()
    .map_err(PlotError)
}

/// Where a report came from: enough to reproduce it.
#[derive(Debug, Clone, PartialEq)]
pub struct Provenance {
    /// Version of calib.
    pub calib_version: String,
    /// The method (`csrr`, `reference`, …).
    pub method: String,
    /// Input files, as given.
    pub inputs: Vec<String>,
    /// The exact command line, when it came from the CLI.
    pub command_line: Option<String>,
}

/// A table: a caption, column headers (with units) and rows of already formatted cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Caption.
    pub caption: String,
    /// Column headers, units in parentheses.
    pub columns: Vec<String>,
    /// Rows; each as long as `columns`.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// An empty table.
    pub fn new(caption: &str, columns: &[&str]) -> Self {
        Table {
            caption: caption.to_string(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows: Vec::new(),
        }
    }
    /// Adds a row (builder style); short rows are padded with empty cells, long ones cut.
    pub fn row<S: Into<String>>(mut self, cells: impl IntoIterator<Item = S>) -> Self {
        let mut row: Vec<String> = cells.into_iter().map(Into::into).collect();
        row.resize(self.columns.len(), String::new());
        self.rows.push(row);
        self
    }
}

/// What a section holds, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    /// A paragraph of text.
    Text(String),
    /// A figure.
    Figure(Figure),
    /// A table.
    Table(Table),
}

/// A section: a heading and its items.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    /// Heading.
    pub heading: String,
    /// Content.
    pub items: Vec<Item>,
}

impl Section {
    /// An empty section.
    pub fn new(heading: &str) -> Self {
        Section {
            heading: heading.to_string(),
            items: Vec::new(),
        }
    }
    /// Adds a paragraph.
    pub fn text(mut self, text: &str) -> Self {
        self.items.push(Item::Text(text.to_string()));
        self
    }
    /// Adds a figure.
    pub fn figure(mut self, figure: Figure) -> Self {
        self.items.push(Item::Figure(figure));
        self
    }
    /// Adds a table.
    pub fn table(mut self, table: Table) -> Self {
        self.items.push(Item::Table(table));
        self
    }
}

/// The report of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Document {
    /// Title.
    pub title: String,
    /// Where it came from.
    pub provenance: Provenance,
    /// Warnings, shown first.
    pub warnings: Vec<String>,
    /// Sections, in order.
    pub sections: Vec<Section>,
}

impl Document {
    /// An empty document.
    pub fn new(title: &str, provenance: Provenance) -> Self {
        Document {
            title: title.to_string(),
            provenance,
            warnings: Vec::new(),
            sections: Vec::new(),
        }
    }
    /// Appends a section.
    pub fn push(&mut self, section: Section) {
        self.sections.push(section);
    }
    /// Every figure, in document order.
    pub fn figures(&self) -> impl Iterator<Item = &Figure> {
        self.sections.iter().flat_map(|s| {
            s.items.iter().filter_map(|i| match i {
                Item::Figure(f) => Some(f),
                _ => None,
            })
        })
    }
    /// The document as one self-contained HTML page.
    pub fn to_html(&self) -> Result<String, PlotError> {
        html::render(self)
    }
    /// Every figure as standalone files: `(file name, bytes)`, an `.svg` and a `.png` each, named
    /// by the figure's id.
    pub fn plot_files(&self) -> Result<Vec<(String, Vec<u8>)>, PlotError> {
        let mut out = Vec::new();
        for (id, f) in html::unique_ids(self.figures()) {
            out.push((format!("{id}.svg"), f.to_svg()?.into_bytes()));
            out.push((format!("{id}.png"), f.to_png()?));
        }
        Ok(out)
    }
}

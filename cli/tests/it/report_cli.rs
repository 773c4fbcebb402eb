//! `report.html` and `--plots`: what a person opens after a run. These tests read the HTML and
//! SVG as text (no browser needed); `renders_in_chromium` (ignored by default) also renders the
//! page with headless Chromium where it is installed.

use crate::common::{self, reference};

use common::*;
use reference::reference;
use std::collections::HashSet;
use std::path::Path;

/// The inline SVG documents of a page, in order.
fn svgs(html: &str) -> Vec<&str> {
    html.split("<svg ")
        .skip(1)
        .map(|s| &s[..s.find("</svg>").expect("unclosed <svg>")])
        .collect()
}

/// The figure of a page with this id, from `<figure` to `</figure>`.
fn figure<'a>(html: &'a str, id: &str) -> &'a str {
    let start = html
        .find(&format!("<figure id=\"fig-{id}\""))
        .unwrap_or_else(|| panic!("no figure {id}"));
    let end = start + html[start..].find("</figure>").unwrap();
    &html[start..end]
}

/// The rows of the table with this caption (start), header row excluded.
fn table_rows(html: &str, caption: &str) -> usize {
    let start = html
        .find(&format!("<caption>{caption}"))
        .unwrap_or_else(|| panic!("no table {caption}"));
    let end = start + html[start..].find("</table>").unwrap();
    html[start..end].matches("<tr>").count() - 1
}

/// The number of points of each line drawn in a figure.
fn polylines(figure: &str) -> Vec<usize> {
    figure
        .split("<polyline")
        .skip(1)
        .map(|p| {
            let points = &p[p.find("points=\"").unwrap() + 8..];
            points[..points.find('"').unwrap()]
                .split_whitespace()
                .count()
        })
        .collect()
}

/// Every `id="…"` of a page.
fn ids(html: &str) -> Vec<&str> {
    html.split(" id=\"")
        .skip(1)
        .map(|s| &s[..s.find('"').unwrap()])
        .collect()
}

/// Checks what every report must be: one self-contained page, ids unique, no NaN or infinity
/// anywhere in a plot, every plot with axis labels.
#[track_caller]
fn check_page(html: &str, figures: &[&str]) {
    assert!(html.starts_with("<!DOCTYPE html>") && html.trim_end().ends_with("</html>"));
    for forbidden in ["<script", "<link", "src=\"", "url("] {
        assert!(
            !html.contains(forbidden),
            "the page loads something: {forbidden}"
        );
    }
    let all = ids(html);
    let unique: HashSet<&&str> = all.iter().collect();
    assert_eq!(unique.len(), all.len(), "repeated ids: {all:?}");
    let found: Vec<&str> = all.iter().filter_map(|i| i.strip_prefix("fig-")).collect();
    assert_eq!(found, figures, "figures");
    let plots = svgs(html);
    assert_eq!(plots.len(), figures.len());
    for (svg, id) in plots.iter().zip(figures) {
        for bad in ["NaN", "inf", "Infinity"] {
            assert!(!svg.contains(bad), "{id}: {bad} in the SVG");
        }
        assert!(svg.matches("<text").count() >= 8, "{id}: too few labels");
        assert!(
            ["(°)", "(s)", "(cycles", ">\nface\n<"]
                .iter()
                .any(|x| svg.contains(x)),
            "{id}: no x axis label with a unit"
        );
    }
}

#[test]
fn csrr_report_shows_maps_against_the_truth_spectrum_and_timeline() {
    let dir = tempfile::tempdir().unwrap();
    let (out, plots) = (dir.path().join("out"), dir.path().join("plots"));
    let o = calib(&[
        "csrr",
        s(&testdata("examples/quick.mcap")),
        "-o",
        s(&out),
        "--truth",
        s(&testdata("examples/quick.truth")),
        "--plots",
        s(&plots),
        "--quiet",
    ]);
    let err = expect_exit(&o, 0);
    assert_eq!(err, "", "--quiet leaves standard error empty");
    let summary = stdout(&o);
    assert_mentions(
        &summary,
        &[
            "p-p before",
            "→ after",
            "kept above the noise",
            "report.html",
            "next: open",
        ],
    );

    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let figures = ["timeline", "map-a", "zoom-a", "map-b", "zoom-b", "spectrum"];
    check_page(&html, &figures);
    assert_mentions(
        &html,
        &[
            "command line",
            "--truth",
            "calib version",
            "Sessions",
            "151.1000",
        ],
    );

    let timeline = figure(&html, "timeline");
    assert_mentions(
        timeline,
        &[
            "time from log start (s)",
            "rotation (rev)",
            "a − b (°)",
            "#4",
        ],
    );
    let map = figure(&html, "map-a");
    assert_mentions(
        map,
        &[
            "reading of a (°)",
            "error (″)",
            "residual (″)",
            "truth − calibrated map",
        ],
    );
    // The map, the dashed truth and the residual.
    assert!(map.matches("<polyline").count() >= 3);
    let zoom = figure(&html, "zoom-a");
    assert_mentions(zoom, &["one period of order 8", "(0–45°)"]);
    let spectrum = figure(&html, "spectrum");
    assert_mentions(
        spectrum,
        &["amplitude (″)", "harmonic order (cycles per revolution)"],
    );
    // Two channels, one bar per order kept by the significance rule (the truth's 1, 2, 6, 8, 12
    // and 16, and the few others that stand above the noise in either sensor; measured 13 in
    // each), minus the orders below the floor. Before issue 16 every fitted order (84) showed.
    let bars = spectrum.matches("<rect").count();
    assert!((12..=40).contains(&bars), "{bars} bars");

    // The hidden manifest lists the set (see docs/integrity.md).
    let mut files: Vec<String> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n != ".calib-manifest")
        .collect();
    files.sort();
    let mut want: Vec<String> = figures
        .iter()
        .flat_map(|f| [format!("{f}.png"), format!("{f}.svg")])
        .collect();
    want.sort();
    assert_eq!(files, want);
    let png = std::fs::read(plots.join("map-a.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 10_000);
    let svg = std::fs::read_to_string(plots.join("map-a.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("error (″)"));
}

#[test]
fn shift_angle_report_shows_polygon_encoder_band_and_residuals() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = calib(&[
        "shift-angle",
        s(&testdata("shift-angle/readings.csv")),
        "-o",
        s(&out),
        "--budget",
        s(&testdata("shift-angle/table3.toml")),
    ]);
    expect_exit(&o, 0);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    check_page(
        &html,
        &[
            "map-encoder",
            "zoom-encoder",
            "spectrum",
            "polygon",
            "residuals",
        ],
    );
    assert_mentions(
        figure(&html, "map-encoder"),
        &[
            "expanded uncertainty U (k = 2.160, budget)",
            "U (″)",
            "<polygon",
        ],
    );
    let polygon = figure(&html, "polygon");
    assert_mentions(polygon, &["pitch deviation β (″)", "face"]);
    assert_eq!(polygon.matches("<rect").count() - 1, 24, "one bar per face");
    let residuals = figure(&html, "residuals");
    assert_eq!(
        residuals.matches("<circle").count() - 1,
        912,
        "one dot per reading"
    );
    // Blind orders 24, 48, 72, 96 are marked on the spectrum.
    assert_mentions(figure(&html, "spectrum"), &["blind order (left out)"]);
    assert_mentions(&html, &["ν_eff", "expanded uncertainty U (95 %)"]);
}

/// The seed paper's rig with its reference encoder: `csrr --ref` draws the maps against the
/// reference and the |Y_Ω| chart with the paper's 1 % and 100 % lines; `reference` draws the
/// DUT's map with its uncertainty band and lists the ISO 230-2 figures.
#[test]
fn reports_with_a_reference_encoder() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/csrr72.toml"), dir.path(), "c72.mcap");
    let out = dir.path().join("csrr");
    expect_exit(&calib(&["csrr", s(&log), "--ref", "ref", "-o", s(&out)]), 0);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    check_page(
        &html,
        &[
            "timeline",
            "map-a",
            "zoom-a",
            "map-b",
            "zoom-b",
            "spectrum",
            "effective-range",
        ],
    );
    let map = figure(&html, "map-b");
    assert_mentions(
        map,
        &[
            "reference measurement − calibrated map (mean per ",
            "° bin)",
            "±1 s of the samples in each bin",
            "residual (″)",
            "± expanded uncertainty U (k = 2)",
        ],
    );
    // Issue 31: the residual against the reference was drawn through every sample (a wall of
    // noise); it is one mean per bin of angle, 360 to 3600 of them.
    let lines = polylines(map);
    assert!(
        lines.iter().any(|&n| (360..=3600).contains(&n)),
        "no binned residual: {lines:?}"
    );
    let y = figure(&html, "effective-range");
    assert_mentions(
        y,
        &[
            "|Y_Ω| (1)",
            "order Ω (cycles per revolution)",
            "1 %",
            "100 %",
        ],
    );
    // One dot per order of ε_θ in the report (10), plus the legend's.
    assert_eq!(y.matches("<circle").count(), 11);

    let out = dir.path().join("reference");
    let o = reference(&log, "b", "ref", &out, &[]);
    expect_exit(&o, 0);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    check_page(&html, &["map-b", "zoom-b", "iso-b", "spectrum"]);
    assert_mentions(
        &html,
        &[
            "E bidirectional systematic positioning deviation",
            "R↑ unidirectional repeatability",
            "expanded uncertainty U (k = 2), u excludes the reference",
        ],
    );
}

/// Issue 31: `calib reference` draws ISO 230-2's chart (each direction's mean deviation and
/// ±2s at every target), lists the per-target statistics that were only in report.json, and
/// draws what the correction leaves in each direction against ±U.
#[test]
fn reference_report_has_the_iso_230_2_chart_and_targets() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/backlash.toml"), dir.path(), "b.mcap");
    let out = dir.path().join("out");
    expect_exit(&reference(&log, "dut", "ref", &out, &[]), 0);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    check_page(&html, &["map-dut", "directions-dut", "iso-dut"]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let targets = json["details"]["iso230_2_targets"]
        .as_array()
        .unwrap()
        .len();
    assert_eq!(targets, 20);

    let iso = figure(&html, "iso-dut");
    assert_mentions(
        iso,
        &[
            "positioning deviation (″)",
            "deviation − bidirectional mean (″)",
            "increasing ↑ mean deviation",
            "decreasing ↓ x̄ ± 2s",
            "<polygon",
        ],
    );
    // A dot per target and direction in each of the two panels; the legend draws no dots.
    assert_eq!(iso.matches("<circle").count(), 2 * 2 * targets);
    assert!(polylines(iso).iter().filter(|&&n| n == targets).count() >= 4);
    assert_eq!(
        table_rows(&html, "ISO 230-2 statistics per target"),
        targets,
        "one row per target"
    );
    assert_mentions(
        &html,
        &[
            "mean deviation x̄↑ (″)",
            "s↓ (″)",
            "reversal B = x̄↑ − x̄↓ (″)",
        ],
    );
    // Large figures also in degrees: E is about 830″.
    assert_mentions(&html, &["(0.23°)"]);

    let after = figure(&html, "directions-dut");
    assert_mentions(
        after,
        &[
            "after correction",
            "± expanded uncertainty U (k = 2)",
            "increasing",
            "decreasing",
            "<polygon",
        ],
    );
    assert_mentions(
        figure(&html, "map-dut"),
        &["U (″)", "expanded uncertainty U (k = 2), u excludes"],
    );
}

/// Issue 31: `calib tdr`'s report draws the coast (speed over time against the fitted motion)
/// and the fit's residual over time, the ±U band on the residual against the reference, and the
/// drag where it was separated.
#[test]
fn tdr_report_shows_the_coast_the_residual_and_the_drag() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(&testdata("scenarios/spindown.toml"), dir.path(), "s.mcap");
    let out = dir.path().join("out");
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--ref",
        "ref",
        "-o",
        s(&out),
    ]);
    expect_exit(&o, 0);
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    check_page(&html, &["coast", "map-enc", "zoom-enc", "spectrum"]);
    let coast = figure(&html, "coast");
    assert_mentions(
        coast,
        &[
            "time from the coast",
            "speed (r/min)",
            "fitted free motion",
            "fit residual (″)",
            "smallest to largest in each interval",
        ],
    );
    // One dot per interval of the coast (and the legend's), the fitted speed a smooth line.
    let dots = coast.matches("<circle").count() - 1;
    assert!((300..=400).contains(&dots), "{dots} intervals");
    let lines = polylines(coast);
    assert!(lines.contains(&601), "{lines:?}");
    assert!(
        lines.contains(&dots),
        "the residual's mean per interval: {lines:?}"
    );
    let map = figure(&html, "map-enc");
    assert_mentions(
        map,
        &[
            "enc − ref (reference) − calibrated map",
            "± expanded uncertainty U (k = 2)",
            "U (″)",
        ],
    );
    // The orders the map holds only: no zero rows under "largest".
    assert!(!html.contains("<td>0.0000</td>"));

    let log = simulate(
        &testdata("scenarios/spindown-drag.toml"),
        dir.path(),
        "d.mcap",
    );
    let out = dir.path().join("drag");
    expect_exit(
        &calib(&["tdr", s(&log), "--channel", "enc", "-o", s(&out)]),
        0,
    );
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let drag = figure(&html, "drag");
    assert_mentions(drag, &["deceleration (rad/s²)", "drag deceleration"]);
    assert!(polylines(drag).contains(&721));
}

/// A failed run writes no report.html either.
#[test]
fn a_failed_run_leaves_no_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = calib(&[
        "csrr",
        s(&testdata("examples/quick.mcap")),
        "-o",
        s(&out),
        "--truth",
        s(&dir.path().join("missing")),
    ]);
    expect_exit(&o, 1);
    assert!(!out.join("report.html").exists() && !out.join("report.json").exists());
}

/// Renders the report of every method (csrr, reference, tdr, multihead, shift-angle,
/// moteus-dump) in headless Chromium (`cargo test -p calib-cli --test it report_cli:: --
/// --ignored` on a machine with the `chromium` package) and checks that a screenshot of each came
/// out; with `CALIB_SHOTS=DIR` the screenshots are kept there (`<method>.png`) for a person to
/// look at.
#[test]
#[ignore = "needs chromium"]
fn renders_in_chromium() {
    let dir = tempfile::tempdir().unwrap();
    let shots = std::env::var_os("CALIB_SHOTS").map_or(dir.path().to_path_buf(), Into::into);
    std::fs::create_dir_all(&shots).unwrap();
    let csrr = dir.path().join("csrr");
    let o = calib(&["csrr", s(&testdata("examples/quick.mcap")), "-o", s(&csrr)]);
    expect_exit(&o, 0);
    let log = simulate(&testdata("scenarios/backlash.toml"), dir.path(), "b.mcap");
    let reference_out = dir.path().join("reference");
    expect_exit(&reference(&log, "dut", "ref", &reference_out, &[]), 0);
    let log = simulate(&testdata("scenarios/spindown.toml"), dir.path(), "s.mcap");
    let tdr = dir.path().join("tdr");
    let o = calib(&[
        "tdr",
        s(&log),
        "--channel",
        "enc",
        "--ref",
        "ref",
        "-o",
        s(&tdr),
    ]);
    expect_exit(&o, 0);
    let heads = dir.path().join("multihead");
    let log = common::multihead::selfa_log(dir.path());
    expect_exit(&common::multihead::multihead(&log, &heads, &[]), 0);
    let polygon = dir.path().join("shift-angle");
    let readings = testdata("shift-angle/readings.csv");
    expect_exit(&calib(&["shift-angle", s(&readings), "-o", s(&polygon)]), 0);
    let dump = dir.path().join("moteus-dump");
    let o = calib(&[
        "moteus-dump",
        s(&testdata("moteus/dump.txt")),
        "-o",
        s(&dump),
    ]);
    expect_exit(&o, 0);
    for (name, out) in [
        ("csrr", csrr),
        ("reference", reference_out),
        ("tdr", tdr),
        ("multihead", heads),
        ("shift-angle", polygon),
        ("moteus-dump", dump),
    ] {
        let shot = shots.join(format!("{name}.png"));
        let status = std::process::Command::new("chromium")
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--disable-background-networking",
                &format!("--user-data-dir={}", dir.path().join("profile").display()),
                &format!("--screenshot={}", shot.display()),
                "--window-size=1300,6000",
            ])
            .arg(format!("file://{}", out.join("report.html").display()))
            .status()
            .expect("chromium is not installed");
        assert!(status.success());
        let png = std::fs::read(Path::new(&shot)).unwrap();
        assert!(
            png.starts_with(b"\x89PNG") && png.len() > 50_000,
            "{name}: {} bytes",
            png.len()
        );
    }
}

/// A commanded reference's motor ripple is a figure of the run, taken out of the map and out of
/// each direction's passes: report.html shows it (issue 31: every figure visible), term by term as
/// report.json holds it. The bundled
/// dump was made with a ripple of 540″ at order 126 (21 pole pairs × k = 6); its fit holds it to
/// its u of 0.36″, so within 1″ (about 3u).
#[test]
fn a_commanded_references_ripple_is_shown_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dump");
    let dump = testdata("moteus/dump.txt");
    expect_exit(&calib(&["moteus-dump", s(&dump), "-o", s(&out), "-q"]), 0);
    let report = common::json::read_json(&out.join("report.json"));
    let terms = report["details"]["ripple"]["terms"].as_array().unwrap();
    let at_126 = terms.iter().find(|t| t["order"] == 126).unwrap();
    let amplitude = at_126["amplitude_arcsec"].as_f64().unwrap();
    assert!((amplitude - 540.0).abs() < 1.0, "{amplitude}″");
    // The ripple is out of each direction's passes too, so the ISO 230-2 figures are the
    // encoder's: E, from the targets' directional means, lies within the map's peak-to-peak
    // (the reversal is nil here) where it was 3099″ with the ripple left in, against 2193″.
    let e = report["details"]["iso230_2"]["systematic_arcsec"]
        .as_f64()
        .unwrap();
    let pp = report["channels"]["encoder"]["peak_to_peak_arcsec"]
        .as_f64()
        .unwrap();
    assert!(e <= pp, "E {e}″ against the map's {pp}″");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("Motor ripple taken out"));
    for term in terms {
        let shown = format!("{:.3}", term["amplitude_arcsec"].as_f64().unwrap());
        assert!(html.contains(&shown), "order {}: {shown}″", term["order"]);
    }
}

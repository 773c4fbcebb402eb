//! The JSON Schemas (2020-12) of calib's JSON outputs, generated from their types and published
//! in the repository's `docs/`: `report.schema.json` ([`calib_core::Report`]),
//! `summary.schema.json` ([`crate::batch::Summary`]), `inspect.schema.json`
//! ([`crate::commands::inspect::InspectJson`]), and the `--json` of `simulate`, `export`, `import`,
//! `apply` and `compose` (`<command>.schema.json`, the types in [`crate::json`]).
//!
//! The published files are checked here against the types: a change of an output's shape fails
//! the test until the files are regenerated (and the change recorded in CHANGELOG.md,
//! with `SCHEMA_VERSION` raised where a key was removed, renamed or changed its meaning).

use schemars::{Schema, schema_for};
use std::path::PathBuf;

/// The command that rewrites the published schemas from the types.
const REGENERATE: &str = "CALIB_WRITE_SCHEMAS=1 cargo test -p calib-cli --bin calib schema";

/// `(file name under docs/, schema)` of every published schema.
fn schemas() -> Vec<(&'static str, Schema)> {
    vec![
        ("report.schema.json", schema_for!(calib_core::Report)),
        ("summary.schema.json", schema_for!(crate::batch::Summary)),
        (
            "inspect.schema.json",
            schema_for!(crate::commands::inspect::InspectJson),
        ),
        ("export.schema.json", schema_for!(crate::json::ExportJson)),
        ("apply.schema.json", schema_for!(crate::json::ApplyJson)),
        ("compose.schema.json", schema_for!(crate::json::ComposeJson)),
        (
            "simulate.schema.json",
            schema_for!(crate::json::SimulateJson),
        ),
        ("import.schema.json", schema_for!(crate::json::ImportJson)),
    ]
}

/// The schema as published: pretty-printed JSON with a final newline.
fn render(schema: &Schema) -> String {
    serde_json::to_string_pretty(schema).expect("a schema serializes") + "\n"
}

fn docs() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs")
}

#[test]
fn published_schemas_match_the_types() {
    let write = std::env::var_os("CALIB_WRITE_SCHEMAS").is_some();
    let mut stale = Vec::new();
    for (name, schema) in schemas() {
        let path = docs().join(name);
        let want = render(&schema);
        if write {
            std::fs::write(&path, &want).unwrap();
        } else if std::fs::read_to_string(&path).ok().as_deref() != Some(want.as_str()) {
            stale.push(name);
        }
    }
    assert!(
        stale.is_empty(),
        "docs/{} differ from the types they describe: regenerate them with `{REGENERATE}`, \
         review the diff and record the change in CHANGELOG.md",
        stale.join(", docs/")
    );
}

#[test]
fn schemas_are_2020_12_and_name_every_method() {
    for (name, schema) in schemas() {
        assert_eq!(
            schema.get("$schema").and_then(|v| v.as_str()),
            Some("https://json-schema.org/draft/2020-12/schema"),
            "{name}"
        );
    }
    let report = render(&schema_for!(calib_core::Report));
    for details in [
        "CsrrDetails",
        "MultiheadDetails",
        "TdrDetails",
        "ReferenceDetails",
        "ShiftAngleDetails",
    ] {
        assert!(report.contains(details), "{details}");
    }
}

//! The README's commands (and the CI page's, `docs/ci.md`), run as a reader runs them, and their
//! output compared with what the page shows (issue 31): every code block's `$ ` lines run in
//! order in one working folder (the repository's `testdata` linked into it, the `calib` under
//! test first on the `PATH`),
//! each command's standard output and error together against the lines that follow it. A line
//! `…` in the README stands for any number of lines; a command followed by nothing (the README
//! shows a step, not its output) must succeed. A block that starts `#!/usr/bin/env bash` then
//! `# NAME …` is a script the README asks to save: it is written as `NAME`, executable.

use std::path::Path;
use std::process::Command;

/// One command of the README and the output it shows.
struct Step {
    command: String,
    shown: Vec<String>,
}

/// The README's code blocks, in order.
fn blocks(text: &str) -> Vec<Vec<&str>> {
    let mut out = Vec::new();
    let mut block: Option<Vec<&str>> = None;
    for line in text.lines() {
        match (&mut block, line.starts_with("```")) {
            (None, true) => block = Some(Vec::new()),
            (Some(_), true) => out.push(block.take().unwrap()),
            (Some(b), false) => b.push(line),
            (None, false) => {}
        }
    }
    out
}

/// Whether `shown` (with `…` for any lines) matches `got`, line by line.
fn matches(shown: &[String], got: &[&str]) -> bool {
    match shown.split_first() {
        None => got.is_empty(),
        Some((first, rest)) if first.trim() == "…" => {
            (0..=got.len()).any(|skip| matches(rest, &got[skip..]))
        }
        Some((first, rest)) => got
            .split_first()
            .is_some_and(|(g, more)| g.trim_end() == first.trim_end() && matches(rest, more)),
    }
}

#[test]
fn readme_commands_print_what_the_readme_shows() {
    run_the_commands_of("README.md", 19);
}

/// The CI page's lab example, moved out of the README (issue 31), is checked the same way.
#[test]
fn ci_page_commands_print_what_the_page_shows() {
    run_the_commands_of("docs/ci.md", 7);
}

/// Runs every `$ ` command of the page `file` (relative to the repository) in order in one
/// fresh folder and compares its output with the page's; at least `fewest` commands.
fn run_the_commands_of(file: &str, fewest: usize) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let readme = std::fs::read_to_string(repo.join(file)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    std::os::unix::fs::symlink(
        repo.join("testdata").canonicalize().unwrap(),
        work.join("testdata"),
    )
    .unwrap();
    let bin = Path::new(env!("CARGO_BIN_EXE_calib")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut steps = Vec::new();
    for block in blocks(&readme) {
        if block.first() == Some(&"#!/usr/bin/env bash") {
            if let Some(name) = block.get(1).and_then(|l| l.strip_prefix("# ")) {
                let name = name.split_whitespace().next().unwrap();
                let file = work.join(name);
                std::fs::write(&file, block.join("\n") + "\n").unwrap();
                use std::os::unix::fs::PermissionsExt;
                std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o755)).unwrap();
            }
            continue;
        }
        for line in block {
            match line.strip_prefix("$ ") {
                Some(command) => steps.push(Step {
                    command: command.to_string(),
                    shown: Vec::new(),
                }),
                None => {
                    if let Some(step) = steps.last_mut() {
                        step.shown.push(line.to_string());
                    }
                }
            }
        }
        // A block's last command shows only what follows it in that block.
        steps.push(Step {
            command: String::new(),
            shown: Vec::new(),
        });
    }
    let mut ran = 0;
    for step in steps.iter().filter(|s| !s.command.is_empty()) {
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!("exec 2>&1; {}", step.command))
            .current_dir(work)
            .env("PATH", &path)
            .output()
            .unwrap();
        let got = String::from_utf8_lossy(&o.stdout);
        ran += 1;
        if step.shown.is_empty() {
            assert!(o.status.success(), "`{}` failed:\n{got}", step.command);
            continue;
        }
        let got: Vec<&str> = got.lines().collect();
        assert!(
            matches(&step.shown, &got),
            "`{}` printed\n{}\nbut {file} shows\n{}",
            step.command,
            got.join("\n"),
            step.shown.join("\n")
        );
    }
    assert!(ran >= fewest, "only {ran} commands found in {file}");
}

#[test]
fn ellipses_stand_for_any_lines() {
    let shown = |s: &[&str]| s.iter().map(|l| l.to_string()).collect::<Vec<_>>();
    assert!(matches(&shown(&["a", "…", "d"]), &["a", "b", "c", "d"]));
    assert!(matches(&shown(&["a", "…"]), &["a"]));
    assert!(!matches(&shown(&["a", "d"]), &["a", "b", "d"]));
    assert!(!matches(&shown(&["a"]), &["a", "b"]));
}

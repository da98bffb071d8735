//! The end of `cargo test --workspace`: checks that xtask/src/slow.rs lists exactly the tests
//! that call the slow gate (tests/support/slow.rs) and that nothing runs after this program
//! (cargo runs xtask's tests last, the packages in order of name, and doc-tests after all test
//! programs: the workspace has none, each library says `doctest = false`); then names the
//! command of the slow tests, which this run skipped. Its own `main` (`harness = false`), so that
//! what it prints reaches the terminal.

#[path = "../src/slow.rs"]
mod slow;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

fn main() -> ExitCode {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask/ is inside the repository").to_path_buf();
    let mut problems = suite_problems(&root);
    problems.extend(doc_test_problems(&root));
    if !problems.is_empty() {
        for p in &problems {
            eprintln!("slow_suite: {p}");
        }
        eprintln!("test slow_suite ... FAILED");
        return ExitCode::FAILURE;
    }
    let tests: usize = slow::SUITE.iter().map(|t| t.tests.len().max(1)).sum();
    println!("test slow_suite ... ok");
    if slow::gate::enabled() {
        println!("\nThe slow tests ran too ({}=1).", slow::VAR);
    } else {
        let names: Vec<&str> = slow::SUITE.iter().map(|t| t.target).collect();
        println!(
            "\n{tests} slow tests ({}) were skipped, each saying so above: \
             run them with `cargo xtask slow`; all of CI with `cargo xtask ci`.",
            names.join(", ")
        );
    }
    ExitCode::SUCCESS
}

/// Where xtask/src/slow.rs and the callers of `slow::skip()` disagree, one line each.
fn suite_problems(root: &Path) -> Vec<String> {
    let mut found = BTreeSet::new();
    for file in rust_files(root) {
        let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("reading {}: {e}", file.display()));
        let rel = file.strip_prefix(root).expect("under the root").to_string_lossy().replace('\\', "/");
        if rel.starts_with("xtask/") || rel == "tests/support/slow.rs" {
            continue;
        }
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.contains("slow::skip()") {
                // The function the call is in: the nearest `fn NAME` above it.
                let name = lines[..=i].iter().rev().find_map(|l| fn_name(l)).unwrap_or_else(|| "?".to_owned());
                found.insert((rel.clone(), name));
            }
        }
    }
    let listed: BTreeSet<(String, String)> = slow::SUITE
        .iter()
        .flat_map(|t| {
            let names: Vec<String> =
                if t.tests.is_empty() { vec!["main".to_owned()] } else { t.tests.iter().map(|s| (*s).to_owned()).collect() };
            names.into_iter().map(|n| (t.file.to_owned(), n))
        })
        .collect();
    let mut out = Vec::new();
    for (file, name) in found.difference(&listed) {
        out.push(format!(
            "{file}: `{name}` calls slow::skip() but xtask/src/slow.rs does not list it: `cargo xtask slow` would never run it"
        ));
    }
    for (file, name) in listed.difference(&found) {
        out.push(format!("xtask/src/slow.rs lists `{name}` of {file}, which does not call slow::skip(): `cargo test --workspace` runs it"));
    }
    out
}

/// `fn NAME` or `async fn NAME` at the start of `line` (after `pub` and indentation): NAME.
fn fn_name(line: &str) -> Option<String> {
    let l = line.trim_start().trim_start_matches("pub ").trim_start_matches("async ");
    let rest = l.strip_prefix("fn ")?;
    Some(rest.split(|c: char| !(c.is_alphanumeric() || c == '_')).next()?.to_owned())
}

/// The Rust files of the workspace's tests and sources, target/ and hidden folders left out.
fn rust_files(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("listing {}: {e}", dir.display()));
        for entry in entries {
            let path = entry.expect("a directory entry").path();
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            if path.is_dir() {
                if !name.starts_with('.') && name != "target" && name != "runs" {
                    stack.push(path);
                }
            } else if name.ends_with(".rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The workspace's libraries whose doc-tests cargo would run after this program, one line each.
fn doc_test_problems(root: &Path) -> Vec<String> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .current_dir(root)
        .args(["metadata", "--no-deps", "--offline", "--format-version", "1"])
        .output()
        .expect("running cargo metadata");
    if !out.status.success() {
        return vec![format!("cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr))];
    }
    let json = String::from_utf8_lossy(&out.stdout);
    // Each target is an object with "name", ..., "doctest": bool; a flat scan is enough here.
    let mut problems = Vec::new();
    for target in json.split("{\"kind\":").skip(1) {
        if target.contains("\"doctest\":true") {
            let name = target.split("\"name\":\"").nth(1).and_then(|s| s.split('"').next()).unwrap_or("?");
            problems.push(format!(
                "the library `{name}` has doc-tests on, which cargo runs after this notice: \
                 set `doctest = false` in its [lib] (the workspace has no doc-tests) or end the run another way"
            ));
        }
    }
    problems
}

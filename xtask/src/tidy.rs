//! The tidy test (rust-analyzer's xtask/src/tidy.rs): rules of the sources that no compiler
//! checks, run by `cargo test --workspace`. Every Rust file opens with a `//!` line saying what it
//! holds (ARCHITECTURE.md need not list the files), no test expects a panic (a bounds check
//! returns a typed error that a test can match), and `cargo xtask slow` runs every slow test.

use std::path::Path;
use std::process::Command;

use crate::slow;

/// The attribute no file may hold, spelt in two halves so that this file does not hold it.
const SHOULD_PANIC: &str = concat!("#[should", "_panic");

/// What is wrong with the file `rel` (from the repository's root) holding `text`, one line each.
fn file_problems(rel: &str, text: &str) -> Vec<String> {
    let mut out = Vec::new();
    if !text.starts_with("//!") {
        out.push(format!("{rel}: does not open with a `//!` line saying what the file holds"));
    }
    if let Some(line) = text.lines().position(|l| l.contains(SHOULD_PANIC)) {
        out.push(format!("{rel}:{}: {SHOULD_PANIC}]: make the check return an error and test the error", line + 1));
    }
    out
}

/// Where the slow suite (xtask/src/slow.rs) and the files that call the gate disagree.
fn slow_problems(gated: &[String]) -> Vec<String> {
    let listed: Vec<&str> = slow::SUITE.iter().map(|t| t.file).collect();
    let unlisted = gated.iter().filter(|f| !listed.contains(&f.as_str()));
    let ungated = listed.iter().filter(|f| !gated.iter().any(|g| g == *f));
    unlisted
        .map(|f| format!("{f}: calls slow::skip() but xtask/src/slow.rs does not list it: `cargo xtask slow` would never run it"))
        .chain(ungated.map(|f| format!("xtask/src/slow.rs lists {f}, which does not call slow::skip()")))
        .collect()
}

/// The repository's Rust files, tracked or new (not ignored), from its root; `None` without git.
fn rust_files(root: &Path) -> Option<Vec<String>> {
    let out = Command::new("git")
        .current_dir(root)
        .args(["ls-files", "--cached", "--others", "--exclude-standard", "--", "*.rs"])
        .output()
        .ok()
        .filter(|o| o.status.success())?;
    Some(String::from_utf8_lossy(&out.stdout).lines().filter(|f| root.join(f).is_file()).map(str::to_owned).collect())
}

#[test]
fn tidy() {
    let root = crate::project_root();
    let Some(files) = rust_files(&root) else {
        eprintln!("tidy: skipped (not a git checkout, or no git)");
        return;
    };
    let (mut problems, mut gated) = (Vec::new(), Vec::new());
    for rel in &files {
        let text = std::fs::read_to_string(root.join(rel)).unwrap_or_else(|e| panic!("reading {rel}: {e}"));
        problems.extend(file_problems(rel, &text));
        if text.contains("slow::skip()") && !rel.starts_with("xtask/") && rel != "tests/support/slow.rs" {
            gated.push(rel.clone());
        }
    }
    problems.extend(slow_problems(&gated));
    assert!(problems.is_empty(), "tidy:\n{}", problems.join("\n"));
}

#[test]
fn tidy_names_a_file_without_its_summary_and_an_expected_panic() {
    assert!(file_problems("a.rs", "//! A.\nfn f() {}\n").is_empty());
    assert_eq!(file_problems("b.rs", "fn f() {}\n//! late\n").len(), 1);
    let p = file_problems("c.rs", &format!("//! C.\n#[test]\n{SHOULD_PANIC}]\nfn t() {{}}\n"));
    assert_eq!(p, [format!("c.rs:3: {SHOULD_PANIC}]: make the check return an error and test the error")]);
    let listed: Vec<String> = slow::SUITE.iter().map(|t| t.file.to_owned()).collect();
    assert_eq!(slow_problems(&listed), Vec::<String>::new());
    assert_eq!(slow_problems(&[listed.clone(), vec!["x.rs".to_owned()]].concat()).len(), 1);
    assert_eq!(slow_problems(&listed[1..]).len(), 1);
}

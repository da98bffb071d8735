//! The crate graph's "must never depend on" rules of ARCHITECTURE.md, checked against what Cargo
//! resolves (`cargo tree -e normal`, the crates a package's own build links, with its default
//! features) and, for the one allowed edge from the actor to the learner, against the sources.

use std::path::Path;
use std::process::Command;

/// The packages `package` links (normal dependencies, transitively), by name.
fn normal_dependencies(package: &str) -> Vec<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let tree = || {
        Command::new(env!("CARGO"))
            .current_dir(&root)
            .args(["tree", "--offline", "--locked", "-e", "normal", "--prefix", "none", "--format", "{p}", "-p", package])
            .output()
            .expect("running cargo tree")
    };
    let mut out = tree();
    if !out.status.success() {
        // `cargo tree` resolves the whole workspace: in a fresh checkout the crates that no
        // built target needed yet (the python binding's) are not downloaded. Fetch them once.
        let fetched = Command::new(env!("CARGO")).current_dir(&root).args(["fetch", "--locked"]).status().expect("running cargo fetch");
        assert!(fetched.success(), "cargo fetch --locked failed: cargo tree -p {package}: {}", String::from_utf8_lossy(&out.stderr));
        out = tree();
    }
    assert!(out.status.success(), "cargo tree -p {package}: {}", String::from_utf8_lossy(&out.stderr));
    let mut names: Vec<String> =
        String::from_utf8_lossy(&out.stdout).lines().filter_map(|l| l.split_whitespace().next()).map(str::to_owned).collect();
    names.sort();
    names.dedup();
    names
}

/// Fails naming every forbidden crate `package` links.
fn assert_never(package: &str, forbidden: &[&str]) {
    let deps = normal_dependencies(package);
    let found: Vec<&&str> = forbidden.iter().filter(|f| deps.iter().any(|d| d == **f)).collect();
    assert!(found.is_empty(), "{package} must never depend on {found:?} (ARCHITECTURE.md, \"Crates and their edges\")");
}

#[test]
fn sim_core_is_pure() {
    assert_never("sim-core", &["tokio", "tonic", "prost", "candle-core", "plotters", "gemm", "proto", "agent", "learner", "actor"]);
}

#[test]
fn proto_knows_only_the_wire() {
    assert_never("proto", &["sim-core", "agent", "learner", "actor", "candle-core", "plotters"]);
}

#[test]
fn agent_has_no_runtime_network_tensor_library_or_plotting() {
    assert_never("agent", &["tokio", "tonic", "prost", "candle-core", "candle-nn", "plotters", "proto", "learner", "actor"]);
}

#[test]
fn the_learner_service_has_no_tools_plotting_or_candle() {
    assert_never("learner", &["actor", "learner-cli", "tonic-reflection", "plotters", "candle-core", "candle-nn", "rcgen", "clap"]);
}

#[test]
fn the_actor_links_no_learner_tools_reflection_plotting_or_candle() {
    assert_never("actor", &["learner-cli", "tonic-reflection", "plotters", "candle-core", "candle-nn"]);
}

/// Every `.rs` file under `actor/src/DIR`, with its text.
fn actor_sources(dir: &str) -> Vec<(String, String)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    let mut stack = vec![src.join(dir)];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push((path.strip_prefix(&src).unwrap().display().to_string(), std::fs::read_to_string(&path).unwrap()));
            }
        }
    }
    files.sort();
    files
}

#[test]
fn only_actor_train_uses_the_learner() {
    let users: Vec<String> = actor_sources("").into_iter().filter(|(_, text)| text.contains("learner::")).map(|(path, _)| path).collect();
    assert!(!users.is_empty(), "actor/src/runner/ starts a learner in process: a test that sees no user sees nothing");
    let outside: Vec<&String> = users.iter().filter(|p| !p.starts_with("runner/")).collect();
    assert!(outside.is_empty(), "only actor/src/runner/ (`actor train`) may use the learner crate (ARCHITECTURE.md): {outside:?}");
}

#[test]
fn the_sampling_worker_uses_no_learner_code() {
    let sampling = actor_sources("sampling");
    assert!(
        sampling.len() >= 4,
        "actor/src/sampling/ holds the worker `actor --learner` runs: {sampling:?}",
        sampling = sampling.iter().map(|(p, _)| p).collect::<Vec<_>>()
    );
    for (path, text) in &sampling {
        for forbidden in ["learner::", "crate::runner", "crate::eval", "crate::tools"] {
            assert!(
                !text.contains(forbidden),
                "actor/src/{path} uses `{forbidden}`: the sampling worker needs only sim-core, agent and proto (ARCHITECTURE.md)"
            );
        }
    }
}

#[test]
fn the_python_binding_is_the_simulator_alone() {
    assert_never("python", &["tokio", "tonic", "prost", "candle-core", "plotters", "proto", "agent", "learner", "actor"]);
}

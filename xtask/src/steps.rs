//! CI's steps, one function each, as .ci/run ran them before it called `cargo xtask ci`: the same
//! commands, flags (`--locked`), virtual environments, timeouts and skips.

use std::path::{Path, PathBuf};

use anyhow::Result;

use crate::cmd::Cmd;
use crate::slow;

/// `cargo fmt --all -- --check`.
pub fn fmt(root: &Path) -> Result<()> {
    Ok(cargo(root).args(["fmt", "--all", "--", "--check"]).run()?)
}

/// `cargo clippy --workspace --all-targets --locked -- -D warnings`.
pub fn clippy(root: &Path) -> Result<()> {
    Ok(cargo(root).args(["clippy", "--workspace", "--all-targets", "--locked", "--", "-D", "warnings"]).run()?)
}

/// `cargo test --workspace --locked`: README's test command, the slow tests skipped.
pub fn test(root: &Path) -> Result<()> {
    Ok(cargo(root).args(["test", "--workspace", "--locked"]).run()?)
}

/// The slow tests alone (xtask/src/slow.rs), with HD_SLOW_TESTS=1: one `cargo test` per test
/// target that holds some, filtered to those tests where the target holds fast ones too.
pub fn slow(root: &Path) -> Result<()> {
    for t in slow::SUITE {
        let mut args = vec!["test", "--locked", "--package", t.package, "--test", t.target];
        if !t.tests.is_empty() {
            args.push("--");
            args.extend(t.tests);
            args.push("--exact");
        }
        cargo(root).args(&args).env(slow::VAR, "1").run()?;
    }
    Ok(())
}

/// The instruction counts of the hot paths against benches/icount-baseline.json
/// (scripts/bench-check.sh, callgrind; +3 % fails), valgrind installed first where it lacks.
pub fn bench_check(root: &Path) -> Result<()> {
    if !Cmd::new(root, "valgrind").args(["--version"]).succeeds() {
        let root_user = Cmd::new(root, "id").args(["-u"]).output().is_some_and(|u| u.trim() == "0");
        let apt = |args: &[&str]| {
            if root_user { Cmd::new(root, "apt-get").args(args) } else { Cmd::new(root, "sudo").args(["apt-get"]).args(args) }
        };
        apt(&["update", "-qq"]).run()?;
        apt(&["install", "-y", "-qq", "valgrind"]).run()?;
    }
    Ok(Cmd::new(root, "bash").args(["scripts/bench-check.sh"]).run()?)
}

/// The Python binding built and installed as a user would (`pip install ./python`, maturin
/// building the crate in release with --locked), its type stub checked against the built module
/// (`mypy.stubtest hybrid_drive._core`: the stub follows python/src/config.rs's signatures), then
/// its pytest suite. The venv lives in target/python-venv and is reused; pip fetches what it lacks
/// from PyPI.
pub fn python(root: &Path) -> Result<()> {
    let venv = root.join("target/python-venv");
    if !venv.join("bin/python").is_file() {
        Cmd::new(root, "python3").args(["-m", "venv"]).args([&venv]).run()?;
    }
    let (pip, python) = (venv.join("bin/pip"), venv.join("bin/python"));
    Cmd::new(root, &pip)
        .args(["install", "--quiet", "--disable-pip-version-check", "maturin>=1.9.4,<2", "gymnasium>=1.0", "numpy", "pytest", "mypy"])
        .run()?;
    // Built with the maturin just installed (its PEP 517 hook runs `maturin` from PATH).
    Cmd::new(root, &pip)
        .args(["install", "--quiet", "--disable-pip-version-check", "--no-build-isolation", "--force-reinstall", "--no-deps", "./python"])
        .env("PATH", path_with(&venv.join("bin"))?)
        .run()?;
    Cmd::new(root, &python).args(["-m", "mypy.stubtest", "hybrid_drive._core"]).run()?;
    Ok(Cmd::new(root, &python).args(["-m", "pytest", "-q", "python/tests"]).run()?)
}

/// tests/interop: third-party tools (a stock reflection client, TensorBoard's reader, NumPy,
/// Grafana/Prometheus files) play the user against the debug binaries, from a venv with the
/// pinned packages of tests/interop/requirements.txt (made again only when that file changes).
pub fn interop(root: &Path) -> Result<()> {
    cargo(root).args(["build", "--workspace", "--locked", "--bins"]).run()?;
    let target = target_dir(root);
    let venv = target.join("interop-venv");
    let requirements = root.join("tests/interop/requirements.txt");
    let kept = venv.join("requirements.txt");
    let current = std::fs::read(&requirements).map_err(|e| anyhow::anyhow!("reading {}: {e}", requirements.display()))?;
    if std::fs::read(&kept).ok().as_deref() != Some(current.as_slice()) {
        if venv.exists() {
            std::fs::remove_dir_all(&venv).map_err(|e| anyhow::anyhow!("removing the stale {}: {e}", venv.display()))?;
        }
        Cmd::new(root, "python3").args(["-m", "venv"]).args([&venv]).run()?;
        Cmd::new(root, venv.join("bin/pip"))
            .args(["install", "--quiet", "--disable-pip-version-check", "-r", "tests/interop/requirements.txt"])
            .run()?;
        std::fs::copy(&requirements, &kept)
            .map_err(|e| anyhow::anyhow!("copying {} to {}: {e}", requirements.display(), kept.display()))?;
    }
    Ok(Cmd::new(root, venv.join("bin/python"))
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/interop"])
        .env("HD_BIN_DIR", target.join("debug"))
        .run()?)
}

/// deploy/validate-k8s.sh: the Kubernetes manifests against the API schemas, their structure,
/// the run configuration.
pub fn k8s(root: &Path) -> Result<()> {
    Ok(Cmd::new(root, "bash").args(["deploy/validate-k8s.sh"]).run()?)
}

/// deploy/test-compose.sh (compose, 3 actors, kill, learner restart, network cut), bounded to 30
/// minutes: a cold release build (7-18 min on 2 cores) and the image, then its faults (~3 min).
/// Skipped, saying why, when no Docker engine answers `docker info`.
pub fn compose(root: &Path) -> Result<()> {
    if !Cmd::new(root, "docker").args(["info"]).succeeds() {
        eprintln!("containers: skipped (no Docker engine reachable: `docker info` failed)");
        return Ok(());
    }
    Ok(Cmd::new(root, "timeout").args(["--kill-after=60", "1800", "bash", "deploy/test-compose.sh"]).run()?)
}

/// Cargo as the one running xtask (`$CARGO`), else `cargo` from PATH.
fn cargo(root: &Path) -> Cmd {
    Cmd::new(root, std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into())).shown_as("cargo")
}

/// `$CARGO_TARGET_DIR`, else target/ in the repository.
fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), |d| root.join(d))
}

/// PATH with `dir` in front.
fn path_with(dir: &Path) -> Result<std::ffi::OsString> {
    let rest = std::env::var_os("PATH").unwrap_or_default();
    Ok(std::env::join_paths(std::iter::once(dir.to_path_buf()).chain(std::env::split_paths(&rest)))?)
}

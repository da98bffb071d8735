//! `cargo xtask STEP`: CI's steps, each one alone, or all of them in CI's order (`ci`, what
//! .ci/run runs after its toolchain check). rust-analyzer's pattern: a workspace member with no
//! dependency on the project, run through the alias in .cargo/config.toml.

mod cmd;
mod slow;
mod steps;
#[cfg(test)]
mod tidy;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// The project's task runner: CI's steps, each alone, or all of them in order (`cargo xtask ci`,
/// which .ci/run runs). A failing step stops `ci` with the step's name and exit status.
#[derive(Debug, Parser)]
#[command(name = "xtask", bin_name = "cargo xtask")]
struct Cli {
    #[command(subcommand)]
    step: Step,
}

/// One step of CI (in CI's order), or `ci`: all of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Subcommand)]
enum Step {
    /// Formatting: `cargo fmt --all -- --check`.
    Fmt,
    /// Lints: `cargo clippy --workspace --all-targets --locked -- -D warnings`.
    Clippy,
    /// The fast tests, README's command: `cargo test --workspace --locked` (slow tests skipped).
    Test,
    /// The slow tests alone (those xtask/src/slow.rs lists): `cargo test` of each with HD_SLOW_TESTS=1.
    Slow,
    /// Instruction counts of the hot paths (scripts/bench-check.sh; installs valgrind if missing).
    BenchCheck,
    /// The Python binding: `pip install ./python` into target/python-venv, mypy's stubtest of its
    /// type stub, then pytest python/tests.
    Python,
    /// tests/interop: third-party tools against the debug binaries (venv under target/).
    Interop,
    /// The Kubernetes manifests: deploy/validate-k8s.sh.
    K8s,
    /// The containers end to end: deploy/test-compose.sh (skipped without a Docker engine).
    Compose,
    /// All of the above, in this order: what CI runs.
    Ci,
}

/// CI's steps in CI's order.
const CI: [Step; 9] =
    [Step::Fmt, Step::Clippy, Step::Test, Step::Slow, Step::BenchCheck, Step::Python, Step::Interop, Step::K8s, Step::Compose];

impl Step {
    /// Its name on the command line.
    fn name(self) -> &'static str {
        match self {
            Step::Fmt => "fmt",
            Step::Clippy => "clippy",
            Step::Test => "test",
            Step::Slow => "slow",
            Step::BenchCheck => "bench-check",
            Step::Python => "python",
            Step::Interop => "interop",
            Step::K8s => "k8s",
            Step::Compose => "compose",
            Step::Ci => "ci",
        }
    }

    fn run(self, root: &Path) -> anyhow::Result<()> {
        match self {
            Step::Fmt => steps::fmt(root),
            Step::Clippy => steps::clippy(root),
            Step::Test => steps::test(root),
            Step::Slow => steps::slow(root),
            Step::BenchCheck => steps::bench_check(root),
            Step::Python => steps::python(root),
            Step::Interop => steps::interop(root),
            Step::K8s => steps::k8s(root),
            Step::Compose => steps::compose(root),
            Step::Ci => unreachable!("`ci` is the list of the steps, not one of them"),
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let root = project_root();
    let steps: &[Step] = if cli.step == Step::Ci { &CI } else { std::slice::from_ref(&cli.step) };
    for &step in steps {
        eprintln!("\n==> {}", step.name());
        if let Err(e) = step.run(&root) {
            let code = e.downcast_ref::<cmd::Failed>().and_then(|f| f.code).filter(|&c| c != 0).unwrap_or(1);
            eprintln!("\nxtask: step `{}` failed (exit status {code}): {e:#}", step.name());
            return ExitCode::from(u8::try_from(code).unwrap_or(1));
        }
    }
    if cli.step == Step::Ci {
        eprintln!("\nxtask: all {} steps of CI passed", CI.len());
    }
    ExitCode::SUCCESS
}

/// The repository's root: the folder above xtask/.
fn project_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("xtask/ is inside the repository").to_path_buf()
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn every_step_is_a_subcommand_named_as_ci_calls_it_and_ci_runs_each_once() {
        let cli = Cli::command();
        let names: Vec<&str> = cli.get_subcommands().map(|s| s.get_name()).collect();
        let ci: Vec<&str> = CI.iter().map(|s| s.name()).collect();
        assert_eq!(names[..names.len() - 1], ci[..], "the subcommands, in CI's order, then `ci`");
        assert_eq!(names.last(), Some(&"ci"));
        for s in CI {
            assert_eq!(Cli::try_parse_from(["xtask", s.name()]).map(|c| c.step).ok(), Some(s), "`{}` parses to itself", s.name());
        }
    }

    #[test]
    fn ci_run_calls_the_runner_after_its_toolchain_check_only() {
        let script = std::fs::read_to_string(project_root().join(".ci/run")).expect("reading .ci/run");
        let commands: Vec<&str> =
            script.lines().map(str::trim).filter(|l| l.starts_with("cargo ") && !l.starts_with("cargo --version")).collect();
        assert_eq!(commands, ["cargo xtask ci"], ".ci/run runs CI's steps through `cargo xtask ci` only");
    }
}

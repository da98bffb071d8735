#!/usr/bin/env bash
# Instruction-count check of the hot paths (docs/PERFORMANCE.md, "Instruction counts"): builds the
# two harnesses in release, counts each bench under valgrind's callgrind and compares the counts
# with benches/icount-baseline.json; fails when one grew by more than 3 %.
#   scripts/bench-check.sh                 check (prints a table)
#   scripts/bench-check.sh --update        write the counts into the baseline (commit it, saying why)
#   scripts/bench-check.sh --only BENCH    one bench (repeatable)
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v valgrind >/dev/null; then
  echo "bench-check: valgrind is not installed (Debian: apt-get install valgrind)" >&2
  exit 2
fi
cargo build --release --locked --quiet -p sim-core --example icount_sim
# Without the learner's default features: the harness needs none of them (no candle to build).
cargo build --release --locked --quiet -p learner --example icount_learner
target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
exec python3 scripts/bench_check.py --baseline benches/icount-baseline.json "$@" \
  "$target_dir/release/examples/icount_sim" "$target_dir/release/examples/icount_learner"

#!/usr/bin/env bash
# The ablation of the tuned hybrid agent: trains `hybrid-tuned` and variants of it with one switch
# changed, each with the same wall-clock budget and seed, one after the other, evaluates them all
# on the seven routes beside the model-based baseline (`actor eval`), and writes a table of the
# mean over the routes to runs/ablation/ablation.md (the full Table I beside it in
# runs/ablation/table.md, raw numbers in runs/ablation/results.json).
#
# Ctrl-C stops the current step (training writes a checkpoint); running the same command again
# resumes: each variant continues to the same total budget, then evaluation runs.
#
# Usage: scripts/ablation.sh [--minutes M] [--seed S] [--runs N] [--actors N] [--envs N]
#                            [--only NAME,NAME] [--runs-dir DIR] [--no-build]
set -euo pipefail

# shellcheck source=scripts/lib.sh
source "$(dirname "$0")/lib.sh"
# The variants (NAME|PRESET|TOML|WHAT), from experiments/agents.txt.
agents_of ablation variants

usage() {
    cat <<'EOF'
scripts/ablation.sh — train and evaluate the tuned hybrid agent and its one-switch variants.

  --minutes M       training budget per variant, wall-clock minutes (default 10)
  --seed S          seed of every run (default 1)
  --runs N          evaluation runs per route (default 5)
  --actors N        local actor processes per run (default 1)
  --envs N          environments per actor (default 4)
  --only A,B        train only these variants (evaluation still covers every variant trained
                    so far in the runs directory)
  --runs-dir DIR    where the run directories and the tables go (default runs/ablation)
  --no-build        use the binaries in target/release as they are
  -h, --help        this text

Variants:
EOF
    for v in "${variants[@]}"; do
        IFS='|' read -r name _ _ what <<<"$v"
        printf '  %-18s %s\n' "$name" "$what"
    done
}

minutes=10
seed=1
runs=5
actors=1
envs=4
only=""
runs_dir=runs/ablation
build=1
while [[ $# -gt 0 ]]; do
    case "$1" in
        --minutes) minutes="${2:?--minutes needs a number}"; shift 2 ;;
        --seed) seed="${2:?--seed needs a number}"; shift 2 ;;
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --actors) actors="${2:?--actors needs a number}"; shift 2 ;;
        --envs) envs="${2:?--envs needs a number}"; shift 2 ;;
        --only) only="${2:?--only needs variant names}"; shift 2 ;;
        --runs-dir) runs_dir="${2:?--runs-dir needs a directory}"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "ablation.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
require_positive ablation.sh "minutes:$minutes" "seed:$seed" "actors:$actors" "envs:$envs" "runs:$runs"
names=()
for v in "${variants[@]}"; do names+=("${v%%|*}"); done
if [[ -n "$only" ]]; then
    IFS=',' read -r -a wanted <<<"$only"
    for w in "${wanted[@]}"; do
        if ! printf '%s\n' "${names[@]}" | grep -qx -- "$w"; then
            echo "ablation.sh: --only: unknown variant \`$w\`: expected one of ${names[*]}" >&2
            exit 2
        fi
    done
else
    wanted=("${names[@]}")
fi

cd "$(dirname "$0")/.."
resume_on_interrupt ablation.sh
bin="${CARGO_TARGET_DIR:-target}/release"
run() {
    echo "+ $*" >&2
    "$@"
}
if [[ "$build" == 1 ]]; then
    build_release
fi
mkdir -p "$runs_dir"

for v in "${variants[@]}"; do
    IFS='|' read -r name preset extra what <<<"$v"
    printf '%s\n' "${wanted[@]}" | grep -qx -- "$name" || continue
    cfg="$runs_dir/$name.toml"
    preset_config "Ablation variant \`$name\`: $what." "$preset" "$extra" >"$cfg"
    echo "== training $name for up to $minutes min ($runs_dir/$name)" >&2
    run "$bin/actor" train --config "$cfg" --run-dir "$runs_dir/$name" --seed "$seed" --max-minutes "$minutes" \
        --actors "$actors" --envs "$envs"
done

eval_args=()
for name in "${names[@]}"; do
    [[ -d "$runs_dir/$name/checkpoint" ]] && eval_args+=(--checkpoint "$runs_dir/$name" --name "$name")
done
if [[ ${#eval_args[@]} -eq 0 ]]; then
    echo "ablation.sh: no variant has a checkpoint in $runs_dir yet" >&2
    exit 1
fi
echo "== evaluating $(( ${#eval_args[@]} / 4 )) variant(s) ($runs runs per route)" >&2
run "$bin/actor" eval "${eval_args[@]}" --runs "$runs" --seed 0 --markdown --json-out "$runs_dir/results.json" \
    >"$runs_dir/table.md.tmp"
mv "$runs_dir/table.md.tmp" "$runs_dir/table.md"

# One row per variant: the "mean of the routes" row and the "routes completed in most runs" line.
{
    echo "| variant | what it tests | mean return | completed | collisions | route types completed in most runs |"
    echo "|---|---|---:|---:|---:|---:|"
    for v in "${variants[@]}"; do
        IFS='|' read -r name _ _ what <<<"$v"
        row=$(grep -F "| mean of the routes | $name |" "$runs_dir/table.md" || true)
        [[ -z "$row" ]] && continue
        IFS='|' read -r _ _ _ ret done coll _ <<<"$row"
        types=$(grep -F -- "- $name:" "$runs_dir/table.md" | sed 's/.*routes completed in most runs: //')
        echo "| \`$name\` | $what | ${ret// /} | ${done// /} | ${coll// /} | $types |"
    done
} >"$runs_dir/ablation.md"
cat "$runs_dir/ablation.md"
echo "wrote $runs_dir/ablation.md, $runs_dir/table.md and $runs_dir/results.json" >&2

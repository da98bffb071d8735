#!/usr/bin/env bash
# Reproduces the paper's experiment in one command: trains the hybrid agent (preset
# `hybrid-tuned`, or `paper` with --paper) and the end-to-end agent (`end-to-end-tuned`, or
# `end-to-end`) with the same wall-clock budget and seed, one after
# the other, evaluates both beside the model-based baseline on the seven routes (`actor eval`),
# plots their learning curves (`learner plot`), and writes a results page with the table, the
# figure, the exact commands, the budget and the machine.
#
# Ctrl-C stops the current step (training writes a checkpoint); running the same command again
# resumes: each training run continues to the same total budget, then evaluation and plotting run.
#
# Usage: scripts/reproduce.sh [--minutes M] [--seed S] [--runs N] [--actors N] [--envs N] [--paper]
#                             [--runs-dir DIR] [--out-dir DIR] [--smoke] [--no-build]
set -euo pipefail

usage() {
    cat <<'EOF'
scripts/reproduce.sh — train, evaluate and plot the hybrid and the end-to-end agent.

  --minutes M     training budget per agent, wall-clock minutes (default 90)
  --seed S        seed of both runs: network initialisation, replay, actors (default 1)
  --runs N        evaluation runs per route (default 5)
  --actors N      local actor processes per training run (default 1: on 2 cores it already
                  feeds the learner at its replay ratio)
  --envs N        environments per actor (default 4)
  --paper         train the paper-faithful presets `paper` and `end-to-end` instead of the
                  tuned `hybrid-tuned` and `end-to-end-tuned` (see `learner config --help`)
  --runs-dir DIR  where the two run directories go (default runs/reproduce, or runs/smoke)
  --out-dir DIR   where RESULTS.md, the figure and the JSON go (default docs, or runs/smoke)
  --smoke         a test of the pipeline: tiny camera (32x32) and network (8 filters, 32
                  units), short warm-up, 2 evaluation runs; pair with e.g. --minutes 1
  --no-build      use the binaries in target/release as they are
  -h, --help      this text

Rerunning the same command resumes: training continues each run to the same total budget.
EOF
}

minutes=90
seed=1
runs=""
actors=1
envs=4
paper=0
runs_dir=""
out_dir=""
smoke=0
build=1
while [[ $# -gt 0 ]]; do
    case "$1" in
        --minutes) minutes="${2:?--minutes needs a number}"; shift 2 ;;
        --seed) seed="${2:?--seed needs a number}"; shift 2 ;;
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --actors) actors="${2:?--actors needs a number}"; shift 2 ;;
        --envs) envs="${2:?--envs needs a number}"; shift 2 ;;
        --runs-dir) runs_dir="${2:?--runs-dir needs a directory}"; shift 2 ;;
        --out-dir) out_dir="${2:?--out-dir needs a directory}"; shift 2 ;;
        --smoke) smoke=1; shift ;;
        --paper) paper=1; shift ;;
        --no-build) build=0; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "reproduce.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
# shellcheck source=scripts/lib.sh
source "$(dirname "$0")/lib.sh"
require_positive reproduce.sh "minutes:$minutes" "seed:$seed" "actors:$actors" "envs:$envs" "runs:${runs:-1}"
if [[ "$smoke" == 1 ]]; then
    runs_dir="${runs_dir:-runs/smoke}"
    out_dir="${out_dir:-runs/smoke}"
    runs="${runs:-2}"
else
    runs_dir="${runs_dir:-runs/reproduce}"
    out_dir="${out_dir:-docs}"
    runs="${runs:-5}"
fi

cd "$(dirname "$0")/.."
trap 'echo; echo "reproduce.sh: interrupted — run the same command again to resume." >&2; exit 130' INT TERM

bin="${CARGO_TARGET_DIR:-target}/release"
actor="$bin/actor"
learner="$bin/learner"
commands=()
# Prints a command, records it for the results page, runs it.
run() {
    echo "+ $*" >&2
    commands+=("$*")
    "$@"
}

started=$(date -u +%Y-%m-%dT%H:%M:%SZ)
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
if [[ "$build" == 1 ]]; then
    run cargo build --release --locked -p actor -p learner
fi
mkdir -p "$runs_dir" "$out_dir/figures"

agents=(hybrid end-to-end)
if [[ "$paper" == 1 ]]; then
    declare -A preset=([hybrid]=paper [end-to-end]=end-to-end)
else
    declare -A preset=([hybrid]=hybrid-tuned [end-to-end]=end-to-end-tuned)
fi
declare -A train_secs=()
for agent in "${agents[@]}"; do
    dir="$runs_dir/$agent"
    config_args=(--preset "${preset[$agent]}")
    if [[ "$smoke" == 1 ]]; then
        mkdir -p "$runs_dir"
        cfg="$runs_dir/$agent.toml"
        cat >"$cfg" <<EOF
# Smoke test of the pipeline: the ${preset[$agent]} preset with a tiny camera and network.
preset = "${preset[$agent]}"

[env.camera]
width = 32
height = 32

[agent]
conv_filters = 8
hidden = 32
min_replay = 256
replay_ratio = 1.0
target_update_period = 100
epsilon_decay_steps = 20000

[service]
checkpoint_interval_secs = 60
EOF
        config_args=(--config "$cfg")
    fi
    echo "== training $agent for up to $minutes min (run directory $dir)" >&2
    t0=$(date +%s)
    run "$actor" train "${config_args[@]}" --run-dir "$dir" --seed "$seed" --max-minutes "$minutes" \
        --actors "$actors" --envs "$envs"
    train_secs[$agent]=$(( $(date +%s) - t0 ))
done

echo "== evaluating both agents beside the model-based baseline ($runs runs per route)" >&2
table="$out_dir/results-table.md"
run "$actor" eval --checkpoint "$runs_dir/hybrid" --name hybrid --checkpoint "$runs_dir/end-to-end" --name end-to-end \
    --runs "$runs" --seed 0 --markdown --json-out "$out_dir/results.json" >"$table.tmp"
mv "$table.tmp" "$table"

echo "== plotting the learning curves" >&2
figure="$out_dir/figures/curves.png"
run "$learner" plot --run-dir "$runs_dir/hybrid" --run-dir "$runs_dir/end-to-end" --out "$figure" >&2

finished=$(date -u +%Y-%m-%dT%H:%M:%SZ)
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
cpu=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//' || true)
mem=$(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo || true)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
if [[ -n "$(git status --porcelain 2>/dev/null | grep -v '^??' || true)" ]]; then
    commit="$commit (with uncommitted changes)"
fi
invocation="scripts/reproduce.sh --minutes $minutes --seed $seed --runs $runs --actors $actors --envs $envs"
[[ "$paper" == 1 ]] && invocation="$invocation --paper"
[[ "$smoke" == 1 ]] && invocation="$invocation --smoke"

results="$out_dir/RESULTS.md"
{
    echo "# Results: hybrid vs end-to-end DQN on the paper's seven routes"
    echo
    if [[ "$smoke" == 1 ]]; then
        echo "> **Smoke run of the tooling, not the experiment**: a tiny camera and network trained for"
        echo "> $minutes min per agent. The numbers below say nothing about the method; they show the pipeline"
        echo "> works end to end. The experiment is \`scripts/reproduce.sh\` (90 min per agent)."
    elif awk "BEGIN { exit !($minutes < 90) }"; then
        echo "> Budget of $minutes min per agent; the experiment allows up to 90."
    fi
    echo
    echo "Reproduce with:"
    echo
    echo '```sh'
    echo "$invocation"
    echo '```'
    echo
    echo "Each agent trained for at most **$minutes min** of wall-clock time (\`actor train --max-minutes\`),"
    echo "one after the other on the same machine, seed $seed, $actors actor process(es) × $envs environments,"
    echo "presets \`${preset[hybrid]}\` and \`${preset[end-to-end]}\` (\`learner config --preset NAME\` prints them):"
    echo "hybrid ${train_secs[hybrid]} s, end-to-end ${train_secs[end-to-end]} s in this session (a resumed run"
    echo "counts its earlier sessions toward the budget). Evaluation: greedy (ε = 0), $runs runs per route"
    echo "(seeds 0..$((runs - 1)), different traffic), every agent scored with the paper's reward."
    echo
    echo "## Table I"
    echo
    cat "$table"
    echo
    echo "Raw numbers: [\`results.json\`](results.json) (\`actor eval --json\` format)."
    echo
    echo "## Figure 5: learning curves"
    echo
    echo "![Smoothed episode return, loss, mean Q and greedy evaluations of both runs against minutes of training](figures/curves.png)"
    echo
    if [[ "$smoke" == 1 ]]; then
        echo "## Smoke configuration (\`$runs_dir/hybrid.toml\`; the end-to-end one differs in the preset)"
        echo
        echo '```toml'
        cat "$runs_dir/hybrid.toml"
        echo '```'
        echo
    fi
    echo "## Machine"
    echo
    echo "- CPU: ${cpu:-unknown}, $(nproc) cores visible (\`nproc\`), memory $mem"
    echo "- load average (1, 5, 15 min): $load_before at the start, $load_after at the end"
    echo "- started $started, finished $finished; commit $commit"
    echo
    echo "## Commands run"
    echo
    echo '```sh'
    printf '%s\n' "${commands[@]}"
    echo '```'
} >"$results"
echo "wrote $results, $table, $out_dir/results.json and $figure" >&2

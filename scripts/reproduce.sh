#!/usr/bin/env bash
# The experiment of docs/RESULTS.md in one command: trains every agent with several seeds and the
# same budget of environment steps, evaluates each run greedily on the town it trained on and on
# a held-out town it never saw, searches settings for the end-to-end baseline, and writes the
# table with bootstrap confidence intervals (docs/RESULTS.md), the raw numbers
# (experiments/results.json) and the figures (docs/figures/).
#
# Each (agent, seed) run keeps what the results need in experiments/results/AGENT/seedS/ (its
# evaluations, its periodic evaluations, train.jsonl, its return curve in 400 points (curves.json),
# a run.json; the full episodes.jsonl stays in the runs directory); a run whose run.json exists is
# done and is skipped. So the script is resumable at two levels: a stopped training run continues
# from its checkpoint in the runs directory to the same budget, and a finished run is never trained
# again, even from a fresh clone (its results are committed).
#
# `--experiment hazards` runs the hazard experiment instead (scripts/reproduce-hazards.sh, which
# takes the flags that follow it); `--experiment hazards2` the second one, with agents that see
# objects (scripts/reproduce-hazards2.sh).
#
# Usage: scripts/reproduce.sh [--experiment main|hazards|hazards2] [--seeds N] [--env-steps N] [--agents A,B] [--runs N] [--report-only]
#                             [--runs-dir DIR] [--out-dir DIR] [--data-dir DIR] [--smoke] [--no-build]
set -euo pipefail
# The whole script is one block, read before it runs: a file edited (or pulled) during an
# experiment of hours cannot change what the running shell reads next.
{

if [[ "${1:-}" == --experiment ]]; then
    case "${2:-}" in
        main) shift 2 ;;
        hazards) shift 2; exec bash "$(dirname "$0")/reproduce-hazards.sh" "$@" ;;
        hazards2) shift 2; exec bash "$(dirname "$0")/reproduce-hazards2.sh" "$@" ;;
        *) echo "reproduce.sh: --experiment \`${2:-}\`: expected \`main\` (docs/RESULTS.md's table), \`hazards\` or \`hazards2\` (its hazard tables)" >&2; exit 2 ;;
    esac
fi

# shellcheck source=scripts/lib.sh
source "$(dirname "$0")/lib.sh"
# The agents (NAME|PRESET|TOML|WHAT) and the search for the end-to-end baseline's settings, from
# experiments/agents.txt. `e2e-best`, the search's winner, is trained by the search's rules below.
agents_of main agents
for i in "${!agents[@]}"; do
    if [[ "${agents[$i]}" == "e2e-best|"* ]]; then unset "agents[$i]"; fi
done
agents=("${agents[@]}")
agents_of search search

# list ENTRY...: the name and description of each table entry, one per line.
list() {
    local v name what
    for v in "$@"; do
        IFS='|' read -r name _ _ what <<<"$v"
        printf '  %-20s %s\n' "$name" "$what"
    done
}

usage() {
    cat <<'EOF'
scripts/reproduce.sh — the experiment of docs/RESULTS.md: agents × seeds, two towns, intervals.

  --experiment E  `main` (this text's experiment, the default), `hazards` (the hazard
                  experiment: scripts/reproduce-hazards.sh, with the flags after it; its --help)
                  or `hazards2` (agents that see objects: scripts/reproduce-hazards2.sh)
                  given first
  --seeds N       seeds per agent, 1..N (default 3)
  --env-steps N   training budget per run, environment steps (default 400000); wall time is
                  recorded beside it
  --agents A,B    train only these agents (names below; `search` for the end-to-end search,
                  `e2e-best` for the search's winner); the report still covers every finished run
  --runs N        evaluation runs per route and town (default 5)
  --eval-every M  minutes between periodic greedy evaluations during training (default 1)
  --report-only   train nothing: rebuild the tables, results.json and figures from
                  experiments/results
  --runs-dir DIR  where the training run directories go (default runs/reproduce)
  --out-dir DIR   where RESULTS.md and figures/ go (default docs)
  --data-dir DIR  where results.json and the kept runs (results/) go (default experiments, or
                  the --out-dir given)
  --smoke         a test of the pipeline: tiny camera and network, 30k steps, 2 seeds, 1 run;
                  writes to runs/smoke
  --no-build      use the binaries in target/release as they are
  -h, --help      this text

Agents (each with --seeds seeds):
EOF
    list "${agents[@]}"
    echo
    echo "End-to-end search (seed 1 each; the best, by periodic evaluation, runs the other seeds):"
    list "${search[@]}"
    echo
    echo "Rerunning the same command resumes; finished runs (experiments/results/AGENT/seedS/run.json) are skipped."
}

seeds=3
env_steps=400000
only=""
runs=""
eval_every=1
report_only=0
runs_dir=""
out_dir=""
data_dir=""
smoke=0
build=1
while [[ $# -gt 0 ]]; do
    case "$1" in
        --seeds) seeds="${2:?--seeds needs a number}"; shift 2 ;;
        --env-steps) env_steps="${2:?--env-steps needs a number}"; shift 2 ;;
        --agents) only="${2:?--agents needs names}"; shift 2 ;;
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --eval-every) eval_every="${2:?--eval-every needs minutes}"; shift 2 ;;
        --report-only) report_only=1; shift ;;
        --runs-dir) runs_dir="${2:?--runs-dir needs a directory}"; shift 2 ;;
        --out-dir) out_dir="${2:?--out-dir needs a directory}"; shift 2 ;;
        --data-dir) data_dir="${2:?--data-dir needs a directory}"; shift 2 ;;
        --smoke) smoke=1; shift ;;
        --no-build) build=0; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "reproduce.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
if [[ "$smoke" == 1 ]]; then
    runs_dir="${runs_dir:-runs/smoke/runs}"
    out_dir="${out_dir:-runs/smoke}"
    data_dir="${data_dir:-$out_dir}"
    runs="${runs:-1}"
    [[ "$env_steps" == 400000 ]] && env_steps=30000
    [[ "$seeds" == 3 ]] && seeds=2
else
    runs_dir="${runs_dir:-runs/reproduce}"
    # The pages and figures in docs/, the run data in experiments/; an --out-dir given alone
    # takes both, as before the run data moved out of docs/.
    data_dir="${data_dir:-${out_dir:-experiments}}"
    out_dir="${out_dir:-docs}"
    runs="${runs:-5}"
fi
require_positive reproduce.sh "seeds:$seeds" "env-steps:$env_steps" "runs:$runs" "eval-every:$eval_every"
if ! [[ "$seeds" =~ ^[0-9]+$ && "$env_steps" =~ ^[0-9]+$ && "$runs" =~ ^[0-9]+$ ]]; then
    echo "reproduce.sh: --seeds, --env-steps and --runs take whole numbers" >&2
    exit 2
fi
require_known reproduce.sh "$only" "search e2e-best" "${agents[@]}" "${search[@]}"

cd "$(dirname "$0")/.."
resume_on_interrupt reproduce.sh

bin="${CARGO_TARGET_DIR:-target}/release"
actor="$bin/actor"
learner="$bin/learner"
results="$data_dir/results"
if [[ "$build" == 1 && "$report_only" == 0 ]]; then
    build_release
fi
mkdir -p "$runs_dir" "$results" "$out_dir/figures"

# config_for NAME PRESET EXTRA FILE: writes the run's configuration file.
config_for() {
    local name="$1" preset="$2" extra="$3" file="$4"
    if [[ "$smoke" == 1 ]]; then
        # Smoke test of the pipeline only: a tiny camera and network, a short warm-up. A TOML
        # table may appear once, so the agent lines join the extra's [agent] table if it has one.
        local tiny='conv_filters = 4\nhidden = 16\nmin_replay = 512'
        if [[ "$extra" == *"[agent]"* ]]; then
            extra="${extra/"[agent]"/"[agent]\n$tiny"}"
        else
            extra="${extra:+$extra\n\n}[agent]\n$tiny"
        fi
        extra="$extra\n\n[env.camera]\nwidth = 24\nheight = 24"
    fi
    preset_config "$name: the \`$preset\` preset$([[ -n "$extra" ]] && echo " with the lines below")." "$preset" "$extra" >"$file"
}

# train_and_evaluate NAME PRESET EXTRA SEED: one run, skipped when its run.json exists.
train_and_evaluate() {
    local name="$1" preset="$2" extra="$3" seed="$4"
    local dir="$runs_dir/$name/seed$seed" out="$results/$name/seed$seed"
    run_done "$name" "$seed" "$out" && return
    mkdir -p "$dir" "$out"
    local cfg="$out/config.toml"
    [[ -f "$cfg" ]] || config_for "$name" "$preset" "$extra" "$cfg"
    session_begin
    echo "== $name seed $seed: training to $env_steps env steps (run directory $dir)" >&2
    echo "+ $actor train --config $cfg --run-dir $dir --seed $seed --max-env-steps $env_steps --eval-every $eval_every" >&2
    # The actors and environments of README's command (actor train's defaults, 1 × 4), so that the
    # minutes to competence are what a user of that command sees.
    "$actor" train --config "$cfg" --run-dir "$dir" --seed "$seed" --max-env-steps "$env_steps" \
        --eval-every "$eval_every"
    session_end
    evaluate_towns "$actor" "$dir" "$name" "$seed" "$runs" "$out"
    local -a kept
    keep_run_args kept "$dir" "$out" "$name" "$preset" "$seed" "$env_steps"
    python3 scripts/results.py keep-run "${kept[@]}"
}

if [[ "$report_only" == 0 ]]; then
    for v in "${agents[@]:0:1}"; do
        IFS='|' read -r name preset extra _ <<<"$v"
        if wanted "$name"; then
            for seed in $(seq 1 "$seeds"); do train_and_evaluate "$name" "$preset" "$extra" "$seed"; done
        fi
    done
    for v in "${search[@]}"; do
        IFS='|' read -r name preset extra _ <<<"$v"
        if wanted search || wanted "$name"; then train_and_evaluate "$name" "$preset" "$extra" 1; fi
    done
    if wanted e2e-best && [[ "$seeds" -gt 1 ]]; then
        best=$(python3 scripts/results.py best-end-to-end --results "$results") || {
            echo "reproduce.sh: the end-to-end search has not finished (run --agents search first)" >&2
            exit 1
        }
        echo "== the end-to-end search's best: $best" >&2
        for v in "${search[@]}"; do
            IFS='|' read -r name preset extra _ <<<"$v"
            if [[ "$name" == "$best" ]]; then
                for seed in $(seq 2 "$seeds"); do train_and_evaluate "$name" "$preset" "$extra" "$seed"; done
            fi
        done
    fi
    # The other agents seed by seed, so that an experiment stopped early has every agent.
    for seed in $(seq 1 "$seeds"); do
        for v in "${agents[@]:1}"; do
            IFS='|' read -r name preset extra _ <<<"$v"
            if wanted "$name"; then train_and_evaluate "$name" "$preset" "$extra" "$seed"; fi
        done
    done
fi

echo "== report: $out_dir/RESULTS.md, $data_dir/results.json, $out_dir/figures/" >&2
python3 scripts/results.py report --results "$results" --out-dir "$out_dir" --json-out "$data_dir/results.json" \
    --learner "$learner"
exit
}

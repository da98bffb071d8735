#!/usr/bin/env bash
# The second hazard experiment of docs/RESULTS.md (`scripts/reproduce.sh --experiment hazards2`
# runs this): do agents that see objects and brake at full authority beat the planner that cannot
# see, and is the hybrid agent better than the end-to-end one with the same observation?
#
#   1. the agents of group `hazards2` of experiments/agents.txt × --seeds (1..N), seed by seed, each
#      to its budget: --env-steps for the vector agents, --camera-env-steps for the camera agent
#      (`h2-hybrid-hazards`), periodic evaluations every --eval-every minutes (the camera agent's
#      every --camera-eval-every: at 30 s they would take most of its CPU) — the learning curves per
#      hazard kind and the choice of best/
#   1b. the longer-budget row (group `hazards2-long`): each of seeds 1..--long-seeds (default 5) of
#      h2-hybrid-vector trained on from its --env-steps checkpoint to --long-env-steps (a copy of
#      its run directory, resumed: the curve is that run's own)
#   2. the last checkpoint and best/ of every run on the hazard suite and the clean suite on
#      default_town, held_out_town and CARLA's Town01 (sim-core/tests/data/opendrive/Town01.xodr),
#      and on the robustness suite (`hazards-robust`: every hazard parameter drawn beyond the
#      training ranges) on both towns, `actor eval --runs N --seed 0`
#   3. the episode figure: each agent's lowest finished seed around the same stalled cars
#   4. the tables: scripts/hazards2_results.py report (docs/RESULTS.md's hazards2 sections, the
#      "hazards2" key of experiments/results.json, docs/figures/hazards2-*.svg)
#
# Each run keeps what the tables need in experiments/hazards2/AGENT/seedS/ (its evaluations
# without the baselines, gzipped; its periodic evaluations; train.jsonl; curves.json; run.json);
# the baselines, the same in every evaluation, once in experiments/hazards2/baselines/. A run whose
# run.json exists is done and skipped; a stopped training run resumes from its checkpoint in
# --runs-dir. Rerun the same command to continue.
set -euo pipefail
{

# shellcheck source=scripts/lib.sh
source "$(dirname "$0")/lib.sh"
agents_of hazards2 agents
agents_of hazards2-long long

seeds=5
env_steps=1000000
camera_env_steps=400000
long_env_steps=3000000
long_seeds=5
only=""
runs=10
eval_every=0.5
camera_eval_every=3
report_only=0
runs_dir="runs/hazards2"
build=1

usage() {
    cat <<'EOF'
scripts/reproduce-hazards2.sh — the second hazard experiment of docs/RESULTS.md.

  --seeds N             seeds per agent, 1..N (default 5)
  --env-steps N         the vector agents' budget, environment steps (default 1000000)
  --camera-env-steps N  the camera agent's budget (default 400000)
  --long-env-steps N    the longer-budget row's budget (default 3000000); 0 skips the row
  --long-seeds N        seeds of the longer-budget row, 1..N (default 5)
  --agents A,B          train only these (names below); the report covers every finished run
  --runs N              evaluation runs per hazard kind or route, suite and town (default 10)
  --eval-every M        minutes between periodic evaluations during training (default 0.5)
  --camera-eval-every M the camera agent's periodic evaluations (default 3)
  --report-only         train nothing: rebuild the tables from experiments/hazards2
  --runs-dir DIR        where the training run directories go (default runs/hazards2)
  --no-build            use the binaries in target/release as they are
  -h, --help            this text

Agents (--seeds seeds each):
EOF
    local v name what
    for v in "${agents[@]}" "${long[@]}"; do
        IFS='|' read -r name _ _ what <<<"$v"
        printf '  %-24s %s\n' "$name" "$what"
    done
    echo
    echo "Rerunning the same command resumes; finished runs (experiments/hazards2/AGENT/seedS/run.json) are skipped."
}

while [[ $# -gt 0 ]]; do
    case "$1" in
        --seeds) seeds="${2:?--seeds needs a number}"; shift 2 ;;
        --env-steps) env_steps="${2:?--env-steps needs a number}"; shift 2 ;;
        --camera-env-steps) camera_env_steps="${2:?--camera-env-steps needs a number}"; shift 2 ;;
        --long-env-steps) long_env_steps="${2:?--long-env-steps needs a number}"; shift 2 ;;
        --long-seeds) long_seeds="${2:?--long-seeds needs a number}"; shift 2 ;;
        --agents) only="${2:?--agents needs names}"; shift 2 ;;
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --eval-every) eval_every="${2:?--eval-every needs minutes}"; shift 2 ;;
        --camera-eval-every) camera_eval_every="${2:?--camera-eval-every needs minutes}"; shift 2 ;;
        --report-only) report_only=1; shift ;;
        --runs-dir) runs_dir="${2:?--runs-dir needs a directory}"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "reproduce-hazards2.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
require_positive reproduce-hazards2.sh "seeds:$seeds" "env-steps:$env_steps" "camera-env-steps:$camera_env_steps" "runs:$runs" "eval-every:$eval_every" "camera-eval-every:$camera_eval_every"
for pair in "seeds:$seeds" "env-steps:$env_steps" "camera-env-steps:$camera_env_steps" "long-env-steps:$long_env_steps" "long-seeds:$long_seeds" "runs:$runs"; do
    if ! [[ "${pair#*:}" =~ ^[0-9]+$ ]]; then
        echo "reproduce-hazards2.sh: --${pair%%:*} ${pair#*:} must be a whole number" >&2
        exit 2
    fi
done
if [[ "$long_env_steps" != 0 && "$long_env_steps" -le "$env_steps" ]]; then
    echo "reproduce-hazards2.sh: --long-env-steps $long_env_steps must exceed --env-steps $env_steps (or be 0)" >&2
    exit 2
fi
require_known reproduce-hazards2.sh "$only" "" "${agents[@]}" "${long[@]}"

cd "$(dirname "$0")/.."
resume_on_interrupt reproduce-hazards2.sh

bin="${CARGO_TARGET_DIR:-target}/release"
actor="$bin/actor"
results="experiments/hazards2"
town01="sim-core/tests/data/opendrive/Town01.xodr"
if [[ "$build" == 1 && "$report_only" == 0 ]]; then
    build_release
fi
mkdir -p "$runs_dir" "$results"

# evaluate DIR OUT: the last checkpoint and best/ of run DIR on every suite and town, each into
# OUT/eval-SUITE-TOWN.json (town01 for CARLA's Town01).
evaluate() {
    local dir="$1" out="$2" pair suite town file
    local -a agents_args=(--checkpoint "$dir" --name last)
    [[ -d "$dir/best" ]] && agents_args+=(--checkpoint "$dir/best" --name best)
    for pair in hazards:default_town hazards:held_out_town hazards:town01 clean:default_town clean:held_out_town clean:town01 \
        hazards-robust:default_town hazards-robust:held_out_town; do
        suite="${pair%%:*}" town="${pair#*:}" file="$out/eval-$suite-$town.json"
        [[ -f "$file" || -f "$file.gz" ]] && continue
        echo "   evaluating on $suite / $town ($runs runs per scenario)" >&2
        "$actor" eval --suite "$suite" --town "$([[ "$town" == town01 ]] && echo "$town01" || echo "$town")" --runs "$runs" --seed 0 \
            "${agents_args[@]}" --json-out "$file.tmp" >/dev/null
        mv "$file.tmp" "$file"
    done
}

# budget_of NAME PRESET: the agent's env-step budget: the longer row's, the vector agents', or
# the camera's.
budget_of() {
    if [[ "$1" == "${long[0]%%|*}" ]]; then echo "$long_env_steps"
    elif vector_preset "$2"; then echo "$env_steps"
    else echo "$camera_env_steps"; fi
}

# eval_every_of PRESET: minutes between periodic evaluations: the vector agents' or the camera's.
eval_every_of() {
    if vector_preset "$1"; then echo "$eval_every"; else echo "$camera_eval_every"; fi
}

# vector_preset PRESET: whether the preset sees objects (the vector sensor) rather than a camera.
vector_preset() {
    [[ "$1" == hybrid-vector || "$1" == e2e-vector ]]
}

# train_and_evaluate NAME PRESET EXTRA SEED: one run, skipped when its run.json exists.
train_and_evaluate() {
    local name="$1" preset="$2" extra="$3" seed="$4"
    local dir="$runs_dir/$name/seed$seed" out="$results/$name/seed$seed" budget every
    budget=$(budget_of "$name" "$preset")
    every=$(eval_every_of "$preset")
    run_done "$name" "$seed" "$out" && return
    mkdir -p "$dir" "$out"
    local cfg="$out/config.toml"
    [[ -f "$cfg" ]] || preset_config "$name: the \`$preset\` preset$([[ -n "$extra" ]] && echo " with the lines below")." "$preset" "$extra" >"$cfg"
    session_begin
    echo "== $name seed $seed: training to $budget env steps (run directory $dir)" >&2
    echo "+ $actor train --config $cfg --run-dir $dir --seed $seed --max-env-steps $budget --eval-every $every" >&2
    "$actor" train --config "$cfg" --run-dir "$dir" --seed "$seed" --max-env-steps "$budget" --eval-every "$every"
    session_end
    evaluate "$dir" "$out"
    local -a kept
    keep_run_args kept "$dir" "$out" "$name" "$preset" "$seed" "$budget"
    python3 scripts/hazards2_results.py keep-run "${kept[@]}"
}

if [[ "$report_only" == 0 ]]; then
    for seed in $(seq 1 "$seeds"); do
        for v in "${agents[@]}"; do
            IFS='|' read -r name preset extra _ <<<"$v"
            if wanted "$name"; then train_and_evaluate "$name" "$preset" "$extra" "$seed"; fi
        done
    done
    # 1b. The longer-budget row: each seed's first agent run trained on from a copy of its run
    # directory.
    IFS='|' read -r long_name long_preset long_extra _ <<<"${long[0]}"
    IFS='|' read -r first _ _ _ <<<"${agents[0]}"
    if [[ "$long_env_steps" != 0 ]] && wanted "$long_name"; then
        for seed in $(seq 1 "$long_seeds"); do
            from="$runs_dir/$first/seed$seed" dir="$runs_dir/$long_name/seed$seed"
            run_done "$long_name" "$seed" "$results/$long_name/seed$seed" && continue
            if [[ ! -f "$results/$first/seed$seed/run.json" || ! -d "$from/checkpoint" ]]; then
                echo "== $long_name seed $seed: waits for $first seed $seed (its run directory $from)" >&2
                continue
            fi
            if [[ ! -d "$dir" ]]; then
                echo "== $long_name seed $seed: starting from a copy of $from" >&2
                mkdir -p "$runs_dir/$long_name"
                cp -r "$from" "$dir.tmp" && mv "$dir.tmp" "$dir"
            fi
            train_and_evaluate "$long_name" "$long_preset" "$long_extra" "$seed"
        done
    fi
    # The episode figure: each agent's lowest finished seed, last checkpoint.
    episode_figure "$actor" "$results" "$runs_dir" "$runs" docs/figures/hazards2-episode.svg "${agents[@]}" "${long[@]}"
fi
if [[ "$report_only" == 1 ]]; then
    kept_episode_figure "$results" docs/figures/hazards2-episode.svg
fi

echo "== report: docs/RESULTS.md (hazards2 sections), experiments/results.json (\"hazards2\"), docs/figures/hazards2-*.svg" >&2
python3 scripts/hazards2_results.py report --results "$results" --out-dir docs --json-out experiments/results.json
exit
}

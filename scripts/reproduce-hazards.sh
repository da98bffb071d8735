#!/usr/bin/env bash
# The hazard experiment of docs/RESULTS.md (`scripts/reproduce.sh --experiment hazards` runs this):
# does an agent trained with r_w and a collision penalty leave the planner's path when following it
# is wrong, and does it beat the planner that follows blindly?
#
#   1. the hazard rate: hz-hybrid-tuned, seed 1, trained at each of --rates (`[env.hazards] rate`,
#      the share of training episodes with a hazard); the rate whose run scored best in its last
#      periodic evaluations (mean of the clean and hazard driving scores, validation seeds
#      10000..) is hz-hybrid-tuned's, and every agent's not in --rate-search; each agent of
#      --rate-search gets a search of its own (seed 1 at each rate, runs rate-R-AGENT; an agent's
#      own seed 1, where it was trained at R, is its point at R) and trains at its best rate
#   2. the agents of group `hazards` of experiments/agents.txt × --seeds, seed by seed, each to
#      --env-steps; `hz-e2e-best` is the end-to-end search's winner of scripts/reproduce.sh
#   2b. the search for a steadier policy (group `steady`): each candidate, seeds 1..--steady-seeds
#      (default 1), trained like hz-hybrid-tuned with one change, same budget and rate; compared by
#      the level and the swing of its periodic evaluations and by its final evaluations (a
#      candidate with two or more seeds also gets rows in the tables)
#   3. the longer-budget row (group `long`): hz-hybrid-tuned's run of each seed trained on from its
#      400k-step checkpoint to --long-env-steps (a copy of its run directory; resumed, so the
#      curve is that run's own; where that directory is gone, from scratch with the same
#      configuration and seed: experiments/hazards/hz-hybrid-tuned-long/seedS/started-from says which)
#   4. every final checkpoint and its best/ (chosen by the periodic evaluations) evaluated on both
#      suites (`hazards`, `clean`) and both towns, `actor eval --runs 5 --seed 0`
#   5. the episode figure: every agent's run around the same stalled cars (scripts/episode_figure.py,
#      docs/figures/hazards-episode.svg; its runs kept in experiments/hazards/episode/)
#   6. the tables: scripts/hazard_results.py report (docs/RESULTS.md's hazard sections, the
#      "hazards" key of experiments/results.json, docs/figures/hazards-*.svg)
#
# Each run keeps what the tables need in experiments/hazards/AGENT/seedS/ (its evaluations, its
# periodic evaluations, train.jsonl, its return curve in 400 points (curves.json), a run.json; the
# full episodes.jsonl stays in --runs-dir). A run whose run.json exists is done and skipped; a
# stopped training run resumes from its checkpoint in --runs-dir. Rerun the same command to continue.
#
# Usage: scripts/reproduce-hazards.sh [--seeds N] [--env-steps N] [--long-env-steps N] [--rates R,R]
#            [--rate-search A,B] [--steady-seeds N] [--agents A,B] [--runs N] [--eval-every M] [--report-only]
#            [--runs-dir DIR] [--no-build]
set -euo pipefail
{

# shellcheck source=scripts/lib.sh
source "$(dirname "$0")/lib.sh"
agents_of hazards agents
agents_of long long
agents_of search search
agents_of steady steady

usage() {
    cat <<'EOF'
scripts/reproduce-hazards.sh — the hazard experiment of docs/RESULTS.md.

  --seeds N            seeds per agent, 1..N (default 3)
  --env-steps N        training budget per run, environment steps (default 400000)
  --long-env-steps N   the longer-budget row's budget (default 1600000, 4x); 0 skips the row
  --rates R,R          hazard rates searched, seed 1 at each (default 0.25,0.5,1.0)
  --rate-search A,B    the agents searched for a rate of their own (default: all four); the others
                       train at hz-hybrid-tuned's
  --steady-seeds N     seeds per candidate of the steadiness search, 1..N (default 1)
  --agents A,B         train only these (names below, `rates` for the rate searches, `long` for the
                       longer row, `steady` for the steadiness search); the report still covers
                       every finished run
  --runs N             evaluation runs per scenario, suite and town (default 5)
  --eval-every M       minutes between periodic evaluations during training (default 1)
  --report-only        train nothing: rebuild the tables from experiments/hazards
  --runs-dir DIR       where the training run directories go (default runs/hazards)
  --no-build           use the binaries in target/release as they are
  -h, --help           this text

Agents (each with --seeds seeds, trained with the searched hazard rate):
EOF
    local v name what
    for v in "${agents[@]}" "${long[@]}"; do
        IFS='|' read -r name _ _ what <<<"$v"
        printf '  %-24s %s\n' "$name" "$what"
    done
    echo
    echo "The search for a steadier policy (--steady-seeds seeds each, hz-hybrid-tuned's rate):"
    for v in "${steady[@]}"; do
        IFS='|' read -r name _ _ what <<<"$v"
        printf '  %-24s %s\n' "$name" "$what"
    done
    echo
    echo "Rerunning the same command resumes; finished runs (experiments/hazards/AGENT/seedS/run.json) are skipped."
}

seeds=3
steady_seeds=1
env_steps=400000
long_env_steps=1600000
rates="0.25,0.5,1.0"
rate_search="hz-hybrid-tuned,hz-hybrid-avoid,hz-hybrid-paper-inputs,hz-e2e-best"
only=""
runs=5
eval_every=1
report_only=0
runs_dir="runs/hazards"
build=1
started_from=""
while [[ $# -gt 0 ]]; do
    case "$1" in
        --seeds) seeds="${2:?--seeds needs a number}"; shift 2 ;;
        --steady-seeds) steady_seeds="${2:?--steady-seeds needs a number}"; shift 2 ;;
        --env-steps) env_steps="${2:?--env-steps needs a number}"; shift 2 ;;
        --long-env-steps) long_env_steps="${2:?--long-env-steps needs a number}"; shift 2 ;;
        --rates) rates="${2:?--rates needs rates}"; shift 2 ;;
        --rate-search) rate_search="${2:?--rate-search needs agent names}"; shift 2 ;;
        --agents) only="${2:?--agents needs names}"; shift 2 ;;
        --runs) runs="${2:?--runs needs a number}"; shift 2 ;;
        --eval-every) eval_every="${2:?--eval-every needs minutes}"; shift 2 ;;
        --report-only) report_only=1; shift ;;
        --runs-dir) runs_dir="${2:?--runs-dir needs a directory}"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "reproduce-hazards.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
require_positive reproduce-hazards.sh "seeds:$seeds" "steady-seeds:$steady_seeds" "env-steps:$env_steps" "runs:$runs" "eval-every:$eval_every"
for pair in "seeds:$seeds" "steady-seeds:$steady_seeds" "env-steps:$env_steps" "long-env-steps:$long_env_steps" "runs:$runs"; do
    if ! [[ "${pair#*:}" =~ ^[0-9]+$ ]]; then
        echo "reproduce-hazards.sh: --${pair%%:*} ${pair#*:} must be a whole number" >&2
        exit 2
    fi
done
if [[ "$long_env_steps" != 0 && "$long_env_steps" -le "$env_steps" ]]; then
    echo "reproduce-hazards.sh: --long-env-steps $long_env_steps must exceed --env-steps $env_steps (or be 0)" >&2
    exit 2
fi
for r in ${rates//,/ }; do
    if ! [[ "$r" =~ ^(0?[.][0-9]+|1([.]0*)?)$ ]] || [[ "$r" =~ ^0?[.]0*$ ]]; then
        echo "reproduce-hazards.sh: --rates: \`$r\` must be a rate in (0, 1]" >&2
        exit 2
    fi
done
require_known reproduce-hazards.sh "$only" "rates long steady" "${agents[@]}" "${long[@]}" "${steady[@]}"
require_known reproduce-hazards.sh --flag --rate-search "$rate_search" "" "${agents[@]}"

cd "$(dirname "$0")/.."
resume_on_interrupt reproduce-hazards.sh

bin="${CARGO_TARGET_DIR:-target}/release"
actor="$bin/actor"
results="experiments/hazards"
if [[ "$build" == 1 && "$report_only" == 0 ]]; then
    build_release
fi
mkdir -p "$runs_dir" "$results"

# config_for NAME PRESET EXTRA RATE FILE: the run's configuration: the preset, the agent's lines,
# and the hazard rate.
config_for() {
    local name="$1" preset="$2" extra="$3" rate="$4" file="$5"
    {
        preset_config "$name: the \`$preset\` preset$([[ -n "$extra" ]] && echo " with the lines below"), trained with hazards in $rate of its episodes." "$preset" "$extra"
        echo
        echo "[env.hazards]"
        echo "rate = $rate"
    } >"$file"
}

# evaluate DIR OUT: the last checkpoint and best/ of run DIR on both suites and towns.
evaluate() {
    local dir="$1" out="$2" suite town
    local -a agents_args=(--checkpoint "$dir" --name last)
    [[ -d "$dir/best" ]] && agents_args+=(--checkpoint "$dir/best" --name best)
    for suite in hazards clean; do
        for town in default_town held_out_town; do
            [[ -f "$out/eval-$suite-$town.json" ]] && continue
            echo "   evaluating on $suite / $town ($runs runs per scenario)" >&2
            "$actor" eval --suite "$suite" --town "$town" --runs "$runs" --seed 0 "${agents_args[@]}" \
                --json-out "$out/eval-$suite-$town.json.tmp" >/dev/null
            mv "$out/eval-$suite-$town.json.tmp" "$out/eval-$suite-$town.json"
        done
    done
}

# train_and_evaluate NAME PRESET EXTRA RATE SEED BUDGET [RESULTS_NAME]: one run, skipped when its
# run.json exists. The run directory is RUNS_DIR/NAME/seedS, its results RESULTS/NAME/seedS.
train_and_evaluate() {
    local name="$1" preset="$2" extra="$3" rate="$4" seed="$5" budget="$6"
    local dir="$runs_dir/$name/seed$seed" out="$results/$name/seed$seed"
    run_done "$name" "$seed" "$out" && return
    mkdir -p "$dir" "$out"
    local cfg="$out/config.toml"
    [[ -f "$cfg" ]] || config_for "$name" "$preset" "$extra" "$rate" "$cfg"
    session_begin
    echo "== $name seed $seed: training to $budget env steps, hazard rate $rate (run directory $dir)" >&2
    echo "+ $actor train --config $cfg --run-dir $dir --seed $seed --max-env-steps $budget --eval-every $eval_every" >&2
    "$actor" train --config "$cfg" --run-dir "$dir" --seed "$seed" --max-env-steps "$budget" --eval-every "$eval_every"
    session_end
    evaluate "$dir" "$out"
    local -a kept
    keep_run_args kept "$dir" "$out" "$name" "$preset" "$seed" "$budget"
    python3 scripts/hazard_results.py keep-run "${kept[@]}" --rate "$rate" ${started_from:+--started-from "$started_from"}
}

if [[ "$report_only" == 0 ]]; then
    e2e=$(python3 scripts/results.py best-end-to-end --results experiments/results) || {
        echo "reproduce-hazards.sh: scripts/reproduce.sh's end-to-end search has not finished" >&2
        exit 1
    }
    e2e_row=""
    for v in "${search[@]}"; do [[ "${v%%|*}" == "$e2e" ]] && e2e_row="$v"; done
    # agent_row NAME: NAME's row (NAME|PRESET|TOML|WHAT); hz-e2e-best takes the search winner's.
    agent_row() {
        local v
        for v in "${agents[@]}" "${steady[@]}"; do
            [[ "${v%%|*}" == "$1" ]] || continue
            if [[ "$1" == hz-e2e-best ]]; then
                IFS='|' read -r _ p x _ <<<"$e2e_row"
                echo "$1|$p|$x|"
            else
                echo "$v"
            fi
        done
    }
    searched() { [[ ",$rate_search," == *",$1,"* ]]; }
    # search_name NAME RATE: the rate search's run of NAME at RATE (hz-hybrid-tuned's, the first
    # search, kept the name rate-R).
    IFS='|' read -r tuned tuned_preset tuned_extra _ <<<"${agents[0]}"
    search_name() { if [[ "$1" == "$tuned" ]]; then echo "rate-$2"; else echo "rate-$2-$1"; fi; }
    kept_rate() { python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["hazard_rate"])' "$results/$1/seed1/run.json"; }
    # 1. The rate searches: hz-hybrid-tuned's first (its best is every unsearched agent's rate),
    # then each other agent of --rate-search; an agent's own seed 1 trained at a rate is its
    # point there. The best run becomes the agent's seed 1.
    declare -A agent_rate=()
    for v in "${agents[@]}"; do
        name="${v%%|*}"
        [[ "$name" == "$tuned" ]] || searched "$name" || continue
        if wanted rates || wanted "$name"; then
            IFS='|' read -r _ preset extra _ <<<"$(agent_row "$name")"
            for r in ${rates//,/ }; do
                if [[ "$name" != "$tuned" && -f "$results/$name/seed1/run.json" ]] \
                    && python3 -c 'import sys; sys.exit(float(sys.argv[1]) != float(sys.argv[2]))' "$(kept_rate "$name")" "$r"; then
                    echo "== $name at rate $r: its own seed 1 ($results/$name/seed1)" >&2
                    continue
                fi
                train_and_evaluate "$(search_name "$name" "$r")" "$preset" "$extra" "$r" 1 "$env_steps"
            done
        fi
        best=$(python3 scripts/hazard_results.py best-rate --results "$results" --rates "$rates" --agent "$name") || {
            if [[ "$name" == "$tuned" ]]; then
                echo "reproduce-hazards.sh: the rate search has not finished (run --agents rates first)" >&2
                exit 1
            fi
            echo "== $name: its rate search has not finished (--agents rates runs it); it trains at $tuned's rate" >&2
            continue
        }
        agent_rate[$name]="$best"
        if [[ ! -e "$results/$name/seed1" ]]; then
            from=$(search_name "$name" "$best")
            mkdir -p "$results/$name" "$runs_dir/$name"
            cp -r "$results/$from/seed1" "$results/$name/seed1"
            sed -i "s/^# $from:/# $name:/" "$results/$name/seed1/config.toml"
            python3 scripts/hazard_results.py rename-run --out "$results/$name/seed1" --name "$name"
            [[ -e "$runs_dir/$name/seed1" ]] || ln -s "../$from/seed1" "$runs_dir/$name/seed1"
        fi
    done
    rate="${agent_rate[$tuned]}"
    echo "== the hazard rate: $rate (hz-hybrid-tuned's search; every agent not in --rate-search trains at it)" >&2
    # rate_of NAME: the rate NAME's seeds train at: its search's best, or hz-hybrid-tuned's; where
    # its kept seeds were trained at another (a search finished after them), theirs, said aloud,
    # so that one row never mixes rates.
    rate_of() {
        local want="${agent_rate[$1]:-$rate}" kept
        if [[ -f "$results/$1/seed1/run.json" ]]; then
            kept=$(kept_rate "$1")
            if python3 -c 'import sys; sys.exit(float(sys.argv[1]) == float(sys.argv[2]))' "$kept" "$want"; then
                echo "== $1: its kept seeds were trained at rate $kept and its search now picks $want; they stay (to retrain at $want, move $results/$1 out of $results: its seed 1 then becomes the search's run at $want)" >&2
                want="$kept"
            fi
        fi
        echo "$want"
    }
    # 2. The agents, seed by seed, so that an experiment stopped early has every agent.
    for seed in $(seq 1 "$seeds"); do
        for v in "${agents[@]}"; do
            IFS='|' read -r name preset extra _ <<<"$(agent_row "${v%%|*}")"
            if wanted "$name"; then train_and_evaluate "$name" "$preset" "$extra" "$(rate_of "$name")" "$seed" "$env_steps"; fi
        done
    done
    # 2b. The search for a steadier policy: seeds 1..--steady-seeds of each candidate,
    # hz-hybrid-tuned's rate and budget; its baseline is hz-hybrid-tuned's seeds.
    for seed in $(seq 1 "$steady_seeds"); do
        for v in "${steady[@]}"; do
            IFS='|' read -r name preset extra _ <<<"$v"
            if wanted steady || wanted "$name"; then train_and_evaluate "$name" "$preset" "$extra" "$(rate_of "$tuned")" "$seed" "$env_steps"; fi
        done
    done
    # 3. The longer-budget row: each seed's hz-hybrid-tuned run trained on.
    IFS='|' read -r long_name _ _ _ <<<"${long[0]}"
    if [[ "$long_env_steps" != 0 ]] && { wanted long || wanted "$long_name"; }; then
        for seed in $(seq 1 "$seeds"); do
            from="$runs_dir/$tuned/seed$seed" dir="$runs_dir/$long_name/seed$seed"
            if [[ -f "$results/$long_name/seed$seed/run.json" ]]; then
                echo "== $long_name seed $seed: done" >&2
                continue
            fi
            if [[ ! -f "$results/$tuned/seed$seed/run.json" ]]; then
                echo "== $long_name seed $seed: waits for $tuned seed $seed" >&2
                continue
            fi
            origin_file="$results/$long_name/seed$seed/started-from"
            mkdir -p "$results/$long_name/seed$seed"
            if [[ ! -d "$dir" ]]; then
                mkdir -p "$runs_dir/$long_name"
                if [[ -d "$from/checkpoint" ]]; then
                    echo "== $long_name seed $seed: starting from a copy of $from" >&2
                    cp -rL "$from" "$dir.tmp" && mv "$dir.tmp" "$dir"
                    echo "a copy of $from" >"$origin_file"
                else
                    # The run directories are not kept (a new machine, or a cleaned runs/): the same
                    # configuration and seed from scratch; its first 400k env steps are then not
                    # $tuned's run, which the tables' independent draws never assumed they were.
                    echo "== $long_name seed $seed: $from is gone; training from scratch with $tuned's configuration and seed" >&2
                    echo "scratch ($from was gone)" >"$origin_file"
                fi
            fi
            cp "$results/$tuned/seed$seed/config.toml" "$results/$long_name/seed$seed/config.toml"
            started_from=$(cat "$origin_file" 2>/dev/null || echo "a copy of $from")
            train_and_evaluate "$long_name" "$tuned_preset" "$tuned_extra" "$rate" "$seed" "$long_env_steps"
            started_from=""
        done
    fi
    # 5. The episode figure: each agent's lowest finished seed (of any --seeds), last checkpoint.
    episode_figure "$actor" "$results" "$runs_dir" "$runs" docs/figures/hazards-episode.svg "${agents[@]}" "${long[@]}"
fi
if [[ "$report_only" == 1 ]]; then
    kept_episode_figure "$results" docs/figures/hazards-episode.svg
fi

echo "== report: docs/RESULTS.md (hazard sections), experiments/results.json (\"hazards\"), docs/figures/hazards-*.svg" >&2
python3 scripts/hazard_results.py report --results "$results" --out-dir docs --json-out experiments/results.json
exit
}

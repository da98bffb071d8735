# Helpers shared by the scripts in this directory (sourced, not run).

# require_positive SCRIPT NAME:VALUE...: exits with status 2 and a message naming the flag unless
# every VALUE is a positive number.
require_positive() {
    local script="$1" pair name value
    shift
    for pair in "$@"; do
        name="${pair%%:*}" value="${pair#*:}"
        if ! [[ "$value" =~ ^[0-9]+([.][0-9]+)?$ ]] || [[ "$value" =~ ^0+([.]0+)?$ ]]; then
            echo "$script: --$name $value must be a positive number" >&2
            exit 2
        fi
    done
}

# require_known SCRIPT [--flag FLAG] ONLY EXTRA AGENT_ROW...: exits with status 2 and a message
# listing the valid names unless every comma-separated name in ONLY (the value of FLAG, by default
# --agents) is the name of one of the AGENT_ROWs (NAME|...) or one of the space-separated EXTRA names.
require_known() {
    local script="$1" flag="--agents"
    shift
    if [[ "$1" == --flag ]]; then flag="$2"; shift 2; fi
    local only="$1" known=" $2 " v name
    shift 2
    for v in "$@"; do known+="${v%%|*} "; done
    for name in ${only//,/ }; do
        if [[ "$known" != *" $name "* ]]; then
            echo "$script: $flag: unknown agent \`$name\`; expected some of:$known" >&2
            exit 2
        fi
    done
}

# resume_on_interrupt SCRIPT: on Ctrl-C or TERM, says how to resume and exits with status 130.
resume_on_interrupt() {
    # shellcheck disable=SC2064  # the script's name is fixed now
    trap "echo; echo \"$1: interrupted — run the same command again to resume.\" >&2; exit 130" INT TERM
}

# agents_of GROUP ARRAY: fills ARRAY with the agents of experiments/agents.txt in GROUP (main,
# search, ablation), in the file's order, each as NAME|PRESET|TOML|WHAT; exits with status 2,
# naming the file and the group, when it has none.
agents_of() {
    local group="$1" line file
    local -n rows="$2"
    file="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/experiments/agents.txt"
    if [[ ! -f "$file" ]]; then
        echo "$file: not found (the agents of the experiments)" >&2
        exit 2
    fi
    rows=()
    while IFS= read -r line || [[ -n "$line" ]]; do
        [[ -z "$line" || "$line" == \#* ]] && continue
        if [[ "${line%%|*}" == "$group" ]]; then rows+=("${line#*|}"); fi
    done <"$file"
    if [[ ${#rows[@]} -eq 0 ]]; then
        echo "$file: no agent in group \`$group\`" >&2
        exit 2
    fi
}

# wanted NAME: whether the script's --agents (the comma-separated names in `$only`) asks for NAME;
# an empty `$only` asks for every agent.
wanted() {
    [[ -z "$only" ]] && return 0
    [[ ",$only," == *",$1,"* ]]
}

# preset_config HEADER PRESET EXTRA: prints a run's configuration file: the comment HEADER, the
# preset, and EXTRA (TOML lines, `\n` for a line break) when there is any.
preset_config() {
    echo "# $1"
    echo "preset = \"$2\""
    if [[ -n "$3" ]]; then
        echo
        printf '%b\n' "$3"
    fi
}

# build_release: builds the programs the experiments run (`actor`, `learner`) in release, saying so.
build_release() {
    echo "+ cargo build --release --locked -p actor -p learner-cli" >&2
    cargo build --release --locked -p actor -p learner-cli
}

# run_done NAME SEED OUT: whether the run of NAME with SEED is kept already (OUT/run.json exists),
# saying so.
run_done() {
    [[ -f "$3/run.json" ]] || return 1
    echo "== $1 seed $2: done ($3/run.json)" >&2
}

# session_begin: notes a training session's start for keep_run_args: `started` (UTC),
# `load_before` (the 1, 5 and 15 min load averages) and `session_t0` (epoch seconds).
session_begin() {
    started=$(date -u +%Y-%m-%dT%H:%M:%SZ)
    load_before=$(cut -d' ' -f1-3 /proc/loadavg)
    session_t0=$(date +%s)
}

# session_end: notes the session's length, `session_secs`, since session_begin.
session_end() {
    session_secs=$(( $(date +%s) - session_t0 ))
}

# keep_run_args ARRAY DIR OUT NAME PRESET SEED BUDGET: fills ARRAY with the flags of `keep-run`
# (scripts/results.py, scripts/hazard_results.py) that keep run DIR in OUT: the agent, its seed and
# env-step budget, the session session_begin and session_end measured, and this checkout's commit.
keep_run_args() {
    local -n flags="$1"
    flags=(--run-dir "$2" --out "$3" --name "$4" --preset "$5" --seed "$6" --env-steps-budget "$7"
        --started "$started" --load-before "$load_before" --session-secs "$session_secs"
        --commit "$(git rev-parse --short HEAD 2>/dev/null || echo unknown)")
}

# evaluate_towns ACTOR DIR NAME SEED RUNS OUT: `actor eval` of run DIR's last checkpoint on the
# training town and the held-out one, RUNS runs per route, into OUT/eval-TOWN.json.
evaluate_towns() {
    local town
    for town in default_town held_out_town; do
        echo "== $3 seed $4: evaluating on $town ($5 runs per route)" >&2
        "$1" eval --checkpoint "$2" --name "$3" --town "$town" --runs "$5" --seed 0 --json-out "$6/eval-$town.json" >/dev/null
    done
}

# episode_figure ACTOR RESULTS RUNS_DIR RUNS FIGURE AGENT_ROW...: the episode figure of a hazard
# experiment: each agent of the AGENT_ROWs (NAME|...) that has a finished run in RESULTS, with its
# lowest finished seed whose run directory is in RUNS_DIR (last checkpoint), driven around the same
# hazards (the suite's seeds on default_town, RUNS runs per kind) beside the baselines; the
# stalled-car runs kept in RESULTS/episode/stalled_car.jsonl and drawn into FIGURE. A kept figure
# is redrawn only when every such agent has its run directory here: a machine that trained a few
# runs must not replace it with a figure of fewer agents.
episode_figure() {
    local actor="$1" results="$2" runs_dir="$3" runs="$4" figure="$5" v name d seed found
    shift 5
    local -a fig_args=() missing=()
    for v in "$@"; do
        name="${v%%|*}"
        compgen -G "$results/$name/seed*/run.json" >/dev/null || continue
        found=0
        for d in $(ls -d "$runs_dir/$name"/seed* 2>/dev/null | sort -V); do
            seed="${d##*/seed}"
            if [[ -f "$results/$name/seed$seed/run.json" && -f "$d/checkpoint/online.safetensors" ]]; then
                fig_args+=(--checkpoint "$d" --name "$name, seed $seed")
                found=1
                break
            fi
        done
        [[ "$found" == 1 ]] || missing+=("$name")
    done
    local kept="$results/episode/stalled_car.jsonl"
    if [[ ${#missing[@]} -gt 0 && -f "$kept" ]]; then
        echo "== the episode figure: kept as it is ($kept); no finished checkpoint here for ${missing[*]}" >&2
        return 0
    fi
    [[ ${#fig_args[@]} -gt 0 ]] || return 0
    echo "== the episode figure's runs: $(( ${#fig_args[@]} / 4 )) checkpoints and the baselines, hazard suite on default_town" >&2
    "$actor" eval --suite hazards --town default_town --runs "$runs" --seed 0 "${fig_args[@]}" \
        --trajectories-out "$runs_dir/trajectories.jsonl" >/dev/null
    mkdir -p "$results/episode"
    python3 scripts/episode_figure.py --trajectories "$runs_dir/trajectories.jsonl" --scenario stalled_car \
        --keep "$kept" --out "$figure"
}

# kept_episode_figure RESULTS FIGURE: FIGURE drawn again from the stalled-car runs that
# episode_figure kept in RESULTS/episode/stalled_car.jsonl (nothing when none are kept).
kept_episode_figure() {
    local kept="$1/episode/stalled_car.jsonl"
    [[ -f "$kept" ]] || return 0
    python3 scripts/episode_figure.py --trajectories "$kept" --scenario stalled_car --out "$2"
}

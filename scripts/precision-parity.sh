#!/usr/bin/env bash
# Learning parity of the two arithmetics (issue 27): README's agent (the `hybrid-tuned` preset)
# trained with `[agent] precision = "f32"` and with `"bf16"` on this machine, same seeds and budget
# as docs/RESULTS.md's main experiment, each run evaluated greedily on both towns as there
# (`actor eval --runs 5 --seed 0`). The bf16 runs need a bf16 kernel here (AMX, or AVX512-BF16 as
# on AMD Zen 4); `actor train` refuses `bf16` elsewhere, naming why.
#
# Each (precision, seed) run keeps what the table needs in OUT/PREC/seedS/ (OUT defaults to
# experiments/precision-parity; give each machine class its own, e.g. `--out
# experiments/precision-parity/amx`): config, evaluations, a compact run.json (results.py
# keep-run). A run whose run.json exists is done and skipped, and a stopped run continues from its
# checkpoint under runs/ (OUT's path less `experiments/`, e.g. runs/precision-parity/amx/PREC/seedS).
# The table at the end gives each run's mean completion and completed runs per town (to read
# against RESULTS.md's hybrid-tuned seed spread).
#
# Usage: scripts/precision-parity.sh [--seeds N] [--env-steps N] [--precisions f32,bf16] [--out DIR] [--no-build]
set -euo pipefail
seeds=1
env_steps=400000
precisions=f32,bf16
build=1
out_root=experiments/precision-parity
while [[ $# -gt 0 ]]; do
    case "$1" in
        --seeds) seeds="${2:?--seeds needs a number}"; shift 2 ;;
        --env-steps) env_steps="${2:?--env-steps needs a number}"; shift 2 ;;
        --precisions) precisions="${2:?--precisions needs f32, bf16 or f32,bf16}"; shift 2 ;;
        --out) out_root="${2:?--out needs a directory}"; shift 2 ;;
        --no-build) build=0; shift ;;
        -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "precision-parity.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
    esac
done
cd "$(dirname "$0")/.."
# shellcheck source=scripts/lib.sh
source scripts/lib.sh
require_positive precision-parity.sh "seeds:$seeds" "env-steps:$env_steps"
IFS=',' read -r -a wanted <<<"$precisions"
for p in "${wanted[@]}"; do
    [[ "$p" == f32 || "$p" == bf16 ]] || { echo "precision-parity.sh: --precisions: \`$p\` is not f32 or bf16" >&2; exit 2; }
done
resume_on_interrupt precision-parity.sh
[[ "$build" == 1 ]] && cargo build --release -q -p actor
actor="${CARGO_TARGET_DIR:-target}/release/actor"
out_root=${out_root%/}
run_root=${out_root#experiments/}
run_root=${run_root#/}
for seed in $(seq 1 "$seeds"); do
    for p in "${wanted[@]}"; do
        name="hybrid-tuned-$p" dir="runs/$run_root/$p/seed$seed" out="$out_root/$p/seed$seed"
        run_done "$name" "$seed" "$out" && continue
        mkdir -p "$dir" "$out"
        printf '# README'"'"'s agent in %s arithmetic (scripts/precision-parity.sh).\npreset = "hybrid-tuned"\n\n[agent]\nprecision = "%s"\n' "$p" "$p" >"$out/config.toml"
        session_begin
        echo "== $name seed $seed: training to $env_steps env steps ($dir)" >&2
        "$actor" train --config "$out/config.toml" --run-dir "$dir" --seed "$seed" --max-env-steps "$env_steps" --eval-every 1
        session_end
        evaluate_towns "$actor" "$dir" "$name" "$seed" 5 "$out"
        keep_run_args kept "$dir" "$out" "$name" hybrid-tuned "$seed" "$env_steps"
        python3 scripts/results.py keep-run "${kept[@]}"
    done
done
python3 - "$out_root" <<'PY'
import glob, json, os, sys
root = sys.argv[1]
print("| precision | seed | town | completion (mean over routes) | runs completed | updates | train minutes | cpu |")
print("|---|---|---|---|---|---|---|---|")
for run in sorted(glob.glob(f"{root}/*/seed*/run.json")):
    r = json.load(open(run))
    base = os.path.dirname(run)
    for town in ("default_town", "held_out_town"):
        agent = next(a for a in json.load(open(f"{base}/eval-{town}.json"))["agents"] if a["kind"] == "checkpoint")
        routes = agent["routes"]
        completion = sum(x["completion_rate"] for x in routes) / len(routes)
        done, runs = sum(x["completed"] for x in routes), sum(x["runs"] for x in routes)
        print(f"| {base.split('/')[-2]} | {r['seed']} | {town} | {completion:.2f} | {done}/{runs} | {r.get('learner_step')} | {r.get('train_minutes')} | {r.get('cpu')} |")
PY

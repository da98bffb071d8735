#!/usr/bin/env bash
# fastnet (f32 and bf16, `learner bench train --precision both`) beside PyTorch (f32 and bf16
# autocast, scripts/torch_peer.py) on the same network, batch and threads, alternating the two
# programs ROUNDS times per input so that both see the same machine. Prints one JSON object per
# run and a summary with the ratios (PyTorch's time / fastnet's: above 1, fastnet is ahead).
# Needs PyTorch: PYTHON (default python3) must import torch. LEARNER names a built `learner`
# binary to time (default: this checkout's, built here first). An INPUT is an image SIZExSIZExC or
# vector:N, the multilayer perceptron of a vector input (N inputs, hidden 256, VECTOR_ACTIONS
# actions, default 27, at batch VECTOR_BATCH, default 256). Where the CPU has no bf16 kernel for
# fastnet, PRECISION=f32 times f32 alone (PyTorch still runs both). Usage:
#   scripts/bench-vs-torch.sh [ROUNDS] [INPUT...]      e.g. scripts/bench-vs-torch.sh 3 84x84x1 48x48x1 vector:150
set -euo pipefail
cd "$(dirname "$0")/.."
rounds=${1:-3}
shift || true
if [ $# -gt 0 ]; then inputs=("$@"); else inputs=(84x84x1 48x48x1); fi
python=${PYTHON:-python3}
"$python" -c 'import torch' 2>/dev/null || { echo "bench-vs-torch: $python cannot import torch (set PYTHON to one that can)" >&2; exit 2; }
learner=${LEARNER:-}
if [ -z "$learner" ]; then
    cargo build --release -q -p learner-cli
    learner=${CARGO_TARGET_DIR:-./target}/release/learner
fi
echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2-) | flags: $(grep -o -w -E 'amx_bf16|amx_tile|avx512_bf16|avx512f' /proc/cpuinfo | sort -u | tr '\n' ' ')" >&2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
precision=${PRECISION:-both}
for input in "${inputs[@]}"; do
    case $input in
        vector:*)
            batch=${VECTOR_BATCH:-256}
            actions=${VECTOR_ACTIONS:-27}
            fastnet_args=(--input "$input" --actions "$actions" --batch "$batch")
            torch_args=(0 0 --vector "${input#vector:}" --actions "$actions" --batch "$batch")
            ;;
        *)
            fastnet_args=(--input "$input")
            torch_args=("${input%%x*}" "${input##*x}")
            ;;
    esac
    for round in $(seq "$rounds"); do
        echo "[$input round $round/$rounds] fastnet" >&2
        "$learner" bench train --precision "$precision" "${fastnet_args[@]}" --threads 2 --updates 10 --json 2>/dev/null | tail -1 | tee -a "$tmp/fastnet-$input.jsonl"
        echo "[$input round $round/$rounds] pytorch" >&2
        "$python" scripts/torch_peer.py "${torch_args[@]}" | tee -a "$tmp/torch-$input.jsonl"
    done
done
"$python" - "$tmp" "${inputs[@]}" <<'PY'
import json, statistics, sys
tmp, inputs = sys.argv[1], sys.argv[2:]
summary = {}
for i in inputs:
    fast = [json.loads(l) for l in open(f"{tmp}/fastnet-{i}.jsonl")]
    torch = [json.loads(l) for l in open(f"{tmp}/torch-{i}.jsonl")]
    # One precision: its figures are top-level fields of fastnet's object.
    fast_p = lambda r, p: r[p] if p in r else (r if r.get("precision") == p else None)
    med = lambda runs, p, k: statistics.median(r[p][k] for r in runs)
    row = {"batch": fast[0]["batch"]}
    for k in ["ms_per_update", "forward_batch1_ms"]:
        for p in ["f32", "bf16"]:
            mine = [fast_p(r, p) for r in fast]
            row[f"fastnet_{p}_{k}"] = statistics.median(m[k] for m in mine) if all(mine) else None
            row[f"torch_{p}_{k}"] = med(torch, p, k)
        for p in ["f32", "bf16"]:
            if row[f"fastnet_{p}_{k}"]:
                row[f"torch_{p}_over_fastnet_{p}_{k}"] = row[f"torch_{p}_{k}"] / row[f"fastnet_{p}_{k}"]
        if row[f"fastnet_bf16_{k}"] and row[f"fastnet_f32_{k}"]:
            row[f"fastnet_bf16_over_f32_{k}"] = row[f"fastnet_bf16_{k}"] / row[f"fastnet_f32_{k}"]
    row["rounds"] = len(fast)
    row["load_before"] = fast[0].get("load_before")
    row["torch"] = torch[0]["torch"]
    summary[i] = row
print(json.dumps({"summary": summary}, indent=1))
PY

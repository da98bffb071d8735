#!/usr/bin/env bash
# The ceiling of each action set (docs/EVALUATION.md): both baselines with every control
# quantised to a set's nearest action, beside the continuous drivers, on both suites and towns,
# 10 runs per scenario; prints the Markdown table. Usage: scripts/action-set-ceiling.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/action-set-ceiling}
mkdir -p "$out"
actor=./target/release/actor
for town in default_town held_out_town; do
  for suite in hazards clean; do
    for set in none paper6 paper12 full15 full21 full27; do
      q=(); [ "$set" != none ] && q=(--quantise "$set")
      echo "$suite $town $set" >&2
      "$actor" eval --suite "$suite" --town "$town" --runs 10 "${q[@]}" --json-out "$out/$suite-$town-$set.json" --json > /dev/null
    done
  done
done
python3 - "$out" <<'PY'
import glob, json, sys
rows = {}
for f in glob.glob(f"{sys.argv[1]}/*.json"):
    r = json.load(open(f))
    for a in r["agents"]:
        rows[(a["name"], r["suite"], r["town"], r.get("quantise", "none"))] = a["driving_score"]
sets = ["paper6", "paper12", "full15", "full21", "full27"]
print("| baseline | suite | town | continuous | " + " | ".join(sets) + " |")
print("|---|---|---|" + "---:|" * (len(sets) + 1))
for a in ["model-based", "model-based-avoid"]:
    for s in ["hazards", "clean"]:
        for t in ["default_town", "held_out_town"]:
            base = rows[(a, s, t, "none")]
            cells = [f"{base:.2f}"] + [f"{rows[(a, s, t, q)]:.2f} ({100 * rows[(a, s, t, q)] / base:.0f} %)" for q in sets]
            print(f"| `{a}` | {s} | {t} | " + " | ".join(cells) + " |")
PY

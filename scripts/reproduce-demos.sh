#!/usr/bin/env bash
# Demonstrations on the hazard suite (docs/RESULTS.md, "Learning from the planner that sees"):
# the `hybrid-vector` preset with and without one `model-based-avoid` demonstrator (and with
# pre-training on its demonstrations, without the margin loss, and with a share of batches that
# decays to none over 200k steps), each seed evaluated on the hazard suite of default_town (10
# runs per kind) at each budget, resumed from the last.
# Resumable: a finished evaluation is kept and not rerun; an interrupted training continues.
# Usage: scripts/reproduce-demos.sh [--seeds "1 2 3"] [--budgets "100000 200000 400000"]
#        [--arms "none demo pretrain nomargin decay"] [--runs-dir runs/demos] [--out experiments/demonstrations]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh
seeds="1 2 3" budgets="100000 200000 400000" arms="none demo pretrain nomargin decay"
runs_dir=runs/demos out=experiments/demonstrations
while [ $# -gt 0 ]; do
  case "$1" in
    --seeds) seeds=$2; shift 2 ;;
    --budgets) budgets=$2; shift 2 ;;
    --arms) arms=$2; shift 2 ;;
    --runs-dir) runs_dir=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    -h|--help) sed -n 2,8p "$0"; exit 0 ;;
    *) echo "reproduce-demos.sh: unknown argument \`$1\` (see --help)" >&2; exit 2 ;;
  esac
done
for a in $arms; do
  case "$a" in none|demo|pretrain|nomargin|decay) ;; *) echo "reproduce-demos.sh: --arms: unknown arm \`$a\`; expected some of: none demo pretrain nomargin decay" >&2; exit 2 ;; esac
done
require_positive reproduce-demos.sh $(for b in $budgets; do echo "budgets:$b"; done)
resume_on_interrupt reproduce-demos.sh
actor=./target/release/actor
mkdir -p "$runs_dir" "$out"
# The pre-training arm: 2,000 updates on demonstrations alone before the first agent step.
cat > "$out/pretrain.toml" <<'TOML'
preset = "hybrid-vector"

[agent]
demo_pretrain_updates = 2000
TOML
# The no-margin arm: demonstrations in the replay, trained on by the TD loss alone.
cat > "$out/nomargin.toml" <<'TOML'
preset = "hybrid-vector"

[agent]
demo_margin_weight = 0.0
TOML
# The decaying arm: the demonstrations' share of batches from 0.25 to none over 200k env steps.
cat > "$out/decay.toml" <<'TOML'
preset = "hybrid-vector"

[agent]
demo_share_final = 0.0
demo_share_decay_steps = 200000
TOML
for seed in $seeds; do
  for arm in $arms; do
    run="$runs_dir/$arm-seed$seed" keep="$out/$arm/seed$seed"
    mkdir -p "$keep"
    case "$arm" in
      none) how=(--preset hybrid-vector) ;;
      demo) how=(--preset hybrid-vector --demo-actors 1) ;;
      pretrain) how=(--config "$out/pretrain.toml" --demo-actors 1) ;;
      nomargin) how=(--config "$out/nomargin.toml" --demo-actors 1) ;;
      decay) how=(--config "$out/decay.toml" --demo-actors 1) ;;
    esac
    for budget in $budgets; do
      [ -f "$keep/hazards-$budget.json" ] && continue
      echo "== $arm seed $seed: $budget env steps" >&2
      /usr/bin/time -f "%e s wall" -a -o "$keep/wall.txt" \
        "$actor" train "${how[@]}" --seed "$seed" --run-dir "$run" --max-env-steps "$budget" > "$keep/train-$budget.log" 2>&1
      "$actor" eval --suite hazards --checkpoint "$run" --runs 10 --json-out "$keep/hazards-$budget.json" --json > /dev/null
    done
  done
done
python3 scripts/demo_results.py "$out"

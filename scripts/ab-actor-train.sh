#!/usr/bin/env bash
# README's `actor train` (the hybrid-tuned preset, fresh run directory each time, no periodic
# evaluation) run by two builds in turn, ROUNDS times each, so that both see the same machine.
# Prints one JSON line per run: env steps/s and updates/s over the progress lines from 20 s to the
# end, and updates per env step (the replay ratio divided by the batch size, 0.25 / 32 = 0.0078
# when the learner keeps up). Then the mean of each build. Usage:
#   scripts/ab-actor-train.sh ROUNDS STEPS ACTOR_A ACTOR_B     e.g. scripts/ab-actor-train.sh 3 60000 /tmp/old/actor target/release/actor
set -euo pipefail
rounds=${1:?ROUNDS}
steps=${2:?STEPS}
bins=("${3:?ACTOR_A}" "${4:?ACTOR_B}")
for b in "${bins[@]}"; do [ -x "$b" ] || { echo "ab-actor-train: $b is not an executable actor" >&2; exit 2; }; done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "cpu: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2-) | load: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
for round in $(seq "$rounds"); do
    for i in 0 1; do
        echo "[round $round/$rounds] ${bins[$i]}" >&2
        "${bins[$i]}" train --run-dir "$tmp/run-$round-$i" --max-env-steps "$steps" --eval-every 0 > "$tmp/log-$round-$i" 2>&1
        python3 - "$tmp/log-$round-$i" "${bins[$i]}" <<'PY' | tee -a "$tmp/all.jsonl"
import json, re, sys
log, binary = sys.argv[1:]
rows = []
for line in open(log):
    m = re.match(r"\[\s*(\d+)s\] env steps (\d+) .* updates (\d+) ", line)
    if m:
        rows.append(tuple(map(int, m.groups())))
warm = [r for r in rows if r[0] >= 20]
if len(warm) < 2:
    sys.exit(f"ab-actor-train: {log}: fewer than two progress lines after 20 s (raise STEPS)")
(t0, s0, u0), (t1, s1, u1) = warm[0], warm[-1]
print(json.dumps({"actor": binary, "env_steps_per_s": round((s1 - s0) / (t1 - t0), 1),
                  "updates_per_s": round((u1 - u0) / (t1 - t0), 2),
                  "updates_per_env_step": round((u1 - u0) / (s1 - s0), 5), "window_s": [t0, t1],
                  "load1": float(open("/proc/loadavg").read().split()[0])}))
PY
    done
done
python3 - "$tmp/all.jsonl" <<'PY'
import json, statistics, sys
runs = [json.loads(l) for l in open(sys.argv[1])]
for actor in dict.fromkeys(r["actor"] for r in runs):
    mine = [r for r in runs if r["actor"] == actor]
    mean = lambda k: round(statistics.mean(r[k] for r in mine), 5)
    print(json.dumps({"actor": actor, "runs": len(mine), "env_steps_per_s": mean("env_steps_per_s"),
                      "updates_per_s": mean("updates_per_s"), "updates_per_env_step": mean("updates_per_env_step")}))
PY

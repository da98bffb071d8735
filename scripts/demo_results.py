#!/usr/bin/env python3
"""The tables of scripts/reproduce-demos.sh: per arm and budget, the hazard suite's driving score per
kind and overall (mean over seeds of the mean over kinds of the mean over runs) with 95 %
hierarchical-bootstrap intervals (seeds drawn with replacement, then each drawn seed's runs within
each kind), the baselines beside them; and the difference of each arm to `none` at the same budget.
Writes OUT/summary.json and prints Markdown. Standard library only.

Usage: scripts/demo_results.py OUT_DIR
"""

import json
import random
import sys
from pathlib import Path

KINDS = ["stalled_car", "pedestrian_crossing", "cut_in", "hard_brake", "construction", "opposite_overtaker", "junction_runner"]
BOOTSTRAP = 10_000


def load(out):
    """{(arm, budget): {seed: {kind: [run scores]}}} and the baselines' {name: {kind: [scores]}}."""
    runs, baselines = {}, {}
    for f in sorted(Path(out).glob("*/seed*/hazards-*.json")):
        arm, seed, budget = f.parent.parent.name, int(f.parent.name[4:]), int(f.stem.split("-")[1])
        report = json.loads(f.read_text())
        for agent in report["agents"]:
            kinds = {s["scenario"]: [r["driving_score"] for r in s["runs"]] for s in agent["scenarios"]}
            if agent["name"] in ("model-based", "model-based-avoid"):
                baselines[agent["name"]] = kinds
            else:
                runs.setdefault((arm, budget), {})[seed] = kinds
    return runs, baselines


def mean(xs):
    return sum(xs) / len(xs)


def statistic(seeds, kinds):
    return mean([mean([mean(s[k]) for k in kinds]) for s in seeds])


def resample(seeds, rng):
    drawn = [rng.choice(seeds) for _ in seeds]
    return [{k: [rng.choice(v) for _ in v] for k, v in s.items()} for s in drawn]


def interval(samples):
    samples.sort()
    return samples[int(0.025 * len(samples))], samples[int(0.975 * len(samples)) - 1]


def summarise(by_seed, kinds, rng):
    seeds = [by_seed[s] for s in sorted(by_seed)]
    boots = [resample(seeds, rng) for _ in range(BOOTSTRAP)]
    return {
        **{k: {"mean": statistic(seeds, [k]), "ci95": interval([statistic(b, [k]) for b in boots])} for k in kinds},
        "overall": {"mean": statistic(seeds, kinds), "ci95": interval([statistic(b, kinds) for b in boots])},
        "seeds": sorted(by_seed),
    }


def difference(a, b, kinds, rng):
    sa, sb = [a[s] for s in sorted(a)], [b[s] for s in sorted(b)]
    boots = [statistic(resample(sa, rng), kinds) - statistic(resample(sb, rng), kinds) for _ in range(BOOTSTRAP)]
    return {"mean": statistic(sa, kinds) - statistic(sb, kinds), "ci95": interval(boots)}


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "experiments/demonstrations")
    runs, baselines = load(out)
    if not runs:
        sys.exit(f"demo_results.py: no evaluations under {out}/ARM/seedS/hazards-BUDGET.json")
    rng = random.Random(0)
    summary = {"kinds": KINDS, "arms": {}, "differences": {}, "baselines": {}}
    for name, kinds in baselines.items():
        summary["baselines"][name] = {k: mean(kinds[k]) for k in KINDS} | {"overall": mean([mean(kinds[k]) for k in KINDS])}
    for (arm, budget), by_seed in sorted(runs.items()):
        summary["arms"][f"{arm} @ {budget}"] = summarise(by_seed, KINDS, rng)
        if arm != "none" and ("none", budget) in runs:
            summary["differences"][f"{arm} - none @ {budget}"] = difference(by_seed, runs[("none", budget)], KINDS, rng)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    short = ["stalled", "walker", "cut_in", "hard_brake", "construction", "overtaker", "runner"]
    print("| arm | env steps | seeds | " + " | ".join(short) + " | overall [95 %] |")
    print("|---|---:|---:|" + "---:|" * (len(KINDS) + 1))
    for key, s in summary["arms"].items():
        arm, budget = key.split(" @ ")
        lo, hi = s["overall"]["ci95"]
        cells = [f"{s[k]['mean']:.2f}" for k in KINDS]
        print(f"| {arm} | {int(budget):,} | {len(s['seeds'])} | " + " | ".join(cells) + f" | **{s['overall']['mean']:.2f}** [{lo:.2f}, {hi:.2f}] |")
    for name, b in summary["baselines"].items():
        print(f"| `{name}` | – | – | " + " | ".join(f"{b[k]:.2f}" for k in KINDS) + f" | {b['overall']:.2f} |")
    print()
    for key, d in summary["differences"].items():
        lo, hi = d["ci95"]
        print(f"- {key}: {d['mean']:+.2f} [{lo:+.2f}, {hi:+.2f}]")


if __name__ == "__main__":
    main()

"""Outcomes behind the driving scores, over every run of every seed of each arm at one budget: mean
route completion, successes, mean steps, mean speed at the hazard point, infractions by kind.
Usage: python3 behaviour.py [BUDGET] (default 400000), from this directory."""
import collections
import glob
import json
import sys

budget = sys.argv[1] if len(sys.argv) > 1 else "400000"
for arm in ["none", "demo", "pretrain", "nomargin", "decay"]:
    comp, steps, speed, infractions, n, success = [], [], [], collections.Counter(), 0, 0
    for f in sorted(glob.glob(f"{arm}/seed*/hazards-{budget}.json")):
        report = json.load(open(f))
        agent = [a for a in report["agents"] if a["name"] not in ("model-based", "model-based-avoid")][0]
        for scenario in agent["scenarios"]:
            for run in scenario["runs"]:
                n += 1
                comp.append(run["route_completion"])
                steps.append(run["steps"])
                success += run["success"]
                infractions.update(run["infractions"])
                if run["behaviour"].get("speed_at_hazard_ms") is not None:
                    speed.append(run["behaviour"]["speed_at_hazard_ms"])
    if n:
        print(f"{arm:9s} runs {n}  completion {sum(comp) / n:.2f}  successes {success}  steps {sum(steps) / n:.0f}  "
              f"speed at the hazard {sum(speed) / max(1, len(speed)):.1f} m/s  {dict(sorted(infractions.items()))}")

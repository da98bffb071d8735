#!/usr/bin/env python3
"""The results of scripts/reproduce-hazards.sh: keeps each run's outputs, picks the hazard rate,
and writes the hazard report (tables with hierarchical-bootstrap intervals, the "hazards" key of
experiments/results.json, figures).

  keep-run     copies what the tables need from a run directory into experiments/hazards/AGENT/seedS
               (the baselines' runs, the same in every evaluation, once into
               experiments/hazards/baselines/)
  rename-run   renames a kept run's agent (the rate search's run that is hz-hybrid-tuned's seed 1)
  best-rate    prints the searched rate whose run scored best in its last periodic evaluations
  report       the hazard sections of docs/RESULTS.md, experiments/results.json's "hazards",
               docs/figures/hazards-*.svg

Standard library only, so that it runs wherever the project's scripts run.
"""

import argparse
import json
import os
import random
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import results as main_results  # noqa: E402  (the main experiment's helpers: agents, bootstrap size, RESULTS.md sections)

SUITES = ["hazards", "clean"]
TOWNS = main_results.TOWNS
HAZARD_KINDS = ["stalled_car", "pedestrian_crossing", "cut_in", "hard_brake", "construction", "opposite_overtaker", "junction_runner"]
BASELINES = ["model-based", "model-based-avoid"]
CHECKPOINTS = ["last", "best"]
# Periodic evaluations whose selection scores choose the rate: the last few, not the best one (a
# maximum over noisy evaluations flatters the run that swings most).
RATE_WINDOW = 3
BOOTSTRAP = main_results.BOOTSTRAP


def eval_files(d):
    return {(s, t): d / f"eval-{s}-{t}.json" for s in SUITES for t in TOWNS}


def keep_run(a):
    run_dir, out = Path(a.run_dir), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    baselines = out.parent.parent / "baselines"
    baselines.mkdir(parents=True, exist_ok=True)
    for name in ["eval.jsonl", "train.jsonl"]:
        if (run_dir / name).exists():
            shutil.copyfile(run_dir / name, out / name)
    episodes = (run_dir / "episodes.jsonl").read_text().splitlines()
    step = max(1, -(-len(episodes) // main_results.MAX_EPISODES_KEPT))
    (out / "episodes.jsonl").write_text("".join(line + "\n" for line in episodes[::step]))
    # The baselines drive the same seeds in every evaluation: kept once, left out of the run's.
    for (suite, town), path in eval_files(out).items():
        ev = json.loads(path.read_text())
        base = [x for x in ev["agents"] if x["name"] in BASELINES]
        kept = baselines / path.name
        if base and not kept.exists():
            kept.write_text(json.dumps({**ev, "agents": base}) + "\n")
        ev["agents"] = [x for x in ev["agents"] if x["name"] not in BASELINES]
        path.write_text(json.dumps(ev) + "\n")
    train = main_results.read_jsonl(run_dir / "train.jsonl")
    counters = {}
    for which, sub in [("last", "checkpoint"), ("best", "best")]:
        p = run_dir / sub / "state.json"
        if p.exists():
            c = json.loads(p.read_text()).get("counters", {})
            counters[which] = {"env_steps": c.get("env_steps"), "learner_step": c.get("learner_step")}
    run = {
        "agent": a.name,
        "preset": a.preset,
        "seed": a.seed,
        "hazard_rate": a.rate,
        "env_steps_budget": a.env_steps_budget,
        "env_steps": counters.get("last", {}).get("env_steps"),
        "learner_step": counters.get("last", {}).get("learner_step"),
        "best": counters.get("best"),
        "episodes": len(episodes),
        "episodes_kept": len(episodes[::step]),
        "training_completion_first_reached": main_results.completion_milestones([json.loads(line) for line in episodes if line.strip()]),
        "train_minutes": round(train[-1]["time_secs"] / 60, 2) if train else None,
        "session_secs": a.session_secs,
        "started": a.started,
        "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "load_before": a.load_before,
        "load_after": " ".join(Path("/proc/loadavg").read_text().split()[:3]),
        "cpu": main_results.cpu_model(),
        "cores": os.cpu_count(),
        "commit": a.commit,
    }
    (out / "run.json").write_text(json.dumps(run, indent=1) + "\n")
    print(f"kept {out}: {run['env_steps']} env steps, {run['learner_step']} updates, {run['train_minutes']} min; best/ at {run['best']}", file=sys.stderr)


def rename_run(a):
    p = Path(a.out) / "run.json"
    run = json.loads(p.read_text())
    run["renamed_from"] = run["agent"]
    run["agent"] = a.name
    p.write_text(json.dumps(run, indent=1) + "\n")


def rate_score(d):
    """Mean selection score of the run's last RATE_WINDOW periodic evaluations, or None."""
    periodic = [e for e in main_results.read_jsonl(d / "eval.jsonl") if e.get("selection_score") is not None]
    last = periodic[-RATE_WINDOW:]
    return sum(e["selection_score"] for e in last) / len(last) if last else None


def best_rate(a):
    scores = {}
    for rate in a.rates.split(","):
        d = Path(a.results) / f"rate-{rate}" / "seed1"
        if not (d / "run.json").exists():
            raise SystemExit(f"{d}: the rate search's run at {rate} has not finished")
        scores[rate] = rate_score(d)
        if scores[rate] is None:
            raise SystemExit(f"{d / 'eval.jsonl'}: no periodic evaluation with a selection score")
    best = max(scores, key=lambda r: scores[r])
    print(", ".join(f"rate {r}: {s:.3f}" for r, s in scores.items()) + f"; best {best}", file=sys.stderr)
    print(best)


def report(a):
    raise SystemExit('report: not written yet')


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    k = sub.add_parser("keep-run")
    for flag in ["--run-dir", "--out", "--name", "--preset", "--rate", "--started", "--load-before", "--commit"]:
        k.add_argument(flag, required=True)
    k.add_argument("--seed", type=int, required=True)
    k.add_argument("--env-steps-budget", type=int, required=True)
    k.add_argument("--session-secs", type=int, required=True)
    n = sub.add_parser("rename-run")
    n.add_argument("--out", required=True)
    n.add_argument("--name", required=True)
    b = sub.add_parser("best-rate")
    b.add_argument("--results", required=True)
    b.add_argument("--rates", required=True)
    r = sub.add_parser("report")
    r.add_argument("--results", required=True)
    r.add_argument("--out-dir", required=True, help="where RESULTS.md and figures/ are")
    r.add_argument("--json-out", required=True, help="the results.json whose \"hazards\" key to write")
    a = p.parse_args()
    {"keep-run": keep_run, "rename-run": rename_run, "best-rate": best_rate, "report": report}[a.cmd](a)


if __name__ == "__main__":
    main()

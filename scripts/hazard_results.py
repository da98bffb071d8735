#!/usr/bin/env python3
"""The results of scripts/reproduce-hazards.sh: keeps each run's outputs, picks the hazard rate,
and writes the hazard report (tables with hierarchical-bootstrap intervals, the "hazards" key of
experiments/results.json, figures).

  keep-run     copies what the tables need from a run directory into experiments/hazards/AGENT/seedS
               (the baselines' runs, the same in every evaluation, once into
               experiments/hazards/baselines/)
  rename-run   renames a kept run's agent (the rate search's run that becomes an agent's seed 1)
  best-rate    prints the searched rate whose run scored best in its last periodic evaluations, for
               one agent (--agent; default hz-hybrid-tuned)
  report       the hazard sections of docs/RESULTS.md, experiments/results.json's "hazards",
               docs/figures/hazards-*.svg

Standard library only, so that it runs wherever the project's scripts run.
"""

import argparse
import json
import random
import shutil
import sys
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
# How much a run's greedy policy swings: the spread of its last few periodic selection scores.
SWING_WINDOW = 5
BOOTSTRAP = main_results.BOOTSTRAP


def eval_files(d):
    return {(s, t): d / f"eval-{s}-{t}.json" for s in SUITES for t in TOWNS}


def run_record(a, run_dir, episodes):
    """What a kept run's run.json says of every run (`a`: keep-run's arguments): the agent, seed
    and budget, the last and best/ checkpoints' counters, and how it ran."""
    counters = {}
    for which, sub in [("last", "checkpoint"), ("best", "best")]:
        p = run_dir / sub / "state.json"
        if p.exists():
            c = json.loads(p.read_text()).get("counters", {})
            counters[which] = {"env_steps": c.get("env_steps"), "learner_step": c.get("learner_step")}
    return {
        "agent": a.name,
        "preset": a.preset,
        "seed": a.seed,
        "env_steps_budget": a.env_steps_budget,
        "env_steps": counters.get("last", {}).get("env_steps"),
        "learner_step": counters.get("last", {}).get("learner_step"),
        "best": counters.get("best"),
        "episodes": len(episodes),
        **main_results.how_it_ran(a, episodes, main_results.read_jsonl(run_dir / "train.jsonl")),
    }


def keep_run(a):
    run_dir, out = Path(a.run_dir), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    baselines = out.parent.parent / "baselines"
    baselines.mkdir(parents=True, exist_ok=True)
    for name in ["eval.jsonl", "train.jsonl"]:
        if (run_dir / name).exists():
            shutil.copyfile(run_dir / name, out / name)
    episodes = main_results.keep_curve(run_dir, out)
    # The baselines drive the same seeds in every evaluation: kept once, left out of the run's.
    for (suite, town), path in eval_files(out).items():
        ev = json.loads(path.read_text())
        base = [x for x in ev["agents"] if x["name"] in BASELINES]
        kept = baselines / path.name
        if base and not kept.exists():
            kept.write_text(json.dumps({**ev, "agents": base}) + "\n")
        ev["agents"] = [x for x in ev["agents"] if x["name"] not in BASELINES]
        path.write_text(json.dumps(ev) + "\n")
    run = {**run_record(a, run_dir, episodes), "hazard_rate": a.rate}
    if a.started_from:
        run["started_from"] = a.started_from
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


def swing(d):
    """Standard deviation of the run's last SWING_WINDOW periodic selection scores, or None."""
    scores = [e["selection_score"] for e in main_results.read_jsonl(d / "eval.jsonl") if e.get("selection_score") is not None][-SWING_WINDOW:]
    if len(scores) < 2:
        return None
    mean = sum(scores) / len(scores)
    return (sum((x - mean) ** 2 for x in scores) / (len(scores) - 1)) ** 0.5


def tuned_agent():
    return main_results.agents_of("hazards")[0]


def search_name(agent, rate):
    """The rate search's run of AGENT at RATE: `rate-R` for the tuned agent (the first search,
    which kept that name), `rate-R-AGENT` for the others."""
    return f"rate-{rate}" if agent == tuned_agent() else f"rate-{rate}-{agent}"


def search_dir(results, agent, rate):
    """The run that is AGENT's search point at RATE: its search run, or else the agent's own seed 1
    where that was trained at RATE (the same configuration and seed: the run the search would do)."""
    d = Path(results) / search_name(agent, rate) / "seed1"
    if (d / "run.json").exists():
        return d
    own = Path(results) / agent / "seed1"
    if (own / "run.json").exists() and float(json.loads((own / "run.json").read_text()).get("hazard_rate", "nan")) == float(rate):
        return own
    return d


def best_rate(a):
    agent = getattr(a, "agent", None) or tuned_agent()
    scores = {}
    for rate in a.rates.split(","):
        d = search_dir(a.results, agent, rate)
        if not (d / "run.json").exists():
            raise SystemExit(f"{d}: the rate search's run of {agent} at {rate} has not finished")
        scores[rate] = rate_score(d)
        if scores[rate] is None:
            raise SystemExit(f"{d / 'eval.jsonl'}: no periodic evaluation with a selection score")
    best = max(scores, key=lambda r: scores[r])
    print(f"{agent}: " + ", ".join(f"rate {r}: {s:.3f}" for r, s in scores.items()) + f"; best {best}", file=sys.stderr)
    print(best)


def load_runs(results):
    """{agent: {seed: run}} of the finished runs, each with its evaluations ({(suite, town):
    {checkpoint: agent report}}) and its periodic evaluations."""
    runs = {}
    for run_json in sorted(Path(results).glob("*/seed*/run.json")):
        d = run_json.parent
        r = json.loads(run_json.read_text())
        r["dir"], r["evals"] = d, {}
        for key, path in eval_files(d).items():
            if path.exists():
                r["evals"][key] = {x["name"]: x for x in json.loads(path.read_text())["agents"]}
        r["periodic"] = main_results.read_jsonl(d / "eval.jsonl")
        runs.setdefault(r["agent"], {})[r["seed"]] = r
    return runs


def load_baselines(results):
    """{(suite, town): {baseline: agent report}}."""
    out = {}
    for key, path in eval_files(Path(results) / "baselines").items():
        if path.exists():
            out[key] = {x["name"]: x for x in json.loads(path.read_text())["agents"]}
    return out


def seed_samples(reports):
    """Per seed (one agent report each): {scenario: [run scores]}."""
    return [{s["scenario"]: s["runs"] for s in rep["scenarios"]} for rep in reports]


def metrics(seeds):
    """The suite's figures from per-seed {scenario: [runs]}: each the mean over seeds of a
    per-seed value. Driving score, completion and success: the mean over scenarios of the mean
    over runs (every kind weighs the same, as in the suite's own overall line); infractions per km:
    all the seed's infractions over all its route kilometres; and the driving score per scenario."""
    per_seed = []
    for s in seeds:
        m = {}
        for key, field in [("driving_score", "driving_score"), ("route_completion", "route_completion"), ("success_rate", "success")]:
            m[key] = sum(sum(float(r[field]) for r in runs) / len(runs) for runs in s.values()) / len(s)
        km = sum(r["km"] for runs in s.values() for r in runs)
        m["infractions_per_km"] = sum(len(r["infractions"]) for runs in s.values() for r in runs) / km if km > 0 else 0.0
        for scenario, runs in s.items():
            m[f"ds:{scenario}"] = sum(r["driving_score"] for r in runs) / len(runs)
        per_seed.append(m)
    return {k: sum(m[k] for m in per_seed) / len(per_seed) for k in per_seed[0]}


def resample(seeds, rng):
    """One hierarchical bootstrap draw: seeds with replacement, then each seed's runs per scenario."""
    return [{sc: rng.choices(runs, k=len(runs)) for sc, runs in s.items()} for s in rng.choices(seeds, k=len(seeds))]


def summarise(seeds, seed):
    """Point estimates and 95 % intervals of every metric, from one set of bootstrap draws."""
    point = metrics(seeds)
    rng = random.Random(seed)
    reps = [metrics(resample(seeds, rng)) for _ in range(BOOTSTRAP)]
    lo, hi = int(0.025 * BOOTSTRAP), int(0.975 * BOOTSTRAP) - 1
    return {k: {"estimate": v, "ci95": [sorted(r[k] for r in reps)[lo], sorted(r[k] for r in reps)[hi]]} for k, v in point.items()}, reps


def behaviour(seeds):
    """Behaviour around the hazards that call for leaving the lane (stalled car, construction)
    and for braking (the pedestrian), pooled over seeds and runs."""
    out = {}
    for kind in ["stalled_car", "construction"]:
        runs = [r for s in seeds for r in s.get(kind, [])]
        if runs:
            passed = [r for r in runs if r["behaviour"]["passed_hazard"]]
            out[kind] = {
                "runs": len(runs),
                "max_abs_lateral_m": sum(r["behaviour"]["max_abs_lateral_m"] for r in runs) / len(runs),
                "passed": len(passed) / len(runs),
                "back_on_route_of_passed": (sum(1 for r in passed if r["behaviour"]["back_on_route"]) / len(passed)) if passed else None,
            }
    runs = [r for s in seeds for r in s.get("pedestrian_crossing", [])]
    if runs:
        speeds = [r["behaviour"]["speed_at_hazard_ms"] for r in runs if r["behaviour"]["speed_at_hazard_ms"] is not None]
        out["pedestrian_crossing"] = {
            "runs": len(runs),
            "speed_at_crossing_ms": sum(speeds) / len(speeds) if speeds else None,
            "reached_crossing": len(speeds) / len(runs),
            "pedestrian_collision": sum(1 for r in runs if "pedestrian_collision" in r["infractions"]) / len(runs),
        }
    return out


def rows(runs, baselines):
    """The table's rows in order: (label, seeds or None for a baseline, {(suite, town): [reports]})."""
    out = []
    for b in BASELINES:
        out.append((b, None, {k: [v[b]] for k, v in baselines.items() if b in v}))
    # The steadiness search's candidates join the tables once they have more than one seed.
    steady = [n for n in main_results.agents_of("steady") if len(runs.get(n, {})) > 1]
    for name in main_results.agents_of("hazards") + main_results.agents_of("long") + steady:
        by_seed = runs.get(name, {})
        if not by_seed:
            continue
        for ck in CHECKPOINTS:
            reports = {}
            for key in [(s, t) for s in SUITES for t in TOWNS]:
                got = [by_seed[seed]["evals"][key][ck] for seed in sorted(by_seed) if ck in by_seed[seed]["evals"].get(key, {})]
                if got:
                    reports[key] = got
            if reports:
                out.append((f"{name} ({ck})", sorted(by_seed), reports))
    return out


def report(a):
    results, out_dir, json_out = Path(a.results), Path(a.out_dir), Path(a.json_out)
    runs, baselines = load_runs(results), load_baselines(results)
    data = {"bootstrap": {"replicates": BOOTSTRAP, "over": "seeds, then runs within each seed and scenario (a baseline: runs only)"},
            "rates": {}, "rows": {}, "differences": {}, "behaviour": {}, "runs": {}}
    for name, by_seed in runs.items():
        rate = name[len("rate-"):]
        if name.startswith("rate-") and "-" not in rate:
            data["rates"][rate] = rate_score(by_seed[1]["dir"]) if 1 in by_seed else None
    data["rate_search"] = rate_search(results, runs)
    data["steadiness"] = steadiness(runs)
    draws = {}
    for i, (label, seeds, reports) in enumerate(rows(runs, baselines)):
        entry = {"seeds": seeds, "suites": {}}
        for j, ((suite, town), reps) in enumerate(sorted(reports.items())):
            ss = seed_samples(reps)
            summary, draw = summarise(ss, 101 * i + j)
            entry["suites"].setdefault(suite, {})[town] = summary
            draws[(label, suite, town)] = (summary, draw)
            if suite == "hazards":
                data["behaviour"].setdefault(label, {})[town] = behaviour(ss)
        data["rows"][label] = entry
        print(f"  {label}: {len(reports)} evaluations summarised", file=sys.stderr)
    # The goal's comparisons: the hybrid agent against the blind planner and the one that sees the
    # hazards; the paper's comparison (hybrid vs end-to-end); the better planner with and without
    # the learner; the longer budget. Independent draws of the two sides.
    pairs = []
    for ck in CHECKPOINTS:
        pairs += [(f"hz-hybrid-tuned ({ck})", "model-based"), (f"hz-hybrid-tuned ({ck})", "model-based-avoid"),
                  (f"hz-hybrid-tuned ({ck})", f"hz-e2e-best ({ck})"), (f"hz-hybrid-paper-inputs ({ck})", f"hz-e2e-best ({ck})"),
                  (f"hz-hybrid-avoid ({ck})", "model-based-avoid"), (f"hz-hybrid-avoid ({ck})", f"hz-hybrid-tuned ({ck})"),
                  (f"hz-hybrid-tuned-long ({ck})", f"hz-hybrid-tuned ({ck})")]
    pairs.append(("hz-hybrid-tuned-long (best)", "hz-hybrid-tuned (last)"))
    for name in main_results.agents_of("steady"):
        pairs += [(f"{name} ({ck})", f"hz-hybrid-tuned ({ck})") for ck in CHECKPOINTS]
    for x, y in pairs:
        for suite in SUITES:
            for town in TOWNS:
                if (x, suite, town) in draws and (y, suite, town) in draws:
                    (px, rx), (py, ry) = draws[(x, suite, town)], draws[(y, suite, town)]
                    d = sorted(a_["driving_score"] - b_["driving_score"] for a_, b_ in zip(rx, ry))
                    data["differences"][f"{x} - {y} | {suite} | {town}"] = {
                        "driving_score": {"estimate": px["driving_score"]["estimate"] - py["driving_score"]["estimate"],
                                          "ci95": [d[int(0.025 * BOOTSTRAP)], d[int(0.975 * BOOTSTRAP) - 1]]},
                    }
    for name, by_seed in runs.items():
        data["runs"][name] = {str(s): {k: r.get(k) for k in ["hazard_rate", "env_steps", "learner_step", "best", "episodes", "train_minutes",
                                                                 "session_secs", "cpu", "load_before", "load_after", "commit", "started_from"]}
                              | {"periodic": [{k: e.get(k) for k in ["time_secs", "env_steps", "driving_score", "hazard_driving_score", "selection_score", "best"]}
                                              for e in r["periodic"]]}
                              for s, r in sorted(by_seed.items())}
    whole = json.loads(json_out.read_text()) if json_out.exists() else {}
    whole["hazards"] = data
    main_results.write_json(json_out, whole)
    sections = tables(data)
    (out_dir / "figures").mkdir(parents=True, exist_ok=True)
    svg = kinds_figure(data)
    if svg:
        (out_dir / "figures" / "hazards-kinds.svg").write_text(svg)
    main_results.write_results_md(out_dir / "RESULTS.md", sections)
    print(f"wrote {json_out} (\"hazards\") and the hazard sections of {out_dir / 'RESULTS.md'}", file=sys.stderr)


def rate_search(results, runs):
    """{agent: {rate: {"selection_score", "swing", "run"}}}: every hazard agent's search points
    that are here (seed 1 at each rate: its search runs and its own seed 1)."""
    rates = sorted({str(r["hazard_rate"]) for by_seed in runs.values() for r in by_seed.values()}, key=float)
    out = {}
    for agent in main_results.agents_of("hazards"):
        points = {}
        for rate in rates:
            d = search_dir(results, agent, rate)
            if (d / "run.json").exists():
                points[rate] = {"selection_score": rate_score(d), "swing": swing(d), "run": d.parent.name}
        if points:
            out[agent] = points
    return out


def final_scores(run):
    """{checkpoint: {"suite/town": driving score}} of one run's final evaluations, computed as the
    tables compute it (every kind or route weighs the same)."""
    out = {}
    for (suite, town), by_ck in run["evals"].items():
        for ck, rep in by_ck.items():
            if ck in CHECKPOINTS:
                out.setdefault(ck, {})[f"{suite}/{town}"] = metrics(seed_samples([rep]))["driving_score"]
    return out


def steadiness(runs):
    """The search for a steadier policy: seed 1 of the tuned agent and of each candidate of group
    `steady`, with the same budget and rate: the level (mean of the last RATE_WINDOW periodic
    selection scores), the swing (standard deviation of the last SWING_WINDOW) and the final
    evaluations' driving scores of last and best/."""
    out = {}
    for name in [tuned_agent()] + main_results.agents_of("steady"):
        r = runs.get(name, {}).get(1)
        if r is None:
            continue
        out[name] = {"selection_score": rate_score(r["dir"]), "swing": swing(r["dir"]), "hazard_rate": r.get("hazard_rate"),
                     "env_steps": r.get("env_steps"), "learner_step": r.get("learner_step"), "final": final_scores(r)}
    return out


def ci(m, pct=False, digits=2):
    e, (lo, hi) = m["estimate"], m["ci95"]
    if pct:
        return f"{100 * e:.0f} % [{100 * lo:.0f}, {100 * hi:.0f}]"
    return f"{e:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def tables(data):
    s = {}
    lines = []
    for town in TOWNS:
        lines += [f"**{town}**", "",
                  "| agent | seeds | hazards: driving score | completion | success | infractions / km | clean: driving score | completion |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for label, e in data["rows"].items():
            h, c = e["suites"].get("hazards", {}).get(town), e["suites"].get("clean", {}).get(town)
            if not (h or c):
                continue
            cells = [ci(h["driving_score"]), ci(h["route_completion"], True), ci(h["success_rate"], True), ci(h["infractions_per_km"], digits=1)] if h else ["–"] * 4
            cells += [ci(c["driving_score"]), ci(c["route_completion"], True)] if c else ["–"] * 2
            lines.append(f"| {label} | {len(e['seeds']) if e['seeds'] else '–'} | " + " | ".join(cells) + " |")
        lines.append("")
    s["hazards-overall"] = "\n".join(lines)
    lines = []
    for town in TOWNS:
        lines += [f"**{town}**: driving score [95 % CI] per hazard kind", "",
                  "| agent | " + " | ".join(HAZARD_KINDS) + " |", "|---|" + "---:|" * len(HAZARD_KINDS)]
        for label, e in data["rows"].items():
            h = e["suites"].get("hazards", {}).get(town)
            if h:
                lines.append(f"| {label} | " + " | ".join(ci(h[f"ds:{k}"]) if f"ds:{k}" in h else "–" for k in HAZARD_KINDS) + " |")
        lines.append("")
    s["hazards-kinds"] = "\n".join(lines)
    lines = ["| difference (driving score) | suite | town | estimate [95 % CI] |", "|---|---|---|---:|"]
    for k, d in data["differences"].items():
        pair, suite, town = k.split(" | ")
        m = d["driving_score"]
        lines.append(f"| {pair} | {suite} | {town} | {m['estimate']:+.2f} [{m['ci95'][0]:+.2f}, {m['ci95'][1]:+.2f}] |")
    s["hazards-differences"] = "\n".join(lines)
    lines = ["| agent | town | stalled car: max \\|d\\|, m | passed | back in lane | construction: max \\|d\\|, m | passed | back in lane | "
             "pedestrian: speed at the crossing, m/s | hit the pedestrian |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    pct = lambda x: "–" if x is None else f"{100 * x:.0f} %"  # noqa: E731
    num = lambda x: "–" if x is None else f"{x:.1f}"  # noqa: E731
    for label, towns in data["behaviour"].items():
        for town, b in towns.items():
            sc, co, pe = b.get("stalled_car", {}), b.get("construction", {}), b.get("pedestrian_crossing", {})
            lines.append(f"| {label} | {town} | {num(sc.get('max_abs_lateral_m'))} | {pct(sc.get('passed'))} | {pct(sc.get('back_on_route_of_passed'))} | "
                         f"{num(co.get('max_abs_lateral_m'))} | {pct(co.get('passed'))} | {pct(co.get('back_on_route_of_passed'))} | "
                         f"{num(pe.get('speed_at_crossing_ms'))} | {pct(pe.get('pedestrian_collision'))} |")
    s["hazards-behaviour"] = "\n".join(lines)
    lines = ["| run | seed | hazard rate | env steps | updates | best/ at env steps | training min | periodic selection score: last 3 (mean) | CPU, load before → after | commit |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---|---|"]
    for name, by_seed in data["runs"].items():
        for seed, r in by_seed.items():
            sel = [e["selection_score"] for e in r["periodic"] if e.get("selection_score") is not None][-RATE_WINDOW:]
            best = r.get("best") or {}
            lines.append(f"| {name} | {seed} | {r['hazard_rate']} | {r['env_steps'] or 0:,} | {r['learner_step'] or 0:,} | "
                         f"{best.get('env_steps') or 0:,} | {r['train_minutes']} | {sum(sel) / len(sel) if sel else float('nan'):.3f} | "
                         f"{r['cpu']}, {r['load_before']} → {r['load_after']} | {r['commit']} |")
    s["hazards-runs"] = "\n".join(lines)
    s["hazards-search"] = search_tables(data)
    return s


def search_tables(data):
    f3 = lambda x: "–" if x is None else f"{x:.3f}"  # noqa: E731
    lines = ["**The hazard rate, per agent** (seed 1 at each rate; level: mean selection score of the last "
             f"{RATE_WINDOW} periodic evaluations; swing: standard deviation of the last {SWING_WINDOW})", "",
             "| agent | rate | run | level | swing |", "|---|---:|---|---:|---:|"]
    for agent, points in data.get("rate_search", {}).items():
        best = max((r for r in points if points[r]["selection_score"] is not None), key=lambda r: points[r]["selection_score"], default=None)
        for rate, p in points.items():
            mark = " (best)" if rate == best and len(points) > 1 else ""
            lines.append(f"| {agent} | {rate}{mark} | {p['run']} | {f3(p['selection_score'])} | {f3(p['swing'])} |")
    lines += ["", "**A steadier policy** (seed 1, the same budget and hazard rate; final evaluations: driving score of "
              "last / best/, 5 runs per scenario)", "",
              "| agent | env steps | updates | level | swing | " + " | ".join(f"{suite}, {town}" for suite in SUITES for town in TOWNS) + " |",
              "|---|---:|---:|---:|---:|" + "---:|" * (len(SUITES) * len(TOWNS))]
    for name, st in data.get("steadiness", {}).items():
        cells = []
        for suite in SUITES:
            for town in TOWNS:
                key = f"{suite}/{town}"
                cells.append(" / ".join(f"{st['final'][ck][key]:.2f}" if key in st["final"].get(ck, {}) else "–" for ck in CHECKPOINTS))
        lines.append(f"| {name} | {st['env_steps'] or 0:,} | {st['learner_step'] or 0:,} | {f3(st['selection_score'])} | {f3(st['swing'])} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def kinds_figure(data, town="default_town"):
    """An SVG bar chart: driving score per hazard kind, one bar per agent (best checkpoints and the
    baselines), with its 95 % interval, on `town`."""
    labels = [l for l, e in data["rows"].items() if not l.endswith("(last)") and town in e["suites"].get("hazards", {})]
    if not labels:
        return None
    colours = ["#444444", "#999999", "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]
    bw, gap, h, top, left = 9, 14, 220, 30, 40
    group_w = len(labels) * bw + gap
    width = left + group_w * len(HAZARD_KINDS) + 10
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{top + h + 120}" font-family="sans-serif" font-size="10">',
           f'<text x="{left}" y="15">driving score per hazard kind on {town} (95 % interval; learned agents: best/ checkpoints, seeds pooled)</text>']
    for t in [0, 0.25, 0.5, 0.75, 1.0]:
        y = top + h - t * h
        out.append(f'<line x1="{left}" x2="{width - 10}" y1="{y}" y2="{y}" stroke="#ddd"/><text x="5" y="{y + 3}">{t:.2f}</text>')
    for k, kind in enumerate(HAZARD_KINDS):
        x0 = left + k * group_w
        out.append(f'<text x="{x0}" y="{top + h + 12}" font-size="9">{kind}</text>')
        for i, label in enumerate(labels):
            m = data["rows"][label]["suites"]["hazards"][town].get(f"ds:{kind}")
            if not m:
                continue
            x, y = x0 + i * bw, top + h - m["estimate"] * h
            lo, hi = top + h - m["ci95"][0] * h, top + h - m["ci95"][1] * h
            out.append(f'<rect x="{x}" y="{y:.1f}" width="{bw - 1}" height="{top + h - y:.1f}" fill="{colours[i % len(colours)]}"/>')
            out.append(f'<line x1="{x + bw / 2 - 0.5}" x2="{x + bw / 2 - 0.5}" y1="{lo:.1f}" y2="{hi:.1f}" stroke="black"/>')
    for i, label in enumerate(labels):
        y = top + h + 30 + 11 * i
        out.append(f'<rect x="{left}" y="{y - 8}" width="9" height="9" fill="{colours[i % len(colours)]}"/><text x="{left + 14}" y="{y}">{label}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    k = sub.add_parser("keep-run")
    for flag in ["--run-dir", "--out", "--name", "--preset", "--rate", "--started", "--load-before", "--commit"]:
        k.add_argument(flag, required=True)
    k.add_argument("--seed", type=int, required=True)
    k.add_argument("--env-steps-budget", type=int, required=True)
    k.add_argument("--session-secs", type=int, required=True)
    k.add_argument("--started-from", default=None, help="where a run that did not start from scratch started")
    n = sub.add_parser("rename-run")
    n.add_argument("--out", required=True)
    n.add_argument("--name", required=True)
    b = sub.add_parser("best-rate")
    b.add_argument("--results", required=True)
    b.add_argument("--rates", required=True)
    b.add_argument("--agent", default=None, help="the agent whose search (default: the first of group hazards, hz-hybrid-tuned)")
    r = sub.add_parser("report")
    r.add_argument("--results", required=True)
    r.add_argument("--out-dir", required=True, help="where RESULTS.md and figures/ are")
    r.add_argument("--json-out", required=True, help="the results.json whose \"hazards\" key to write")
    a = p.parse_args()
    {"keep-run": keep_run, "rename-run": rename_run, "best-rate": best_rate, "report": report}[a.cmd](a)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The results of scripts/reproduce-hazards2.sh: keeps each run's outputs and writes the second
hazard report (tables with hierarchical-bootstrap intervals, the "hazards2" key of
experiments/results.json, figures).

  keep-run   copies what the tables need from a run directory into experiments/hazards2/AGENT/seedS
             (its evaluations without the baselines, gzipped; the baselines, the same in every
             evaluation, once into experiments/hazards2/baselines/)
  report     the hazards2 sections of docs/RESULTS.md, experiments/results.json's "hazards2",
             docs/figures/hazards2-*.svg
  readme     README's expectation table for its first command, from h2-hybrid-vector's runs

Standard library only, so that it runs wherever the project's scripts run.
"""

import argparse
import gzip
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import hazard_results as hz  # noqa: E402  (the first hazard experiment's statistics)
import results as main_results  # noqa: E402

# (suite, town) of every evaluation; town01 is CARLA's Town01, which no run trains on.
EVALS = [("hazards", "default_town"), ("hazards", "held_out_town"), ("hazards", "town01"),
         ("clean", "default_town"), ("clean", "held_out_town"), ("clean", "town01"),
         ("hazards-robust", "default_town"), ("hazards-robust", "held_out_town")]
BASELINES = hz.BASELINES
CHECKPOINTS = hz.CHECKPOINTS
HAZARD_KINDS = hz.HAZARD_KINDS
BOOTSTRAP = hz.BOOTSTRAP


def eval_path(d, suite, town):
    return d / f"eval-{suite}-{town}.json.gz"


def read_eval(path):
    with gzip.open(path, "rt") as f:
        return json.load(f)


def write_eval(path, ev):
    # mtime 0: the same evaluation gives the same bytes.
    with open(path, "wb") as raw, gzip.GzipFile(fileobj=raw, mode="wb", mtime=0) as f:
        f.write((json.dumps(ev, separators=(",", ":")) + "\n").encode())


def keep_run(a):
    run_dir, out = Path(a.run_dir), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    baselines = out.parent.parent / "baselines"
    baselines.mkdir(parents=True, exist_ok=True)
    for name in ["eval.jsonl", "train.jsonl"]:
        if (run_dir / name).exists():
            (out / name).write_bytes((run_dir / name).read_bytes())
    episodes = main_results.keep_curve(run_dir, out)
    for suite, town in EVALS:
        plain = out / f"eval-{suite}-{town}.json"
        if not plain.exists():
            continue
        ev = json.loads(plain.read_text())
        base = [x for x in ev["agents"] if x["name"] in BASELINES]
        kept = eval_path(baselines, suite, town)
        if base and not kept.exists():
            write_eval(kept, {**ev, "agents": base})
        ev["agents"] = [x for x in ev["agents"] if x["name"] not in BASELINES]
        write_eval(eval_path(out, suite, town), ev)
        plain.unlink()
    run = hz.run_record(a, run_dir, episodes)
    (out / "run.json").write_text(json.dumps(run, indent=1) + "\n")
    print(f"kept {run_dir} in {out}", file=sys.stderr)


def load_runs(results):
    """{agent: {seed: run}} of the finished runs, each with its evaluations ({(suite, town):
    {checkpoint: agent report}}) and its periodic evaluations."""
    runs = {}
    for run_json in sorted(Path(results).glob("*/seed*/run.json")):
        d = run_json.parent
        r = json.loads(run_json.read_text())
        r["dir"], r["evals"] = d, {}
        for suite, town in EVALS:
            path = eval_path(d, suite, town)
            if path.exists():
                r["evals"][(suite, town)] = {x["name"]: x for x in read_eval(path)["agents"]}
        r["periodic"] = main_results.read_jsonl(d / "eval.jsonl")
        runs.setdefault(r["agent"], {})[r["seed"]] = r
    return runs


def load_baselines(results):
    out = {}
    for suite, town in EVALS:
        path = eval_path(Path(results) / "baselines", suite, town)
        if path.exists():
            out[(suite, town)] = {x["name"]: x for x in read_eval(path)["agents"]}
    return out


def seed_samples(reports, suite):
    """Per seed: {scenario: [run scores]}; on a hazard suite only the runs whose hazard was placed
    (a town's roads may not allow a kind: Town01 has no road for some), and kinds with none left out."""
    out = []
    for rep in reports:
        s = {}
        for sc in rep["scenarios"]:
            runs = sc["runs"] if suite == "clean" else [r for r in sc["runs"] if r.get("hazard")]
            if runs:
                s[sc["scenario"]] = runs
        out.append(s)
    return out


def placed(reports):
    """{kind: share of runs whose hazard was placed}, of the first report (the same seeds and town
    place the same hazards for every agent)."""
    return {sc["scenario"]: sum(1 for r in sc["runs"] if r.get("hazard")) / len(sc["runs"]) for sc in reports[0]["scenarios"]}


def agents():
    return main_results.agents_of("hazards2") + main_results.agents_of("hazards2-long")


def rows(runs, baselines):
    """(label, seeds or None for a baseline, {(suite, town): [reports]}) in the tables' order."""
    out = [(b, None, {k: [v[b]] for k, v in baselines.items() if b in v}) for b in BASELINES]
    for name in agents():
        by_seed = runs.get(name, {})
        for ck in CHECKPOINTS:
            reports = {}
            for key in EVALS:
                got = [by_seed[seed]["evals"][key][ck] for seed in sorted(by_seed) if ck in by_seed[seed]["evals"].get(key, {})]
                if got:
                    reports[key] = got
            if reports:
                out.append((f"{name} ({ck})", sorted(by_seed), reports))
    return out


def curves(runs, step=100_000):
    """The learning curves of the periodic evaluations (validation seeds, `--eval-runs` runs per
    kind): per agent, at every `step` env steps up to the shortest run, the mean over seeds of
    each seed's hazard driving score per kind, clean driving score and hazard driving score,
    linearly interpolated between its evaluations (none before a seed's first)."""
    out = {}
    for name, by_seed in runs.items():
        series = [r["periodic"] for r in by_seed.values() if r["periodic"]]
        if not series:
            continue
        keys = ["driving_score", "hazard_driving_score"] + [f"ds:{k}" for k in HAZARD_KINDS]

        def value(e, key):
            if key.startswith("ds:"):
                return next((k["driving_score"] for k in e.get("hazard_kinds", []) if k["kind"] == key[3:]), None)
            return e.get(key)

        def at(points, x):
            pts = [(e["env_steps"], v) for e, v in points if v is not None]
            if not pts or x < pts[0][0]:
                return None
            for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
                if x0 <= x <= x1:
                    return y0 + (y1 - y0) * (x - x0) / (x1 - x0) if x1 > x0 else y1
            return pts[-1][1]

        end = min(s[-1]["env_steps"] for s in series)
        grid = list(range(step, end + 1, step))
        c = {"env_steps": grid, "seeds": len(series)}
        for key in keys:
            ys = []
            for x in grid:
                vals = [at([(e, value(e, key)) for e in s], x) for s in series]
                vals = [v for v in vals if v is not None]
                ys.append(round(sum(vals) / len(vals), 4) if len(vals) == len(series) else None)
            c[key] = ys
        out[name] = c
    return out


def report(a):
    results, out_dir, json_out = Path(a.results), Path(a.out_dir), Path(a.json_out)
    runs, baselines = load_runs(results), load_baselines(results)
    data = {"bootstrap": {"replicates": BOOTSTRAP, "over": "seeds, then runs within each seed and scenario (a baseline: runs only)"},
            "rows": {}, "differences": {}, "behaviour": {}, "placed": {}, "curves": curves(runs), "runs": {}}
    draws = {}
    for i, (label, seeds, reports) in enumerate(rows(runs, baselines)):
        entry = {"seeds": seeds, "suites": {}}
        for j, ((suite, town), reps) in enumerate(sorted(reports.items())):
            ss = seed_samples(reps, suite)
            summary, draw = hz.summarise(ss, 101 * i + j)
            if seeds:
                # The seeds that have this evaluation: a run without checkpoints has fewer towns.
                summary["seeds"] = len(reps)
            entry["suites"].setdefault(suite, {})[town] = summary
            draws[(label, suite, town)] = (summary, draw)
            if suite == "hazards":
                data["behaviour"].setdefault(label, {})[town] = hz.behaviour(ss)
            if suite != "clean" and town not in data["placed"].get(suite, {}):
                data["placed"].setdefault(suite, {})[town] = placed(reps)
        data["rows"][label] = entry
        print(f"  {label}: {len(reports)} evaluations summarised", file=sys.stderr)
    # The goal's comparisons: each learned agent against the blind planner and the one that sees;
    # the paper's (hybrid against end-to-end, same observation and budget); the planner that
    # feeds the hybrid agent; the observation (vector against camera). Independent draws.
    pairs = []
    for ck in CHECKPOINTS:
        for name in agents():
            pairs += [(f"{name} ({ck})", "model-based"), (f"{name} ({ck})", "model-based-avoid")]
        pairs += [(f"h2-hybrid-vector ({ck})", f"h2-e2e-vector ({ck})"), (f"h2-hybrid-vector-avoid ({ck})", f"h2-hybrid-vector ({ck})"),
                  (f"h2-hybrid-vector ({ck})", f"h2-hybrid-hazards ({ck})"), (f"h2-hybrid-vector-long ({ck})", f"h2-hybrid-vector ({ck})")]
    for x, y in pairs:
        for suite, town in EVALS:
            if (x, suite, town) in draws and (y, suite, town) in draws:
                (px, rx), (py, ry) = draws[(x, suite, town)], draws[(y, suite, town)]
                d = sorted(a_["driving_score"] - b_["driving_score"] for a_, b_ in zip(rx, ry))
                data["differences"][f"{x} - {y} | {suite} | {town}"] = {
                    "driving_score": {"estimate": px["driving_score"]["estimate"] - py["driving_score"]["estimate"],
                                      "ci95": [d[int(0.025 * BOOTSTRAP)], d[int(0.975 * BOOTSTRAP) - 1]]},
                }
    for name, by_seed in runs.items():
        data["runs"][name] = {str(s): {k: r.get(k) for k in ["env_steps_budget", "env_steps", "learner_step", "best", "episodes", "train_minutes",
                                                                 "session_secs", "cpu", "load_before", "load_after", "commit", "imported_from"]}
                              for s, r in sorted(by_seed.items())}
    whole = json.loads(json_out.read_text()) if json_out.exists() else {}
    whole["hazards2"] = data
    main_results.write_json(json_out, whole)
    (out_dir / "figures").mkdir(parents=True, exist_ok=True)
    svg = curves_figure(data["curves"])
    if svg:
        (out_dir / "figures" / "hazards2-curves.svg").write_text(svg)
    main_results.write_results_md(out_dir / "RESULTS.md", tables(data))
    print(f"wrote {json_out} (\"hazards2\") and the hazards2 sections of {out_dir / 'RESULTS.md'}", file=sys.stderr)


TOWN_NAMES = {"default_town": "default_town", "held_out_town": "held_out_town", "town01": "Town01"}


def seed_count(hazards, clean):
    """The seeds column: the seeds that have the row's hazard and clean evaluations (– for a
    baseline), both when they differ."""
    h, c = (x.get("seeds") if x else None for x in (hazards, clean))
    if h and c and h != c:
        return f"{h} (clean {c})"
    return str(h or c or "–")


def tables(data):
    ci = hz.ci
    s = {}
    lines = []
    for town in ["default_town", "held_out_town", "town01"]:
        lines += [f"**{TOWN_NAMES[town]}**", "",
                  "| agent | seeds | hazards: driving score | completion | success | infractions / km | clean: driving score | completion | success |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for label, e in data["rows"].items():
            h, c = e["suites"].get("hazards", {}).get(town), e["suites"].get("clean", {}).get(town)
            if not (h or c):
                continue
            cells = [ci(h["driving_score"]), ci(h["route_completion"], True), ci(h["success_rate"], True), ci(h["infractions_per_km"], digits=1)] if h else ["–"] * 4
            cells += [ci(c["driving_score"]), ci(c["route_completion"], True), ci(c["success_rate"], True)] if c else ["–"] * 3
            lines.append(f"| {label} | {seed_count(h, c)} | " + " | ".join(cells) + " |")
        lines.append("")
    pl = data["placed"].get("hazards", {}).get("town01")
    if pl:
        lines.append("Town01's hazard runs: the share of runs whose hazard its roads allowed (the others are left out): "
                     + ", ".join(f"{k} {100 * v:.0f} %" for k, v in pl.items()) + ".")
    s["hazards2-overall"] = "\n".join(lines)
    lines = []
    for town in ["default_town", "held_out_town", "town01"]:
        lines += [f"**{TOWN_NAMES[town]}**: driving score [95 % CI] per hazard kind", "",
                  "| agent | " + " | ".join(HAZARD_KINDS) + " |", "|---|" + "---:|" * len(HAZARD_KINDS)]
        for label, e in data["rows"].items():
            h = e["suites"].get("hazards", {}).get(town)
            if h:
                lines.append(f"| {label} | " + " | ".join(ci(h[f"ds:{k}"]) if f"ds:{k}" in h else "–" for k in HAZARD_KINDS) + " |")
        lines.append("")
    s["hazards2-kinds"] = "\n".join(lines)
    lines = ["| difference (driving score) | suite | town | estimate [95 % CI] |", "|---|---|---|---:|"]
    for k, d in data["differences"].items():
        pair, suite, town = k.split(" | ")
        if suite not in ("hazards", "clean") or town == "town01":
            continue
        m = d["driving_score"]
        lines.append(f"| {pair} | {suite} | {TOWN_NAMES[town]} | {m['estimate']:+.2f} [{m['ci95'][0]:+.2f}, {m['ci95'][1]:+.2f}] |")
    s["hazards2-differences"] = "\n".join(lines)
    lines = []
    for town in ["default_town", "held_out_town"]:
        lines += [f"**{town}**: driving score [95 % CI], the suite's draws → every parameter beyond training's", "",
                  "| agent | hazards | hazards-robust | " + " | ".join(HAZARD_KINDS) + " |", "|---|---:|---:|" + "---:|" * len(HAZARD_KINDS)]
        for label, e in data["rows"].items():
            h, r = e["suites"].get("hazards", {}).get(town), e["suites"].get("hazards-robust", {}).get(town)
            if not r:
                continue
            kinds = [f"{h[f'ds:{k}']['estimate']:.2f} → {r[f'ds:{k}']['estimate']:.2f}" if h and f"ds:{k}" in h and f"ds:{k}" in r else "–" for k in HAZARD_KINDS]
            lines.append(f"| {label} | {ci(h['driving_score']) if h else '–'} | {ci(r['driving_score'])} | " + " | ".join(kinds) + " |")
        lines.append("")
    s["hazards2-robustness"] = "\n".join(lines)
    lines = ["| agent | town | stalled car: max \\|d\\|, m | passed | back in lane | construction: max \\|d\\|, m | passed | back in lane | "
             "pedestrian: speed at the crossing, m/s | hit the pedestrian |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    pct = lambda x: "–" if x is None else f"{100 * x:.0f} %"  # noqa: E731
    num = lambda x: "–" if x is None else f"{x:.1f}"  # noqa: E731
    for label, towns in data["behaviour"].items():
        for town, b in towns.items():
            if town == "town01":
                continue
            sc, co, pe = b.get("stalled_car", {}), b.get("construction", {}), b.get("pedestrian_crossing", {})
            lines.append(f"| {label} | {town} | {num(sc.get('max_abs_lateral_m'))} | {pct(sc.get('passed'))} | {pct(sc.get('back_on_route_of_passed'))} | "
                         f"{num(co.get('max_abs_lateral_m'))} | {pct(co.get('passed'))} | {pct(co.get('back_on_route_of_passed'))} | "
                         f"{num(pe.get('speed_at_crossing_ms'))} | {pct(pe.get('pedestrian_collision'))} |")
    s["hazards2-behaviour"] = "\n".join(lines)
    lines = []
    for name, c in data["curves"].items():
        lines += [f"**{name}** ({c['seeds']} seeds; periodic evaluations, validation seeds, mean over seeds)", "",
                  "| env steps | clean | hazards | " + " | ".join(HAZARD_KINDS) + " |", "|---:|---:|---:|" + "---:|" * len(HAZARD_KINDS)]
        f = lambda v: "–" if v is None else f"{v:.2f}"  # noqa: E731
        for i, x in enumerate(c["env_steps"]):
            if (i + 1) % 2 and i + 1 != len(c["env_steps"]):
                continue
            lines.append(f"| {x:,} | {f(c['driving_score'][i])} | {f(c['hazard_driving_score'][i])} | "
                         + " | ".join(f(c[f'ds:{k}'][i]) for k in HAZARD_KINDS) + " |")
        lines.append("")
    s["hazards2-curves"] = "\n".join(lines)
    lines = ["| run | seed | env steps | updates | best/ at env steps | training min | CPU, load before → after | commit |",
             "|---|---:|---:|---:|---:|---:|---|---|"]
    for name, by_seed in data["runs"].items():
        for seed, r in by_seed.items():
            best = r.get("best") or {}
            lines.append(f"| {name} | {seed} | {r['env_steps'] or 0:,} | {r['learner_step'] or 0:,} | {best.get('env_steps') or 0:,} | "
                         f"{r['train_minutes']} | {r['cpu']}, {r['load_before'] or '–'} → {r['load_after'] or '–'} | {r['commit'] or 'imported'} |")
    s["hazards2-runs"] = "\n".join(lines)
    return s


def curves_figure(curves):
    """An SVG of the learning curves: one panel per hazard kind (and the hazard suite overall), the
    mean over seeds of each agent's periodic hazard driving score against env steps."""
    if not curves:
        return None
    keys = ["hazard_driving_score"] + [f"ds:{k}" for k in HAZARD_KINDS]
    titles = ["hazard suite"] + HAZARD_KINDS
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd"]
    pw, ph, cols, left, top = 200, 120, 4, 30, 30
    xmax = max(c["env_steps"][-1] for c in curves.values() if c["env_steps"]) if any(c["env_steps"] for c in curves.values()) else 1
    rows_ = (len(keys) + cols - 1) // cols
    width, height = cols * (pw + left + 10) + 10, top + rows_ * (ph + 40) + 20 * len(curves) + 10
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="10">',
           '<text x="10" y="15">hazard driving score against env steps (periodic evaluations, validation seeds; mean over seeds)</text>']
    for p, (key, title) in enumerate(zip(keys, titles)):
        x0, y0 = 10 + (p % cols) * (pw + left + 10) + left, top + (p // cols) * (ph + 40) + 12
        out.append(f'<text x="{x0}" y="{y0 - 3}">{title}</text>')
        out.append(f'<rect x="{x0}" y="{y0}" width="{pw}" height="{ph}" fill="none" stroke="#999"/>')
        for t in [0, 0.5, 1.0]:
            y = y0 + ph - t * ph
            out.append(f'<text x="{x0 - 22}" y="{y + 3}">{t:.1f}</text>')
        out.append(f'<text x="{x0 + pw - 40}" y="{y0 + ph + 12}">{xmax / 1e6:.1f}M</text>')
        for i, c in enumerate(curves.values()):
            pts = [(x, v) for x, v in zip(c["env_steps"], c[key]) if v is not None]
            if len(pts) > 1:
                path = " ".join(f"{x0 + pw * x / xmax:.1f},{y0 + ph - ph * v:.1f}" for x, v in pts)
                out.append(f'<polyline points="{path}" fill="none" stroke="{colours[i % len(colours)]}" stroke-width="1.5"/>')
    for i, name in enumerate(curves):
        y = top + rows_ * (ph + 40) + 14 * i + 5
        out.append(f'<rect x="10" y="{y - 8}" width="9" height="9" fill="{colours[i % len(colours)]}"/><text x="24" y="{y}">{name}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def readme(a):
    """README's expectation table for its first command (`actor train --preset hybrid-vector
    --max-env-steps 1000000 --eval-every 0.5`): the runs of `--agent` (h2-hybrid-vector, the
    same preset, budget and evaluation interval) and any `--extra RUN_DIR` run the same way
    (README's own check), as ranges over runs, printed as JSON."""
    rows = []
    for run_json in sorted(Path(a.results).glob(f"{a.agent}/seed*/run.json")):
        d = run_json.parent
        r = json.loads(run_json.read_text())
        rows.append({"run": str(d), "periodic": main_results.read_jsonl(d / "eval.jsonl"), "session_secs": r.get("session_secs"), "cpu": r.get("cpu"),
                     "evals": {k: read_eval(eval_path(d, *k)) for k in [("clean", "default_town"), ("hazards", "default_town")] if eval_path(d, *k).exists()}})
    for extra in a.extra or []:
        d = Path(extra)
        evals = {}
        for suite in ["clean", "hazards"]:
            p = eval_path(d, suite, "default_town")
            if p.exists():
                evals[(suite, "default_town")] = read_eval(p)
        rows.append({"run": str(d), "periodic": main_results.read_jsonl(d / "eval.jsonl"), "session_secs": None, "cpu": None, "evals": evals})
    out = {"runs": len(rows), "per_run": []}
    for r in rows:
        first = lambda n: next((e["env_steps"] for e in r["periodic"] if e["route_types_mastered"] >= n), None)  # noqa: E731
        scores = {}
        for (suite, _), ev in r["evals"].items():
            for ag in ev["agents"]:
                if ag["name"] not in CHECKPOINTS:
                    continue
                key = f"{suite}_{ag['name']}"
                scores[key] = round(ag["driving_score"], 3)
                if suite == "clean":
                    scores[f"route_types_majority_{ag['name']}"] = sum(
                        1 for sc in ag["scenarios"] if 2 * sum(1 for x in sc["runs"] if x["route_completion"] >= 1.0) > len(sc["runs"]))
        out["per_run"].append({"run": r["run"], "first_5_of_7": first(5), "first_7_of_7": first(7), "session_secs": r["session_secs"], "cpu": r["cpu"], **scores})
    keys = ["first_5_of_7", "first_7_of_7", "session_secs"] + [f"{k}_{ck}" for ck in CHECKPOINTS for k in ["clean", "hazards", "route_types_majority"]]
    for key in keys:
        vals = [x[key] for x in out["per_run"] if x.get(key) is not None]
        out[key] = {"min": min(vals), "max": max(vals), "n": len(vals), "missing": len(out["per_run"]) - len(vals)} if vals else None
    print(json.dumps(out, indent=1))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    k = sub.add_parser("keep-run")
    for flag in ["--run-dir", "--out", "--name", "--preset", "--started", "--load-before", "--commit"]:
        k.add_argument(flag, required=True)
    for flag in ["--seed", "--env-steps-budget", "--session-secs"]:
        k.add_argument(flag, type=int, required=True)
    r = sub.add_parser("report")
    r.add_argument("--results", default="experiments/hazards2")
    r.add_argument("--out-dir", default="docs")
    r.add_argument("--json-out", default="experiments/results.json")
    m = sub.add_parser("readme")
    m.add_argument("--results", default="experiments/hazards2")
    m.add_argument("--agent", default="h2-hybrid-vector")
    m.add_argument("--extra", action="append", help="a directory with a run's eval.jsonl and its eval-SUITE-default_town.json.gz (README's own check)")
    a = p.parse_args()
    {"keep-run": keep_run, "report": report, "readme": readme}[a.command](a)


if __name__ == "__main__":
    main()

"""scripts/episode_figure.py, docs/figures/hazards-episode.svg: every run of the scenario drawn, each
panel turned so that the route runs left to right through the hazard point, and a clear refusal
when the file has no run of the scenario asked for."""

import importlib.util
import json
import math
import subprocess
import sys

from conftest import ROOT

spec = importlib.util.spec_from_file_location("episode_figure", ROOT / "scripts" / "episode_figure.py")
ef = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ef)


def run(agent, seed, heading, score=1.0, infractions=(), scenario="stalled_car"):
    """A straight route at `heading` through the origin, the hazard at the origin."""
    c, s = math.cos(heading), math.sin(heading)
    route = [[t * c, t * s] for t in range(-60, 61, 2)]
    ego = [[t * c, t * s, 5.0] for t in range(-60, 0)]
    car = {"kind": "hazard_car", "centre": [0.0, 0.0], "half": [2.25, 1.0], "angle": heading}
    return {"agent": agent, "scenario": scenario, "seed": seed, "hazard": scenario, "hazard_point": [0.0, 0.0], "route": route,
            "ego": ego, "bodies_start": [car], "bodies_end": [car], "infractions": list(infractions), "driving_score": score}


def test_a_panel_turns_the_route_to_run_left_to_right_through_the_hazard_point():
    r = run("a", 0, math.radians(90))
    f = ef.frame(r)
    u, v = ef.to_panel(f, 0.0, 10.0)  # 10 m further along the route
    assert abs(u - 10.0) < 1e-6 and abs(v) < 1e-6
    assert ef.to_panel(f, 0.0, 0.0) == (0.0, 0.0)


def test_every_seed_gets_a_panel_and_every_agent_its_line_and_score(tmp_path):
    runs = [run(agent, seed, 0.3 * seed, score=0.25 if agent == "blind" else 1.0, infractions=["vehicle_collision"] if agent == "blind" else [])
            for seed in (0, 1, 2) for agent in ("blind", "avoid")]
    for r in runs:
        if r["agent"] == "blind":
            r["bodies_end"].append({"kind": "traffic", "centre": [3.0, 3.0], "half": [2.25, 1.0], "angle": 0.0})
    runs.append(run("blind", 0, 0.0, scenario="construction"))
    path = tmp_path / "t.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in runs))
    out, kept = tmp_path / "f.svg", tmp_path / "kept.jsonl"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "episode_figure.py"), "--trajectories", str(path), "--keep", str(kept),
                    "--out", str(out)], check=True)
    svg = out.read_text()
    assert svg.startswith("<svg") and svg.count(">seed ") == 3
    assert svg.count("blind: 0.25 (vehicle_collision)") == 3 and svg.count("avoid: 1.00 (arrived, no infraction)") == 3
    assert svg.count("×</text>") == 3, "a collision is marked where the run ended"
    assert svg.count('stroke-dasharray="3 2"') == 3, "the traffic near each run's end, in its colour"
    assert len(kept.read_text().splitlines()) == 6, "only the scenario's runs are kept"


def test_a_file_without_the_scenario_is_refused_by_name(tmp_path):
    path = tmp_path / "t.jsonl"
    path.write_text(json.dumps(run("a", 0, 0.0, scenario="cut_in")) + "\n")
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "episode_figure.py"), "--trajectories", str(path), "--out", str(tmp_path / "f.svg")],
                       capture_output=True, text=True)
    assert p.returncode != 0 and "no run of scenario `stalled_car`" in p.stderr

"""scripts/hazard_results.py, the statistics of docs/RESULTS.md's hazard tables: the suite's figures
per seed, the hierarchical bootstrap, the choice of the hazard rate, behaviour around the hazards,
and the report (which must keep RESULTS.md's hand-written text and results.json's other keys)."""

import importlib.util
import json
import sys

import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "scripts"))
spec = importlib.util.spec_from_file_location("hazard_results", ROOT / "scripts" / "hazard_results.py")
hz = importlib.util.module_from_spec(spec)
spec.loader.exec_module(hz)
hz.BOOTSTRAP = 1000  # enough for these tests' bounds


def run(ds, completion=None, infractions=(), km=0.1, lateral=0.0, passed=True, back=True, speed=5.0):
    return {"driving_score": ds, "route_completion": ds if completion is None else completion, "success": ds == 1.0 and not infractions,
            "infractions": list(infractions), "km": km,
            "behaviour": {"max_abs_lateral_m": lateral, "passed_hazard": passed, "back_on_route": back, "speed_at_hazard_ms": speed}}


def agent_report(name, runs_per_kind):
    return {"name": name, "scenarios": [{"scenario": k, "runs": runs} for k, runs in runs_per_kind.items()]}


def test_the_suite_figures_weigh_every_kind_the_same_and_count_infractions_per_km():
    seed = {"stalled_car": [run(0.0, 0.5, ["static_collision"], km=0.05)] * 4, "cut_in": [run(1.0)] * 2}
    m = hz.metrics([seed])
    assert m["driving_score"] == pytest.approx(0.5), "the mean over kinds, not over runs (4 + 2)"
    assert m["route_completion"] == pytest.approx(0.75)
    assert m["success_rate"] == pytest.approx(0.5)
    assert m["infractions_per_km"] == pytest.approx(4 / (4 * 0.05 + 2 * 0.1))
    assert m["ds:stalled_car"] == 0.0 and m["ds:cut_in"] == 1.0


def test_identical_runs_give_a_point_interval_and_seed_variance_widens_it():
    same = [{"cut_in": [run(0.8)] * 5}] * 3
    s, _ = hz.summarise(same, 1)
    assert s["driving_score"]["ci95"] == [pytest.approx(0.8), pytest.approx(0.8)]
    spread = [{"cut_in": [run(v)] * 5} for v in (0.1, 0.5, 0.9)]
    s, _ = hz.summarise(spread, 1)
    lo, hi = s["driving_score"]["ci95"]
    assert lo < 0.5 < hi and hi - lo > 0.3


def test_the_rate_is_chosen_by_the_last_periodic_evaluations_not_the_best_one(tmp_path):
    def write(rate, scores):
        d = tmp_path / f"rate-{rate}" / "seed1"
        d.mkdir(parents=True)
        (d / "run.json").write_text("{}")
        (d / "eval.jsonl").write_text("".join(json.dumps({"selection_score": s}) + "\n" for s in scores))

    write("0.25", [0.9, 0.1, 0.1, 0.1])  # one lucky evaluation early
    write("0.5", [0.2, 0.5, 0.5, 0.6])
    args = type("A", (), {"results": str(tmp_path), "rates": "0.25,0.5"})
    hz.best_rate(args)  # prints the rate; the choice is checked through rate_score
    assert hz.rate_score(tmp_path / "rate-0.5" / "seed1") > hz.rate_score(tmp_path / "rate-0.25" / "seed1")
    with pytest.raises(SystemExit, match="rate-1.0"):
        hz.best_rate(type("A", (), {"results": str(tmp_path), "rates": "0.5,1.0"}))


def test_an_agents_own_search_counts_its_seed_1_where_it_was_trained_at_that_rate(tmp_path, capsys):
    def write(d, rate, scores):
        d.mkdir(parents=True)
        (d / "run.json").write_text(json.dumps({"agent": d.parent.name, "seed": 1, "hazard_rate": rate}))
        (d / "eval.jsonl").write_text("".join(json.dumps({"selection_score": s}) + "\n" for s in scores))

    write(tmp_path / "hz-hybrid-avoid" / "seed1", "0.5", [0.4, 0.4, 0.4])  # the agent's own run, at 0.5
    write(tmp_path / "rate-0.25-hz-hybrid-avoid" / "seed1", "0.25", [0.6, 0.5, 0.7])
    write(tmp_path / "rate-0.5" / "seed1", "0.5", [0.9, 0.9, 0.9])  # hz-hybrid-tuned's search: not this agent's
    assert hz.search_name("hz-hybrid-tuned", "0.5") == "rate-0.5"
    assert hz.search_dir(tmp_path, "hz-hybrid-avoid", "0.5") == tmp_path / "hz-hybrid-avoid" / "seed1"
    hz.best_rate(type("A", (), {"results": str(tmp_path), "rates": "0.25,0.5", "agent": "hz-hybrid-avoid"}))
    assert capsys.readouterr().out.strip() == "0.25"
    with pytest.raises(SystemExit, match="rate-1.0-hz-hybrid-avoid"):
        hz.best_rate(type("A", (), {"results": str(tmp_path), "rates": "0.5,1.0", "agent": "hz-hybrid-avoid"}))
    assert hz.swing(tmp_path / "rate-0.25-hz-hybrid-avoid" / "seed1") == pytest.approx(0.1)
    assert hz.swing(tmp_path / "rate-0.5" / "seed1") == 0.0
    runs = hz.load_runs(tmp_path)
    points = hz.rate_search(tmp_path, runs)["hz-hybrid-avoid"]
    assert {r: p["run"] for r, p in points.items()} == {"0.25": "rate-0.25-hz-hybrid-avoid", "0.5": "hz-hybrid-avoid"}
    table = hz.search_tables({"rate_search": {"hz-hybrid-avoid": points}, "steadiness": {}})
    assert "| hz-hybrid-avoid | 0.25 (best) | rate-0.25-hz-hybrid-avoid | 0.600 | 0.100 |" in table


def test_a_steadiness_candidate_joins_the_tables_once_it_has_two_seeds():
    evals = {(s, t): {"last": agent_report("last", {"stalled_car": [run(0.5)]})} for s in hz.SUITES for t in hz.TOWNS}
    one = {"st-lr-half": {1: {"evals": evals}}}
    assert [label for label, seeds, _ in hz.rows(one, {}) if seeds] == [], "one seed: the search's table only"
    two = {"st-lr-half": {1: {"evals": evals}, 2: {"evals": evals}}}
    assert [(label, seeds) for label, seeds, _ in hz.rows(two, {}) if seeds] == [("st-lr-half (last)", [1, 2])]


def test_behaviour_counts_returns_among_the_runs_that_passed():
    seed = {"stalled_car": [run(1.0, lateral=3.0), run(0.2, lateral=1.0, passed=False, back=False)],
            "pedestrian_crossing": [run(1.0, speed=2.0), run(0.5, infractions=["pedestrian_collision"], speed=8.0), run(0.3, speed=None)]}
    b = hz.behaviour([seed])
    assert b["stalled_car"] == {"runs": 2, "max_abs_lateral_m": 2.0, "passed": 0.5, "back_on_route_of_passed": 1.0}
    p = b["pedestrian_crossing"]
    assert p["speed_at_crossing_ms"] == pytest.approx(5.0) and p["reached_crossing"] == pytest.approx(2 / 3)
    assert p["pedestrian_collision"] == pytest.approx(1 / 3)


def write_eval(d, suite, town, agents):
    d.mkdir(parents=True, exist_ok=True)
    (d / f"eval-{suite}-{town}.json").write_text(json.dumps({"suite": suite, "town": town, "runs": 2, "agents": agents}))


def test_the_report_fills_its_sections_keeps_the_prose_and_the_main_results(tmp_path):
    res = tmp_path / "hazards"
    kinds = lambda v: {k: [run(v), run(v)] for k in hz.HAZARD_KINDS}  # noqa: E731
    for suite in hz.SUITES:
        for town in hz.TOWNS:
            write_eval(res / "baselines", suite, town, [agent_report("model-based", kinds(0.5)), agent_report("model-based-avoid", kinds(0.9))])
            for seed in (1, 2):
                write_eval(res / "hz-hybrid-tuned" / f"seed{seed}", suite, town, [agent_report("last", kinds(0.7)), agent_report("best", kinds(0.8))])
    for seed in (1, 2):
        d = res / "hz-hybrid-tuned" / f"seed{seed}"
        (d / "run.json").write_text(json.dumps({"agent": "hz-hybrid-tuned", "seed": seed, "hazard_rate": "0.5", "env_steps": 400000,
                                                "learner_step": 3000, "best": {"env_steps": 300000}, "cpu": "test", "commit": "abc"}))
        (d / "eval.jsonl").write_text(json.dumps({"selection_score": 0.7, "env_steps": 1000}) + "\n")
    md = tmp_path / "RESULTS.md"
    md.write_text("# Results\n\nA reading.\n\n<!-- generated by scripts/results.py: hazards-overall -->\nold\n"
                  "<!-- end of generated: hazards-overall -->\n\nMore prose.\n")
    out = tmp_path / "results.json"
    out.write_text(json.dumps({"agents": {"hybrid-tuned": {}}}))
    args = type("A", (), {"results": str(res), "out_dir": str(tmp_path), "json_out": str(out)})
    hz.report(args)
    text = md.read_text()
    assert "A reading." in text and "More prose." in text and "\nold\n" not in text
    assert "| hz-hybrid-tuned (best) | 2 | 0.80 [0.80, 0.80] |" in text
    assert "| model-based | – | 0.50 [0.50, 0.50] |" in text
    data = json.loads(out.read_text())
    assert data["agents"] == {"hybrid-tuned": {}}, "the main experiment's keys are left alone"
    d = data["hazards"]["differences"]["hz-hybrid-tuned (best) - model-based | hazards | default_town"]["driving_score"]
    assert d["estimate"] == pytest.approx(0.3) and d["ci95"][0] > 0.0
    assert (tmp_path / "figures" / "hazards-kinds.svg").read_text().startswith("<svg")
    hz.report(args)
    assert md.read_text() == text, "a second report replaces the sections, it does not append them"


def test_keep_run_says_where_a_run_that_did_not_start_from_scratch_started(tmp_path):
    run_dir, out = tmp_path / "runs" / "seed1", tmp_path / "hazards" / "hz-hybrid-tuned-long" / "seed1"
    (run_dir / "checkpoint").mkdir(parents=True)
    (run_dir / "checkpoint" / "state.json").write_text(json.dumps({"counters": {"env_steps": 1600000, "learner_step": 12500}}))
    (run_dir / "train.jsonl").write_text(json.dumps({"time_secs": 120.0}) + "\n")
    (run_dir / "episodes.jsonl").write_text("".join(json.dumps({"episode_index": i, "arrived": True, "time_secs": i, "env_steps": i, "return": 1.0})
                                                    + "\n" for i in range(3)))
    for suite in hz.SUITES:
        for town in hz.TOWNS:
            write_eval(out, suite, town, [agent_report("model-based", {}), agent_report("last", {})])
    common = {"run_dir": str(run_dir), "out": str(out), "name": "hz-hybrid-tuned-long", "preset": "hybrid-tuned", "rate": "0.5",
              "started": "2026-12-03T00:00:00Z", "load_before": "0 0 0", "commit": "abc", "seed": 1, "env_steps_budget": 1600000,
              "session_secs": 120}
    hz.keep_run(type("A", (), {**common, "started_from": "scratch (runs/hazards/hz-hybrid-tuned/seed1 was gone)"}))
    kept = json.loads((out / "run.json").read_text())
    assert kept["started_from"].startswith("scratch") and kept["env_steps"] == 1600000 and kept["episodes"] == 3
    assert json.loads((out / "curves.json").read_text())["return"] == [1.0, 1.0, 1.0] and not (out / "episodes.jsonl").exists()
    hz.keep_run(type("A", (), {**common, "started_from": None}))
    assert "started_from" not in json.loads((out / "run.json").read_text()), "a run from scratch says nothing"

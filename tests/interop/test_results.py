"""scripts/results.py, the statistics of docs/RESULTS.md: the hierarchical bootstrap, the choice of
the end-to-end search's best, time to competence, and the report's generated sections (which must
leave the hand-written text of RESULTS.md alone)."""

import importlib.util
import json

import pytest

from conftest import ROOT

spec = importlib.util.spec_from_file_location("results", ROOT / "scripts" / "results.py")
results = importlib.util.module_from_spec(spec)
spec.loader.exec_module(results)
ROUTES = results.ROUTES
results.BOOTSTRAP = 2000  # enough for these tests' bounds, five times faster than the report's


def seed_sample(returns, completed):
    """One seed's evaluation: the same runs on every route."""
    return {r: (list(returns), [1.0 if c else 0.0 for c in completed]) for r in ROUTES}


def test_identical_runs_give_a_point_interval():
    ss = [seed_sample([10.0] * 5, [True] * 5)] * 3
    s = results.summarise(ss, ROUTES, 1)
    assert s["mean_return"] == 10.0 and s["mean_return_ci95"] == [10.0, 10.0]
    assert s["completion"] == 1.0 and s["completion_ci95"] == [1.0, 1.0]


def test_the_interval_holds_the_estimate_and_widens_with_seed_variance():
    close = [seed_sample([v] * 5, [True] * 5) for v in (99.0, 100.0, 101.0)]
    far = [seed_sample([v] * 5, [True] * 5) for v in (0.0, 100.0, 200.0)]
    c, f = results.summarise(close, ROUTES, 1), results.summarise(far, ROUTES, 1)
    assert c["mean_return_ci95"][0] <= 100.0 <= c["mean_return_ci95"][1]
    assert f["mean_return_ci95"][0] <= 100.0 <= f["mean_return_ci95"][1]
    width = lambda s: s["mean_return_ci95"][1] - s["mean_return_ci95"][0]
    assert width(f) > 50 * width(c)
    # Runs within one seed vary too: resampled inside each drawn seed.
    one_seed = [seed_sample([0.0, 0.0, 100.0, 100.0, 100.0], [False, False, True, True, True])]
    o = results.summarise(one_seed, ROUTES, 1)
    assert o["mean_return"] == pytest.approx(60.0) and o["mean_return_ci95"][0] < 60.0 < o["mean_return_ci95"][1]
    assert o["completion"] == pytest.approx(0.6)


def test_differences_of_an_agent_with_itself_straddle_zero_and_real_gaps_do_not():
    a = [seed_sample([v, v + 20.0, v - 20.0], [True, True, False]) for v in (50.0, 70.0, 90.0)]
    same = results.difference(a, a, ROUTES, 0, 3)
    assert same["estimate"] == 0.0 and same["ci95"][0] <= 0.0 <= same["ci95"][1]
    b = [seed_sample([v - 100.0] * 3, [False] * 3) for v in (50.0, 70.0, 90.0)]
    gap = results.difference(a, b, ROUTES, 0, 3)
    assert gap["estimate"] == pytest.approx(100.0) and gap["ci95"][0] > 0.0


def periodic(*mastered):
    return [{"time_secs": 60.0 * (k + 1), "env_steps": 1000 * (k + 1), "route_types_mastered": m,
             "completion_rate": m / 7, "mean_return": 10.0 * m} for k, m in enumerate(mastered)]


def test_competence_is_the_first_evaluation_with_five_route_types():
    assert results.competence({"periodic": periodic(1, 4, 5, 3, 6)}) == (3.0, 3000)
    assert results.competence({"periodic": periodic(1, 4, 4)}) is None


def test_the_search_picks_the_best_late_evaluations_and_waits_for_every_candidate():
    runs = {"e2e-tuned": {1: {"periodic": periodic(6, 0, 0)}}, "e2e-one-step": {1: {"periodic": periodic(1, 3, 4)}}}
    assert results.best_end_to_end(runs) is None, "e2e-slow-eps has not run"
    runs["e2e-slow-eps"] = {1: {"periodic": periodic(2, 2, 3)}}
    assert results.best_end_to_end(runs) is None, "the paper's end-to-end preset is a candidate too"
    runs["end-to-end"] = {1: {"periodic": periodic(0, 0, 1)}}
    # e2e-tuned mastered 6 early but none at the end: the last two evaluations decide.
    assert results.best_end_to_end(runs) == "e2e-one-step"


def eval_report(name, town, returns, completed):
    routes = [{"route": r, "runs": len(returns), "mean_return": sum(returns) / len(returns), "completed": sum(completed),
               "completion_rate": sum(completed) / len(completed), "run_returns": returns, "run_completed": completed} for r in ROUTES]
    base = [{"route": r, "mean_return": 150.0, "completion_rate": 1.0} for r in ROUTES]
    return {"town": town, "agents": [
        {"name": "model-based", "kind": "model_based", "mean_return": 150.0, "routes": base},
        {"name": name, "kind": "checkpoint", "checkpoint": {"env_steps": 400000, "learner_step": 3000, "episodes": 5000}, "routes": routes}]}


def write_run(results_dir, name, seed, returns, completed, mastered):
    d = results_dir / name / f"seed{seed}"
    d.mkdir(parents=True)
    for town in results.TOWNS:
        (d / f"eval-{town}.json").write_text(json.dumps(eval_report(name, town, returns, completed)))
    (d / "eval.jsonl").write_text("".join(json.dumps(e) + "\n" for e in periodic(*mastered)))
    run = {"agent": name, "seed": seed, "env_steps": 400000, "learner_step": 3000, "episodes": 5000, "train_minutes": 5.0,
           "cpu": "test", "load_before": "0 0 0", "load_after": "0 0 0", "commit": "abc"}
    (d / "run.json").write_text(json.dumps(run))


def test_the_report_fills_its_sections_and_keeps_the_hand_written_text(tmp_path):
    res = tmp_path / "results"
    for seed in (1, 2, 3):
        write_run(res, "hybrid-tuned", seed, [150.0, 140.0, 160.0, 150.0, 150.0], [True] * 5, (3, 5, 6))
    for name in results.SEARCH:
        write_run(res, name, 1, [0.0] * 5, [False] * 5, (0, 0, 1 if name == "e2e-slow-eps" else 0))
    write_run(res, "e2e-slow-eps", 2, [10.0] * 5, [True, False, False, False, False], (0, 1, 1))
    md = tmp_path / "RESULTS.md"
    md.write_text("# Results\n\nA reading written by hand.\n\n<!-- generated by scripts/results.py: overall -->\nold\n"
                  "<!-- end of generated: overall -->\n\nMore prose.\n")
    args = type("A", (), {"results": str(res), "out_dir": str(tmp_path), "json_out": str(tmp_path / "data.json"),
                          "learner": str(tmp_path / "no-learner")})
    results.report(args)
    text = md.read_text()
    assert "A reading written by hand." in text and "More prose." in text and "\nold\n" not in text
    assert "| hybrid-tuned | 3 | held_out_town | 150.0 [" in text
    assert "e2e-slow-eps (best end-to-end) | 2 |" in text
    assert not (tmp_path / "results.json").exists(), "the data goes to --json-out, not beside RESULTS.md"
    data = json.loads((tmp_path / "data.json").read_text())
    assert data["search"]["chosen"] == "e2e-slow-eps"
    h = data["agents"]["hybrid-tuned"]
    assert h["runs"]["1"]["minutes_to_competence"] == 2.0 and h["runs"]["1"]["env_steps_to_competence"] == 2000
    assert h["towns"]["held_out_town"]["route_types_in_3_of_5_mean"] == 7
    diff = data["differences"]["hybrid-tuned - e2e-best (default_town)"]
    assert diff["seeds"] == [3, 2] and diff["mean_return"]["ci95"][0] > 100.0
    # A second report gives the same file: the sections are replaced, not appended.
    results.report(args)
    assert md.read_text() == text
    # The hazard experiment's key (scripts/hazard_results.py) survives the main report.
    data["hazards"] = {"rows": {"model-based": {}}}
    (tmp_path / "data.json").write_text(json.dumps(data))
    results.report(args)
    assert json.loads((tmp_path / "data.json").read_text())["hazards"] == {"rows": {"model-based": {}}}


def test_training_completion_milestones_follow_the_progress_lines_window():
    # 100 failures, then arrivals: the window of 100 holds 20 arrivals at episode 120, 40 at 140.
    eps = [{"episode_index": i + 1, "arrived": i >= 100, "time_secs": 60.0 * i / 100, "env_steps": 10 * i} for i in range(150)]
    m = results.completion_milestones(eps, shares=(0.2, 0.4, 0.6))
    assert m == {"0.2": [1.19, 1190], "0.4": [1.39, 1390]}
    assert results.completion_milestones(eps[:50]) == {}, "no window is full"


def test_a_kept_curve_redraws_the_full_logs_moving_average(tmp_path):
    # 1000 episodes kept as 400 points (blocks of 2 or 3): the episodes `learner plot` reads back
    # have, at the end of every block, the time, env steps and running sum of the full log.
    episodes = [{"episode_index": i + 1, "time_secs": 0.5 * i, "env_steps": 10 * i, "return": float(i % 7) - 2.0, "arrived": False}
                for i in range(1000)]
    run_dir, kept = tmp_path / "runs" / "seed1", tmp_path / "results" / "a" / "seed1"
    run_dir.mkdir(parents=True)
    kept.mkdir(parents=True)
    (run_dir / "episodes.jsonl").write_text("".join(json.dumps(e) + "\n" for e in reversed(episodes)))
    (run_dir / "train.jsonl").write_text(json.dumps({"time_secs": 10.0}) + "\n")
    assert results.keep_curve(run_dir, kept) == results.read_jsonl(run_dir / "episodes.jsonl")
    assert len((kept / "curves.json").read_text().splitlines()) == 1 and not (kept / "episodes.jsonl").exists()
    (kept / "train.jsonl").write_text((run_dir / "train.jsonl").read_text())
    d = results.plot_dir(kept, tmp_path / "plot")
    assert (d / "train.jsonl").read_text() == (run_dir / "train.jsonl").read_text()
    rebuilt = results.read_jsonl(d / "episodes.jsonl")
    assert len(rebuilt) == 1000
    assert set(rebuilt[0]) == {"time_secs", "episode_index", "actor_id", "env", "return", "steps", "arrived", "collision", "scenario",
                               "learner_step", "env_steps"}, "every field of an episodes.jsonl line"
    ends = [(i + 1) * 1000 // results.CURVE_POINTS for i in range(results.CURVE_POINTS)]
    assert [(rebuilt[j - 1]["time_secs"], rebuilt[j - 1]["env_steps"]) for j in ends] == [(0.5 * (j - 1), 10 * (j - 1)) for j in ends]
    for j in ends:
        assert abs(sum(e["return"] for e in rebuilt[:j]) - sum(e["return"] for e in episodes[:j])) <= 0.0005 * j
    assert results.return_curve(episodes[:3]) == {"episodes": 3, "time_secs": [0.0, 0.5, 1.0], "env_steps": [0, 10, 20], "return": [-2.0, -1.0, 0.0]}

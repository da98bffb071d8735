"""scripts/hazards2_results.py, docs/RESULTS.md's tables of the second hazard experiment: the seeds
column counts the seeds that have each evaluation, not the agent's seeds."""

import importlib.util
import sys

from conftest import ROOT

sys.path.insert(0, str(ROOT / "scripts"))
spec = importlib.util.spec_from_file_location("hazards2_results", ROOT / "scripts" / "hazards2_results.py")
h2 = importlib.util.module_from_spec(spec)
spec.loader.exec_module(h2)


def test_the_seeds_column_counts_the_seeds_that_have_the_rows_evaluations():
    assert h2.seed_count({"seeds": 5}, {"seeds": 5}) == "5"
    # A seed imported without checkpoints has no Town01 clean evaluation: the row says so.
    assert h2.seed_count({"seeds": 5}, {"seeds": 4}) == "5 (clean 4)"
    assert h2.seed_count(None, {"seeds": 3}) == "3", "a row with the clean suite alone"
    assert h2.seed_count({"driving_score": {}}, None) == "–", "a baseline has no seeds"

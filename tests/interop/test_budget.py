"""`actor train --max-env-steps`: the budget of docs/RESULTS.md's experiment. A run stops by itself
with a checkpoint once it has received the budget's env steps, and the same command on the
finished run trains nothing (the budget counts every session)."""

import re

from conftest import TINY_TOML, actor_train


def train(run_dir, *extra):
    done = actor_train(run_dir, "--eval-every", "0", *extra)
    assert done.returncode == 0, done.stderr
    return done.stderr


def test_a_step_budget_stops_the_run_and_holds_across_sessions(tmp_path):
    config = tmp_path / "tiny.toml"
    config.write_text(TINY_TOML)
    run_dir = tmp_path / "run"
    first = train(run_dir, "--config", str(config), "--max-env-steps", "3000")
    assert "step budget: 3000 env steps in total (0 so far)" in first, first
    assert "step budget of 3000 env steps spent" in first, first
    steps = int(re.search(r"checkpoint written to .* \((\d+) env steps", first).group(1))
    # The budget is checked every 200 ms and the actor's last batches arrive while it stops: over
    # the budget by what the actors make in that time (the tiny run here makes thousands of steps
    # per second), never under.
    assert steps >= 3000, steps
    again = train(run_dir, "--max-env-steps", "3000")
    assert f"the run has already received {steps} env steps, the budget of --max-env-steps 3000: nothing to do" in again, again
    assert "starting" not in again, "no actor starts on a spent budget"


def test_a_zero_budget_is_refused_by_name(tmp_path):
    done = actor_train(tmp_path / "run", "--max-env-steps", "0", timeout=60)
    assert done.returncode != 0 and "--max-env-steps 0 must be a positive number" in done.stderr, done.stderr

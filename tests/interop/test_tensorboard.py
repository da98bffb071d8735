"""TensorBoard's own reader (the `tensorboard` package's EventAccumulator, as `tensorboard --logdir
runs/` uses it) on a real run of `actor train`, resumed once: every scalar the learner logs is
there, at env-step steps, with the values of train.jsonl and episodes.jsonl."""

import json

from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
from tensorboard.backend.event_processing.event_multiplexer import EventMultiplexer

TAGS = {
    "train/loss", "train/mean_q", "train/epsilon", "train/updates",
    "episodes/return_mean", "episodes/completion_rate", "episodes/collision_rate",
    "throughput/env_steps_per_sec", "throughput/updates_per_sec",
    "actors/weights_lag_mean", "replay/size", "episode/return", "episode/steps",
}


def jsonl(path):
    return [json.loads(l) for l in path.read_text().splitlines() if l.strip()]


def test_tensorboard_reads_the_runs_scalars(trained_run):
    run = trained_run.run_dir
    files = sorted(run.glob("events.out.tfevents.*"))
    assert len(files) == 2, f"one event file per session: {files}"

    acc = EventAccumulator(str(run), size_guidance={"scalars": 0})
    acc.Reload()
    tags = set(acc.Tags()["scalars"])
    assert TAGS <= tags, f"missing: {sorted(TAGS - tags)}"

    train = jsonl(run / "train.jsonl")
    losses = {r["env_steps"]: r["loss"] for r in train if r["loss"] is not None}
    events = acc.Scalars("train/loss")
    assert len(events) == len(losses), (len(events), len(losses))
    for e in events:
        want = losses[e.step]
        assert abs(e.value - want) <= 1e-6 * max(1.0, abs(want)), (e.step, e.value, want)
    updates = [e.value for e in acc.Scalars("train/updates")]
    assert updates == sorted(updates), "the update count never goes back across the resume"

    episodes = jsonl(run / "episodes.jsonl")
    returns = acc.Scalars("episode/return")
    assert len(returns) == len(episodes)
    # Stored as float32 by TensorBoard: equal to ~7 significant digits.
    for got, want in zip(sorted(e.value for e in returns), sorted(r["return"] for r in episodes)):
        assert abs(got - want) <= 1e-5 * max(1.0, abs(want)), (got, want)


def test_tensorboard_finds_the_run_under_a_parent_directory(trained_run):
    # `tensorboard --logdir runs/`: each directory holding event files is a run.
    mux = EventMultiplexer()
    mux.AddRunsFromDirectory(str(trained_run.run_dir.parent))
    mux.Reload()
    runs = mux.Runs()
    assert list(runs) == [trained_run.run_dir.name], runs
    assert "train/loss" in runs[trained_run.run_dir.name]["scalars"]

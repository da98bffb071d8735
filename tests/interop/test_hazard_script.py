"""scripts/reproduce-hazards.sh on a machine that has trained only some of the agents: the kept
episode figure (docs/figures/hazards-episode.svg and its runs, experiments/hazards/episode/) stays
as it is, rather than being redrawn from the few checkpoints this machine has."""

import os
import shutil
import subprocess

from conftest import ROOT


def test_the_kept_episode_figure_survives_a_machine_with_some_checkpoints(tmp_path):
    for d in ("scripts", "experiments", "docs"):
        shutil.copytree(ROOT / d, tmp_path / d)
    # An actor that must not be called: the one agent asked for has finished its run (the kept
    # experiment may have searches in progress, which --agents leaves out), and the figure is kept.
    release = tmp_path / "target" / "release"
    release.mkdir(parents=True)
    calls = tmp_path / "actor-calls"
    (release / "actor").write_text(f'#!/bin/sh\necho "$@" >> {calls}\nexit 1\n')
    (release / "actor").chmod(0o755)
    # One agent's finished run directory, with its checkpoint, as a machine that trained it has.
    checkpoint = tmp_path / "runs" / "hz-e2e-best" / "seed1" / "checkpoint"
    checkpoint.mkdir(parents=True)
    (checkpoint / "online.safetensors").write_bytes(b"")
    figure = tmp_path / "docs" / "figures" / "hazards-episode.svg"
    kept = tmp_path / "experiments" / "hazards" / "episode" / "stalled_car.jsonl"
    before = (figure.read_bytes(), kept.read_bytes())

    env = dict(os.environ, CARGO_TARGET_DIR=str(tmp_path / "target"))
    p = subprocess.run(
        ["bash", "scripts/reproduce-hazards.sh", "--seeds", "1", "--agents", "hz-e2e-best", "--no-build", "--runs-dir", str(tmp_path / "runs")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)

    assert p.returncode == 0, p.stderr[-3000:]
    assert not calls.exists(), f"the actor was run: {calls.read_text()}"
    assert "the episode figure: kept as it is" in p.stderr
    assert "no finished checkpoint here for hz-hybrid-tuned" in p.stderr, "the missing agents are named"
    assert (figure.read_bytes(), kept.read_bytes()) == before

"""`python -m hybrid_drive.bench --json` runs and prints its object (figures are not asserted:
benchmarks measure, tests check behaviour)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


@pytest.mark.parametrize("num_envs", [1, 3])
def test_bench_prints_one_json_object(num_envs):
    out = subprocess.run(
        [sys.executable, "-m", "hybrid_drive.bench", "--json", "--steps", "300", "--num-envs", str(num_envs), "--camera", "32x32"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    result = json.loads(out.strip().splitlines()[-1])
    assert result["num_envs"] == num_envs and result["camera"] == "32x32"
    assert result["steps_per_sec"] > 0 and result["steps"] == 300 // num_envs * num_envs
    assert "profile" in result and "load_before" in result


def test_bench_times_the_vector_observation():
    out = subprocess.run(
        [sys.executable, "-m", "hybrid_drive.bench", "--json", "--steps", "200", "--num-envs", "2", "--observation", "vector"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    result = json.loads(out.strip().splitlines()[-1])
    assert result["observation"] == "vector" and result["camera"] is None
    assert result["steps"] == 200 and result["steps_per_sec"] > 0

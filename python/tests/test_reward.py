"""Reward terms through the binding equal the simulator's own values, and follow the paper's
formulas (r_v = v/v0 - 1, r_l = 1 - l/l_prev, r_w = 1 - d/d0; collision -1, arrival +100)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hybrid_drive
from hybrid_drive._core import reference_rollout
from conftest import random_actions

V0 = 50.0 / 3.6  # the paper's v0, m/s (EnvConfig's reward.v0_kmh default)
D0 = 8.0  # the paper's d0, m


@pytest.mark.parametrize("kwargs", [{}, {"variant": "end_to_end", "rgb": True}, {"route": "right_turn"}])
def test_single_env_equals_the_simulator_bit_for_bit(kwargs):
    # reference_rollout drives sim_core::Env directly (no seeding stream, buffers or dicts).
    seed, actions = 21, random_actions(300, seed=4)
    env = gymnasium.make("HybridDrive-v0", **kwargs)
    reference = reference_rollout(env.unwrapped.config, seed, actions.tolist())
    env.reset(seed=seed)
    assert len(reference) >= 5
    for t, (a, ref) in enumerate(zip(actions, reference)):
        obs, reward, terminated, truncated, info = env.step(a)
        r, r_v, r_l, r_w, term, trunc, state, camera = ref
        # f32 values reach Python as the same doubles: compare exactly.
        assert (reward, info["r_v"], info["r_l"], info["r_w"]) == (r, r_v, r_l, r_w), f"step {t}"
        assert (terminated, truncated) == (term, trunc), f"step {t}"
        assert env.unwrapped.state_hash() == state, f"step {t}"
        assert obs["camera"].tobytes() == camera, f"step {t}"


def test_vector_env_equals_the_simulator():
    seed, actions = 33, random_actions(120, seed=6, shape=(2,))
    envs = hybrid_drive.make_vec(num_envs=2)
    envs.reset(seed=seed)
    reference = [reference_rollout(envs.config, seed + i, actions[:, i].tolist()) for i in range(2)]
    for t, a in enumerate(actions):
        _, rewards, terminated, truncated, info = envs.step(a)
        for i in range(2):
            if t < len(reference[i]):
                r, r_v, _, r_w, term, trunc, state, _ = reference[i][t]
                assert rewards[i] == r and info["r_v"][i] == np.float32(r_v) and info["r_w"][i] == np.float32(r_w)
                assert (terminated[i], truncated[i]) == (term, trunc)
                assert envs.state_hashes()[i] == state


def test_terms_follow_the_papers_formulas():
    env = gymnasium.make("HybridDrive-v0", route="straight_urban", camera=None)
    _, info = env.reset(seed=2)
    l_prev = info["l"]
    checked = 0
    for a in [0] * 15 + [3] * 5 + [0] * 30:
        _, reward, terminated, truncated, info = env.step(a)
        if terminated:
            break
        assert info["r_v"] == pytest.approx(info["speed"] / V0 - 1.0, abs=1e-6)
        assert info["r_l"] == pytest.approx(1.0 - info["l"] / l_prev, abs=1e-6)
        assert info["r_w"] == pytest.approx(1.0 - info["d"] / D0, abs=1e-6)
        assert reward == pytest.approx(info["r_v"] + info["r_l"] + info["r_w"], abs=1e-5)
        l_prev = info["l"]
        checked += 1
    assert checked >= 20


def test_config_overrides_reach_the_reward():
    env = gymnasium.make("HybridDrive-v0", config={"reward": {"d0": 4.0, "beta_v": 0.0, "beta_l": 0.0}}, camera=None)
    env.reset(seed=3)
    for _ in range(10):
        _, reward, *_, info = env.step(0)
        assert info["r_w"] == pytest.approx(1.0 - info["d"] / 4.0, abs=1e-6)
        assert reward == pytest.approx(info["r_w"], abs=1e-6)


def test_end_to_end_has_no_waypoint_term():
    env = gymnasium.make("HybridDrive-v0", variant="end_to_end", camera=None)
    env.reset(seed=4)
    for _ in range(10):
        _, reward, *_, info = env.step(0)
        assert info["r_w"] == 0.0
        assert reward == pytest.approx(info["r_v"] + info["r_l"], abs=1e-6)


def test_arrival_pays_100():
    # The straight highway route with no other car: full throttle straight ahead arrives.
    env = gymnasium.make("HybridDrive-v0", route="straight_highway", vehicles=0, parked_cars=0, camera=None)
    env.reset(seed=0)
    for _ in range(300):
        _, reward, terminated, truncated, info = env.step(0)
        if terminated or truncated:
            break
    assert terminated and info["arrived"] and info["collision"] is None
    assert reward == 100.0

"""Gymnasium's own checks pass, with no warning, for the main configurations."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hybrid_drive

CONFIGS = [
    {},
    {"camera": (84, 84), "variant": "hybrid", "route": "random", "render_mode": "rgb_array"},
    {"variant": "end_to_end", "camera": (64, 48), "rgb": True},
    {"path_features": True, "route": "left_turn"},
    {"camera": None, "vehicles": 0},
]


@pytest.mark.parametrize("kwargs", CONFIGS, ids=lambda k: ",".join(f"{a}={b}" for a, b in k.items()) or "defaults")
def test_check_env_passes_without_warnings(kwargs):
    env = gymnasium.make("HybridDrive-v0", **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_wrapped_env_runs_episodes_without_warnings():
    # gymnasium.make adds the passive checker and order enforcing: a few episodes through them.
    env = gymnasium.make("HybridDrive-v0", render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        obs, info = env.reset(seed=3)
        episodes = 0
        for a in np.random.default_rng(0).integers(0, 6, size=400):
            obs, reward, terminated, truncated, info = env.step(a)
            assert obs in env.observation_space
            if terminated or truncated:
                episodes += 1
                obs, info = env.reset()
        frame = env.render()
    assert episodes >= 2
    assert frame.shape == (256, 256, 3) and frame.dtype == np.uint8
    env.close()


def test_spaces_follow_the_arguments():
    env = gymnasium.make("HybridDrive-v0", camera=(64, 48), rgb=True, path_features=True)
    space = env.observation_space
    assert set(space.spaces) == {"camera", "speed", "d", "path"}
    assert space["camera"].shape == (48, 64, 3) and space["camera"].dtype == np.uint8
    assert space["speed"].shape == (1,) and space["speed"].dtype == np.float32
    assert space["path"].shape == (3,)
    assert env.action_space == gymnasium.spaces.Discrete(6)
    obs, _ = env.reset(seed=0)
    assert obs["camera"].shape == (48, 64, 3)
    end_to_end = gymnasium.make("HybridDrive-v0", variant="end_to_end", camera=None)
    assert set(end_to_end.observation_space.spaces) == {"speed"}
    assert set(end_to_end.reset(seed=0)[0]) == {"speed"}


def test_info_names_route_terms_and_outcome():
    env = gymnasium.make("HybridDrive-v0", route="sharp_curve")
    _, info = env.reset(seed=5)
    assert info["route"] == "sharp_curve" and info["seed"] == 5 and info["steps"] == 0
    for key in ("r_v", "r_l", "r_w", "collision", "arrived", "progress", "d", "l", "speed"):
        assert key in info
    # Steering hard left at full throttle leaves the road: the collision is named.
    for _ in range(300):
        _, reward, terminated, truncated, info = env.step(1)
        if terminated or truncated:
            break
    assert terminated and info["collision"] in hybrid_drive.COLLISION_KINDS[1:]
    assert reward == -1.0


def test_reset_option_switches_route():
    env = gymnasium.make("HybridDrive-v0")
    _, info = env.reset(seed=1, options={"route": "left_turn"})
    assert info["route"] == "left_turn" and env.unwrapped.route == "left_turn"
    _, info = env.reset()
    assert info["route"] == "left_turn"

"""``observation="vector"``: the vector sensor's reading (``[env.vector]``) as one float32 array in
[-1, 1], no camera; Gymnasium's checks, the simulator's own values, determinism, the vector env,
and how ``config`` combines with it."""

from __future__ import annotations

import json
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hybrid_drive
from hybrid_drive._core import reference_rollout
from conftest import random_actions

CONFIGS = [
    {"observation": "vector"},
    {"observation": "vector", "render_mode": "rgb_array", "route": "left_turn"},
    {"observation": "vector", "variant": "end_to_end", "config": {"vector": {"objects": 3, "rays": 4}}},
    {"observation": "vector", "camera": None, "vehicles": 0, "hazards": 1.0},
]


@pytest.mark.parametrize("kwargs", CONFIGS, ids=lambda k: ",".join(f"{a}={b}" for a, b in k.items()))
def test_check_env_passes_without_warnings(kwargs):
    env = gymnasium.make("HybridDrive-v0", **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_the_space_is_a_box_of_the_layouts_length():
    env = gymnasium.make("HybridDrive-v0", observation="vector")
    cfg = env.unwrapped.config
    assert cfg.observation == "vector"
    assert cfg.camera_shape is None, "the vector observation renders no camera"
    assert cfg.vector_len == sum(count * fields for _, count, fields in cfg.vector_segments)
    assert cfg.vector_layout.startswith("vector/")
    assert [name for name, *_ in cfg.vector_segments][:2] == ["ego", "path"]
    space = env.observation_space
    assert space == gymnasium.spaces.Box(-1.0, 1.0, shape=(cfg.vector_len,), dtype=np.float32)
    obs, _ = env.reset(seed=0)
    assert isinstance(obs, np.ndarray) and obs.shape == (cfg.vector_len,) and obs.dtype == np.float32
    # The end-to-end agent observes nothing of the planner: no path segments, a shorter vector.
    end_to_end = gymnasium.make("HybridDrive-v0", observation="vector", variant="end_to_end").unwrapped.config
    assert "path" not in [name for name, *_ in end_to_end.vector_segments]
    assert end_to_end.vector_len < cfg.vector_len


def test_the_default_observation_is_still_the_dict():
    cfg = gymnasium.make("HybridDrive-v0").unwrapped.config
    assert cfg.observation == "dict" and cfg.vector_len is None and cfg.vector_layout is None
    assert cfg.vector_segments == []
    assert cfg.camera_shape == (84, 84, 1)


def test_observations_are_the_simulators_readings_and_stay_in_the_space():
    env = gymnasium.make("HybridDrive-v0", observation="vector")
    seed, actions = 21, random_actions(120, seed=4)
    reference = reference_rollout(env.unwrapped.config, seed, actions.tolist())
    obs, _ = env.reset(seed=seed)
    assert obs in env.observation_space
    for a, ref in zip(actions, reference):
        obs, reward, terminated, truncated, _ = env.step(a)
        assert obs in env.observation_space
        assert np.array_equal(obs, np.frombuffer(ref[7], dtype=np.float32))
        assert (np.float32(reward), terminated, truncated) == (ref[0], ref[4], ref[5])
        if terminated or truncated:
            break


def vectors(seed: int, actions, **kwargs) -> tuple[np.ndarray, list]:
    """Every observation of an episode sequence (resetting without a seed when one ends), and the
    simulator's state hashes."""
    env = gymnasium.make("HybridDrive-v0", observation="vector", **kwargs)
    obs, _ = env.reset(seed=seed)
    seen, states = [obs], []
    for a in actions:
        obs, _, terminated, truncated, _ = env.step(a)
        seen.append(obs)
        states.append(env.unwrapped.state_hash())
        if terminated or truncated:
            seen.append(env.reset()[0])
    return np.stack(seen), states


def test_same_seed_gives_identical_vectors():
    actions = random_actions(400, seed=1)
    a = vectors(7, actions, hazards=0.5)
    b = vectors(7, actions, hazards=0.5)
    assert a[0].tobytes() == b[0].tobytes()
    assert a[1] == b[1]
    assert len(a[0]) > len(actions), "the sequence went through resets"


def test_config_sizes_the_sensor_and_loses_its_camera():
    env = gymnasium.make(
        "HybridDrive-v0",
        observation="vector",
        config={"vector": {"objects": 2, "waypoints": 3, "rays": 6}, "camera": {"width": 32, "height": 32}},
    )
    cfg = env.unwrapped.config
    assert cfg.vector_segments == [("ego", 1, 3), ("path", 1, 4), ("waypoints", 3, 2), ("objects", 2, 13), ("rays", 6, 2)]
    assert env.observation_space.shape == (cfg.vector_len,)
    effective = json.loads(cfg.config_json())
    assert effective["camera"] is None
    assert effective["vector"] == {"objects": 2, "waypoints": 3, "rays": 6, "range": 50.0}
    # Without a `vector` table: the sensor's defaults.
    default = json.loads(gymnasium.make("HybridDrive-v0", observation="vector").unwrapped.config.config_json())
    assert default["vector"] == {"objects": 8, "waypoints": 5, "rays": 16, "range": 50.0}


def test_errors_name_the_bad_value():
    with pytest.raises(ValueError, match=r'unknown observation "pixels": expected one of "dict", "vector"'):
        gymnasium.make("HybridDrive-v0", observation="pixels")
    with pytest.raises(ValueError, match=r"camera=\(84, 84\) with observation='vector'"):
        gymnasium.make("HybridDrive-v0", observation="vector", camera=(84, 84))
    with pytest.raises(ValueError, match="rgb=True needs a camera"):
        gymnasium.make("HybridDrive-v0", observation="vector", rgb=True)
    with pytest.raises(ValueError, match="path_features=True is for the dict observation"):
        gymnasium.make("HybridDrive-v0", observation="vector", path_features=True)
    with pytest.raises(ValueError, match=r"vector\.rays"):
        gymnasium.make("HybridDrive-v0", observation="vector", config={"vector": {"rays": 1000}})
    with pytest.raises(ValueError, match="unknown observation"):
        hybrid_drive.make_vec(num_envs=2, observation="Vector")


NUM_ENVS = 3
SEED = 60


def test_vector_env_batches_the_readings():
    envs = gymnasium.make_vec("HybridDrive-v0", num_envs=NUM_ENVS, observation="vector")
    n = envs.config.vector_len
    assert envs.single_observation_space == gymnasium.spaces.Box(-1.0, 1.0, shape=(n,), dtype=np.float32)
    assert envs.observation_space.shape == (NUM_ENVS, n)
    obs, _ = envs.reset(seed=SEED)
    assert obs.shape == (NUM_ENVS, n) and obs.dtype == np.float32 and obs in envs.observation_space
    obs, *_ = envs.step(np.zeros(NUM_ENVS, dtype=np.int64))
    assert obs in envs.observation_space
    kept = obs.copy()
    envs.step([1] * NUM_ENVS)
    assert np.array_equal(kept, obs), "fresh arrays each call"


@pytest.mark.parametrize("num_threads", [1, 2])
def test_vector_env_sub_envs_match_single_envs_through_auto_resets(num_threads):
    steps = 200
    actions = random_actions(steps, seed=6, shape=(NUM_ENVS,))
    envs = hybrid_drive.make_vec(num_envs=NUM_ENVS, num_threads=num_threads, observation="vector")
    batches = [envs.reset(seed=SEED)[0]]
    rewards = []
    for a in actions:
        obs, r, *_ = envs.step(a)
        batches.append(obs)
        rewards.append(r)
    resets = 0
    for i in range(NUM_ENVS):
        env = gymnasium.make("HybridDrive-v0", observation="vector")
        obs, _ = env.reset(seed=SEED + i)
        assert np.array_equal(obs, batches[0][i])
        needs_reset = False
        for t, a in enumerate(actions[:, i]):
            if needs_reset:
                obs, _ = env.reset()
                reward, needs_reset = 0.0, False
                resets += 1
            else:
                obs, reward, terminated, truncated, _ = env.step(a)
                needs_reset = terminated or truncated
            assert np.array_equal(obs, batches[t + 1][i]), f"env {i}, step {t + 1}"
            assert reward == rewards[t][i], f"env {i}, step {t + 1}"
    assert resets >= NUM_ENVS, "the comparison went through auto-resets"

"""The vector env: batched arrays, NEXT_STEP auto-reset, and each sub-environment driving exactly
what a single environment drives with the same seed and actions."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import hybrid_drive
from conftest import random_actions

KWARGS = {"camera": (32, 24), "path_features": True}
NUM_ENVS = 3
SEED = 40


def test_make_vec_gives_the_rust_vector_env():
    envs = gymnasium.make_vec("HybridDrive-v0", num_envs=4, **KWARGS)
    assert isinstance(envs, hybrid_drive.HybridDriveVectorEnv)
    assert envs.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert envs.num_envs == 4
    assert envs.single_action_space == gymnasium.spaces.Discrete(6)
    assert envs.action_space == gymnasium.spaces.MultiDiscrete([6] * 4)
    assert isinstance(hybrid_drive.make_vec(num_envs=2), hybrid_drive.HybridDriveVectorEnv)


def test_batches_have_the_declared_shapes_and_types():
    envs = hybrid_drive.make_vec(num_envs=NUM_ENVS, **KWARGS)
    obs, info = envs.reset(seed=SEED)
    assert obs in envs.observation_space
    assert obs["camera"].shape == (NUM_ENVS, 24, 32, 1) and obs["camera"].dtype == np.uint8
    assert obs["speed"].shape == (NUM_ENVS, 1) and obs["path"].shape == (NUM_ENVS, 3)
    assert list(info["seed"]) == [SEED + i for i in range(NUM_ENVS)]
    obs, rewards, terminated, truncated, info = envs.step(np.zeros(NUM_ENVS, dtype=np.int64))
    assert obs in envs.observation_space
    assert rewards.shape == (NUM_ENVS,) and rewards.dtype == np.float64
    assert terminated.dtype == np.bool_ and truncated.dtype == np.bool_
    for key in ("r_v", "r_l", "r_w", "collision", "arrived", "progress", "d", "l", "speed", "steps", "seed"):
        assert info[key].shape == (NUM_ENVS,), key
    assert np.all(info["steps"] == 1)
    # Fresh arrays each call: nothing the caller keeps is overwritten later.
    kept = obs["camera"].copy()
    envs.step([0] * NUM_ENVS)
    assert np.array_equal(kept, obs["camera"])


def single_env_like_next_step(seed: int, actions: np.ndarray):
    """What NEXT_STEP auto-reset means for one sub-environment, written with the single env."""
    env = gymnasium.make("HybridDrive-v0", **KWARGS)
    out = []
    obs, info = env.reset(seed=seed)
    out.append((obs, 0.0, False, False, info))
    needs_reset = False
    for a in actions:
        if needs_reset:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
            needs_reset = False
        else:
            obs, reward, terminated, truncated, info = env.step(a)
            out.append((obs, reward, terminated, truncated, info))
            needs_reset = terminated or truncated
    return out


@pytest.mark.parametrize("num_threads", [1, 2])
def test_sub_envs_match_single_envs_through_auto_resets(num_threads):
    steps = 250
    actions = random_actions(steps, seed=5, shape=(NUM_ENVS,))
    envs = hybrid_drive.make_vec(num_envs=NUM_ENVS, num_threads=num_threads, **KWARGS)
    batches = [envs.reset(seed=SEED)]
    batches[0] = (batches[0][0], np.zeros(NUM_ENVS), np.zeros(NUM_ENVS, bool), np.zeros(NUM_ENVS, bool), batches[0][1])
    for a in actions:
        batches.append(envs.step(a))

    resets_seen = 0
    for i in range(NUM_ENVS):
        expected = single_env_like_next_step(SEED + i, actions[:, i])
        assert len(expected) == len(batches)
        for t, ((obs, reward, terminated, truncated, info), (b_obs, b_rew, b_term, b_trunc, b_info)) in enumerate(
            zip(expected, batches)
        ):
            where = f"env {i}, step {t}"
            for key in obs:
                assert np.array_equal(obs[key], b_obs[key][i]), f"{where}: observation {key}"
            assert reward == b_rew[i], where
            assert (terminated, truncated) == (b_term[i], b_trunc[i]), where
            assert info["seed"] == b_info["seed"][i], where
            assert info["steps"] == b_info["steps"][i], where
            assert np.float32(info["r_w"]) == b_info["r_w"][i], where
            code = hybrid_drive.COLLISION_KINDS.index(info["collision"] or "none")
            assert code == b_info["collision"][i], where
            if t > 0 and info["steps"] == 0:
                resets_seen += 1
    # Random driving ends episodes quickly: the comparison went through auto-resets.
    assert resets_seen >= NUM_ENVS


def test_auto_reset_step_ignores_the_action_and_starts_the_next_episode():
    envs = hybrid_drive.make_vec(num_envs=2, **KWARGS)
    envs.reset(seed=1)
    ended = None
    for a in random_actions(400, seed=9, shape=(2,)):
        _, _, terminated, truncated, info = envs.step(a)
        done = terminated | truncated
        if done.any():
            ended = int(np.flatnonzero(done)[0])
            seed_before = int(info["seed"][ended])
            break
    assert ended is not None
    obs, rewards, terminated, truncated, info = envs.step(np.array([5, 5]))
    assert rewards[ended] == 0.0 and not terminated[ended] and not truncated[ended]
    assert info["steps"][ended] == 0 and info["seed"][ended] != seed_before
    assert obs["speed"][ended, 0] == 0.0


def test_errors_name_the_bad_value():
    envs = hybrid_drive.make_vec(num_envs=2, camera=None)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions\[1\] = 6 is not an action: expected 0..=5"):
        envs.step([0, 6])
    with pytest.raises(ValueError, match="3 actions for 2 environments"):
        envs.step([0, 0, 0])
    with pytest.raises(ValueError, match="1 seeds for 2 environments"):
        envs.reset(seed=[1])


def test_more_threads_than_cores_give_the_same_batches():
    # The stepping threads claim environments in whatever order the OS runs them: the results
    # must not depend on it. Oversubscribed on purpose (8 threads on this machine's cores).
    actions = random_actions(150, seed=8, shape=(16,))
    runs = []
    for threads in (1, 8):
        envs = hybrid_drive.make_vec(num_envs=16, num_threads=threads, camera=(16, 16))
        assert envs.num_threads == threads
        obs, _ = envs.reset(seed=3)
        cameras, rewards = [obs["camera"]], []
        for a in actions:
            obs, r, *_ = envs.step(a)
            cameras.append(obs["camera"])
            rewards.append(r)
        runs.append((np.stack(cameras), np.stack(rewards), envs.state_hashes()))
        envs.close()
    assert np.array_equal(runs[0][0], runs[1][0])
    assert np.array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2]


def test_vector_envs_come_and_go():
    # Each owns threads; dropping one stops and joins them.
    for k in range(20):
        envs = hybrid_drive.make_vec(num_envs=3, num_threads=3, camera=None, vehicles=0)
        envs.reset(seed=k)
        envs.step([0, 1, 2])
        del envs


def test_gymnasium_vector_wrappers_see_whole_episodes():
    # RecordEpisodeStatistics reads metadata["autoreset_mode"] to count episodes across auto-resets.
    from gymnasium.wrappers.vector import RecordEpisodeStatistics

    envs = RecordEpisodeStatistics(gymnasium.make_vec("HybridDrive-v0", num_envs=2, camera=None))
    envs.reset(seed=0)
    lengths, steps = [], np.zeros(2, dtype=int)
    needs_reset = np.zeros(2, dtype=bool)
    for a in random_actions(300, seed=1, shape=(2,)):
        _, _, terminated, truncated, info = envs.step(a)
        steps = np.where(needs_reset, 0, steps + 1)
        needs_reset = terminated | truncated
        if "episode" in info:
            for i in np.flatnonzero(info["_episode"]):
                assert info["episode"]["l"][i] == steps[i]
                lengths.append(int(steps[i]))
    assert len(lengths) >= 2


def test_a_stacked_camera_observes_the_last_frames_in_one_array():
    # `[env.camera] stack = 3`: the camera array holds the last three gray frames, oldest first.
    env = gymnasium.make("HybridDrive-v0", camera=(16, 16), config={"camera": {"stack": 3}})
    assert env.observation_space["camera"].shape == (16, 16, 3)
    obs, _ = env.reset(seed=1)
    first = obs["camera"]
    assert first.shape == (16, 16, 3)
    assert (first[..., 0] == first[..., 2]).all(), "at the start every frame is the first"
    frames = [first[..., 2]]
    for _ in range(3):
        obs, *_ = env.step(0)
        frames.append(obs["camera"][..., 2])
    np.testing.assert_array_equal(obs["camera"][..., 0], frames[-3])
    np.testing.assert_array_equal(obs["camera"][..., 1], frames[-2])
    assert not (frames[0] == frames[-1]).all(), "driving changes the view"

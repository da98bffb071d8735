"""Errors arrive as Python exceptions carrying the simulator's message: the bad value and what
would be valid."""

from __future__ import annotations

import gymnasium
import pytest

import hybrid_drive


def test_bad_map_file_names_line_and_field(tmp_path):
    path = tmp_path / "bad.map"
    path.write_text("map name=bad\nnode A x=0 y=0\nroad r from=A heading=0 to=B lanes=1,1\n  arc radius=-3 angle=90\nend\n")
    with pytest.raises(ValueError, match=r"bad\.map: map line 4, field `radius`: -3 must be"):
        gymnasium.make("HybridDrive-v0", map=path)


def test_missing_map_file():
    with pytest.raises(FileNotFoundError, match="reading map file /nonexistent.map"):
        gymnasium.make("HybridDrive-v0", map="/nonexistent.map")


def test_map_file_drives_random_routes_and_the_route_types_it_has(small_map):
    env = gymnasium.make("HybridDrive-v0", map=small_map, vehicles=2, parked_cars=0)
    obs, _ = env.reset(seed=0)
    assert obs in env.observation_space
    # Route types are found in any map by their shape (sim-core's route_types): the two blocks
    # have a left turn, but nothing that reads as a highway.
    env = gymnasium.make("HybridDrive-v0", map=small_map, route="left_turn")
    obs, _ = env.reset(seed=0)
    assert obs in env.observation_space
    with pytest.raises(ValueError, match="route \"straight_highway\" needs the default town's roads"):
        gymnasium.make("HybridDrive-v0", map=small_map, route="straight_highway")


def test_bad_route_lists_the_valid_ones():
    with pytest.raises(ValueError, match="unknown route \"left-turn\": expected one of random, straight_highway, .*, left_turn"):
        gymnasium.make("HybridDrive-v0", route="left-turn")
    env = gymnasium.make("HybridDrive-v0")
    with pytest.raises(ValueError, match="unknown route"):
        env.reset(options={"route": "nowhere"})
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"rout": "left_turn"})
    assert set(hybrid_drive.EVAL_ROUTES) < set(hybrid_drive.ROUTES)


def test_bad_arguments_name_the_field():
    with pytest.raises(ValueError, match="unknown variant \"e2e\": expected \"hybrid\" or \"end_to_end\""):
        gymnasium.make("HybridDrive-v0", variant="e2e")
    with pytest.raises(ValueError, match="path_features=True needs variant=\"hybrid\""):
        gymnasium.make("HybridDrive-v0", variant="end_to_end", path_features=True)
    with pytest.raises(ValueError, match="config field `camera.width`: 2 pixels is outside 8..=1024"):
        gymnasium.make("HybridDrive-v0", camera=(2, 84))
    with pytest.raises(ValueError, match="config field `reward.d0`: -1 must be a finite number > 0"):
        gymnasium.make("HybridDrive-v0", config={"reward": {"d0": -1}})
    with pytest.raises(ValueError, match="config: unknown field `spead`"):
        gymnasium.make("HybridDrive-v0", config={"spead": 3})
    with pytest.raises(ValueError, match="action_set \"paper7\": unknown variant `paper7`, expected one of `paper6`, `paper12`, `full15`, `full21`, `full27`"):
        gymnasium.make("HybridDrive-v0", action_set="paper7")


def test_bad_actions_and_finished_episodes():
    env = gymnasium.make("HybridDrive-v0", camera=None).unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action 6 is not an action: expected 0..=5"):
        env.step(6)
    with pytest.raises(ValueError, match="action -1 is not an action"):
        env.step(-1)
    with pytest.raises(ValueError, match="is not an integer"):
        env.step("left")
    for _ in range(400):
        *_, terminated, truncated, _ = env.step(1)
        if terminated or truncated:
            break
    with pytest.raises(RuntimeError, match="step called on a finished episode: call reset first"):
        env.step(0)

"""The `hazards=` keyword: an episode gets a hazard the planner does not know, reported in `info`."""

from __future__ import annotations

import gymnasium

import hybrid_drive

KINDS = {"stalled_car", "pedestrian_crossing", "cut_in", "hard_brake", "construction", "opposite_overtaker", "junction_runner"}
LONG_ROUTES = {"route_length_min": 120.0, "route_length_max": 220.0}


def test_hazards_keyword_puts_a_hazard_in_info_and_none_without_it():
    env = gymnasium.make("HybridDrive-v0", camera=None, hazards=1.0, config=LONG_ROUTES)
    _, info = env.reset(seed=3)
    assert info["hazard"] in KINDS and info["hazard_triggered"] is False
    kinds = {env.reset(seed=s)[1]["hazard"] for s in range(12)}
    assert len(kinds) >= 3, kinds
    plain = gymnasium.make("HybridDrive-v0", camera=None, config=LONG_ROUTES)
    _, info = plain.reset(seed=3)
    assert info["hazard"] is None
    assert "pedestrian" in hybrid_drive.COLLISION_KINDS and "construction" in hybrid_drive.COLLISION_KINDS


def test_hazards_out_of_range_names_the_field():
    import pytest

    with pytest.raises(ValueError, match="hazards.rate"):
        gymnasium.make("HybridDrive-v0", camera=None, hazards=2.0)

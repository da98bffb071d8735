"""Shared helpers for the hybrid_drive tests (pytest python/tests, run by .ci/run)."""

from __future__ import annotations

import numpy as np
import pytest


def random_actions(n: int, seed: int = 0, shape: tuple = ()) -> np.ndarray:
    """``n`` action indices of the paper's six, drawn reproducibly (random driving ends episodes
    within a few dozen steps, mostly by leaving the road)."""
    return np.random.default_rng(seed).integers(0, 6, size=(n, *shape))


@pytest.fixture
def small_map(tmp_path):
    """A valid map file without the default town's roads (the MAP-FORMAT.md example)."""
    path = tmp_path / "two_blocks.map"
    path.write_text(
        """map name=two_blocks
defaults lane_width=3.5 shoulder=2.5 sidewalk=3

node A x=0 y=0
node B x=100 y=0
road main from=A heading=0 to=B lanes=1,1
  straight length=100
end
road bend from=B heading=0 to=C lanes=1,1
  straight length=30
  arc radius=20 angle=90
  straight length=50
end
road side from=B heading=-90 to=D lanes=1,1
  straight length=60
end
building x=50 y=25 width=40 depth=20 height=15
pole x=50 y=-8
"""
    )
    return path

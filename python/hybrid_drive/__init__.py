"""hybrid_drive: the hybrid-drive simulator as a Gymnasium environment.

``import hybrid_drive`` registers ``HybridDrive-v0``::

    import gymnasium, hybrid_drive
    env = gymnasium.make("HybridDrive-v0", camera=(84, 84), variant="hybrid", route="random")
    envs = gymnasium.make_vec("HybridDrive-v0", num_envs=8)   # Rust threads, batched NumPy arrays

The simulator, the A* planner, the reward and the cameras are Rust (``sim-core``); this package only
turns them into Gymnasium's API.
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from typing import Any

import gymnasium

from hybrid_drive._core import COLLISION_KINDS, ROUTES
from hybrid_drive.env import HybridDriveEnv
from hybrid_drive.vector import HybridDriveVectorEnv

__all__ = [
    "COLLISION_KINDS",
    "ENV_ID",
    "ROUTES",
    "EVAL_ROUTES",
    "HybridDriveEnv",
    "HybridDriveVectorEnv",
    "__version__",
    "make_vec",
]

ENV_ID = "HybridDrive-v0"

try:
    __version__ = version("hybrid-drive")
except PackageNotFoundError:  # imported from a source tree without installing
    __version__ = "unknown"

#: The paper's seven evaluation routes (Table I), in its order.
EVAL_ROUTES = tuple(r for r in ROUTES if r != "random")


def make_vec(env_id: str = ENV_ID, num_envs: int = 8, **kwargs: Any) -> HybridDriveVectorEnv:
    """``num_envs`` environments stepped together in Rust threads (``gymnasium.make_vec`` does the same).

    Takes the keyword arguments of :class:`HybridDriveEnv` plus ``num_threads``.
    """
    if env_id != ENV_ID:
        raise ValueError(f"unknown environment {env_id!r}: hybrid_drive provides {ENV_ID!r}")
    return HybridDriveVectorEnv(num_envs=num_envs, **kwargs)


if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="hybrid_drive.env:HybridDriveEnv",
        vector_entry_point="hybrid_drive.vector:HybridDriveVectorEnv",
        # Episodes end inside the simulator (time limits of 200 and 300 steps): no TimeLimit wrapper.
        max_episode_steps=None,
        nondeterministic=False,
    )

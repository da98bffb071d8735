"""``HybridDriveVectorEnv``: N environments stepped together in Rust threads."""

from __future__ import annotations

from typing import Any, Optional, Sequence, Union

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hybrid_drive._core import VecSim
from hybrid_drive.spaces import observation_space, route_option, sim_config


class HybridDriveVectorEnv(VectorEnv):
    """``num_envs`` copies of :class:`hybrid_drive.HybridDriveEnv` (same keyword arguments, plus
    ``num_threads``, default one per core, the calling thread among them) stepped in Rust threads
    with the GIL released.

    Observations, rewards, terminations, truncations and each ``info`` key come as NumPy arrays
    with the environments along the first axis (``observation="vector"``: one ``(num_envs,
    vector_len)`` ``float32`` array) (``info["collision"]`` as indices into
    :data:`hybrid_drive.COLLISION_KINDS`, 0 meaning none); there is no per-environment Python
    object.

    Auto-reset is Gymnasium's ``NEXT_STEP`` mode (``metadata["autoreset_mode"]``): the step that
    ends an episode returns its last observation; the next ``step`` resets that environment,
    ignoring its action, and returns the new episode's first observation with reward 0.

    ``reset(seed=s)`` seeds environment ``i`` with ``s + i`` (a list gives each its own);
    environment ``i`` then drives exactly what ``HybridDriveEnv`` does after ``reset(seed=s + i)``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 8,
        *,
        num_threads: Optional[int] = None,
        render_mode: Optional[str] = None,
        **kwargs: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        self.render_mode = render_mode
        self.config = sim_config(**kwargs)
        self._sim = VecSim(self.config, num_envs, num_threads)
        self.num_envs = num_envs
        self._seeded = False
        self.single_observation_space = observation_space(self.config)
        self.single_action_space = spaces.Discrete(len(self.config.actions))
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.actions = self.config.actions

    @property
    def num_threads(self) -> int:
        return self._sim.num_threads

    def reset(
        self,
        *,
        seed: Union[int, Sequence[int], None] = None,
        options: Optional[dict] = None,
    ) -> tuple[Union[dict, np.ndarray], dict]:
        if seed is None or isinstance(seed, (int, np.integer)):
            super().reset(seed=None if seed is None else int(seed))
        route = route_option(options)
        if seed is None:
            seeds = None
            if not self._seeded:
                base = int(self.np_random.integers(np.iinfo(np.int64).max))
                seeds = [base + i for i in range(self.num_envs)]
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = [int(s) for s in seed]
        self._seeded = True
        return self._sim.reset(seeds, route)

    def step(self, actions: Any) -> tuple[Union[dict, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict]:
        return self._sim.step(np.asarray(actions, dtype=np.int64))

    def render(self) -> Optional[tuple[np.ndarray, ...]]:
        if self.render_mode == "rgb_array":
            return self._sim.render()
        return None

    def close_extras(self, **kwargs: Any) -> None:
        """Stops the stepping threads (the environment cannot be used afterwards)."""
        self._sim = None

    def state_hashes(self) -> list[int]:
        """Each environment's ``HybridDriveEnv.state_hash``."""
        return self._sim.state_hashes()

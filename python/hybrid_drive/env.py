"""``HybridDriveEnv``: one simulator environment as a ``gymnasium.Env``."""

from __future__ import annotations

from typing import Any, Optional, Union

import numpy as np
import gymnasium
from gymnasium import spaces

from hybrid_drive._core import Sim
from hybrid_drive.spaces import observation_space, route_option, sim_config


class HybridDriveEnv(gymnasium.Env):
    """The hybrid-drive simulator: drive the ego car along an A* route through traffic.

    Keyword arguments (all optional):

    - ``observation``: ``"dict"`` (the default: a dict of ``camera``, ``speed``, ``d`` and
      ``path``, as below) or ``"vector"``: the vector sensor's reading (``[env.vector]``: the ego's
      state, the planner's path and next waypoints (hybrid), the nearest visible objects, range
      rays), one ``float32`` array in ``Box(-1, 1, (config.vector_len,))`` whose layout
      ``config.vector_layout`` and ``config.vector_segments`` describe. It renders no camera, which
      makes it fast: ``camera`` must be left out (or ``None``), ``rgb`` and ``path_features`` are
      refused. The sensor is ``config``'s ``"vector"`` table when it has one (e.g.
      ``config={"vector": {"objects": 4, "rays": 8}}``, missing fields at their defaults), else
      the defaults; ``config``'s ``"camera"`` table is dropped. With ``"dict"``, a ``"vector"``
      table is read by the simulator but not observed.
    - ``route``: ``"random"`` (random 50–150 m training routes, 200-step limit) or one of the
      paper's seven evaluation routes (:data:`hybrid_drive.EVAL_ROUTES`, 300-step limit).
    - ``camera``: ``(width, height)`` of the front camera in pixels (default ``(84, 84)``), or
      ``None`` for no image; ``rgb=True`` for 3 channels instead of gray.
    - ``variant``: ``"hybrid"`` (the paper's method: ``d`` observed, ``r_w`` in the reward) or
      ``"end_to_end"`` (camera and speed only, no ``r_w``).
    - ``path_features``: also observe the planner's path (``path``: lateral offset, near and far
      heading angles); hybrid only.
    - ``vehicles``, ``parked_cars``: traffic (defaults 20 and 12).
    - ``map``: path of a map file (docs/MAP-FORMAT.md); default the embedded town.
    - ``action_set``: ``"paper6"`` (forward, forward-left, forward-right, brake, brake-left,
      brake-right), ``"paper12"`` (the seed code's earlier twelve), or a full-authority set —
      ``"full15"``, ``"full21"``, ``"full27"``: 5, 7 or 9 steering values × full throttle, coast,
      full brake (docs/EVALUATION.md).
    - ``config``: a dict of any ``EnvConfig`` field (``learner config``'s ``[env]`` table, e.g.
      ``{"reward": {"d0": 10.0}}``), applied first; the arguments above override it.
    - ``render_mode="rgb_array"``: ``render()`` returns the bird's-eye view (``birdseye_size``
      pixels square, RGB).

    ``info`` holds the reward terms ``r_v``, ``r_l``, ``r_w``, ``collision`` (a name from
    :data:`hybrid_drive.COLLISION_KINDS`, or ``None``), ``arrived``, ``progress`` (fraction of the
    route driven), ``d``, ``l`` (distance to the destination), ``speed``, ``steps``, ``route`` and
    ``seed`` (``reset(seed=info["seed"])`` replays the episode).

    Seeding: ``reset(seed=s)`` starts the episode with seed ``s``; later ``reset()`` calls take
    their seeds from a stream that ``s`` fixes, so one seed fixes every later episode.
    ``reset(options={"route": NAME})`` switches the route from then on.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, *, render_mode: Optional[str] = None, **kwargs: Any) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        self.render_mode = render_mode
        #: The checked configuration (``config.config_json()`` shows every setting).
        self.config = sim_config(**kwargs)
        self._sim = Sim(self.config)
        self._seeded = False
        self.observation_space = observation_space(self.config)
        self.action_space = spaces.Discrete(len(self.config.actions))
        #: ``(throttle, brake, steer)`` of each action index.
        self.actions = self.config.actions

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict] = None) -> tuple[Union[dict, np.ndarray], dict]:
        super().reset(seed=seed)
        route = route_option(options)
        if seed is None and not self._seeded:
            # Unseeded from the start: one seed from Gymnasium's generator (fresh entropy).
            seed = int(self.np_random.integers(np.iinfo(np.int64).max))
        self._seeded = True
        return self._sim.reset(seed, route)

    def step(self, action: Any) -> tuple[Union[dict, np.ndarray], float, bool, bool, dict]:
        return self._sim.step(action)

    def render(self) -> Optional[np.ndarray]:
        if self.render_mode == "rgb_array":
            return self._sim.render()
        return None

    def state_hash(self) -> int:
        """A hash of the simulator's dynamic state: equal after the same seed and actions."""
        return self._sim.state_hash()

    @property
    def route(self) -> str:
        """The route episodes drive now."""
        return self._sim.route

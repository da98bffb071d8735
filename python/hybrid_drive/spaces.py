"""The keyword arguments shared by the single and the vector environment, and the spaces.

Everything is checked in Rust (``hybrid_drive._core.SimConfig``); the bounds of the spaces come
from it too (top speed, the map's size), so that no simulator constant is repeated here.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any, Optional

import numpy as np
from gymnasium import spaces

from hybrid_drive._core import SimConfig


def sim_config(**kwargs: Any) -> SimConfig:
    """Checks the environment's keyword arguments (see :class:`hybrid_drive.HybridDriveEnv`): those
    of :class:`hybrid_drive._core.SimConfig`, whose signature (names and defaults) is their one home,
    with the Python forms it does not take turned into its own: ``camera`` any pair of numbers,
    ``map`` any path-like, ``config`` a dict (passed as JSON), ``hazards`` any number.

    ``observation="vector"`` renders no camera: a ``camera`` other than ``None`` is refused (rather
    than silently dropped)."""
    if kwargs.get("observation") == "vector" and kwargs.get("camera") is not None:
        raise ValueError(
            f"camera={kwargs['camera']!r} with observation='vector': the vector observation has no camera "
            "(leave camera out, or use observation='dict')"
        )
    camera = kwargs.get("camera")
    if camera is not None:
        if len(camera) != 2:
            raise ValueError(f"camera={camera!r}: expected (width, height) in pixels, or None")
        kwargs["camera"] = (int(camera[0]), int(camera[1]))
    if kwargs.get("map") is not None:
        kwargs["map"] = os.fspath(kwargs["map"])
    if kwargs.get("config") is not None:
        kwargs["config"] = json.dumps(kwargs["config"])
    if kwargs.get("hazards") is not None:
        kwargs["hazards"] = float(kwargs["hazards"])
    return SimConfig(**kwargs)


def observation_space(cfg: SimConfig) -> spaces.Space:
    """With ``observation="vector"``: ``Box(-1, 1, (cfg.vector_len,), float32)``, the vector sensor's
    reading. Else the dict: ``camera`` (uint8, H×W×C), ``speed`` (m/s), ``d`` (m, hybrid) and
    ``path`` (lateral offset in m, near and far heading angles in radians; with
    ``path_features=True``)."""
    if cfg.vector_len is not None:
        return spaces.Box(np.float32(-1.0), np.float32(1.0), shape=(cfg.vector_len,), dtype=np.float32)
    dist = np.float32(cfg.distance_max)
    angle = np.float32(math.pi)
    parts: dict[str, Any] = {}
    if cfg.camera_shape is not None:
        parts["camera"] = spaces.Box(0, 255, shape=cfg.camera_shape, dtype=np.uint8)
    parts["speed"] = spaces.Box(np.float32(0.0), np.float32(cfg.speed_max), shape=(1,), dtype=np.float32)
    if cfg.observes_d:
        parts["d"] = spaces.Box(np.float32(0.0), dist, shape=(1,), dtype=np.float32)
    if cfg.observes_path:
        parts["path"] = spaces.Box(
            low=np.array([-dist, -angle, -angle], dtype=np.float32),
            high=np.array([dist, angle, angle], dtype=np.float32),
            dtype=np.float32,
        )
    return spaces.Dict(parts)


def route_option(options: Optional[dict]) -> Optional[str]:
    """The ``route`` of ``reset(options=...)``, the one option there is."""
    if not options:
        return None
    unknown = set(options) - {"route"}
    if unknown:
        raise ValueError(f"unknown reset options {sorted(unknown)}: the only option is 'route'")
    return options.get("route")

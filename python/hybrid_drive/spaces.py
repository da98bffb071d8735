"""The keyword arguments shared by the single and the vector environment, and the spaces.

Everything is checked in Rust (``hybrid_drive._core.SimConfig``); the bounds of the spaces come
from it too (top speed, the map's size), so that no simulator constant is repeated here.
"""

from __future__ import annotations

import json
import math
import os
from typing import Any, Optional, Tuple, Union

import numpy as np
from gymnasium import spaces

from hybrid_drive._core import SimConfig


def sim_config(
    *,
    map: Union[str, "os.PathLike[str]", None] = None,
    route: str = "random",
    camera: Optional[Tuple[int, int]] = (84, 84),
    rgb: bool = False,
    variant: str = "hybrid",
    vehicles: Optional[int] = None,
    parked_cars: Optional[int] = None,
    path_features: bool = False,
    action_set: str = "paper6",
    config: Optional[dict] = None,
    birdseye_size: int = 256,
    hazards: Optional[float] = None,
) -> SimConfig:
    """Checks the environment's keyword arguments (see :class:`hybrid_drive.HybridDriveEnv`)."""
    if camera is not None:
        if len(camera) != 2:
            raise ValueError(f"camera={camera!r}: expected (width, height) in pixels, or None")
        camera = (int(camera[0]), int(camera[1]))
    return SimConfig(
        map=os.fspath(map) if map is not None else None,
        route=route,
        camera=camera,
        rgb=rgb,
        variant=variant,
        vehicles=vehicles,
        parked_cars=parked_cars,
        path_features=path_features,
        action_set=action_set,
        config=json.dumps(config) if config is not None else None,
        birdseye_size=birdseye_size,
        hazards=None if hazards is None else float(hazards),
    )


def observation_space(cfg: SimConfig) -> spaces.Dict:
    """``camera`` (uint8, H×W×C), ``speed`` (m/s), ``d`` (m, hybrid) and ``path`` (lateral offset in m,
    near and far heading angles in radians; with ``path_features=True``)."""
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

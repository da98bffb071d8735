"""Train Stable-Baselines3's DQN with an MLP on HybridDrive-v0's vector observation for a few
minutes, then drive the paper's seven evaluation routes greedily.

Not run in CI (it needs PyTorch). Setup as for ``sb3_dqn.py`` (this file reuses its progress
callback and evaluation), from the repository root:

    python -m venv .venv && . .venv/bin/activate
    pip install ./python
    pip install torch --index-url https://download.pytorch.org/whl/cpu   # CPU-only PyTorch
    pip install "stable-baselines3>=2.3"
    python python/examples/sb3_dqn_vector.py --minutes 5

``observation="vector"`` gives one ``float32`` array in [-1, 1] (the ego's state, the planner's path
and next waypoints, the nearest visible objects, range rays; ``env.unwrapped.config.vector_layout``
names its segments) and renders no camera, so each step is cheaper than with ``sb3_dqn.py``'s
camera and SB3's ``MlpPolicy`` (two fully connected layers of 256, one Q value per action) updates
much faster than a CNN. ``--objects``, ``--rays`` and ``--waypoints`` size the sensor (the
``[env.vector]`` table, passed through ``config=``).
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium

import hybrid_drive  # noqa: F401  (registers HybridDrive-v0)

try:
    import torch
    from stable_baselines3 import DQN
except ImportError as e:  # pragma: no cover - the example's only extra dependency
    raise SystemExit(f"{e}: install PyTorch and stable-baselines3 first (see this file's docstring)") from None

# The script's own directory is on sys.path when it is run as shown above.
from sb3_dqn import TimeBudget, evaluate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=5.0, help="training budget (default 5)")
    p.add_argument("--steps", type=int, default=200_000, help="step budget, whichever ends first (default 200000)")
    p.add_argument("--explore-steps", type=int, default=20_000, help="steps over which epsilon falls to 0.05")
    p.add_argument("--variant", choices=["hybrid", "end_to_end"], default="hybrid")
    p.add_argument("--objects", type=int, default=None, help="objects listed (default: the sensor's)")
    p.add_argument("--rays", type=int, default=None, help="range rays (default: the sensor's)")
    p.add_argument("--waypoints", type=int, default=None, help="planner waypoints, hybrid only (default: the sensor's)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--runs", type=int, default=3, help="evaluation runs per route (default 3)")
    p.add_argument("--save", default=None, help="save the model to this .zip")
    args = p.parse_args()

    torch.set_num_threads(os.cpu_count() or 1)
    sensor = {k: v for k, v in (("objects", args.objects), ("rays", args.rays), ("waypoints", args.waypoints)) if v is not None}
    kwargs = {"observation": "vector", "variant": args.variant, "config": {"vector": sensor}}
    env = gymnasium.make("HybridDrive-v0", **kwargs)
    print(f"observation: {env.observation_space} ({env.unwrapped.config.vector_layout})")
    env.reset(seed=args.seed)
    model = DQN(
        "MlpPolicy",
        env,
        learning_rate=2.5e-4,
        buffer_size=100_000,  # two vectors per transition: well under 200 MB at the default layout
        learning_starts=1_000,
        batch_size=32,
        gamma=0.99,
        train_freq=4,
        target_update_interval=1_000,
        exploration_fraction=min(1.0, args.explore_steps / args.steps),
        exploration_final_eps=0.05,
        policy_kwargs={"net_arch": [256, 256]},
        seed=args.seed,
        verbose=0,
    )
    budget = TimeBudget(args.minutes * 60.0)
    model.learn(total_timesteps=args.steps, callback=budget)
    elapsed = time.monotonic() - budget.start
    print(f"trained {model.num_timesteps} steps in {elapsed:.0f} s ({model.num_timesteps / elapsed:.0f} steps/s with updates)")
    if args.save:
        model.save(args.save)
    evaluate(model, args.runs, seed=1000, kwargs=kwargs)


if __name__ == "__main__":
    main()

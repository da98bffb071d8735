"""Train Stable-Baselines3's DQN with a CNN on HybridDrive-v0 for a few minutes, then drive the
paper's seven evaluation routes greedily.

Not run in CI (it needs PyTorch). Setup, from the repository root:

    python -m venv .venv && . .venv/bin/activate
    pip install ./python
    pip install torch --index-url https://download.pytorch.org/whl/cpu   # CPU-only PyTorch
    pip install "stable-baselines3>=2.3"
    python python/examples/sb3_dqn.py --minutes 5

It prints training progress every 15 s, then the greedy return on each of the seven routes. Five
minutes on two CPU cores is a smoke test of the pipeline, not a trained driver: PyTorch's updates,
not the simulator, set the pace (``actor train`` is the fast path, see the README).

The policy is SB3's ``MultiInputPolicy``: its NatureCNN reads the camera, the speed and d are
concatenated to the image features, and two fully connected layers of 256 give one Q value per
action, the paper's network shape. The environment runs in Rust at tens of thousands of steps per
second; here the time goes to PyTorch's updates (``train_freq`` and ``gradient_steps`` set the
ratio).
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium
import numpy as np

import hybrid_drive

try:
    import torch
    from stable_baselines3 import DQN
    from stable_baselines3.common.callbacks import BaseCallback
except ImportError as e:  # pragma: no cover - the example's only extra dependency
    raise SystemExit(f"{e}: install PyTorch and stable-baselines3 first (see this file's docstring)") from None


class TimeBudget(BaseCallback):
    """Stops training after ``seconds`` and prints progress every ``every`` seconds."""

    def __init__(self, seconds: float, every: float = 15.0) -> None:
        super().__init__()
        self.seconds, self.every = seconds, every
        self.start = self.last = 0.0
        self.returns: list[float] = []
        self.episode_return = 0.0

    def _on_training_start(self) -> None:
        self.start = self.last = time.monotonic()

    def _on_step(self) -> bool:
        self.episode_return += float(self.locals["rewards"][0])
        if self.locals["dones"][0]:
            self.returns.append(self.episode_return)
            self.episode_return = 0.0
        now = time.monotonic()
        if now - self.last >= self.every:
            self.last = now
            recent = self.returns[-20:]
            mean = f"{np.mean(recent):8.2f}" if recent else "     n/a"
            print(
                f"{now - self.start:6.0f} s  {self.num_timesteps:8d} steps  "
                f"{self.num_timesteps / (now - self.start):7.0f} steps/s  "
                f"episodes {len(self.returns):5d}  mean return (last 20) {mean}  "
                f"epsilon {self.model.exploration_rate:.2f}",
                flush=True,
            )
        return now - self.start < self.seconds


def evaluate(model: DQN, runs: int, seed: int, kwargs: dict) -> None:
    """Greedy returns on the seven routes (the paper's Table I metric), ``runs`` runs each."""
    print(f"\n{'route':24s} {'mean return':>12s} {'completed':>10s} {'collided':>9s}")
    for route in hybrid_drive.EVAL_ROUTES:
        env = gymnasium.make("HybridDrive-v0", route=route, **kwargs)
        returns, completed, collided = [], 0, 0
        for k in range(runs):
            obs, _ = env.reset(seed=seed + k)
            total, done = 0.0, False
            while not done:
                action, _ = model.predict(obs, deterministic=True)
                obs, reward, terminated, truncated, info = env.step(int(action))
                total += reward
                done = terminated or truncated
            returns.append(total)
            completed += bool(info["arrived"])
            collided += info["collision"] is not None
        print(f"{route:24s} {np.mean(returns):12.1f} {completed:7d}/{runs} {collided:6d}/{runs}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--minutes", type=float, default=5.0, help="training budget (default 5)")
    p.add_argument("--steps", type=int, default=50_000, help="step budget, whichever ends first (default 50000)")
    p.add_argument("--explore-steps", type=int, default=10_000, help="steps over which epsilon falls to 0.05")
    p.add_argument("--camera", type=int, nargs=2, default=(48, 48), metavar=("W", "H"), help="default 48 48 (the hybrid-tuned preset's)")
    p.add_argument("--variant", choices=["hybrid", "end_to_end"], default="hybrid")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--runs", type=int, default=3, help="evaluation runs per route (default 3)")
    p.add_argument("--save", default=None, help="save the model to this .zip")
    args = p.parse_args()

    torch.set_num_threads(os.cpu_count() or 1)
    kwargs = {"camera": tuple(args.camera), "variant": args.variant}
    env = gymnasium.make("HybridDrive-v0", **kwargs)
    env.reset(seed=args.seed)
    model = DQN(
        "MultiInputPolicy",
        env,
        learning_rate=2.5e-4,
        buffer_size=20_000,  # two frames per transition: ~90 MB at 48×48, ~280 MB at 84×84
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

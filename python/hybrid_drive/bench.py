"""``python -m hybrid_drive.bench``: environment steps per second as a Python user sees them.

One environment (``--num-envs 1``) is made with ``gymnasium.make`` (so Gymnasium's wrappers are
included) and stepped from a Python loop that resets it when an episode ends; more are made with
``gymnasium.make_vec`` (the Rust-threaded vector env, auto-resetting). Actions are drawn uniformly
at random beforehand (``--policy random``), or always "forward" (``--policy forward``: longer
episodes, fewer resets). ``--observation vector`` times the vector observation (no camera
rendered) instead of the dict. The time includes resets, observation arrays and info dicts: everything
between the Python caller and the simulator.

``--json`` prints one JSON object on the last line of stdout:
``{"steps_per_sec", "num_envs", "camera", ...}`` with the machine's CPU and load averages and a
profile of where the time went: for one environment, inside the simulator (``Env::step`` and
``Env::reset``), in the binding (building the observation and info), and in Python (the loop,
Gymnasium's wrappers, the call), plus the same loop run in Rust (``rust_loop_steps_per_sec``);
for a vector env, in the threads (stepping and rendering), in the binding (assembling the batch)
and in Python.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from typing import Optional, Tuple

import numpy as np
import gymnasium

import hybrid_drive
from hybrid_drive._core import rust_loop


def parse_size(text: str) -> Optional[Tuple[int, int]]:
    if text == "none":
        return None
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected WIDTHxHEIGHT, e.g. 84x84, or none") from None
    return (w, h)


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def load() -> Optional[list]:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def env_kwargs(args: argparse.Namespace) -> dict:
    """The environment's keyword arguments: the vector observation has no camera to size."""
    if args.observation == "vector":
        return {"observation": "vector", "vehicles": args.vehicles, "route": args.route}
    return {"camera": args.camera, "rgb": args.rgb, "vehicles": args.vehicles, "route": args.route}


def bench_single(args: argparse.Namespace, actions: np.ndarray) -> Tuple[int, int, float, dict]:
    env = gymnasium.make(hybrid_drive.ENV_ID, **env_kwargs(args))
    env.reset(seed=args.seed)
    sim = env.unwrapped._sim
    step, reset = env.step, env.reset
    episodes = 0
    calls_0, sim_0 = sim.timings()
    cpu_0, start = time.process_time(), time.perf_counter()
    for a in actions.tolist():
        _, _, terminated, truncated, _ = step(a)
        if terminated or truncated:
            reset()
            episodes += 1
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_0
    calls, in_sim = (t - t0 for t, t0 in zip(sim.timings(), (calls_0, sim_0)))
    # The same loop in Rust: what the simulator alone does on this machine now.
    rust_steps, _, rust_seconds = rust_loop(env.unwrapped.config, actions, args.seed)
    env.close()
    profile = {
        "simulator_s": round(in_sim, 3),
        "binding_s": round(calls - in_sim, 3),
        "python_s": round(elapsed - calls, 3),
        "rust_loop_steps_per_sec": round(rust_steps / rust_seconds),
        "cpu_s": cpu,
    }
    return len(actions), episodes, elapsed, profile


def bench_vector(args: argparse.Namespace, actions: np.ndarray) -> Tuple[int, int, float, dict]:
    envs = gymnasium.make_vec(
        hybrid_drive.ENV_ID,
        num_envs=args.num_envs,
        num_threads=args.threads,
        **env_kwargs(args),
    )
    envs.reset(seed=args.seed)
    sim = envs.unwrapped._sim
    step = envs.step
    batches = actions.reshape(-1, args.num_envs)
    episodes = 0
    calls_0, threads_0 = sim.timings()
    cpu_0, start = time.process_time(), time.perf_counter()
    for a in batches:
        _, _, terminated, truncated, _ = step(a)
        episodes += int(np.count_nonzero(terminated | truncated))
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_0
    calls, in_threads = (t - t0 for t, t0 in zip(sim.timings(), (calls_0, threads_0)))
    envs.close()
    profile = {
        "threads_s": round(in_threads, 3),
        "binding_s": round(calls - in_threads, 3),
        "python_s": round(elapsed - calls, 3),
        "num_threads": sim.num_threads,
        "cpu_s": cpu,
    }
    return batches.size, episodes, elapsed, profile


def main(argv: Optional[list] = None) -> int:
    p = argparse.ArgumentParser(prog="python -m hybrid_drive.bench", description=__doc__.split("\n\n")[0])
    p.add_argument("--num-envs", type=int, default=1, help="1: gymnasium.make; more: gymnasium.make_vec (default 1)")
    p.add_argument("--threads", type=int, default=None, help="vector env threads (default: one per core)")
    p.add_argument("--camera", type=parse_size, default=(84, 84), help="WIDTHxHEIGHT or none (default 84x84)")
    p.add_argument("--rgb", action="store_true", help="RGB camera instead of gray")
    p.add_argument(
        "--observation", choices=["dict", "vector"], default="dict", help="vector: the vector sensor, no camera (default dict)"
    )
    p.add_argument("--vehicles", type=int, default=50, help="moving traffic cars (default 50)")
    p.add_argument("--route", default="random", help="route name (default random)")
    p.add_argument("--policy", choices=["random", "forward"], default="random")
    p.add_argument("--steps", type=int, default=100_000, help="environment steps to time (default 100000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeat", type=int, default=1, help="runs; the median one is reported (default 1)")
    p.add_argument("--json", action="store_true", help="print one JSON object on the last line")
    args = p.parse_args(argv)
    if args.num_envs < 1:
        p.error("--num-envs must be at least 1")
    if args.observation == "vector":
        args.camera, args.rgb = None, False

    steps = max(args.steps // args.num_envs, 1) * args.num_envs
    rng = np.random.default_rng(args.seed)
    actions = rng.integers(0, 6, size=steps) if args.policy == "random" else np.zeros(steps, dtype=np.int64)
    load_before = load()
    run = bench_single if args.num_envs == 1 else bench_vector
    runs = sorted((run(args, actions) for _ in range(max(args.repeat, 1))), key=lambda r: r[0] / r[2])
    done, episodes, elapsed, profile = runs[len(runs) // 2]
    result = {
        "steps_per_sec": round(done / elapsed),
        "num_envs": args.num_envs,
        "observation": args.observation,
        "camera": None if args.camera is None else f"{args.camera[0]}x{args.camera[1]}" + ("x3" if args.rgb else ""),
        "vehicles": args.vehicles,
        "policy": args.policy,
        "route": args.route,
        "steps": done,
        "episodes": episodes,
        "seconds": round(elapsed, 3),
        "runs_steps_per_sec": [round(r[0] / r[2]) for r in runs],
        # CPU time of this process's threads in the timed loop: on a machine shared with other
        # work, steps per CPU-second say what the code costs where wall-clock steps/s also say how
        # busy the machine was.
        "steps_per_cpu_sec": round(done / profile.pop("cpu_s")),
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "load_before": load_before,
        "load_after": load(),
        "python": platform.python_version(),
        "profile": profile,
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{result['steps_per_sec']:,} steps/s: {done} steps, {episodes} episodes in {elapsed:.2f} s "
            f"({args.num_envs} env(s), {args.observation} observation, camera {result['camera']}, {args.vehicles} vehicles, policy {args.policy}; "
            f"{result['cpu']}, load {load_before} -> {result['load_after']})\nprofile: {profile}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())

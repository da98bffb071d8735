"""Shared fixtures of the interop tests: the project's binaries (built by `cargo build`; the
directory is $HD_BIN_DIR, default target/debug) and a learner running a tiny configuration on
127.0.0.1 with a free port."""

import os
import pathlib
import signal
import subprocess
import time

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN_DIR = pathlib.Path(os.environ.get("HD_BIN_DIR", ROOT / "target" / "debug"))

# A run small enough to train within seconds in a debug build: 16x16 gray camera, tiny network.
TINY_TOML = """
[env.camera]
width = 16
height = 16

[env.traffic]
vehicles = 5

[agent]
conv_filters = 2
hidden = 8
batch_size = 8
min_replay = 64
replay_capacity = 5000
replay_ratio = 0.5
publish_every_updates = 2

[service]
checkpoint_interval_secs = 3600
"""


def binary(name):
    path = BIN_DIR / name
    if not path.exists():
        pytest.fail(f"{path} not found: run `cargo build` first (or set HD_BIN_DIR)")
    return str(path)


def actor_train(run_dir, *args, timeout=300):
    """`actor train --run-dir RUN_DIR ARGS...` to its end, without a terminal; its output kept."""
    return subprocess.run([binary("actor"), "train", "--run-dir", str(run_dir), *args],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)


def wait_for_file(path, proc, secs=60):
    """Waits until `path` exists and is non-empty; fails naming the process's log otherwise."""
    deadline = time.monotonic() + secs
    while time.monotonic() < deadline:
        if path.exists() and path.read_text().strip():
            return path.read_text().strip()
        if proc.poll() is not None:
            pytest.fail(f"process exited with {proc.returncode} before writing {path}")
        time.sleep(0.1)
    pytest.fail(f"{path} did not appear within {secs} s")


class Learner:
    def __init__(self, tmp, extra=(), config=TINY_TOML):
        tmp.mkdir(parents=True, exist_ok=True)
        self.run_dir = tmp / "run"
        self.config = tmp / "tiny.toml"
        self.config.write_text(config)
        self.log = open(tmp / "learner.log", "w")
        self.proc = subprocess.Popen(
            [binary("learner"), "serve", "--config", str(self.config), "--listen", "127.0.0.1:0",
             "--run-dir", str(self.run_dir), *extra],
            stdin=subprocess.DEVNULL, stdout=self.log, stderr=subprocess.STDOUT)
        self.addr = wait_for_file(self.run_dir / "server.addr", self.proc)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()


@pytest.fixture
def learner(tmp_path):
    running = Learner(tmp_path)
    yield running
    running.stop()


class TrainedRun:
    """`actor train` on the tiny configuration, run twice as a user resumes it: 15 s, then to a
    24 s budget. Keeps each session's stderr."""

    def __init__(self, tmp):
        self.run_dir = tmp / "run"
        config = tmp / "tiny.toml"
        config.write_text(TINY_TOML)
        self.sessions = []
        for extra in (["--config", str(config), "--max-minutes", "0.25"], ["--max-minutes", "0.4"]):
            # Two actors (the default is one) for the logs of each actor across a resume.
            done = actor_train(self.run_dir, "--actors", "2", *extra)
            assert done.returncode == 0, done.stderr
            self.sessions.append(done.stderr)


@pytest.fixture(scope="session")
def trained_run(tmp_path_factory):
    return TrainedRun(tmp_path_factory.mktemp("trained"))

"""The commands README tells a newcomer to paste, run as a user runs them."""

import json
import subprocess

from conftest import binary


def run(*args):
    return subprocess.run([binary(args[0]), *args[1:]], capture_output=True, text=True, timeout=60)


def test_status_finds_a_local_run_by_its_directory(learner, tmp_path):
    by_dir = run("learner", "status", "--run-dir", str(learner.run_dir), "--json")
    assert by_dir.returncode == 0, by_dir.stderr
    by_addr = run("learner", "status", "--addr", learner.addr, "--json")
    assert by_addr.returncode == 0, by_addr.stderr
    assert json.loads(by_dir.stdout.splitlines()[-1])["run_id"] == json.loads(by_addr.stdout.splitlines()[-1])["run_id"]

    nowhere = run("learner", "status", "--run-dir", str(tmp_path / "empty"))
    assert nowhere.returncode != 0
    assert "server.addr does not exist" in nowhere.stderr and "--addr" in nowhere.stderr, nowhere.stderr

    neither = run("learner", "status")
    assert neither.returncode != 0 and "--addr" in neither.stderr and "--run-dir" in neither.stderr, neither.stderr

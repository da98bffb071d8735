"""The README's "From Python" example runs as shown, and the crate keeps to its layer."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_readme_example_runs():
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## From Python", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert blocks, "README's From Python section has no python block"
    namespace: dict = {}
    exec(compile(blocks[0], "README.md (From Python)", "exec"), namespace)
    assert namespace["obs"]["camera"].shape == (8, 84, 84, 1)


def test_binding_depends_on_sim_core_alone():
    # ARCHITECTURE.md: python/ never depends on learner, actor or proto (nor their runtimes).
    manifest = (ROOT / "python" / "Cargo.toml").read_text()
    deps = manifest.split("[dependencies]", 1)[1].split("\n[", 1)[0]
    names = {line.split(".")[0].split("=")[0].strip() for line in deps.splitlines() if line.strip() and not line.startswith("#")}
    assert "sim-core" in names
    forbidden = {"learner", "actor", "proto", "tokio", "tonic", "candle-core", "candle-nn"}
    assert not names & forbidden, f"python/ must not depend on {sorted(names & forbidden)}"

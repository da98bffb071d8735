"""The commands README.md and docs/*.md tell a user to type: every `./target/release/actor ...` and
`./target/release/learner ...` line of their shell blocks names a subcommand that exists and only
flags it accepts (checked against the programs' own --help, with the debug builds), and every
`cargo xtask STEP` line names a step of the task runner."""

import re
import shlex
import subprocess

import pytest

from conftest import ROOT, binary

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def commands():
    for page in PAGES:
        for block in re.findall(r"```sh\n(.*?)```", page.read_text(), re.S):
            for line in block.replace("\\\n", " ").splitlines():
                line = line.split(" #")[0]
                for part in line.split("&&"):
                    part = part.strip()
                    m = re.match(r"\./target/release/(actor|learner)\b(.*)", part)
                    if m:
                        yield page.name, m.group(1), m.group(2)


def parse(rest):
    words = [w.strip("[]()|") for w in shlex.split(rest.replace(">", " > "))]
    words = words[:words.index(">")] if ">" in words else words
    sub = []
    for w in words:
        if w.startswith("-") or not re.fullmatch(r"[a-z0-9-]+", w):
            break
        sub.append(w)
    flags = [w.split("=")[0] for w in words if w.startswith("--")]
    return sub, flags


ALL = list(commands())


def test_the_pages_have_commands_to_check():
    assert len(ALL) >= 20, ALL
    assert any(p == "README.md" for p, _, _ in ALL)


@pytest.mark.parametrize("page,program,rest", ALL, ids=[f"{p}: {b}{r}"[:80] for p, b, r in ALL])
def test_each_documented_command_exists_with_its_flags(page, program, rest):
    sub, flags = parse(rest)
    done = subprocess.run([binary(program), *sub, "--help"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, f"{page}: `{program} {' '.join(sub)}` is not a command: {done.stderr}"
    for flag in flags:
        if flag != "--help":
            assert re.search(rf"{re.escape(flag)}\b", done.stdout), f"{page}: `{program} {' '.join(sub)}` has no {flag}"


XTASK_STEPS = sorted({(page.name, step) for page in PAGES
                      for block in re.findall(r"```sh\n(.*?)```", page.read_text(), re.S)
                      for step in re.findall(r"^cargo xtask ([a-z-]+)", block, re.M)})


def test_the_readme_names_the_task_runners_steps():
    assert {s for p, s in XTASK_STEPS if p == "README.md"} >= {"slow", "ci"}, XTASK_STEPS


@pytest.mark.parametrize("page,step", XTASK_STEPS, ids=[f"{p}: cargo xtask {s}" for p, s in XTASK_STEPS])
def test_each_documented_task_runner_step_exists(page, step):
    # `cargo xtask` is `cargo run --package xtask --`: the same program, built beside the others.
    done = subprocess.run([binary("xtask"), step, "--help"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, f"{page}: `cargo xtask {step}` is not a step: {done.stderr}"

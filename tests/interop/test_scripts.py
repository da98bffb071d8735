"""The experiment scripts refuse a mistake before they build or train anything: an unknown agent
named by --agents gets its name and the valid ones back, with status 2 (scripts/lib.sh)."""

import subprocess

import pytest

from conftest import ROOT


@pytest.mark.parametrize("args, script, valid", [
    (["scripts/reproduce.sh", "--agents", "hybrid-tuned,no-such-agent", "--no-build"], "reproduce.sh", "hybrid-tuned"),
    (["scripts/reproduce.sh", "--experiment", "hazards", "--agents", "no-such-agent", "--no-build"], "reproduce-hazards.sh", "hybrid-tuned"),
    (["scripts/reproduce.sh", "--experiment", "hazards2", "--agents", "no-such-agent", "--no-build"], "reproduce-hazards2.sh",
     "h2-hybrid-hazards"),
])
def test_an_unknown_agent_is_refused_by_name_with_the_valid_ones(args, script, valid):
    p = subprocess.run(["bash", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"{script}: --agents: unknown agent `no-such-agent`; expected some of:" in p.stderr
    assert valid in p.stderr.split("expected some of:")[1], "the valid names are listed"
    assert "hybrid-tuned," not in p.stderr, "the names are checked one by one"


@pytest.mark.parametrize("args, message", [
    (["--precisions", "f32,f16"], "precision-parity.sh: --precisions: `f16` is not f32 or bf16"),
    (["--seeds", "0"], "precision-parity.sh"),
    (["--frobnicate"], "precision-parity.sh: unknown argument `--frobnicate`"),
])
def test_precision_parity_refuses_a_bad_flag_before_training(args, message):
    p = subprocess.run(["bash", "scripts/precision-parity.sh", *args, "--no-build"], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    assert message in p.stderr
    assert "training to" not in p.stderr, "nothing was trained"


@pytest.mark.parametrize("flag", ["--eval-every", "--camera-eval-every"])
def test_hazards2_refuses_a_periodic_evaluation_interval_that_is_not_positive(flag):
    p = subprocess.run(["bash", "scripts/reproduce-hazards2.sh", flag, "0", "--no-build"], cwd=ROOT,
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"reproduce-hazards2.sh: {flag} 0 must be a positive number" in p.stderr
    assert "training to" not in p.stderr, "nothing was trained"

"""What `actor train` shows a user whose stderr is not a terminal (a pipe here): one plain progress
line per interval in one format, no ANSI escape codes, no second (tracing) progress line; the
actors' logs kept across a resume, a header per session."""

import re

PROGRESS = re.compile(
    r"^\[ *\d+s\] env steps \d+ \(\d+/s\)  episodes \d+  mean return -?[\d.]+  completed \d+%  "
    r"updates \d+ \([\d.]+/s\)  loss (-|[\d.]+)  weights v\d+  replay \d+  actors \d+"
    r"(  stalled: .+|  STOPPED: .+)?$")


def test_one_plain_progress_format(trained_run):
    for stderr in trained_run.sessions:
        assert "\x1b" not in stderr, "ANSI escape codes in a non-terminal stderr"
        lines = stderr.splitlines()
        progress = [l for l in lines if "env steps" in l and l.startswith("[")]
        assert progress, stderr
        for line in progress:
            assert PROGRESS.match(line), line
        assert not [l for l in lines if "progress" in l and "INFO" in l], "a second, tracing progress line"
        assert "status, from another terminal: " in stderr and f"status --run-dir {trained_run.run_dir}" in stderr


def test_resumed_rates_start_from_this_session(trained_run):
    first, second = trained_run.sessions
    total_before = max(int(m) for m in re.findall(r"env steps (\d+) ", first))
    resumed = [l for l in second.splitlines() if PROGRESS.match(l)]
    assert resumed, second
    rate = int(re.search(r"\((\d+)/s\)", resumed[0]).group(1))
    steps = int(re.search(r"env steps (\d+) ", resumed[0]).group(1))
    # A rate is this session's steps over this session's seconds: never more than the steps this
    # session has made per second of its first interval (2 s), whatever the machine's speed.
    assert rate * 1 <= steps - total_before, (rate, steps, total_before)


def test_actor_logs_are_appended_across_resumes(trained_run):
    for k in (0, 1):
        log = (trained_run.run_dir / f"actor-{k}.log").read_text()
        headers = [l for l in log.splitlines() if l.startswith("==== ")]
        assert len(headers) == 2, headers
        assert " started run " in headers[0] and " resumed run " in headers[1], headers
        assert f"actor {k} of 2" in headers[0]
        assert "\x1b" not in log
        # The first session's lines are still there, before the second header.
        assert log.index("registered") < log.index(headers[1])

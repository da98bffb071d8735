#!/usr/bin/env python3
"""Instruction-count check (docs/PERFORMANCE.md, "Instruction counts"); run by
scripts/bench-check.sh, which builds the harnesses first.

Runs every bench of each harness binary under callgrind, counting only the harness's
`icount_measured` function, and compares each count with the committed baseline of the CPU class
the harness reports (under valgrind: the features valgrind emulates). Fails when a count grew by
more than the tolerance, when a bench has no baseline, or when its iterations changed.
`--update` writes the counts into the baseline instead (a deliberate commit that says why).
Python standard library only.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

TOLERANCE_PERCENT = 3.0


def run(cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True)


def tool_version(cmd):
    try:
        return run(cmd).stdout.strip().splitlines()[0]
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def count(binary, bench, workdir):
    """Instructions of one bench's measured region, and the harness's own report."""
    out = os.path.join(workdir, f"callgrind.{bench}")
    proc = run([
        "valgrind", "--tool=callgrind", "--collect-atstart=no", "--toggle-collect=*icount_measured*",
        f"--callgrind-out-file={out}", binary, "run", bench,
    ])
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    with open(out) as f:
        totals = [line.split()[1] for line in f if line.startswith(("totals:", "summary:"))]
    if not totals:
        sys.exit(f"bench-check: {out} has no totals line (valgrind output changed?)")
    report["instructions"] = int(totals[0])
    return report


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", required=True, help="the baseline JSON file")
    ap.add_argument("--update", action="store_true", help="write the counts into the baseline instead of checking")
    ap.add_argument("--only", action="append", default=[], metavar="BENCH", help="run only this bench (repeatable)")
    ap.add_argument("binaries", nargs="+", help="harness binaries (`list` and `run NAME`)")
    args = ap.parse_args()

    benches = []
    for binary in args.binaries:
        for line in run([binary, "list"]).stdout.splitlines():
            name = line.split("\t")[0]
            if not args.only or name in args.only:
                benches.append((binary, name))
    unknown = set(args.only) - {b for _, b in benches}
    if unknown:
        sys.exit(f"bench-check: no bench named {', '.join(sorted(unknown))} in {', '.join(args.binaries)}")

    try:
        with open(args.baseline) as f:
            baseline = json.load(f)
    except FileNotFoundError:
        if not args.update:
            sys.exit(f"bench-check: no baseline file {args.baseline}: run with --update to create it")
        baseline = {}
    classes = baseline.setdefault("classes", {})

    results = []
    with tempfile.TemporaryDirectory() as workdir:
        for binary, name in benches:
            results.append(count(binary, name, workdir))
            print(f"  counted {name}", file=sys.stderr, flush=True)
    cpu_classes = {r["cpu_class"] for r in results}
    if len(cpu_classes) != 1:
        sys.exit(f"bench-check: the harnesses saw different CPU classes: {sorted(cpu_classes)}")
    cpu_class = cpu_classes.pop()
    rustc = tool_version(["rustc", "--version"])
    valgrind = tool_version(["valgrind", "--version"])

    if args.update:
        entry = classes.setdefault(cpu_class, {"benches": {}})
        entry["rustc"], entry["valgrind"] = rustc, valgrind
        for r in results:
            entry["benches"][r["bench"]] = {"iterations": r["iterations"], "instructions": r["instructions"]}
        entry["benches"] = dict(sorted(entry["benches"].items()))
        baseline["tolerance_percent"] = baseline.get("tolerance_percent", TOLERANCE_PERCENT)
        with open(args.baseline, "w") as f:
            json.dump(baseline, f, indent=2)
            f.write("\n")
        for r in results:
            print(f"{r['bench']:<24} {r['instructions'] // r['iterations']:>14,} instructions per iteration")
        print(f"bench-check: wrote {len(results)} counts for CPU class {cpu_class} into {args.baseline}")
        return 0

    tolerance = float(baseline.get("tolerance_percent", TOLERANCE_PERCENT))
    entry = classes.get(cpu_class)
    if entry is None:
        sys.exit(
            f"bench-check: {args.baseline} has no baseline for CPU class {cpu_class} (it has: {', '.join(sorted(classes)) or 'none'}); "
            "counts differ between classes, so make one on such a machine with --update and commit it"
        )
    if entry.get("rustc") != rustc or entry.get("valgrind") != valgrind:
        print(f"note: baseline made with {entry.get('rustc')}, {entry.get('valgrind')}; this run: {rustc}, {valgrind}", file=sys.stderr)

    failures = []
    print(f"{'bench':<24} {'baseline/iter':>14} {'now/iter':>14} {'change':>8} {'Δ total':>10}  verdict   (CPU class {cpu_class}, tolerance +{tolerance:g} %)")
    for r in results:
        base = entry["benches"].get(r["bench"])
        per_iter = r["instructions"] // r["iterations"]
        if base is None:
            failures.append(r["bench"])
            print(f"{r['bench']:<24} {'-':>14} {per_iter:>14,} {'':>8}  NO BASELINE (run with --update)")
            continue
        if base["iterations"] != r["iterations"]:
            failures.append(r["bench"])
            print(f"{r['bench']:<24} iterations {base['iterations']} -> {r['iterations']}: the bench changed; update the baseline")
            continue
        change = 100.0 * (r["instructions"] - base["instructions"]) / base["instructions"]
        if change > tolerance:
            verdict = "FAIL"
            failures.append(r["bench"])
        elif change < -tolerance:
            verdict = "faster (consider --update)"
        else:
            verdict = "ok"
        print(f"{r['bench']:<24} {base['instructions'] // base['iterations']:>14,} {per_iter:>14,} {change:>+7.2f}% {r['instructions'] - base['instructions']:>+10,}  {verdict}")
    if failures:
        print(f"bench-check: FAILED: {', '.join(failures)}")
        return 1
    print(f"bench-check: {len(results)} counts within +{tolerance:g} % of the baseline")
    return 0


if __name__ == "__main__":
    sys.exit(main())

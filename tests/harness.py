"""Helpers for the end-to-end tests: run the signorini executable (on 1 or more MPI ranks) and read its
JSON summary. Standard library only, so the tests run with any python3."""
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OPTIONS = os.path.join(ROOT, "petsc-options")
EXE = os.environ.get("SIGNORINI_EXE", os.path.join(ROOT, "build", "signorini"))
MPIEXEC = os.environ.get("SIGNORINI_MPIEXEC", "mpirun")

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")


def scene(name):
    return ["-options_file", os.path.join(OPTIONS, name)]


def run(args, ranks=1, check=True):
    """Runs signorini with `args`; returns (returncode, stdout, stderr, summary dict or None). When `args`
    name their own -summary file, it is left to the caller and the dict is None."""
    with tempfile.TemporaryDirectory() as tmp:
        summary = os.path.join(tmp, "summary.json")
        cmd = [EXE] + list(args) + ([] if "-summary" in args else ["-summary", summary])
        if ranks > 1:
            cmd = [MPIEXEC, "--oversubscribe", "-n", str(ranks)] + cmd
        p = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=600)
        data = None
        if os.path.exists(summary):
            with open(summary) as f:
                data = json.load(f)
    if check and p.returncode != 0:
        sys.stderr.write(p.stdout + p.stderr)
        raise AssertionError("signorini failed (exit %d): %s" % (p.returncode, " ".join(cmd)))
    return p.returncode, p.stdout, p.stderr, data


def rate(hs, errs):
    """Least-squares slope of log(err) against log(h)."""
    import math
    xs = [math.log(h) for h in hs]
    ys = [math.log(e) for e in errs]
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


class Checker:
    """Collects named assertions, prints each, and exits non-zero if any failed."""

    def __init__(self):
        self.failed = 0
        self.passed = 0

    def check(self, ok, what):
        print(("PASS " if ok else "FAIL ") + what, flush=True)
        if ok:
            self.passed += 1
        else:
            self.failed += 1

    def done(self):
        print("%d passed, %d failed" % (self.passed, self.failed))
        sys.exit(1 if self.failed else 0)

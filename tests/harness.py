"""Helpers for the end-to-end tests: run the signorini executable (on 1 or more MPI ranks) and read its
JSON summary. Standard library only, so the tests run with any python3."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "run"))
from launch import ENV, EXE, MPIEXEC, OPTIONS, ROOT, command, scene  # noqa: E402,F401  (the tests import these from here)
import launch  # noqa: E402


def run(args, ranks=1, check=True):
    """Runs signorini with `args`; returns (returncode, stdout, stderr, summary dict or None). When `args`
    name their own -summary file, it is left to the caller and the dict is None."""
    r = launch.run(args, ranks, summary="-summary" not in args, timeout=600)
    if check and r.returncode != 0:
        sys.stderr.write(r.stdout + r.stderr)
        raise AssertionError("signorini failed (exit %d): %s" % (r.returncode, " ".join(r.cmd)))
    return r.returncode, r.stdout, r.stderr, r.summary


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

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


def scene_with(name, token, value, directory):
    """The options of the scene petsc-options/NAME with a literal parameter of its option lines (a contrast
    1e6, a load factor 1e10) replaced by value, as a file written in directory."""
    import tempfile
    args = scene(name)
    with open(args[1]) as f:
        text = f.read()
    assert token in text, "%s does not contain %s" % (name, token)
    fd, path = tempfile.mkstemp(prefix=name + "-", dir=directory)
    with os.fdopen(fd, "w") as f:
        f.write("\n".join(l if l.startswith("#") else l.replace(token, value) for l in text.splitlines()) + "\n")
    return ["-options_file", path]


def adapted_meshes(s):
    """The sequence of adapted meshes of a run's summary: cells, DOFs and marked cells of every step."""
    return [(r["cells"], r["dofs"], r["marked"]) for r in s["adapt"]]


def rel(a, b):
    """Relative difference of a and b."""
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


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

    def kkt(self, tag, s):
        """The discrete KKT conditions of a converged contact solve (summary s) to solver tolerance."""
        k = s["kkt"]
        self.check(s["solver"]["converged_reason"].startswith("CONVERGED"), "%s: %s" % (tag, s["solver"]["converged_reason"]))
        self.check(k["min_gap"] >= -1e-12, "%s: primal feasibility min(u - psi) = %.2e" % (tag, k["min_gap"]))
        self.check(k["min_pressure"] >= -1e-7 * k["max_pressure"], "%s: dual feasibility min pressure = %.2e (max %.2e)" % (tag, k["min_pressure"], k["max_pressure"]))
        self.check(k["max_complementarity"] <= 1e-7 * max(k["max_pressure"] * k["max_gap"], 1e-300), "%s: complementarity %.2e" % (tag, k["max_complementarity"]))
        self.check(s["stationarity"] <= 1e-8, "%s: equation residual off Gamma_C %.2e" % (tag, s["stationarity"]))

    def done(self):
        print("%d passed, %d failed" % (self.passed, self.failed))
        sys.exit(1 if self.failed else 0)

"""run/bench on small 2D CR meshes (independent recomputation from the per-run summaries it keeps):
- one run per case: each row's times, VI / linear ratio and bytes per DOF are those of the run's JSON;
- --repeat 3: three runs per case, each kept; each row holds the median of every time and of the three
  ratios and the largest peak memory, recomputed here from the three JSON files;
- bench.csv and time-per-dof.png are written, no *.tmp file is left; --repeat 0, an unknown element or
  dimension, a repeated one, a size or rank count that is no positive integer are clear usage errors
  before any run; where every run fails, the last results are left as they were (exit 1);
- --estimate: each estimate / solve ratio is that of its run's Estimate and Solve stages, and each adaptive
  step's overhead / solve is that of the run's "adapt" row (estimate + mark + refine + redistribute + transfer);
- --error --quick: each error / solve ratio is that of its run's Error and Solve stages;
- --nohier on N = 32 Gmsh files: each row is that of its run's JSON (one level, read without -refine), and
  no mesh file is left."""
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker

c = Checker()
BENCH = os.path.join(ROOT, "run", "bench.py")
STAGES = ["mesh", "distribute", "refine", "setup", "assemble", "solve"]
SIZES = [32, 64]


def bench(tmp, *more):
    cmd = [sys.executable, BENCH, "--dims", "2", "--elements", "cr", "--n2", ",".join(map(str, SIZES)), "--no-warm-memory", "--out", tmp] + list(more)
    return subprocess.run(cmd, capture_output=True, text=True, env=ENV)


def close(a, b):
    return abs(a - b) <= 1e-9 * max(abs(a), abs(b), 1e-30)


def check_rows(tmp, repeat):
    with open(os.path.join(tmp, "bench.csv")) as f:
        rows = {int(r["N"]): r for r in csv.DictReader(f)}
    c.check(sorted(rows) == SIZES and all(r["status"] == "ok" and int(r["repeats"]) == repeat for r in rows.values()), "repeat %d: rows %s" % (repeat, sorted(rows)))
    for N in SIZES:
        names = ["2d-cr-N%d-np1%s.json" % (N, "-run%d" % (k + 1) if repeat > 1 else "") for k in range(repeat)]
        runs = []
        for name in names:
            with open(os.path.join(tmp, name)) as f:
                runs.append(json.load(f))
        r = rows[N]
        want = {k + "_s": statistics.median(s["time"][k] for s in runs) for k in STAGES}
        want["linear_s"] = statistics.median(s["solver"]["linear_solve_seconds"] for s in runs)
        want["ratio"] = statistics.median(s["solver"]["solve_linear_ratio"] for s in runs)
        want["bytes_per_dof"] = max(s["memory"]["peak_rss_bytes_sum"] for s in runs) / runs[0]["dofs"]
        bad = [k for k, v in want.items() if not close(float(r[k]), v)]
        c.check(not bad and int(r["dofs"]) == runs[0]["dofs"], "repeat %d, N = %d: row against %d run(s) (%s)" % (repeat, N, repeat, "mismatch in %s" % bad if bad else "times, ratio, bytes agree"))
    files = os.listdir(tmp)
    c.check("time-per-dof.png" in files and not any(f.endswith(".tmp") or ".tmp." in f for f in files), "repeat %d: files %s" % (repeat, sorted(files)))


for repeat in [1, 3]:
    with tempfile.TemporaryDirectory() as tmp:
        p = bench(tmp, *(["--repeat", str(repeat)] if repeat > 1 else []))
        c.check(p.returncode == 0, "run/bench --repeat %d exit status %d %s" % (repeat, p.returncode, p.stderr[-400:]))
        if p.returncode == 0:
            check_rows(tmp, repeat)
            c.check(("medians of %d runs each" % repeat in p.stdout) == (repeat > 1), "repeat %d: the summary says whether it shows medians" % repeat)

def check_estimate(tmp):
    with open(os.path.join(tmp, "estimate-cost.csv")) as f:
        est = list(csv.DictReader(f))
    c.check(len(est) == 1 and est[0]["status"] == "ok", "--estimate: one estimate row %s" % [r["status"] for r in est])
    for r in est:
        with open(os.path.join(tmp, "estimate-2d-cr-N32-np1-run1.json")) as f:
            t = json.load(f)["time"]
        c.check(t["estimate"] > 0 and close(float(r["ratio"]), t["estimate"] / t["solve"]), "--estimate: ratio %s = Estimate / Solve stage %g / %g" % (r["ratio"], t["estimate"], t["solve"]))
    with open(os.path.join(tmp, "adapt-overhead.csv")) as f:
        ada = list(csv.DictReader(f))
    with open(os.path.join(tmp, "adapt-2d-cr-N16-np1-run1.json")) as f:
        steps = json.load(f)["adapt"]
    c.check(len(steps) == 3 and [int(r["step"]) for r in ada] == [0, 1], "--estimate: rows for the steps that refine %s of %d" % ([r["step"] for r in ada], len(steps)))
    for r in ada:
        a = steps[int(r["step"])]
        overhead = sum(a[k + "_seconds"] for k in ["estimate", "mark", "refine", "redistribute", "transfer"])
        c.check(int(r["dofs"]) == a["dofs"] and close(float(r["ratio"]), overhead / a["solve_seconds"]), "--estimate: step %s overhead / solve %s = %g / %g" % (r["step"], r["ratio"], overhead, a["solve_seconds"]))


with tempfile.TemporaryDirectory() as tmp:
    p = bench(tmp, "--estimate", "--est-n2", "32", "--adapt-n2", "16", "--adapt-steps", "2")
    c.check(p.returncode == 0 and "estimate / solve" in p.stdout and "overhead / solve" in p.stdout, "run/bench --estimate exit status %d %s" % (p.returncode, p.stderr[-400:]))
    if p.returncode == 0:
        check_estimate(tmp)

def check_error_cost(tmp, stdout):
    """--error: each printed ratio is the kept summary's Error stage over its Solve stage."""
    lines = [l for l in stdout.splitlines() if "error/solve" in l]
    c.check(len(lines) == 4, "--error: %d rows, expected 4" % len(lines))
    for l in lines:
        scene, element = l.split()[:2]
        t = json.load(open(os.path.join(tmp, "error-%s-%s-np1.json" % (scene, element))))["time"]
        ratio = float(l.split("error/solve")[1].split()[0])
        c.check(abs(ratio - t["error"] / t["solve"]) <= 0.01 * ratio + 0.005, "--error %s %s: printed %g, summary %g" % (scene, element, ratio, t["error"] / t["solve"]))


with tempfile.TemporaryDirectory() as tmp:
    p = bench(tmp, "--error", "--quick")
    c.check(p.returncode == 0, "run/bench --error exit status %d %s" % (p.returncode, p.stderr[-400:]))
    if p.returncode == 0:
        check_error_cost(tmp, p.stdout)

def check_nohier(tmp, p):
    """--nohier: each row's Newton steps, CG iterations, set-ups and ratio contact / linear solve are those of
    the run's JSON, the run read the file without -refine (one level), and the mesh files are removed."""
    c.check(p.returncode == 0, "run/bench --nohier exits 0 (%s)" % (p.stderr.strip()[-300:] or "ok"))
    with open(os.path.join(tmp, "nohier.csv")) as f:
        rows = list(csv.DictReader(f))
    c.check([row["element"] for row in rows] == ["p1", "cr"] and all(row["status"] == "ok" for row in rows), "one row per element: %s" % [(row["element"], row["status"]) for row in rows])
    for row in rows:
        with open(os.path.join(tmp, "nohier-%s-N32-np1-run1.json" % row["element"])) as f:
            s = json.load(f)
        v = s["solver"]
        same = (int(row["dofs"]) == s["dofs"] and int(row["newton"]) == v["newton_iterations"] and int(row["ksp"]) == v["ksp_iterations"]
                and int(row["amg_setups"]) == v["amg_setups"] and abs(float(row["ratio"]) - v["solve_linear_ratio"]) <= 1e-9 * v["solve_linear_ratio"])
        c.check(same and not v["nested"] and s["refine"] == 0 and s["mesh"].endswith(".msh"),
                "%s: row against its JSON (ratio %s, mesh %s, nested %s)" % (row["element"], row["ratio"], s["mesh"], v["nested"]))
    left = [f for f in os.listdir(tmp) if f.endswith(".msh") or f.endswith(".tmp")]
    c.check(not left, "no mesh file or temporary file left: %s" % left)


with tempfile.TemporaryDirectory() as tmp:
    check_nohier(tmp, bench(tmp, "--nohier", "--nohier-n2", "32", "--elements", "p1,cr"))

with tempfile.TemporaryDirectory() as tmp:
    p = bench(tmp, "--repeat", "0")
    c.check(p.returncode == 2 and "--repeat: 0 is not a positive count" in p.stderr, "--repeat 0: exit %d, %s" % (p.returncode, p.stderr.strip().splitlines()[-1:]))
    # a mistyped list value ran nothing, or failed half-way with a traceback, and wrote a table: now refused first
    for args, message in [(["--elements", "q1"], "--elements q1: 'q1' is not one of p1, cr"), (["--dims", "4"], "--dims 4: '4' is not one of 2, 3"),
                          (["--elements", "cr,cr"], "'cr' is given twice"), (["--n2", "32,x"], "--n2 32,x: 'x' is not an integer"),
                          (["--n2", "32,0"], "--n2 32,0: 0 is not a positive count"), (["--ranks", "0"], "--ranks: 0 is not a positive count"),
                          (["--estimate", "--est-n2", "-4"], "--est-n2: -4 is not a positive count"),
                          (["--nohier", "--nohier-n2", "32,0"], "--nohier-n2 32,0: 0 is not a positive count"),
                          (["--nohier", "--nohier-n2", "3x"], "--nohier-n2 3x: '3x' is not an integer")]:
        p = bench(tmp, *args)
        c.check(p.returncode == 2 and message in p.stderr and not os.listdir(tmp), "%s: exit %d, %s, nothing written" % (" ".join(args), p.returncode, p.stderr.strip().splitlines()[-1:]))

# Every run failed (kappa < 0): exit 1 and the last results left as they were, not replaced by a table of
# failures and an empty plot; so for --estimate and --nohier.
for mode, files in [([], ["bench.csv", "time-per-dof.png"]), (["--estimate", "--quick"], ["estimate-cost.csv", "adapt-overhead.csv"]),
                    (["--nohier", "--quick"], ["nohier.csv"])]:
    with tempfile.TemporaryDirectory() as tmp:
        for name in files:
            with open(os.path.join(tmp, name), "w") as f:
                f.write("earlier results\n")
        p = bench(tmp, *(mode + ["-kappa", "-1"]))
        kept = all(open(os.path.join(tmp, name)).read() == "earlier results\n" for name in files)
        c.check(p.returncode == 1 and kept and "no run succeeded" in p.stdout, "%s with every run failing: exit %d, %s left as they were: %s" % (" ".join(mode) or "bench", p.returncode, ", ".join(files), kept))

# An output that cannot be written ended the scripts in a traceback, run/stability after all its runs: now a
# usage error (exit 2) before any run, in every script of run/.
for script, args in [("bench.py", ["--quick", "--out", "/dev/null/x"]), ("bench.py", ["--estimate", "--quick", "--out", "/dev/null"]),
                     ("scaling.py", ["--ranks", "1", "--out", "/dev/null/x"]), ("study.py", ["paper-5.1", "--out", "/dev/null/x"]),
                     ("stability.py", ["--only", "psi", "--csv", "/dev/null/x.csv"]), ("stability.py", ["--only", "psi", "--csv", ROOT])]:
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", script)] + args, capture_output=True, text=True, env=ENV)
    lines = p.stderr.strip().splitlines()
    c.check(p.returncode == 2 and lines and ("--out" in lines[-1] or "--csv" in lines[-1]) and "Traceback" not in p.stderr and "running" not in p.stderr,
            "run/%s %s: exit %d, %s" % (script, " ".join(args), p.returncode, lines[-1:]))
c.done()

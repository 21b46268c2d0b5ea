"""Uniform against adaptive refinement (run/study, run/compare.py) and the error against an adaptive reference
(-adapt_reference_steps):
  - on manufactured-2d (exact solution known) the energy error of each step against the reference, the
    solution m steps further, approaches the exact energy error: within 10 % for the steps at least 6 steps
    before the reference (an independent computation: the exact error by quadrature against u), and the
    relative gap shrinks with the distance to the reference; the run's result is the last step of the
    adaptive run, not the reference;
  - on 2 ranks the same meshes give the same reference errors (1e-8 relative) for the steps after the last
    redistribution, and none for the steps before it;
  - run/study on a small scene writes compare.csv/.json with both strategies and both elements and their
    fields, the two comparison plots and the adapted meshes; the adaptive run stops at the DOFs of the finest
    uniform level; without an exact solution the adaptive errors are against the adaptive reference, which
    ends at -adapt_reference_dofs times the run's last DOFs (2D and 3D); it lists only the files it wrote."""
import csv
import json
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker, run, scene

c = Checker()
K, M = 8, 6
# Tight solver tolerances: the 1- and 2-rank reference errors are differences of two discrete solutions,
# which must agree to round-off rather than to the default tolerance for the comparison below.
tight = ["-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
base = scene("manufactured-2d") + ["-box_faces", "4", "-adapt_steps", str(K), "-adapt_reference_steps", str(M)] + tight

one = {}
for element in ["p1", "cr"]:
    _, _, _, s = run(base + ["-space", element])
    rows = one[element] = s["adapt"]
    c.check(len(rows) == K + M + 1 and [r["reference_step"] for r in rows] == [False] * (K + 1) + [True] * M,
            "%s: %d adaptive steps, then %d reference steps" % (element, K + 1, M))
    c.check(s["dofs"] == rows[K]["dofs"] and s["cells"] == rows[K]["cells"] and abs(s["error"]["energy"] - rows[K]["error"]) <= 1e-12 * rows[K]["error"],
            "%s: the run's result is step %d (%d DOFs), not the reference" % (element, K, s["dofs"]))
    c.check(rows[-1]["error_reference"] is None and all(r["error_reference"] is not None for r in rows[:-1]), "%s: every step but the reference has a reference error" % element)
    gaps = [abs(r["error_reference"] - r["error"]) / r["error"] for r in rows[:-1]]
    far = gaps[:len(rows) - 1 - M]
    c.check(max(far) <= 0.10, "%s: steps 0..%d (>= %d steps before the reference): reference error within %.1f %% of the exact error" % (element, len(far) - 1, M, 100 * max(far)))
    c.check(gaps[0] < gaps[-1], "%s: the gap shrinks with the distance to the reference (%.3f at step 0, %.3f at the step before it)" % (element, gaps[0], gaps[-1]))

# -adapt_reference_dofs F: the reference steps end at the first mesh with F times the DOFs of the run's last
# step, before the M steps (3D steps grow the mesh about 4 times, and 6 of them ran out of memory).
F = 4
_, _, _, s = run(scene("manufactured-2d") + ["-box_faces", "4", "-adapt_steps", str(K), "-adapt_reference_steps", str(M), "-adapt_reference_dofs", str(F), "-space", "cr"])
rows, last = s["adapt"], s["adapt"][K]["dofs"]
ref = [r["dofs"] for r in rows if r["reference_step"]]
c.check(0 < len(ref) < M and all(d < F * last for d in ref[:-1]) and ref[-1] >= F * last and [r["dofs"] for r in rows[:K + 1]] == [r["dofs"] for r in one["cr"][:K + 1]],
        "-adapt_reference_dofs %d: %d reference steps (of %d), the last the first with %d >= %d x %d DOFs; the same run before them" % (F, len(ref), M, ref[-1] if ref else 0, F, last))

# 2 ranks: the same meshes, so the same errors where the parent chain is intact.
_, _, _, s = run(base + ["-space", "cr", "-adapt_imbalance", "1.05"], ranks=2)
rows = s["adapt"]
cut = max([k for k, r in enumerate(rows) if r["redistributed"]], default=-1)
same = all(abs(a["error_reference"] - b["error_reference"]) <= 1e-8 * b["error_reference"] for a, b in zip(rows[cut + 1:-1], one["cr"][cut + 1:-1]))
c.check([r["dofs"] for r in rows] == [r["dofs"] for r in one["cr"]] and same, "2 ranks: the same meshes and reference errors after the last redistribution (step %d)" % cut)
c.check(all(r["error_reference"] is None for r in rows[:cut + 1]), "2 ranks: no reference error for the %d steps before the last redistribution" % (cut + 1))

env = dict(ENV, PYTHONDONTWRITEBYTECODE="1")
with tempfile.TemporaryDirectory() as tmp:
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "manufactured-2d", "-box_faces", "4", "-study_levels", "3", "--out", tmp],
                       capture_output=True, text=True, env=env)
    c.check(p.returncode == 0 and "uniform against adaptive refinement" in p.stdout, "run/study exit status %d %s" % (p.returncode, p.stderr[-300:]))
    files = os.listdir(tmp)
    pictures = ["compare-vs-dofs.png", "compare-vs-time.png", "adapted-mesh-p1.png", "adapted-mesh-cr.png"]
    for name in pictures:
        ok = name in files
        if ok:
            with open(os.path.join(tmp, name), "rb") as f:
                ok = f.read(8) == b"\x89PNG\r\n\x1a\n"
        c.check(ok, "run/study wrote the picture %s" % name)
    with open(os.path.join(tmp, "compare.json")) as f:
        rows = json.load(f)["rows"]
    with open(os.path.join(tmp, "compare.csv")) as f:
        table = list(csv.DictReader(f))
    c.check(len(table) == len(rows) and {(r["strategy"], r["element"]) for r in table} == {(a, e) for a in ["uniform", "adaptive"] for e in ["p1", "cr"]},
            "compare.csv and compare.json: the same %d rows, both strategies and both elements" % len(rows))
    fields = ["strategy", "element", "step", "dofs", "error", "eta", "efficiency", "newton", "ksp", "seconds"]
    c.check(all(all(r[k] is not None for k in fields) and r["error_against"] == "exact" for r in rows), "every row has %s, against the exact solution" % ", ".join(fields))
    for element in ["p1", "cr"]:
        uni = [r for r in rows if r["strategy"] == "uniform" and r["element"] == element]
        ada = [r for r in rows if r["strategy"] == "adaptive" and r["element"] == element]
        finest = uni[-1]["dofs"]
        c.check(ada[-1]["dofs"] >= finest > ada[-2]["dofs"], "%s: the adaptive run stops at the finest uniform DOFs (%d >= %d > %d)" % (element, ada[-1]["dofs"], finest, ada[-2]["dofs"]))
        c.check(all(a["seconds"] <= b["seconds"] for a, b in zip(ada, ada[1:])), "%s: the adaptive run time is cumulative (non-decreasing)" % element)
        c.check(all(abs(r["efficiency"] - r["eta"] / r["error"]) <= 1e-12 * r["efficiency"] for r in uni + ada), "%s: efficiency = eta / error in every row" % element)

    # A scene without an exact solution: the adaptive errors against the adaptive reference. In the folder of
    # the study above, whose P1 files this one, with CR only, must not list as its own.
    out = tmp
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "paper-5.1", "-box_faces", "2", "-study_levels", "3", "-reference_refine", "1",
                        "-study_spaces", "cr", "--reference-steps", "3", "--out", out], capture_output=True, text=True, env=env)
    c.check(p.returncode == 0, "run/study paper-5.1 exit status %d %s" % (p.returncode, p.stderr[-300:]))
    wrote = [l.split(": ", 1)[1].split(", ") for l in p.stdout.splitlines() if l.startswith("wrote in")]
    c.check(len(wrote) == 1 and "compare.json" in wrote[0] and not any("p1" in name for name in wrote[0]), "run/study lists the files it wrote, not the earlier study's: %r" % wrote)
    with open(os.path.join(out, "compare.json")) as f:
        rows = [r for r in json.load(f)["rows"] if r["strategy"] == "adaptive"]
    ref = [r for r in rows if r["reference_step"]]
    c.check(len(ref) == 3 and all(r["error_against"] == "adaptive reference" and r["error"] > 0 for r in rows[:-1]) and rows[-1]["error"] is None,
            "paper-5.1: %d adaptive rows against the adaptive reference, the last 3 steps for the reference" % len(rows))

    # A 3D scene without an exact solution: the reference ends at -adapt_reference_dofs (run/compare.py's
    # default), not after the 6 steps, which ran paper-5.1-3d P1 out of memory from 8 k DOFs.
    out = os.path.join(tmp, "3d")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "paper-5.1-3d", "-box_faces", "2", "-study_levels", "2", "-reference_refine", "1",
                        "-study_spaces", "p1", "--out", out], capture_output=True, text=True, env=env)
    c.check(p.returncode == 0, "run/study paper-5.1-3d exit status %d %s" % (p.returncode, p.stderr[-300:]))
    with open(os.path.join(out, "compare.json")) as f:
        rows = [r for r in json.load(f)["rows"] if r["strategy"] == "adaptive"]
    last = [r["dofs"] for r in rows if not r["reference_step"]][-1]
    ref = [r["dofs"] for r in rows if r["reference_step"]]
    c.check(0 < len(ref) < 6 and ref[-1] >= 32 * last and all(d < 32 * last for d in ref[:-1]),
            "paper-5.1-3d: %d reference steps, ending at %d >= 32 x %d DOFs" % (len(ref), ref[-1] if ref else 0, last))

# run/study's own options, checked before the uniform study runs (--theta 0 failed only in the adaptive run
# after it): usage errors, exit 2, nothing written.
for args, message in [(["--theta", "0"], "--theta: 0 is not in (0, 1]"), (["--reference-dofs", "-1"], "--reference-dofs: -1 is not in [0, inf]"),
                      (["--reference-steps", "2.5"], "--reference-steps: '2.5' is not an integer"), (["--ranks", "0"], "--ranks: 0 is not a positive count"),
                      (["--adapt-steps", "0"], "--adapt-steps: 0 is not a positive count")]:
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "out")
        p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "paper-5.1", "-study_levels", "2", "--out", out] + args,
                           capture_output=True, text=True, env=env)
        c.check(p.returncode == 2 and message in p.stderr and not os.path.exists(out), "run/study %s: exit %d, %s, nothing written" % (" ".join(args), p.returncode, p.stderr.strip().splitlines()[-1:]))
c.done()

"""Convergence-study machinery (issue: error against run time):
- the error integrators are exact where the answer is known analytically: for u = x^2 the P1 solution on a
  uniform mesh is the interpolant of u (the problem is one-dimensional and P1 is nodally exact in 1D), so
  ||u - I_h u||_L2 = h^2/sqrt(30) and |u - I_h u|_1 = h/sqrt(3); against a reference on a refined mesh the
  error of I_H u is ||I_H u - I_h u||, computed here independently with Simpson's rule, and
  |I_H u - I_h u|_1^2 = (H^2 - h^2)/3 (H1-orthogonality of the 1D interpolant); a discrete function against
  its own refinement gives 0; the same figures on 1 and 2 ranks;
- on the manufactured scene the errors against a fine reference agree with those against the exact solution
  to within the reference's own error (triangle inequality);
- each level starts from the one before, with the same errors and estimates as levels solved from u_D;
- -space narrows the study to one element, and -summary holds the study's table;
- run/study writes the CSV, JSON and PNG files and the rates are in range;
- without an exact solution or a reference the study measures the error by the estimate alone."""
import json
import math
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker, run, scene

c = Checker()
tight = ["-ksp_rtol", "1e-13"]


def study(args, ranks=1):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "study.json")
        run(args + ["-study_output", path], ranks=ranks)
        with open(path) as f:
            return json.load(f)


def interp_difference_l2(H, h):
    """||I_H x^2 - I_h x^2||_L2 on (0,1) x (0,1), exactly: both are piecewise linear in x on the fine grid."""
    def IH(x):
        a = math.floor(x / H + 1e-12) * H
        a = min(a, 1 - H)
        b = a + H
        return a * a + (x - a) * (a + b)  # linear interpolant of x^2 on [a, b]
    total, n = 0.0, round(1 / h)
    for i in range(n):
        x0, x1 = i * h, (i + 1) * h
        d0, d1 = IH(x0) - x0 * x0, IH(x1) - x1 * x1  # difference is linear on the fine interval
        total += h * (d0 * d0 + d0 * d1 + d1 * d1) / 3
    return math.sqrt(total)


quad = ["-dim", "2", "-bc_dirichlet", "2,4", "-bc_neumann", "1,3", "-u_D", "x^2", "-f", "-2",
        "-exact_u", "x^2", "-exact_grad", "2*x, 0", "-space", "p1"] + tight
for ranks in [1, 2]:
    for diag in ["slash", "backslash"]:
        s = study(quad + ["-box_diagonal", diag, "-box_faces", "4", "-study_levels", "3", "-reference_refine", "2", "-study_spaces", "p1"], ranks)
        href = s["rows"][-1]["h"] / 4
        for r in s["rows"]:
            h = r["h"]
            ex, rf = r["error_exact"], r["error_reference"]
            tag = "%d rank(s) %s N=%d" % (ranks, diag, r["N"])
            c.check(abs(ex["l2"] - h * h / math.sqrt(30)) <= 1e-8 * ex["l2"], "%s: ||u - I_h u|| = %.10e = h^2/sqrt(30)" % (tag, ex["l2"]))
            c.check(abs(ex["h1_semi"] - h / math.sqrt(3)) <= 1e-8 * ex["h1_semi"], "%s: |u - I_h u|_1 = %.10e = h/sqrt(3)" % (tag, ex["h1_semi"]))
            want = interp_difference_l2(h, href)
            c.check(abs(rf["l2"] - want) <= 1e-8 * want, "%s: ||I_H u - I_h u|| = %.10e, independent %.10e" % (tag, rf["l2"], want))
            want1 = math.sqrt((h * h - href * href) / 3)
            c.check(abs(rf["h1_semi"] - want1) <= 1e-8 * want1, "%s: |I_H u - I_h u|_1 = %.10e = sqrt((H^2-h^2)/3)" % (tag, rf["h1_semi"]))

# A discrete function against its own refinement: linear u is in both spaces on every level, for either element.
lin = ["-dim", "2", "-box_faces", "3", "-bc_dirichlet", "1,2,3,4", "-u_D", "1 + 2*x - 3*y", "-study_levels", "2",
       "-reference_refine", "2"] + tight
for ref in ["p1", "cr"]:
    s = study(lin + ["-reference_space", ref])
    worst = max(max(r["error_reference"]["l2"], r["error_reference"]["h1_semi"]) for r in s["rows"])
    c.check(worst < 1e-11, "linear u against its own refinement (%s reference): largest error %.2e" % (ref, worst))

# -space narrows a study to that element (without it, -study_spaces' p1,cr), and -summary, every run's summary
# file, holds the study's table as -study_output does: the same rows, here those of CR alone.
with tempfile.TemporaryDirectory() as tmp:
    table, summary = os.path.join(tmp, "table.json"), os.path.join(tmp, "summary.json")
    run(lin + ["-space", "cr", "-study_output", table, "-summary", summary])
    with open(table) as f, open(summary) as g:
        a, b = json.load(f), json.load(g)
c.check([r["element"] for r in a["rows"]] == ["cr", "cr"] and a == b,
        "study -space cr: rows of %s; -summary holds the table of -study_output: %s" % ([r["element"] for r in a["rows"]], a == b))

# Manufactured scene: | ||u_H - u_ref|| - ||u_H - u|| | <= ||u_ref - u||.
levels, extra = 3, 2
s = study(scene("manufactured-2d") + ["-box_faces", "4", "-study_levels", str(levels), "-reference_refine", str(extra), "-reference_space", "p1"])
_, _, _, ref = run(scene("manufactured-2d") + ["-box_faces", "4", "-refine", str(levels - 1 + extra), "-space", "p1"])
for r in s["rows"]:
    for norm in ["l2", "h1_semi"]:
        gap = abs(r["error_reference"][norm] - r["error_exact"][norm])
        c.check(gap <= ref["error"][norm] * (1 + 1e-9), "manufactured %s N=%d %s: |e_ref - e_exact| = %.2e <= reference error %.2e"
                % (r["element"], r["N"], norm, gap, ref["error"][norm]))

# Each level of an element starts from the one before (prolongation with its active set, the multigrid over
# the levels so far), as a run of that level would: the same rows as levels solved each from u_D
# (-nested 0, an independent solve of the same discrete problems; the reference from u_D too), on 1 and 2
# ranks; a row's total time is the run up to its level (cumulative within an element).
base = scene("manufactured-2d") + ["-box_faces", "4", "-study_levels", "4", "-reference_refine", "1"] + tight + ["-snes_rtol", "1e-13"]
alone = study(base + ["-nested", "0"])
for ranks in [1, 2]:
    s = study(base, ranks)
    c.check([r["carried"] for r in s["rows"]] == [r["level"] > 0 for r in s["rows"]] and not any(r["carried"] for r in alone["rows"]),
            "study, %d rank(s): every level after an element's first starts from the one before; with -nested 0 none" % ranks)
    # the reference is solved as a run of its level is: by nested iteration over the study's levels and its own
    c.check(s["reference"]["nested_levels"] == 4 + 1 and alone["reference"]["nested_levels"] == 0,
            "study, %d rank(s): reference by nested iteration over %d levels (5), with -nested 0 from u_D (%d levels)"
            % (ranks, s["reference"]["nested_levels"], alone["reference"]["nested_levels"]))
    worst = max(abs(a[k][n] - b[k][n]) / a[k][n] for a, b in zip(alone["rows"], s["rows"]) for k in ["error_exact", "error_reference"] for n in ["l2", "h1_semi"])
    worst = max([worst] + [abs(a["estimate"]["eta"] - b["estimate"]["eta"]) / a["estimate"]["eta"] for a, b in zip(alone["rows"], s["rows"])])
    c.check(worst <= 1e-8, "study, %d rank(s): errors and eta as with every level from u_D (largest relative difference %.1e <= 1e-8)" % (ranks, worst))
    for el in ["p1", "cr"]:
        t = [r["total_seconds"] for r in s["rows"] if r["element"] == el]
        c.check(all(a <= b for a, b in zip(t, t[1:])), "study %s, %d rank(s): total time cumulative over the levels (%s)" % (el, ranks, ["%.3f" % x for x in t]))

# run/study: files and rates.
with tempfile.TemporaryDirectory() as tmp:
    env = dict(ENV, PYTHONDONTWRITEBYTECODE="1")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "manufactured-2d", "-box_faces", "8", "-study_levels", "3", "--out", tmp],
                       capture_output=True, text=True, env=env)
    c.check(p.returncode == 0, "run/study exit status %d %s" % (p.returncode, p.stderr[-300:]))
    files = sorted(os.listdir(tmp))
    want = ["contact.png", "error-vs-h.png", "error-vs-time.png", "solution.png", "study.csv", "study.json"]
    c.check(all(f in files for f in want) and not any(f.endswith(".tmp") for f in files), "run/study wrote %s" % files)
    # the free boundary: the contact profile of the finest level has active and inactive DOFs on Gamma_C
    with open(os.path.join(tmp, "finest-cr-contact.csv")) as f:
        prof = [l.split(",") for l in f.read().splitlines()[1:]]
    gaps = [float(r[2]) - float(r[3]) for r in prof]
    c.check(len(prof) == 32 and min(gaps) <= 1e-10 and max(gaps) > 1e-3, "contact profile: %d DOFs, some active, some not" % len(prof))
    with open(os.path.join(tmp, "study.csv")) as f:
        lines = f.read().splitlines()
    c.check(len(lines) == 1 + 2 * 3 and lines[0].startswith("element,N,h"), "study.csv has a header and 6 rows")
    for name in ["error-vs-h.png", "error-vs-time.png", "solution.png", "contact.png"]:
        with open(os.path.join(tmp, name), "rb") as f:
            c.check(f.read(8) == b"\x89PNG\r\n\x1a\n", "%s is a PNG" % name)
    with open(os.path.join(tmp, "study.json")) as f:
        rows = json.load(f)["rows"]
    for el in ["p1", "cr"]:
        rs = [r for r in rows if r["element"] == el]
        r2 = math.log(rs[0]["error_exact"]["l2"] / rs[-1]["error_exact"]["l2"]) / math.log(rs[0]["h"] / rs[-1]["h"])
        r1 = math.log(rs[0]["error_exact"]["h1_semi"] / rs[-1]["error_exact"]["h1_semi"]) / math.log(rs[0]["h"] / rs[-1]["h"])
        c.check(1.8 <= r2 <= 2.3 and 0.9 <= r1 <= 1.2, "run/study %s rates: L2 %.2f, H1 %.2f" % (el, r2, r1))

# A scene without an exact solution and a study without a reference: the error is measured by the estimate
# alone (every row has eta, no row an error), eta falls like h (paper-5.1's solution is smooth enough for
# rate 1 in the energy norm), and run/study writes its files and plots from it. With -estimate none too,
# nothing would measure the error: one line.
base = scene("paper-5.1") + ["-box_faces", "4", "-study_levels", "3"]
s = study(base)
for el in ["p1", "cr"]:
    rs = [r for r in s["rows"] if r["element"] == el]
    rate = math.log(rs[0]["estimate"]["eta"] / rs[-1]["estimate"]["eta"]) / math.log(rs[0]["h"] / rs[-1]["h"])
    c.check(len(rs) == 3 and not any("error_exact" in r or "error_reference" in r for r in rs) and 0.9 <= rate <= 1.3,
            "paper-5.1 %s without a reference: rows measured by eta alone, eta ~ h^%.2f" % (el, rate))
_, out, _, _ = run(base)
c.check(any(l.startswith("cr ") and l.split()[5] == "-" for l in out.splitlines()), "the table prints '-' for the errors it has not got")
code, out, err, _ = run(base + ["-estimate", "none"], check=False)
lines = [l for l in (out + err).splitlines() if "error" in l]
c.check(code != 0 and len(lines) == 1 and "-estimate none" in lines[0] and "-reference_refine" in lines[0], "-estimate none without a reference: %s" % lines)
with tempfile.TemporaryDirectory() as tmp:
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "study.py"), "paper-5.1", "-box_faces", "4", "-study_levels", "3", "--adapt-steps", "4", "--out", tmp],
                       capture_output=True, text=True, env=dict(ENV, PYTHONDONTWRITEBYTECODE="1"))
    files = sorted(os.listdir(tmp))
    c.check(p.returncode == 0 and all(f in files for f in ["error-vs-h.png", "error-vs-time.png", "compare-vs-dofs.png", "compare.csv"]),
            "run/study paper-5.1 without a reference: exit %d, wrote %s %s" % (p.returncode, files, p.stderr[-300:]))
c.done()

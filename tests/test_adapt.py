"""Adaptive refinement (-adapt_steps): solve, estimate, mark, refine. Checked end to end:
  - the same adapted meshes on 1 and 2 ranks (cells, DOFs, marked cells at every step) and the same final
    energy (1e-9 relative), also when the refined mesh is redistributed at every step (-adapt_imbalance 1),
    and on 1 and 3 ranks where thousands of indicators lie closer together than the solver's tolerance,
    and on 1, 2 and 3 ranks on cells stretched 1000 : 1 (with the load scaled: tests/test_stiff.py);
  - every step refines, eta falls, eta bounds the energy error from above (the guaranteed bound) with
    efficiency index <= 3 at every step on the manufactured scenes, the last solution satisfies the KKT
    conditions, and the summary describes the last mesh (cells, DOFs, the "adapt" rows);
  - on the singular scene stiff-below-h2 the estimate falls like DOFs^-1/2 (fitted slope over the last
    steps <= -0.45), where uniform refinement gives DOFs^-0.32;
  - the same partition and results bit for bit in a second run on 2 ranks with repartitioning;
  - the first mesh, built by uniform refinement, is solved by nested iteration over its levels, with the
    same adapted meshes as from u_D on it (-nested 0);
  - -adapt_tol stops at the first step whose eta is below it, -adapt_max_dofs at the first mesh that has as
    many DOFs, and a zero estimate at once, each with a line that says so; -output writes the last mesh;
  - an option of the adaptive run (-adapt_tol, ...) without -adapt_steps is refused, not ignored;
  - a next mesh beyond the memory of the nodes (-memory_limit) ends the run, or its reference steps, at the
    step before it, with a line; at step 0 the refined mesh is refused in one line;
  - bad input: one clear line each."""
import math
import os
import tempfile

from harness import ENV, ROOT, Checker, adapted_meshes, run, scene

c = Checker()
ENV.pop("SCOTCH_PTHREAD_NUMBER", None)  # the executable's own setting is what is tested


def strip_times(x):
    """x less the fields that hold timings (they differ from run to run)."""
    if isinstance(x, dict):
        return {k: strip_times(v) for k, v in x.items() if "seconds" not in k and k != "time"}
    if isinstance(x, list):
        return [strip_times(v) for v in x]
    return x


def slope(dofs, values):
    xs, ys = [math.log(d) for d in dofs], [math.log(v) for v in values]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def kkt_ok(tag, s):
    k = s["kkt"]
    c.check(s["solver"]["converged_reason"].startswith("CONVERGED") and k["min_gap"] >= -1e-12 and k["relative"] <= 1e-6,
            "%s: the last solution satisfies the KKT conditions (relative %.1e)" % (tag, k["relative"]))


base = scene("manufactured-2d") + ["-space", "cr", "-box_faces", "8", "-adapt_steps", "6"]
runs = {}
for ranks, extra in [(1, []), (2, []), (2, ["-adapt_imbalance", "1"])]:
    _, _, _, s = run(base + extra, ranks=ranks)
    tag = "manufactured-2d cr, %d rank(s)%s" % (ranks, " " + " ".join(extra) if extra else "")
    rows = s["adapt"]
    c.check(len(rows) == 7 and all(r["marked"] > 0 for r in rows[:-1]) and all(b["cells"] > a["cells"] for a, b in zip(rows, rows[1:])),
            "%s: 6 steps, each marks and refines (%s cells)" % (tag, [r["cells"] for r in rows]))
    c.check(all(b["eta"] < a["eta"] for a, b in zip(rows, rows[1:])), "%s: eta falls (%s)" % (tag, ["%.3g" % r["eta"] for r in rows]))
    c.check(all(b["error"] < a["error"] for a, b in zip(rows, rows[1:])), "%s: the energy error falls" % tag)
    c.check(all(r["error"] <= r["eta"] <= 3 * r["error"] for r in rows), "%s: energy error <= eta <= 3 x error at every step (indices %s)" % (tag, ["%.2f" % (r["eta"] / r["error"]) for r in rows]))
    c.check(s["cells"] == rows[-1]["cells"] and s["dofs"] == rows[-1]["dofs"] and sum(s["cells_per_rank"]) == s["cells"],
            "%s: the summary describes the last mesh (%d cells, %d DOFs)" % (tag, s["cells"], s["dofs"]))
    kkt_ok(tag, s)
    # Stage times are exclusive (a stage pushed inside another pauses it), so they add up to at most the
    # run's total; the work between meshes has its own stage.
    t = s["time"]
    stages = sum(v for k, v in t.items() if k != "total")
    c.check(t["adapt"] > 0 and all(v >= 0 for v in t.values()) and stages <= t["total"] * (1 + 1e-9),
            "%s: stage times (adapt %.3f s) add up to %.3f s <= total %.3f s" % (tag, t["adapt"], stages, t["total"]))
    runs[(ranks, bool(extra))] = s
    if extra:
        c.check(any(r["redistributed"] for r in rows[:-1]), "%s: the refined meshes are redistributed" % tag)
one = runs[(1, False)]
for key in [(2, False), (2, True)]:
    other = runs[key]
    same = adapted_meshes(one) == adapted_meshes(other)
    c.check(same, "2 ranks%s: the same adapted meshes as on 1 rank (cells, DOFs, marked cells per step)" % (" redistributed" if key[1] else ""))
    c.check(abs(other["energy"] - one["energy"]) <= 1e-9 * abs(one["energy"]), "2 ranks%s: energy %.15e, 1 rank %.15e" % (" redistributed" if key[1] else "", other["energy"], one["energy"]))

# The other element, tetrahedra, and PETSc's refine_sbr: the same checks, and the same meshes on 1 and 2 ranks.
# Also unstructured Gmsh meshes, whose bisection makes a few stretched cells beside shape-regular ones, so
# that P1 patches mix the full RT0 mass matrices of the first with the diagonal of the others (the 3D P1 run
# crashed there until stop 29).
cube = ["-mesh_file", os.path.join(ROOT, "tests", "data", "cube.msh")]
for name, extra in [("manufactured-2d", ["-space", "p1", "-box_faces", "8", "-adapt_steps", "6"]),
                    ("manufactured-2d", ["-space", "cr", "-box_faces", "8", "-adapt_steps", "4", "-adapt_refinement", "sbr"]),
                    ("manufactured-3d", ["-space", "cr", "-box_faces", "3", "-adapt_steps", "4"]),
                    ("manufactured-3d", ["-space", "p1", "-box_faces", "4", "-adapt_steps", "4"]),
                    ("manufactured-3d", ["-space", "p1", "-adapt_steps", "4"] + cube),
                    ("manufactured-3d", ["-space", "cr", "-adapt_steps", "3"] + cube)]:
    tag = "%s %s" % (name, " ".join(extra))
    _, _, _, s1 = run(scene(name) + extra)
    _, _, _, s2 = run(scene(name) + extra + ["-adapt_imbalance", "1"], ranks=2)
    rows = s1["adapt"]
    c.check(all(b["cells"] > a["cells"] for a, b in zip(rows, rows[1:])) and rows[-1]["eta"] < rows[0]["eta"],
            "%s: every step refines, eta falls (%s cells, eta %s)" % (tag, [r["cells"] for r in rows], ["%.3g" % r["eta"] for r in rows]))
    c.check(all(r["error"] <= r["eta"] <= 3 * r["error"] for r in rows), "%s: energy error <= eta <= 3 x error at every step (indices %s)" % (tag, ["%.2f" % (r["eta"] / r["error"]) for r in rows]))
    same = adapted_meshes(s1) == adapted_meshes(s2)
    c.check(same and abs(s2["energy"] - s1["energy"]) <= 1e-9 * abs(s1["energy"]),
            "%s: the same adapted meshes and energy on 2 ranks, redistributed (%.15e, %.15e)" % (tag, s1["energy"], s2["energy"]))
    kkt_ok(tag, s2)
    if name == "manufactured-3d" and "p1" in extra:
        # Run to run: PT-Scotch's repartitioning is the same each time (left to its own threads it was not:
        # other cells per rank, eta in the 11th digit), so the whole summary is too, bit for bit.
        _, _, _, again = run(scene(name) + extra + ["-adapt_imbalance", "1"], ranks=2)
        keys = ["cells_per_rank", "energy", "adapt", "estimate", "kkt", "solver"]
        c.check(all(strip_times(again[k]) == strip_times(s2[k]) for k in keys),
                "%s: a second run on 2 ranks, redistributed, gives the same partition and results bit for bit (cells per rank %s, %s)" % (tag, s2["cells_per_rank"], again["cells_per_rank"]))

# The first mesh solved by nested iteration over the levels it was refined from (the box 32 x 32 is built as
# 8 x 8 refined twice, 8 x 8 x 8 as 4 x 4 x 4 refined once), and the later steps' multigrid down through
# them: the same adapted meshes, estimates and energy as from u_D on the first mesh alone (-nested 0), an
# independent solve of the same discrete problems, and on 2 ranks.
for name, extra, levels in [("manufactured-2d", ["-box_faces", "32"], 3), ("manufactured-3d", ["-box_faces", "8"], 2)]:
    for el in ["cr", "p1"]:
        args = scene(name) + extra + ["-space", el, "-adapt_steps", "3"]
        tag = "%s %s %s" % (name, el, " ".join(extra))
        _, _, _, s = run(args)
        _, _, _, alone = run(args + ["-nested", "0"])
        _, _, _, s2 = run(args, ranks=2)
        c.check([r["nested_levels"] for r in s["adapt"]] == [levels, 0, 0, 0] and [r["nested_levels"] for r in s2["adapt"]] == [levels, 0, 0, 0]
                and all(r["nested_levels"] == 0 for r in alone["adapt"]),
                "%s: step 0 by nested iteration over %d levels, with -nested 0 from u_D (%s, %s)" % (tag, levels, [r["nested_levels"] for r in s["adapt"]], [r["nested_levels"] for r in alone["adapt"]]))
        for other, what in [(alone, "-nested 0"), (s2, "2 ranks")]:
            same = adapted_meshes(s) == adapted_meshes(other)
            deta = max(abs(a["eta"] - b["eta"]) / a["eta"] for a, b in zip(s["adapt"], other["adapt"]))
            c.check(same and deta <= 1e-6 and abs(other["energy"] - s["energy"]) <= 1e-9 * abs(s["energy"]),
                    "%s: the same adapted meshes as %s, eta within %.1e (<= 1e-6), energy %.15e against %.15e" % (tag, what, deta, s["energy"], other["energy"]))

# A structured mesh under a periodic load packs thousands of indicators closer together than the solver's
# tolerance perturbs them between rank counts (mark.h): the same adapted meshes on 1 and 3 ranks (with the
# cut at the Doerfler threshold itself, step 3 marked 119 426 cells on 1 rank, 119 425 on 3).
args = scene("stiff-critical") + ["-box_faces", "64,64", "-space", "p1", "-adapt_steps", "4"]
_, _, _, s1 = run(args)
_, _, _, s3 = run(args, ranks=3)
meshes = [adapted_meshes(s) for s in (s1, s3)]
c.check(meshes[0] == meshes[1], "stiff-critical -box_faces 64,64 p1: the same adapted meshes on 1 and 3 ranks (marked %s, %s)" % (
    [m[2] for m in meshes[0]], [m[2] for m in meshes[1]]))

# Stiff rows (cells stretched 1000 : 1): the residual norm the solver tests is the stiff rows', and the solve
# ends only when the KKT checks hold too (kktstop.h), so each rank count reaches the same solution, estimate
# and meshes (with the residual test alone, 3 ranks refined step 2 to 7744 cells, 1 and 2 ranks to 5824, and
# the estimates differed by 4 %).
args = scene("stiff-stretched-2d") + ["-space", "cr", "-adapt_steps", "4"]
runs = [run(args, ranks=n)[3] for n in (1, 2, 3)]
for n, s in zip((2, 3), runs[1:]):
    deta = max(abs(a["eta"] - b["eta"]) / b["eta"] for a, b in zip(s["adapt"], runs[0]["adapt"]))
    c.check(adapted_meshes(s) == adapted_meshes(runs[0]) and deta <= 1e-6,
            "stiff-stretched-2d cr: the same adapted meshes on %d ranks as on 1 (cells %s, %s), eta within %.1e (<= 1e-6)" % (
                n, [m[0] for m in adapted_meshes(s)], [m[0] for m in adapted_meshes(runs[0])], deta))
    kkt_ok("stiff-stretched-2d cr, %d ranks" % n, s)

# Scaling the load: the same adapted meshes, tests/test_stiff.py.

# The singular scene: u ~ r^(1/2) next to (1/2, 0).
for el in ["cr", "p1"]:
    _, _, _, s = run(scene("stiff-below-h2") + ["-mesh_file", os.path.join(ROOT, "petsc-options", "meshes", "split-bottom.msh"), "-space", el, "-adapt_steps", "10"])
    rows = s["adapt"][-5:]
    k = slope([r["dofs"] for r in rows], [r["eta"] for r in rows])
    c.check(k <= -0.45, "stiff-below-h2 %s: eta ~ DOFs^%.3f over the last 5 steps (<= -0.45)" % (el, k))

# -adapt_tol: stop at the first step with eta below it.
tol = math.sqrt(one["adapt"][2]["eta"] * one["adapt"][3]["eta"])
_, out, _, s = run(base + ["-adapt_tol", repr(tol)])
c.check(len(s["adapt"]) == 4 and s["cells"] == one["adapt"][3]["cells"], "-adapt_tol %.3g stops after step 3 (%d rows)" % (tol, len(s["adapt"])))
# An end before -adapt_steps is said (fewer steps than asked for do not pass unseen), and why; the summary
# names the reason in every adaptive run.
ended = [l for l in out.splitlines() if l.startswith("  adaptive refinement ended at step 3 of -adapt_steps")]
c.check(s["adapt_ended"] == "tol" and len(ended) == 1 and "is below -adapt_tol" in ended[0], "-adapt_tol: the end said: %s, %s" % (s["adapt_ended"], ended))
_, out, _, s = run(base + ["-adapt_max_dofs", str(one["adapt"][1]["dofs"])])
ended = [l for l in out.splitlines() if l.startswith("  adaptive refinement ended at step 1 of -adapt_steps")]
c.check(s["adapt_ended"] == "max_dofs" and len(s["adapt"]) == 2 and len(ended) == 1 and "-adapt_max_dofs" in ended[0], "-adapt_max_dofs: stops at step 1, said: %s, %s" % (s["adapt_ended"], ended))
c.check(one["adapt_ended"] == "steps", "all steps done: adapt_ended %s" % one["adapt_ended"])
_, out, _, s = run(scene("paper-5.1") + ["-box_faces", "8", "-adapt_steps", "2", "-f", "0", "-psi", "-1"])  # u = 0: eta 0
ended = [l for l in out.splitlines() if "adaptive refinement ended at step 0" in l]
c.check(s["adapt_ended"] == "zero_estimate" and len(s["adapt"]) == 1 and len(ended) == 1 and "nothing to refine" in ended[0], "a zero estimate: stops at step 0, said: %s, %s" % (s["adapt_ended"], ended))

# -output: the last mesh.
try:
    import h5py
except ImportError:
    h5py = None
c.check(h5py is not None, "h5py can be imported (run/setup installs python3-h5py)")
with tempfile.TemporaryDirectory() as tmp:
    out = os.path.join(tmp, "adapt.h5")
    _, _, _, s = run(base + ["-adapt_steps", "2", "-output", out], ranks=2)
    if h5py is not None and os.path.exists(out):
        with h5py.File(out, "r") as f:
            n = f["/viz/topology/cells"].shape[0]
        c.check(n == s["cells"], "-output writes the last mesh (%d cells, summary %d)" % (n, s["cells"]))
    else:
        c.check(False, "-output wrote %s" % out)

# Bad input.
for args, message in [(["-adapt_theta", "0"], "-adapt_theta"),
                      (["-study_levels", "2"], "options -adapt_steps and -study_levels"),
                      (["-estimate", "none"], "adaptive refinement marks cells by the error estimate"),
                      (["-adapt_reference_dofs", "8"], "-adapt_reference_dofs: ends the reference steps early; give -adapt_reference_steps"),
                      (["-adapt_reference_steps", "2", "-adapt_reference_dofs", "-1"], "-adapt_reference_dofs")]:
    rc, out, err, _ = run(base + args, check=False)
    lines = [l for l in (out + err).splitlines() if l.startswith("signorini: error:")]
    c.check(rc == 1 and len(lines) == 1 and message in lines[0], "%s: one error line (%s)" % (" ".join(args), lines[0] if lines else "none"))
# An option of the adaptive run without -adapt_steps is refused, not ignored.
rc, out, err, _ = run(scene("manufactured-2d") + ["-adapt_tol", "0.01"], check=False)
lines = [l for l in (out + err).splitlines() if l.startswith("signorini: error:")]
c.check(rc == 1 and len(lines) == 1 and "-adapt_tol" in lines[0] and "-adapt_steps" in lines[0] and "energy" not in out,
        "-adapt_tol without -adapt_steps: one error line before the solve (%s)" % (lines[0] if lines else "none"))
# A next mesh beyond the memory (-memory_limit in GB per node stands in for a small machine) ends the run at the
# step before it, with that step's result and a line that says why, instead of the out-of-memory killer in the
# next solve; -memory_check 0 goes on. Predicted from the growth of the steps so far; at step 0, which has
# none, the refined mesh itself is checked: one error line, on 1 and 2 ranks alike, and no summary.
mem = scene("manufactured-2d") + ["-box_faces", "4", "-space", "p1", "-adapt_steps", "30"]
rc, out, err, s = run(mem + ["-memory_limit", "0.06"], check=False)
_, _, _, free = run(mem + ["-memory_limit", "0.06", "-memory_check", "0", "-adapt_steps", "14"])
ended = [l for l in out.splitlines() if "adaptive refinement ended" in l]
c.check(rc == 0 and s is not None and s["adapt_ended"] == "memory" and len(ended) == 1 and "-memory_check 0" in ended[0] and "0.06 GB" in ended[0],
        "-memory_limit 0.06: the run ends for memory, with a line (%s)" % (ended[0] if ended else "none"))
if s is not None:
    k = len(s["adapt"]) - 1
    c.check(3 < k < 14 and len(free["adapt"]) > k + 1 and [r["dofs"] for r in free["adapt"][:k + 1]] == [r["dofs"] for r in s["adapt"]] and s["dofs"] == s["adapt"][-1]["dofs"],
            "-memory_limit 0.06: the result is step %d's, the steps before it as without the check, which goes on (%d steps)" % (k, len(free["adapt"])))
rc, out, err, s = run(mem + ["-memory_limit", "0.08", "-adapt_max_dofs", "2000", "-adapt_reference_steps", "6"], check=False)
ref = [r for r in (s or {}).get("adapt", []) if r["reference_step"]]
c.check(rc == 0 and s["adapt_ended"] == "max_dofs" and 0 < len(ref) < 6 and "reference steps ended at step" in out,
        "-memory_limit 0.08 -adapt_reference_steps 6: the reference ends early, after %d steps, and says so" % len(ref))
for ranks, limit in [(1, "0.06"), (2, "0.11")]:
    rc, out, err, s = run(scene("manufactured-2d") + ["-box_faces", "64", "-space", "p1", "-adapt_steps", "2", "-adapt_theta", "1", "-memory_limit", limit], ranks=ranks, check=False)
    lines = sorted(set(l for l in (out + err).splitlines() if l.startswith("signorini: error:")))
    c.check(rc != 0 and len(lines) == 1 and "adaptive step 1: the refined mesh has" in lines[0] and "-memory_check 0" in lines[0] and s is None,
            "%d rank(s), -adapt_theta 1 -memory_limit %s: step 1's mesh refused in one line, no summary (%s)" % (ranks, limit, lines[0] if lines else "none"))
# sbr refines triangles only: refused on a tetrahedral mesh before anything is solved (no summary line).
rc, out, err, _ = run(scene("manufactured-3d") + ["-adapt_steps", "1", "-adapt_refinement", "sbr"], check=False)
lines = [l for l in (out + err).splitlines() if l.startswith("signorini: error:")]
c.check(rc == 1 and len(lines) == 1 and "sbr refines triangles only" in lines[0] and "energy" not in out,
        "-adapt_refinement sbr in 3D: one error line before the solve (%s)" % (lines[0] if lines else "none"))
c.done()

"""Where the levels of the nested iteration stop (-solve_to).

Full multigrid (fmg, the default) stops the coarse levels early and the finest at the full test, so it gives
the same discrete solution as every level to the full test (-solve_to full): the same energy to 1e-9
relative and the same active set, for both elements, in 2D and 3D, on 1 and 2 ranks; the summary says which
test stopped each level, and the coarse levels need no more CG iterations than under `full`.

-solve_to discretization stops every level, the finest included, once the algebraic error is estimated below
-solve_to_fraction times the predicted discretization error. Checked against two independent measures on
the manufactured scenes (exact solution known): the algebraic error itself from the energies, since for an
admissible v, J(v) - J(u_h) >= |||v - u_h|||^2 / 2 (u_h the discrete solution of the full solve), so
sqrt(2 (J(v) - J(u_h))) bounds it and must lie below the level's target; and the true energy error against
the exact solution, within (1 + fraction) of the full solve's. The same for adaptive refinement, where every
step after the first stops so (error per cost in DOFs against the full solves' adaptive run)."""
import math

from harness import Checker, run, scene

c = Checker()

cases = [("paper-5.1", ["-box_faces", "4", "-refine", "3"]),
         ("manufactured-2d", ["-box_faces", "4", "-refine", "2"]),
         ("manufactured-3d", ["-box_faces", "2", "-refine", "2"])]
for name, mesh in cases:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            args = scene(name) + mesh + ["-space", space, "-estimate", "none"]
            _, _, _, full = run(args + ["-solve_to", "full"], ranks=ranks)
            _, _, _, fmg = run(args, ranks=ranks)
            tag = "%s %s %d rank(s)" % (name, space, ranks)
            c.kkt(tag + " fmg", fmg)
            e0, e1 = full["energy"], fmg["energy"]
            c.check(abs(e1 - e0) <= 1e-9 * abs(e0), "%s: energy fmg %.15e vs full %.15e" % (tag, e1, e0))
            c.check(fmg["kkt"]["active"] == full["kkt"]["active"], "%s: active set %d vs %d" % (tag, fmg["kkt"]["active"], full["kkt"]["active"]))
            lf, lg = full["solver"]["levels"], fmg["solver"]["levels"]
            c.check(full["solver"]["solve_to"] == "full" and fmg["solver"]["solve_to"] == "fmg" and all(l["stopped_by"] == "full" for l in lf)
                    and lg[-1]["stopped_by"] == "full" and all(l["stopped_by"] in ("start_error", "full") for l in lg[:-1]),
                    "%s: the summary names the stopping (fmg levels: %s)" % (tag, [l["stopped_by"] for l in lg]))
            kf, kg = sum(l["ksp"] for l in lf[:-1]), sum(l["ksp"] for l in lg[:-1])
            c.check(kg <= kf, "%s: CG iterations on the coarse levels, fmg %d <= full %d" % (tag, kg, kf))

# -solve_to discretization on scenes with an exact solution.
for name, mesh, ranks in [("manufactured-2d", ["-box_faces", "4", "-refine", "4"], 1),
                          ("manufactured-3d", ["-box_faces", "2", "-refine", "3"], 1),
                          ("manufactured-3d", ["-box_faces", "2", "-refine", "3"], 2)]:
    for space in ["p1", "cr"]:
        args = scene(name) + mesh + ["-space", space]
        _, _, _, full = run(args + ["-solve_to", "full"], ranks=ranks)
        _, _, _, disc = run(args + ["-solve_to", "discretization", "-solve_to_fraction", "0.1"], ranks=ranks)
        tag = "%s %s %s, %d rank(s)" % (name, space, " ".join(mesh), ranks)
        levels = disc["solver"]["levels"]
        target = levels[-1]["energy_error_target"]
        c.check(disc["solver"]["solve_to"] == "discretization" and levels[0]["stopped_by"] == "full" and target > 0
                and all(l["energy_error_target"] > 0 for l in levels[1:]),
                "%s: the coarsest level to the full test, the others to an energy error target (finest %.3e)" % (tag, target))
        # the finest target: fraction 0.1 of half the coarser level's estimate, so about 0.1 of this level's error
        c.check(0.02 * full["error"]["energy"] <= target <= 0.5 * full["error"]["energy"],
                "%s: target %.3e is a fraction of the discretization error %.3e" % (tag, target, full["error"]["energy"]))
        dj = disc["energy"] - full["energy"]
        c.check(dj >= -1e-12 * abs(full["energy"]), "%s: J(u) %.15e >= J(u_h) %.15e" % (tag, disc["energy"], full["energy"]))
        algebraic = math.sqrt(2 * max(dj, 0))
        c.check(algebraic <= target, "%s: algebraic error <= sqrt(2 (J(u) - J(u_h))) = %.3e <= target %.3e" % (tag, algebraic, target))
        ed, ef = disc["error"]["energy"], full["error"]["energy"]
        c.check(ed <= 1.1 * ef, "%s: energy error vs exact %.6e <= 1.1 x the full solve's %.6e" % (tag, ed, ef))
        c.check(disc["solver"]["ksp_iterations"] <= full["solver"]["ksp_iterations"],
                "%s: finest level CG iterations %d <= full %d" % (tag, disc["solver"]["ksp_iterations"], full["solver"]["ksp_iterations"]))

# Bad values: one error line naming the option, exit status 1.
# Adaptive refinement with -solve_to discretization: every step after the first stops at its share of the
# discretization error. Against the full solves of the same adaptive run: the meshes may differ a little (the
# estimate moves with the algebraic error), so the true energy error (exact solution) is compared at equal
# cost in DOFs, error x sqrt(DOFs) at the last step within (1 + fraction); each step after the first needs
# no more CG iterations than the full solve's fewest, and the estimate stays above the true error.
for space in ["p1", "cr"]:
    args = scene("manufactured-2d") + ["-space", space, "-adapt_steps", "6"]
    _, _, _, full = run(args + ["-solve_to", "full"])
    _, _, _, disc = run(args + ["-solve_to", "discretization"])
    rf, rd = full["adapt"], disc["adapt"]
    tag = "adaptive manufactured-2d %s" % space
    c.check(len(rf) == len(rd) == 7, "%s: %d and %d steps" % (tag, len(rf), len(rd)))
    cost = lambda r: r["error"] * math.sqrt(r["dofs"])
    c.check(cost(rd[-1]) <= 1.1 * cost(rf[-1]), "%s: error x sqrt(DOFs) %.4g vs full %.4g" % (tag, cost(rd[-1]), cost(rf[-1])))
    c.check(all(r["ksp"] <= min(q["ksp"] for q in rf[1:]) for r in rd[1:]), "%s: CG per step %s vs full %s" % (tag, [r["ksp"] for r in rd], [r["ksp"] for r in rf]))
    c.check(all(r["eta"] >= r["error"] for r in rd), "%s: eta >= error at every step" % tag)

for opt, value, text in [("-solve_to", "sometimes", "-solve_to"), ("-solve_to_fraction", "1.5", "-solve_to_fraction"), ("-solve_to_rtol", "0", "-solve_to_rtol")]:
    rc, _, err, _ = run(scene("paper-5.1") + ["-box_faces", "4", "-refine", "1", opt, value], check=False)
    lines = err.strip().splitlines()
    c.check(rc == 1 and len(lines) == 1 and lines[0].startswith("signorini: error:") and text in lines[0],
            "%s %s: exit %d, %r" % (opt, value, rc, err.strip()))
c.done()

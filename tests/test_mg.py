"""The geometric multigrid over the refinement hierarchy (-vi_pc_type mg, the default) as the preconditioner
of the reduced-space Newton systems gives the same discrete solution as BoomerAMG (-vi_pc_type hypre): the same
energy to 1e-9 relative, the same active set, the discrete KKT conditions to solver tolerance, for both
elements, in 2D and 3D, on 1 and 2 ranks. Its CG iterations per Newton step stay bounded as the mesh is
refined: over the last three levels of a nested iteration they stay below a fixed bound and grow by at
most a few iterations from the coarsest of them to the finest (the invariant of a multigrid method, which
a preconditioner without the hierarchy, e.g. Jacobi, would break by doubling per level)."""
from harness import Checker, run, scene

c = Checker()


# The same discrete solution as with BoomerAMG.
for name, mesh in [("paper-5.1", ["-box_faces", "4", "-refine", "2"]), ("paper-5.1-3d", ["-box_faces", "2", "-refine", "2"])]:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            args = scene(name) + mesh + ["-space", space]
            _, _, _, ref = run(args + ["-vi_pc_type", "hypre"], ranks=ranks)
            _, _, _, mg = run(args + ["-vi_pc_type", "mg"], ranks=ranks)
            tag = "%s %s %d rank(s)" % (name, space, ranks)
            c.kkt(tag + " mg", mg)
            e0, e1 = ref["energy"], mg["energy"]
            c.check(abs(e1 - e0) <= 1e-9 * abs(e0), "%s: energy with mg %.15e vs hypre %.15e" % (tag, e1, e0))
            c.check(mg["kkt"]["active"] == ref["kkt"]["active"] and mg["kkt"]["active"] > 0, "%s: active set %d vs %d" % (tag, mg["kkt"]["active"], ref["kkt"]["active"]))
            c.check(len(mg["solver"]["levels"]) == 3, "%s: nested iteration over 3 levels" % tag)

# CG iterations per Newton step over the last three levels (the multigrid has 3 to 5 levels there), each
# level solved to the full test (-solve_to full: full multigrid stops the coarse levels early).
for name, mesh, bound in [("paper-5.1", ["-box_faces", "8", "-refine", "4"], 8), ("paper-5.1-3d", ["-box_faces", "3", "-refine", "3"], 11)]:
    for space in ["p1", "cr"]:
        _, _, _, s = run(scene(name) + mesh + ["-space", space, "-vi_pc_type", "mg", "-solve_to", "full"])
        per = [l["ksp"] / l["newton"] for l in s["solver"]["levels"][-3:]]
        tag = "%s %s %s" % (name, space, " ".join(mesh))
        c.check(max(per) <= bound, "%s: CG iterations per Newton step on the last 3 levels %s <= %d" % (tag, ["%.1f" % p for p in per], bound))
        c.check(per[-1] <= per[0] + 3, "%s: from the third-finest to the finest level they grow by at most 3 (%.1f -> %.1f)" % (tag, per[0], per[-1]))

c.done()

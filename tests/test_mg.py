"""The geometric multigrid over the refinement hierarchy (-vi_pc_type mg, the default) as the preconditioner
of the reduced-space Newton systems gives the same discrete solution as BoomerAMG (-vi_pc_type hypre): the same
energy to 1e-9 relative, the same active set, the discrete KKT conditions to solver tolerance, for both
elements, in 2D and 3D, on 1 and 2 ranks. Its CG iterations per Newton step stay bounded as the mesh is
refined: over the last three levels of a nested iteration they stay below a fixed bound and grow by at
most a few iterations from the coarsest of them to the finest (the invariant of a multigrid method, which
a preconditioner without the hierarchy, e.g. Jacobi, would break by doubling per level).

The same over the levels of adaptive refinement (-adapt_steps): the same adapted meshes and discrete
solution as with BoomerAMG (energy to 1e-9, the same active set), 2D and 3D, both elements, on 1 and 2 ranks
(there with every new mesh redistributed, -adapt_imbalance 1.01, so the transfers cross the migration), and
CG iterations per Newton step bounded over the last steps of a longer run."""
import os

from harness import ROOT, Checker, run, scene

c = Checker()


def same_solution(tag, args, ranks):
    """Solves with -vi_pc_type hypre and mg; checks the KKT conditions of the mg run, the same energy to 1e-9
    and the same (nonempty) active set. Returns both summaries."""
    _, _, _, ref = run(args + ["-vi_pc_type", "hypre"], ranks=ranks)
    _, _, _, mg = run(args + ["-vi_pc_type", "mg"], ranks=ranks)
    c.kkt(tag + " mg", mg)
    e0, e1 = ref["energy"], mg["energy"]
    c.check(abs(e1 - e0) <= 1e-9 * abs(e0), "%s: energy with mg %.15e vs hypre %.15e" % (tag, e1, e0))
    c.check(mg["kkt"]["active"] == ref["kkt"]["active"] and mg["kkt"]["active"] > 0, "%s: active set %d vs %d" % (tag, mg["kkt"]["active"], ref["kkt"]["active"]))
    return ref, mg


# The same discrete solution as with BoomerAMG.
for name, mesh in [("paper-5.1", ["-box_faces", "4", "-refine", "2"]), ("paper-5.1-3d", ["-box_faces", "2", "-refine", "2"])]:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            tag = "%s %s %d rank(s)" % (name, space, ranks)
            ref, mg = same_solution(tag, scene(name) + mesh + ["-space", space], ranks)
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

# Adaptive refinement: the multigrid over the adapted meshes against BoomerAMG on each.
BELOW_H2 = scene("stiff-below-h2") + ["-mesh_file", os.path.join(ROOT, "petsc-options", "meshes", "split-bottom.msh")]
for name, mesh, steps in [("stiff-below-h2", [], 5), ("paper-5.1-3d", ["-box_faces", "2"], 3)]:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            tag = "adaptive %s %s %d rank(s)" % (name, space, ranks)
            args = (BELOW_H2 if name == "stiff-below-h2" else scene(name)) + mesh + ["-space", space, "-adapt_steps", str(steps), "-adapt_imbalance", "1.01"]
            ref, mg = same_solution(tag, args, ranks)
            d0, d1 = [x["dofs"] for x in ref["adapt"]], [x["dofs"] for x in mg["adapt"]]
            c.check(d0 == d1 and len(d1) == steps + 1, "%s: the same adapted meshes (DOFs %s vs %s)" % (tag, d1, d0))
            if ranks == 2:
                c.check(any(x["redistributed"] for x in mg["adapt"]), "%s: some mesh was redistributed" % tag)

# CG iterations per Newton step over the last 4 of 12 adaptive steps (the multigrid has 5 to 7 levels there).
for space in ["p1", "cr"]:
    _, _, _, s = run(BELOW_H2 + ["-space", space, "-adapt_steps", "12", "-vi_pc_type", "mg"])
    per = [x["ksp"] / x["newton"] for x in s["adapt"][-4:]]
    tag = "adaptive stiff-below-h2 %s, 12 steps" % space
    c.check(len(s["adapt"]) == 13 and max(per) <= 8, "%s: CG iterations per Newton step on the last 4 steps %s <= 8" % (tag, ["%.1f" % p for p in per]))
    c.check(per[-1] <= per[0] + 2, "%s: from the fourth-last to the last step they grow by at most 2 (%.1f -> %.1f)" % (tag, per[0], per[-1]))

c.done()

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
CG iterations per Newton step bounded over the last steps of a longer run.

On meshes of stretched cells the default is BoomerAMG alone (the run says so); -vi_pc_type mg still gets the
multigrid, with the same discrete solution and more CG iterations."""
import os

from harness import OPTIONS, ROOT, Checker, run, scene

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

# Stretched cells (aspect ratio 10 and more): the multigrid's pointwise smoother does not smooth across
# them, so without -vi_pc_type the run takes BoomerAMG alone and says so; -vi_pc_type mg still gets the
# multigrid. Both solve the same discrete problem; BoomerAMG in far fewer CG iterations (stiff-stretched-2d
# CR at this size: 3 against several hundred). A box of shape-regular cells keeps the multigrid.
# Solved to round-off (30 full Newton steps, CG to 1e-14): with the default stopping test the stiff rows
# stop either solve where the soft rows' residual still moves the energy in the 8th digit. The round-off
# floor of these rows (eps times the coupling contrast, about 1e6 here) still leaves 2e-9 relative between
# the two preconditioners' solutions in 2D, so the energies are compared to 1e-8, and the active sets exactly.
exact = ["-options_file", os.path.join(OPTIONS, "solvers", "high-contrast"), "-ksp_rtol", "1e-14"]
for name, space in [("stiff-stretched-2d", "cr"), ("stiff-stretched-3d", "p1")]:
    tag = "%s %s" % (name, space)
    _, out, _, auto = run(scene(name) + ["-space", space, "-refine", "1"] + exact)
    _, _, _, mg = run(scene(name) + ["-space", space, "-refine", "1", "-vi_pc_type", "mg"] + exact)
    c.check(auto["solver"]["preconditioner"] == "hypre" and auto["solver"]["max_aspect_ratio"] >= 10 and "BoomerAMG alone, for cells stretched" in out,
            "%s: the default is BoomerAMG alone, and the run says why (aspect ratio %.3g, %s)" % (tag, auto["solver"]["max_aspect_ratio"], auto["solver"]["preconditioner"]))
    c.check(mg["solver"]["preconditioner"] == "mg", "%s: -vi_pc_type mg keeps the multigrid" % tag)
    c.check(abs(auto["energy"] - mg["energy"]) <= 1e-8 * abs(mg["energy"]) and auto["kkt"]["active"] == mg["kkt"]["active"],
            "%s: the same energy (%.15e, mg %.15e) and active set (%d, %d)" % (tag, auto["energy"], mg["energy"], auto["kkt"]["active"], mg["kkt"]["active"]))
    c.check(auto["solver"]["ksp_iterations"] < mg["solver"]["ksp_iterations"],
            "%s: fewer CG iterations with BoomerAMG (%d) than with the multigrid (%d)" % (tag, auto["solver"]["ksp_iterations"], mg["solver"]["ksp_iterations"]))
_, _, _, box = run(scene("paper-5.1") + ["-box_faces", "16"])
c.check(box["solver"]["preconditioner"] == "mg" and box["solver"]["max_aspect_ratio"] < 10, "paper-5.1: shape-regular cells (aspect ratio %.3g) keep the multigrid" % box["solver"]["max_aspect_ratio"])
c.done()

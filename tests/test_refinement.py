"""The direct refinement (-mesh_refinement direct, the default) and PETSc's
DMPlexTransform (-mesh_refinement transform) give the same discrete solution: the same DOFs, Dirichlet and
contact DOFs, active set, and energy and errors to 1e-10 relative, for P1 and CR on 1 and 2 ranks
in 2D and 3D (independent computation: PETSc's refinement shares no code with ours; unit_refine compares
the meshes themselves). Gmsh meshes with "Cell Sets" check that the refined labels carry kappa's cell sets."""
import os

from harness import ROOT, Checker, rel, run, scene

c = Checker()
# Solver tolerances tight enough that the two solutions differ by less than 1e-10 of what is compared; the
# errors of manufactured-2d (1e-4 of u) need the solve to 1e-14.
tight = ["-ksp_rtol", "1e-12"]
tighter = ["-ksp_rtol", "1e-14", "-snes_rtol", "1e-14"]
# The two meshes list the vertices of a child tetrahedron in other orders; the error integrals then agree
# only with a rule that treats all vertices alike (the symmetric rules go up to degree 5).
symmetric = ["-error_quadrature_degree", "5"]
square = os.path.join(ROOT, "tests", "data", "square.msh")
cube = os.path.join(ROOT, "tests", "data", "cube.msh")
cases = [
    ("paper-5.1", scene("paper-5.1") + ["-box_faces", "8", "-refine", "3"] + tight),
    ("manufactured-2d", scene("manufactured-2d") + ["-box_faces", "4", "-refine", "3"] + tighter),
    ("gmsh square, kappa by cell set", scene("paper-5.1") + ["-mesh_file", square, "-refine", "2", "-kappa", "cell_set == 1 ? 1 : 100"] + tight),
    ("paper-5.1-3d", scene("paper-5.1-3d") + ["-box_faces", "3", "-refine", "2"] + tight),
    ("manufactured-3d", scene("manufactured-3d") + ["-box_faces", "2", "-refine", "2"] + tighter + symmetric),
    ("gmsh cube, kappa by cell set", scene("manufactured-3d") + ["-mesh_file", cube, "-refine", "1", "-kappa", "cell_set == 1 ? 1 : 10"] + tighter + symmetric),
]


for name, args in cases:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            tag = "%s %s %d rank(s)" % (name, space, ranks)
            _, _, _, t = run(args + ["-space", space, "-mesh_refinement", "transform"], ranks=ranks)
            _, _, _, d = run(args + ["-space", space, "-mesh_refinement", "direct"], ranks=ranks)
            same = all(t[k] == d[k] for k in ["cells", "dofs", "dirichlet_dofs", "contact_dofs"]) and t["kkt"]["active"] == d["kkt"]["active"]
            c.check(same, "%s: same cells (%d), DOFs (%d), Dirichlet (%d), contact (%d) and active (%d) DOFs" % (tag, d["cells"], d["dofs"], d["dirichlet_dofs"], d["contact_dofs"], d["kkt"]["active"]))
            c.check(rel(t["energy"], d["energy"]) <= 1e-10, "%s: energy %.15e (transform) vs %.15e (direct)" % (tag, t["energy"], d["energy"]))
            if "error" in t:
                for key in ["l2", "h1_semi"]:
                    c.check(rel(t["error"][key], d["error"][key]) <= 1e-10, "%s: %s error %.15e vs %.15e" % (tag, key, t["error"][key], d["error"][key]))
c.done()

"""A mistyped option never passes unseen. An unknown application option is an error before the run (see
test_input_numbers); an option of a PETSc family that nothing read (-snes_monitr, or -snes_rtol in a scene
without contact, where no SNES is created) is listed at the end of the run, and so is an option of this
program that the run has no use for (solver options without a contact part, nested-iteration options
without levels, the degree of the centroid rule, non-zero data of a boundary part the scene does not have, the
box's options with a mesh file);
a run with only valid options lists none."""
import os

from harness import ROOT, Checker, run, scene

c = Checker()
base = scene("paper-5.1") + ["-box_faces", "8"]
for ranks in [1, 2]:
    _, out, _, _ = run(base + ["-snes_monitr", "-ksp_monitr", "2"], ranks=ranks)
    warned = [l for l in out.splitlines() if l.startswith("signorini: warning: option")]
    c.check(len(warned) == 2 and "-snes_monitr" in warned[0] + warned[1] and "-ksp_monitr 2" in warned[0] + warned[1],
            "%d rank(s): mistyped PETSc options listed once each: %s" % (ranks, warned))
_, out, _, _ = run(base + ["-snes_monitor", "-ksp_converged_reason"])
c.check("warning" not in out, "valid options: no warning")
_, out, _, _ = run(base + ["-bc_contact", "", "-snes_rtol", "1e-9"])
c.check("option -snes_rtol 1e-9 was not used" in out, "no contact part: the SNES option is reported unused")

# So are this program's own options where the run has no use for them (read up front, PETSc cannot tell),
# each once with the reason; where they apply, nothing is said.
def warnings(args, ranks=1):
    out = run(base + args, ranks=ranks)[1]
    return [l for l in out.splitlines() if l.startswith("signorini: warning: option")]


for ranks in [1, 2]:
    w = warnings(["-bc_contact", "", "-bc_neumann", "1,2,4", "-vi_pc_type", "hypre", "-amg_reuse", "0", "-solve_to", "full"], ranks)
    c.check(len(w) == 3 and all("no contact part" in l for l in w) and "-vi_pc_type hypre" in w[0] + w[1] + w[2],
            "%d rank(s): contact solver options without a contact part, reported: %s" % (ranks, w))
w = warnings(["-box_coarsen", "0", "-solve_to", "discretization", "-nested_levels", "2"])
c.check(len(w) == 2 and all("no coarser refinement levels" in l for l in w), "no refinement levels: the nested options reported: %s" % w)
w = warnings(["-nested", "0", "-solve_to_rtol", "0.5"])
c.check(len(w) == 1 and "-nested 0" in w[0], "-nested 0: -solve_to_rtol reported: %s" % w)
w = warnings(["-load_quadrature", "centroid", "-load_quadrature_degree", "6"])
c.check(len(w) == 1 and "one-point rule" in w[0], "centroid rule: -load_quadrature_degree reported: %s" % w)
# Data of a boundary part the scene does not have (the scene files' 0 for every part is no data).
for args, option in [(["-bc_neumann", "", "-bc_dirichlet", "2,3,4", "-g", "1"], "-g 1"), (["-bc_contact", "", "-bc_neumann", "1,2,4", "-psi", "0.1*x"], "-psi 0.1*x"),
                     (["-bc_dirichlet", "", "-bc_neumann", "2,3,4", "-f", "-1", "-u_D", "1"], "-u_D 1")]:
    w = warnings(args)
    c.check(len(w) == 1 and ("option %s was not used" % option) in w[0] and "the scene has no" in w[0], "%s without its part: reported: %s" % (option, w))
# The box's options with a mesh file (a scene file's box, given another mesh): each reported, with its value.
square = ["-mesh_file", os.path.join(ROOT, "tests", "data", "square.msh"), "-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4"]
w = warnings(square + ["-box_upper", "2"])
c.check(len(w) == 3 and all("the mesh is read from -mesh_file" in l for l in w) and all(("option %s" % o) in "".join(w) for o in ["-box_faces 8", "-box_diagonal backslash", "-box_upper 2"]),
        "box options with -mesh_file: reported: %s" % w)
w = warnings(["-study_levels", "2", "-reference_space", "p1"])
c.check(len(w) == 1 and "option -reference_space p1 was not used (the study has no reference: -reference_refine 0)" in w[0], "-reference_space without a reference: reported: %s" % w)
w = [l for l in run(scene("stiff-below-h2") + ["-mesh_file", os.path.join(ROOT, "petsc-options", "meshes", "split-bottom.msh"), "-refine", "1"])[1].splitlines() if l.startswith("signorini: warning: option")]
c.check(not w, "stiff-below-h2 (mesh file, -dim 2 of its mesh): nothing reported: %s" % w)
for args in [["-bc_contact", "", "-bc_neumann", "1,2,4"], ["-bc_neumann", "", "-bc_dirichlet", "2,3,4"]]:
    w = warnings(args)
    c.check(not w, "%s: the scene file's zero data, nothing reported: %s" % (" ".join(args), w))
for args in [["-box_faces", "16", "-solve_to", "full", "-nested_levels", "2", "-vi_pc_type", "hypre"], ["-adapt_steps", "1", "-solve_to", "discretization"],
             ["-box_coarsen", "0", "-study_levels", "2", "-solve_to", "full"], ["-load_quadrature_degree", "6"]]:
    w = warnings(args)
    c.check(not w, "%s: applied, nothing reported: %s" % (" ".join(args), w))
c.done()

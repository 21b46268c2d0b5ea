"""The same scene on 1 and on 2 MPI ranks (METIS partition) gives the same energy and errors to 1e-10
relative (independent computation: the two runs share nothing but the input)."""
from harness import Checker, rel, run, scene

c = Checker()
tight = ["-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
cases = [
    ("paper-5.1", ["-box_faces", "8", "-refine", "2"]),
    ("manufactured-2d", ["-box_faces", "4", "-refine", "2"]),
    ("manufactured-3d", ["-box_faces", "2", "-refine", "2"]),
]


for name, extra in cases:
    for space in ["p1", "cr"]:
        args = scene(name) + ["-space", space] + extra + tight
        _, _, _, s1 = run(args, ranks=1)
        _, _, _, s2 = run(args, ranks=2)
        tag = "%s %s" % (name, space)
        c.check(s2["ranks"] == 2 and min(s2["cells_per_rank"]) > 0, "%s: 2 ranks hold %s cells" % (tag, s2["cells_per_rank"]))
        c.check(s1["dofs"] == s2["dofs"] and s1["kkt"]["active"] == s2["kkt"]["active"], "%s: same DOFs (%d) and active set (%d)" % (tag, s1["dofs"], s1["kkt"]["active"]))
        c.check(rel(s1["energy"], s2["energy"]) <= 1e-10, "%s: energy %.15e vs %.15e" % (tag, s1["energy"], s2["energy"]))
        if "error" in s1:
            for key in ["l2", "h1_semi"]:
                c.check(rel(s1["error"][key], s2["error"][key]) <= 1e-10, "%s: %s error %.15e vs %.15e" % (tag, key, s1["error"][key], s2["error"][key]))
c.done()

"""The variable cell_set ("Cell Sets" value of the cell) is defined wherever an expression is evaluated in a
cell, and refused where it is not.

tests/data/square.msh has two cell sets: 1 (x < 0.5) and 2 (x > 0.5), whose interface x = 0.5 lies on cell
faces. So in -f (cell integrals), -g (the one cell of a Neumann face) and -exact_u/-exact_grad (error
integrals), an expression of cell_set must give what the same function written in x gives: the same energy
to 1e-12 in an independent run. Before, cell_set was -1 outside -kappa, and -f "cell_set==1?1:0" gave u = 0.
-u_D and -psi are values at boundary points, which may touch cells of both sets: cell_set there is an input
error, and so is cell_set where a cell has no "Cell Sets" value (it would read -1). An expression of any length is read whole: "0+0+...+1" (> 4096 characters) gives what "1" gives."""
import os
import tempfile

from harness import ROOT, Checker, run

c = Checker()
square = ["-mesh_file", os.path.join(ROOT, "tests", "data", "square.msh"), "-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4"]


def energy(extra, ranks=1):
    return run(square + extra, ranks=ranks)[3]["energy"]


def same(a, b):
    return abs(a - b) <= 1e-12 * max(abs(a), abs(b))


# (what, options with cell_set, the same data written without it)
pairs = [
    ("-f on both sets", ["-f", "cell_set == 1 || cell_set == 2 ? 1 : 0"], ["-f", "1"]),
    ("-f on set 1 only", ["-f", "cell_set == 1 ? 1 : 0"], ["-f", "x < 0.5 ? 1 : 0"]),
    ("-g on both sets", ["-g", "cell_set == 1 || cell_set == 2 ? 1 : 0"], ["-g", "1"]),
    ("-g on set 2 only (the right side)", ["-g", "cell_set == 2 ? 1 : 0"], ["-g", "x > 0.5 ? 1 : 0"]),
]
for what, with_set, without in pairs:
    for ranks in [1, 2]:
        a, b = energy(with_set, ranks), energy(without, ranks)
        c.check(same(a, b) and a != 0, "%s, %d rank(s): energy %.15g with cell_set, %.15g without" % (what, ranks, a, b))

# Error integrals: the exact solution u = 1 + 2x of test_gmsh's inactive case, written with cell_set.
linear = ["-f", "0", "-g", "x < 0.5 ? -2 : 2", "-psi", "2*x", "-u_D", "1 + 2*x", "-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
plain = run(square + linear + ["-exact_u", "1 + 2*x", "-exact_grad", "2, 0"])[3]["error"]
by_set = run(square + linear + ["-exact_u", "cell_set == 1 || cell_set == 2 ? 1 + 2*x : 100", "-exact_grad", "cell_set >= 1 ? 2 : 100, 0"])[3]["error"]
c.check(plain["l2"] < 1e-10 and by_set["l2"] < 1e-10 and by_set["h1_semi"] < 1e-9,
        "-exact_u/-exact_grad with cell_set: the linear solution to round-off (L2 %.2e, H1 semi %.2e)" % (by_set["l2"], by_set["h1_semi"]))

# Boundary point values: cell_set is refused in one line, and nothing is written.
for option in ["-psi", "-u_D"]:
    with tempfile.TemporaryDirectory() as out:
        rc, _, err, _ = run(square + [option, "cell_set", "-summary", os.path.join(out, "s.json")], check=False)
        left = os.listdir(out)
    lines = [l for l in err.splitlines() if l.strip()]
    c.check(rc == 1 and len(lines) == 1 and lines[0].startswith("signorini: error: option %s: cell_set is not defined here" % option),
            "%s cell_set: one error line (exit %d): %s" % (option, rc, lines))
    c.check(not left, "%s cell_set: nothing written" % option)

# Where a cell has no "Cell Sets" value, cell_set would read -1 there: refused in one line, on 1 and 2 ranks,
# naming the option, for a mesh without the label (the built-in box: kappa "cell_set == 1 ? 1 : 100" was 100
# everywhere) and for a Gmsh file with one triangle left out of the physical surfaces.
with tempfile.TemporaryDirectory() as tmp:
    partial = os.path.join(tmp, "partial.msh")
    lines = open(os.path.join(ROOT, "tests", "data", "square.msh")).read().split("\n")
    start = lines.index("$Elements")
    for i in range(start + 2, start + 2 + int(lines[start + 1])):
        p = lines[i].split()
        if p[1] == "2":  # the first triangle, now without tags (in no physical surface)
            lines[i] = " ".join(p[:2] + ["0"] + p[3 + int(p[2]):])
            break
    open(partial, "w").write("\n".join(lines))
    box = ["-dim", "2", "-box_faces", "4", "-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4"]
    for what, args, says in [("box, -kappa", box + ["-kappa", "cell_set == 1 ? 1 : 100"], "option -kappa: 'cell_set == 1 ? 1 : 100' uses cell_set, but no cell of the mesh is in a \"Cell Sets\""),
                             ("box, -exact_grad", box + ["-exact_u", "x", "-exact_grad", "cell_set, 0"], "option -exact_grad: 'cell_set, 0' uses cell_set, but no cell"),
                             ("one triangle in no set, -f", square[:2] + ["-mesh_file", partial] + square[2:] + ["-f", "cell_set == 1 ? 1 : 0"],
                              "option -f: 'cell_set == 1 ? 1 : 0' uses cell_set, but 1 of the ")]:
        for ranks in [1, 2]:
            rc, _, err, summary = run(args, ranks=ranks, check=False)
            ours = [l for l in err.splitlines() if l.startswith("signorini: error:")]
            c.check(rc == 1 and len(ours) == 1 and says in ours[0] and summary is None, "%s with cell_set, %d rank(s): exit %d, %s" % (what, ranks, rc, ours))
    rc, _, _, _ = run(square[:2] + ["-mesh_file", partial] + square[2:] + ["-f", "x"], check=False)
    c.check(rc == 0, "the same file without cell_set in any expression: runs (exit %d)" % rc)

# No length limit cuts an expression: 3000 terms (6001 characters), on the command line and in an options file.
long_f = "0+" * 3000 + "1"
reference = energy(["-f", "1"])
c.check(same(energy(["-f", long_f]), reference), "-f of %d characters on the command line gives the energy of -f 1" % len(long_f))
with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "long")
    with open(path, "w") as f:
        f.write("-f %s\n" % long_f)
    c.check(same(energy(["-options_file", path]), reference), "-f of %d characters in an options file gives the energy of -f 1" % len(long_f))
c.done()

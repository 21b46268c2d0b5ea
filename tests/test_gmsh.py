"""Gmsh meshes (tests/data/square.msh, tests/data/cube.msh): the physical groups become the boundary parts
and the "Cell Sets" used by kappa. A linear exact solution is reproduced to round-off on both meshes with
both elements, on 1 and 2 ranks; and a kappa that jumps between the two cell sets of the square gives the
piecewise linear exact solution with continuous flux, again to round-off. A boundary part left out of the
options gets kappa du/dn = 0 and a note with the number of its faces, counted independently from the file. The
parts may be named: by a file's physical names, or the box's sides, the same run as by their numbers."""
import os
import tempfile

from harness import ROOT, Checker, rel, run

c = Checker()
DATA = os.path.join(ROOT, "tests", "data")
SQUARE = os.path.join(DATA, "square.msh")
CUBE = os.path.join(DATA, "cube.msh")
tight = ["-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]


def round_off(s):
    e = s["error"]
    return e["l2"] < 1e-10 and e["h1_semi"] < 1e-9


# A linear u solves the Signorini problem exactly only if, on Gamma_C, either du/dn = 0 (contact inactive:
# psi below u) or u = psi with pressure du/dn > 0 (contact active everywhere); both are checked.
# Square: bottom 1 (contact, n = -y), right 2, top 3 (Dirichlet), left 4 (Neumann on 2 and 4).
g2 = "x < 0.5 ? -2 : 2"
cases2d = {
    # u = 1 + 2x: du/dn = 0 on the bottom, psi = u - 1.
    "inactive": dict(u="1 + 2*x", grad="2, 0", psi="2*x"),
    # u = 1 + 2x - 3y, psi = u on the bottom: active everywhere with pressure du/dn = -du/dy = 3.
    "active": dict(u="1 + 2*x - 3*y", grad="2, -3", psi="1 + 2*x"),
}
# Cube: bottom z=0 1 (contact, n = -z), top 2 (Dirichlet), front y=0 3, back y=1 4, right x=1 5, left x=0 6.
g3 = "x < 1e-6 ? -2 : (x > 1 - 1e-6 ? 2 : (y < 1e-6 ? 3 : -3))"
cases3d = {
    # u = 1 + 2x - 3y: du/dn = 0 on the bottom, psi = u - 1.
    "inactive": dict(u="1 + 2*x - 3*y", grad="2, -3, 0", psi="2*x - 3*y"),
    # u = 1 + 2x - 3y - 0.5z, psi = u on the bottom: active everywhere with pressure -du/dz = 0.5.
    "active": dict(u="1 + 2*x - 3*y - 0.5*z", grad="2, -3, -0.5", psi="1 + 2*x - 3*y"),
}
meshes = [("square", SQUARE, 2, "3", "2,4", g2, cases2d), ("cube", CUBE, 3, "2", "3,4,5,6", g3, cases3d)]
for mesh, path, dim, dirichlet, neumann, g, cases in meshes:
    for name, d in cases.items():
        for space in ["p1", "cr"]:
            for ranks in [1, 2]:
                args = ["-mesh_file", path, "-space", space, "-bc_dirichlet", dirichlet, "-u_D", d["u"],
                        "-bc_neumann", neumann, "-g", g, "-bc_contact", "1", "-psi", d["psi"], "-f", "0",
                        "-exact_u", d["u"], "-exact_grad", d["grad"]] + tight
                _, _, _, s = run(args, ranks=ranks)
                e = s["error"]
                what = "%s %s %s %d rank(s)" % (mesh, name, space, ranks)
                c.check(s["dim"] == dim and s["ranks"] == ranks and s["solver"]["type"] == "snesvi",
                        "%s: dim %d, %d rank(s), solver %s" % (what, s["dim"], s["ranks"], s["solver"]["type"]))
                k = s["kkt"]
                if name == "inactive":  # gap u - psi = 1 everywhere
                    ok = k["active"] == 0 and abs(k["min_gap"] - 1) < 1e-9
                else:  # u = psi up to the linear solver's tolerance, pressure > 0 (SNESVI may leave a DOF it
                    # counts as active a few 1e-12 above psi, so the gap is checked instead of the active count)
                    ok = k["max_gap"] < 1e-10 and k["min_pressure"] > 0.1
                c.check(s["contact_dofs"] > 0 and ok, "%s: %d of %d contact DOFs active, gap in [%.2e, %.2e], pressure >= %.3g"
                        % (what, k["active"], s["contact_dofs"], k["min_gap"], k["max_gap"], k["min_pressure"]))
                c.check(round_off(s), "%s: linear u reproduced, L2 %.2e H1 %.2e" % (what, e["l2"], e["h1_semi"]))

# kappa jumps between the cell sets of the square (1: x < 0.5, 2: x > 0.5). With u = x on the left and
# u = 0.5 + (x - 0.5)/100 on the right the flux kappa du/dx = 1 is continuous, so u solves the problem
# with Dirichlet data on the left and right (4, 2), g = 0 on the top and bottom (3, 1), f = 0, no contact.
uj = "x < 0.5 ? x : 0.5 + (x - 0.5)/100"
argsj = ["-mesh_file", SQUARE, "-kappa", "cell_set == 1 ? 1 : 100", "-bc_dirichlet", "4,2", "-u_D", uj,
         "-bc_neumann", "3,1", "-g", "0", "-f", "0", "-exact_u", uj, "-exact_grad", "x < 0.5 ? 1 : 0.01, 0"] + tight
for space in ["p1", "cr"]:
    for ranks in [1, 2]:
        _, _, _, s = run(argsj + ["-space", space], ranks=ranks)
        e = s["error"]
        what = "square kappa jump %s %d rank(s)" % (space, ranks)
        c.check(s["solver"]["type"] == "ksp", "%s: no contact part, plain KSP solve (%s)" % (what, s["solver"]["type"]))
        c.check(round_off(s), "%s: piecewise linear u reproduced, L2 %.2e H1 %.2e" % (what, e["l2"], e["h1_semi"]))

# The same problem with kappa = 1 everywhere is not solved by that u: the cell sets really are used.
_, _, _, s = run([a if a != "cell_set == 1 ? 1 : 100" else "1" for a in argsj] + ["-space", "cr"])
c.check(s["error"]["l2"] > 1e-3, "square kappa = 1 (no jump): error %.2e is not round-off" % s["error"]["l2"])


def file_boundary(path, named):
    """From the file itself (an independent count): the boundary faces (faces of one cell) of the mesh, and
    those not listed as a lower-dimensional element with a physical tag in `named`."""
    lines = open(path).read().split("\n")
    start = lines.index("$Elements")
    elements = [[int(v) for v in line.split()] for line in lines[start + 2:start + 2 + int(lines[start + 1])]]
    cell = 4 if any(p[1] == 4 for p in elements) else 2  # Gmsh types: 4 tetrahedron, 2 triangle
    count, tagged = {}, {}
    for p in elements:
        kind, ntags, nodes = p[1], p[2], p[3 + p[2]:]
        if kind == cell:
            for skip in range(len(nodes)):
                face = tuple(sorted(nodes[:skip] + nodes[skip + 1:]))
                count[face] = count.get(face, 0) + 1
        elif ntags > 0:
            tagged.setdefault(tuple(sorted(nodes)), set()).add(p[3])
    boundary = [f for f, k in count.items() if k == 1]
    return len(boundary), sum(1 for f in boundary if not tagged.get(f, set()) & named)


# A boundary part left out of the options: kappa du/dn = 0 holds on its faces (the natural condition), and the
# run says how many faces that is. The counts against the file's own (independent), on 1 and 2 ranks (a face
# between two ranks' cells is not boundary); the solution against the same scene with that part named as
# Neumann with g = 0 (the same discrete problem); no note where every boundary face is in a part.
for mesh, path, dirichlet, neumann, left_out in [("square", SQUARE, "3", "2", "4"), ("cube", CUBE, "2", "3,5,6", "4")]:
    faces, unnamed = file_boundary(path, {int(v) for v in (dirichlet + "," + neumann + ",1").split(",")})
    base = ["-mesh_file", path, "-bc_dirichlet", dirichlet, "-bc_contact", "1", "-g", "0", "-f", "1 + x", "-u_D", "0", "-psi", "-0.01"]
    for space in ["p1", "cr"]:
        _, _, _, named = run(base + ["-space", space, "-bc_neumann", neumann + "," + left_out] + tight)
        for ranks in [1, 2]:
            _, out, _, s = run(base + ["-space", space, "-bc_neumann", neumann] + tight, ranks=ranks)
            what = "%s, part %s left out, %s, %d rank(s)" % (mesh, left_out, space, ranks)
            c.check(unnamed > 0 and (s["boundary_faces_coarse"], s["unnamed_boundary_faces_coarse"]) == (faces, unnamed),
                    "%s: %d boundary faces, %d in no part (the file: %d, %d)" % (what, s["boundary_faces_coarse"], s["unnamed_boundary_faces_coarse"], faces, unnamed))
            note = [line for line in out.splitlines() if line.startswith("note: %d of the %d boundary faces" % (unnamed, faces))]
            c.check(len(note) == 1 and "kappa du/dn = 0" in note[0], "%s: one note says so: %s" % (what, note))
            c.check(rel(s["energy"], named["energy"]) < 1e-12 and s["dofs"] == named["dofs"],
                    "%s: energy %.15g, with the part named Neumann g = 0: %.15g" % (what, s["energy"], named["energy"]))
        c.check(named["unnamed_boundary_faces_coarse"] == 0 and named["boundary_faces_coarse"] == faces,
                "%s, every part named, %s: %d of %d boundary faces in no part" % (mesh, space, named["unnamed_boundary_faces_coarse"], named["boundary_faces_coarse"]))
# Boundary parts by name: the physical names of the file (one name given to two groups names both) and the
# box's sides give the same run as their numbers (DOFs and energy to the last digit), on 1 and 2 ranks.
with tempfile.TemporaryDirectory() as tmp:
    named_square = os.path.join(tmp, "named.msh")
    text = open(SQUARE).read()
    names = '$PhysicalNames\n6\n1 1 "floor"\n1 2 "wall"\n1 3 "lid"\n1 4 "wall"\n2 1 "left half"\n2 2 "right half"\n$EndPhysicalNames\n'
    open(named_square, "w").write(text.replace("$EndMeshFormat\n", "$EndMeshFormat\n" + names))
    data = ["-f", "1 + x", "-u_D", "0", "-psi", "-0.01", "-g", "0.5"]
    pairs = [("square by physical names", ["-mesh_file", named_square] + data, ["-bc_dirichlet", "lid", "-bc_neumann", "wall", "-bc_contact", "floor"],
              ["-bc_dirichlet", "3", "-bc_neumann", "2,4", "-bc_contact", "1"]),
             ("2D box by its sides' names", ["-box_faces", "8"] + data, ["-bc_dirichlet", "top", "-bc_neumann", "left, right", "-bc_contact", "bottom"],
              ["-bc_dirichlet", "3", "-bc_neumann", "4,2", "-bc_contact", "1"]),
             ("3D box by its sides' names", ["-dim", "3", "-box_faces", "4"] + data, ["-bc_dirichlet", "top", "-bc_neumann", "front,back,right,left", "-bc_contact", "bottom"],
              ["-bc_dirichlet", "2", "-bc_neumann", "3,4,5,6", "-bc_contact", "1"])]
    for what, base, by_name, by_number in pairs:
        for ranks in [1, 2]:
            _, _, _, a = run(base + by_name, ranks=ranks)
            _, _, _, b = run(base + by_number, ranks=ranks)
            c.check(a["dofs"] == b["dofs"] and a["energy"] == b["energy"] and a["unnamed_boundary_faces_coarse"] == 0,
                    "%s, %d rank(s): %d DOFs, energy %.15g; by numbers %d, %.15g" % (what, ranks, a["dofs"], a["energy"], b["dofs"], b["energy"]))
c.done()

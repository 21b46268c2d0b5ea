"""A solution that lies in the discrete space is reproduced to round-off (comparison with an exact
solution): linear u, both elements, 2D (all three diagonal patterns) and 3D, with the contact part either
inactive everywhere (u > psi, du/dn = 0 on Gamma_C) or active everywhere (u = psi with pressure 3 > 0)."""
from harness import Checker, run

c = Checker()
tight = ["-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]

# 2D unit square: bottom 1 (contact), right 2, top 3 (Dirichlet), left 4 (Neumann on 2 and 4).
cases2d = {
    # u = 1 + 2x: du/dn = 0 on the bottom and psi = u - 1 lies below u, so no contact is active.
    "inactive": dict(u="1 + 2*x", grad="2, 0", g="x < 0.5 ? -2 : 2", psi="2*x"),
    # u = 1 + 2x - 3y, psi = u on the bottom: contact everywhere with pressure -du/dy = 3 > 0.
    "active": dict(u="1 + 2*x - 3*y", grad="2, -3", g="x < 0.5 ? -2 : 2", psi="1 + 2*x"),
}
for name, d in cases2d.items():
    for diag in ["slash", "backslash", "crossed"]:
        for space in ["p1", "cr"]:
            args = ["-dim", "2", "-box_faces", "5,3", "-box_diagonal", diag, "-space", space,
                    "-bc_dirichlet", "3", "-bc_neumann", "2,4", "-bc_contact", "1", "-f", "0",
                    "-u_D", d["u"], "-g", d["g"], "-psi", d["psi"], "-exact_u", d["u"], "-exact_grad", d["grad"]] + tight
            _, _, _, s = run(args)
            e = s["error"]
            c.check(e["l2"] < 1e-10 and e["h1_semi"] < 1e-9, "2D %s %s %s: L2 %.2e H1 %.2e" % (name, diag, space, e["l2"], e["h1_semi"]))
            expect_active = s["contact_dofs"] if name == "active" else 0
            c.check(s["kkt"]["active"] == expect_active, "2D %s %s %s: %d of %d contact DOFs active" % (name, diag, space, s["kkt"]["active"], s["contact_dofs"]))

# 3D unit cube: bottom z=0 1 (contact), top 2 (Dirichlet), sides 3 (y=0), 4 (y=1), 5 (x=1), 6 (x=0).
g3 = "x < 1e-9 ? -2 : (x > 1 - 1e-9 ? 2 : (y < 1e-9 ? 3 : -3))"
cases3d = {
    "inactive": dict(u="1 + 2*x - 3*y", grad="2, -3, 0", psi="2*x - 3*y - 1"),
    "active": dict(u="1 + 2*x - 3*y - 0.5*z", grad="2, -3, -0.5", psi="1 + 2*x - 3*y"),
}
for name, d in cases3d.items():
    for space in ["p1", "cr"]:
        args = ["-dim", "3", "-box_faces", "2,3,2", "-space", space, "-bc_dirichlet", "2", "-bc_neumann", "3,4,5,6",
                "-bc_contact", "1", "-f", "0", "-u_D", d["u"], "-g", g3, "-psi", d["psi"],
                "-exact_u", d["u"], "-exact_grad", d["grad"]] + tight
        _, _, _, s = run(args)
        e = s["error"]
        c.check(e["l2"] < 1e-10 and e["h1_semi"] < 1e-9, "3D %s %s: L2 %.2e H1 %.2e" % (name, space, e["l2"], e["h1_semi"]))
        expect_active = s["contact_dofs"] if name == "active" else 0
        c.check(s["kkt"]["active"] == expect_active, "3D %s %s: %d of %d contact DOFs active" % (name, space, s["kkt"]["active"], s["contact_dofs"]))

# Without a contact part the VI machinery is not used: one KSP solve.
_, _, _, s = run(["-dim", "2", "-box_faces", "4", "-space", "cr", "-bc_dirichlet", "1,2,3,4", "-u_D", "1 + 2*x - 3*y",
                  "-exact_u", "1 + 2*x - 3*y", "-exact_grad", "2, -3"] + tight)
c.check(s["solver"]["type"] == "ksp" and s["error"]["l2"] < 1e-10, "no contact part: plain KSP solve, L2 %.2e" % s["error"]["l2"])
c.done()

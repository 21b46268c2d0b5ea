"""Both elements satisfy the discrete KKT conditions of the Signorini problem to solver tolerance on the
paper's scene (invariants): u >= psi on Gamma_C, contact pressure >= 0, complementarity, and the equation
on all DOFs off Gamma_C and Gamma_D; the contact set is a proper, non-empty part of Gamma_C; so too without a
Dirichlet part, where the load pushes u towards the obstacle, from an obstacle below the start and on a mesh in
two pieces, one of them held by contact alone.
The solve ends when these checks pass, not only its residual test: on a kappa jump of 1e6, where the stiff rows
dominate the residual norm SNESVI tests, the default solver goes on beyond that test until the KKT conditions and
the stationarity hold to -kkt_tolerance, and its u equals the high-contrast preset's (an independent run of 30
Newton steps without any test), on 1 and 2 ranks; its extra Newton steps are reported. A stopping test loosened
by the user (-snes_rtol, -snes_atol, -snes_vi_zero_tolerance) is not overridden: a warning names that option. A
KKT residual that the default stopping test permits (it grows like h^(1-d) under refinement: the pressure
divides the reaction by a boundary measure) is no warning: the shipped scenes on fine meshes show none. Where the
conditions on Gamma_C hold and the stationarity off it ends above the tolerance at the residual's round-off floor
(an obstacle 1e10 times what the load adds to u), one warning says so; the same for the linear solve without a
contact part, whose restarts end at that floor."""
import os

from harness import OPTIONS, ROOT, Checker, run, scene

c = Checker()
for n in [16, 64]:
    for space in ["p1", "cr"]:
        _, _, _, s = run(scene("paper-5.1") + ["-space", space, "-box_faces", str(n)])
        k = s["kkt"]
        tag = "paper-5.1 %s N=%d" % (space, n)
        c.check(s["solver"]["converged_reason"].startswith("CONVERGED"), "%s: SNESVI %s" % (tag, s["solver"]["converged_reason"]))
        c.check(k["min_gap"] >= -1e-12, "%s: primal feasibility min(u - psi) = %.2e" % (tag, k["min_gap"]))
        c.check(k["min_pressure"] >= -1e-8 * k["max_pressure"], "%s: dual feasibility min pressure = %.2e (max %.2e)" % (tag, k["min_pressure"], k["max_pressure"]))
        c.check(k["max_complementarity"] <= 1e-8 * k["max_pressure"] * k["max_gap"], "%s: complementarity %.2e" % (tag, k["max_complementarity"]))
        c.check(s["stationarity"] <= 1e-8, "%s: equation residual off Gamma_C %.2e" % (tag, s["stationarity"]))
        c.check(0 < k["active"] < s["contact_dofs"], "%s: %d of %d contact DOFs active" % (tag, k["active"], s["contact_dofs"]))
        c.check(k["relative"] <= 1e-8, "%s: worst relative KKT residual %.1e" % (tag, k["relative"]))

# Without a Dirichlet part only the contact holds u, and a load pushing it towards the obstacle (a negative
# total) has one solution: the KKT conditions hold, contact is active somewhere (the pressure balances the
# load), and 1 and 2 ranks give the same energy. (Other totals are refused: test_bad_input.)
for space in ["p1", "cr"]:
    energies = []
    for ranks in [1, 2]:
        rc, _, _, s = run(scene("paper-5.1") + ["-space", space, "-box_faces", "32", "-bc_dirichlet", "", "-bc_neumann", "2,3,4",
                                               "-f", "2*pi*sin(2*pi*x) - 1"], ranks=ranks)
        k = s["kkt"]
        tag = "paper-5.1 without Dirichlet part, total load -1, %s %d rank(s)" % (space, ranks)
        c.check(s["dirichlet_dofs"] == 0 and 0 < k["active"] and k["relative"] <= 1e-8 and s["stationarity"] <= 1e-8,
                "%s: %d of %d contact DOFs active, worst relative KKT residual %.1e, stationarity %.1e" % (tag, k["active"], s["contact_dofs"], k["relative"], s["stationarity"]))
        energies.append(s["energy"])
    c.check(abs(energies[0] - energies[1]) <= 1e-10 * abs(energies[0]), "paper-5.1 without Dirichlet part %s: energy %.12g on 1 rank, %.12g on 2" % (space, energies[0], energies[1]))

# The same with the obstacle below the start (u_D = 0) and a load that lifts the contact side (f = 1 there,
# -3 above y = 1/2: total -1): from u_D no contact DOF starts active, and the first Newton step met the
# singular block of the floating body (DIVERGED_LINEAR_SOLVE); the start in full contact keeps one active.
# Piece by piece too: tests/data/two-squares.msh is [0,1]^2 (bottom 1, sides 2, top 3) and [2,3] x [0,1]
# (bottom 4, sides and top 5), the second held by contact alone. Invariants: KKT, the same energy on 1 and 2
# ranks, and the floating body resting on its obstacle (contact active).
lift = ["-f", "y < 0.5 ? 1 : -3", "-psi", "-1 + 0.2 * sin(3 * x)"]
two = ["-mesh_file", os.path.join(ROOT, "tests", "data", "two-squares.msh"), "-dim", "2", "-refine", "4", "-bc_dirichlet", "3", "-bc_contact", "1,4", "-bc_neumann", "2,5"]
for name, args in [("paper-5.1 without Dirichlet part", scene("paper-5.1") + ["-box_faces", "32", "-bc_dirichlet", "", "-bc_neumann", "2,3,4"] + lift),
                   ("two squares, one held by contact alone", scene("paper-5.1") + two + lift),
                   # kappa 1e6 or 1e-6 on half the floating square: from the start carried by nested iteration
                   # no contact DOF of it was active (DIVERGED_LINEAR_SOLVE), so every level starts in full contact
                   ("two squares, kappa 1e6 on half the floating one", scene("paper-5.1") + two + lift + ["-kappa", "x > 2.5 ? 1e6 : 1"]),
                   ("two squares, kappa 1e-6 on half the floating one", scene("paper-5.1") + two + lift + ["-kappa", "x > 2.5 ? 1e-6 : 1"])]:
    for space in ["p1", "cr"]:
        energies = []
        for ranks in [1, 2]:
            rc, out, err, s = run(args + ["-space", space], ranks=ranks, check=False)
            tag = "%s, obstacle below u_D, %s %d rank(s)" % (name, space, ranks)
            c.check(rc == 0 and s is not None, "%s: ran (%s)" % (tag, "exit 0" if rc == 0 else (err + out).strip().splitlines()[0]))
            if rc != 0 or s is None:
                continue
            k = s["kkt"]
            # (across a jump of 1e6 the stationarity's round-off floor is near 1e-7: the solve's own -kkt_tolerance, 1e-6)
            station = 1e-6 if "kappa" in name else 1e-8
            c.check(0 < k["active"] and k["relative"] <= 1e-8 and s["stationarity"] <= station,
                    "%s: %d of %d contact DOFs active, worst relative KKT residual %.1e, stationarity %.1e" % (tag, k["active"], s["contact_dofs"], k["relative"], s["stationarity"]))
            c.check(s["pieces_coarse"] == (2 if "two" in name else 1), "%s: the mesh in %d piece(s)" % (tag, s["pieces_coarse"]))
            energies.append(s["energy"])
        if len(energies) == 2:
            c.check(abs(energies[0] - energies[1]) <= 1e-10 * abs(energies[0]), "%s %s: energy %.12g on 1 rank, %.12g on 2" % (name, space, energies[0], energies[1]))

# A contact part whose DOFs all lie on Gamma_D (P1 on one square: the bottom's two vertices are also on the
# Dirichlet sides) leaves nothing to check: the line says so, and the summary's minima and maxima are null,
# not the +-DBL_MAX of an empty set.
rc, out, _, s = run(scene("paper-5.1") + ["-box_faces", "1", "-box_coarsen", "0", "-space", "p1", "-bc_dirichlet", "2,4", "-bc_neumann", "3", "-u_D", "1"])
k = s["kkt"]
c.check(s["contact_dofs"] == 0 and "KKT on Gamma_C: nothing to check" in out and all(k[n] is None for n in ["min_gap", "min_pressure", "max_gap", "relative"]),
        "no contact DOFs: %d contact DOFs, KKT %s" % (s["contact_dofs"], k))

WARNING = "signorini: warning: the discrete KKT conditions"
_, out, _, s = run(scene("paper-5.1") + ["-box_faces", "16"])
c.check(WARNING not in out, "paper-5.1: no KKT warning after a converged solve")
for ranks in [1, 2]:
    for space in ["p1", "cr"]:
        args = scene("stiff-layers") + ["-space", space, "-box_coarsen", "0"]  # the one-level solve (nested iteration settles it)
        rc, out, _, s = run(args, ranks=ranks)
        tag = "stiff-layers K=1e6 %s %d rank(s)" % (space, ranks)
        c.check(rc == 0 and s["kkt"]["relative"] <= 1e-6 and s["stationarity"] <= 1e-6 and WARNING not in out,
                "%s, default solver: relative KKT residual %.1e, stationarity %.1e, no warning" % (tag, s["kkt"]["relative"], s["stationarity"]))
        # the residual test alone stops with a KKT residual of 1e-2 to 1e-1 here: the checks took more steps
        c.check(s["solver"]["kkt_steps"] >= 1 and "after the residual test passed, for the KKT checks" in out,
                "%s, default solver: %d Newton steps after the residual test, reported" % (tag, s["solver"]["kkt_steps"]))
        rc2, out2, _, p = run(args + ["-options_file", os.path.join(OPTIONS, "solvers", "high-contrast")], ranks=ranks)
        c.check(rc2 == 0 and p["kkt"]["relative"] <= 1e-6 and WARNING not in out2,
                "%s, high-contrast preset: relative KKT residual %.1e, no warning" % (tag, p["kkt"]["relative"]))
        c.check(abs(s["energy"] - p["energy"]) <= 1e-12 * abs(p["energy"]) and s["kkt"]["active"] == p["kkt"]["active"],
                "%s: energy %.15e and %d active DOFs, the preset's %.15e and %d" % (tag, s["energy"], s["kkt"]["active"], p["energy"], p["kkt"]["active"]))
# Without a contact part the linear solve meets the same stiff rows (cells stretched 1000 : 1): its relative
# test passes with a stationarity of 1e-3, and it goes on from where it stopped until the check holds. Its u
# has the energy of the direct solve (MUMPS LU).
args = scene("stiff-stretched-2d") + ["-space", "cr", "-bc_contact", "", "-bc_neumann", "1,2,4", "-g", "0"]
_, _, _, d = run(args + ["-options_file", os.path.join(OPTIONS, "solvers", "mumps")])
for ranks in [1, 2]:
    rc, out, _, s = run(args, ranks=ranks)
    tag = "stiff-stretched-2d cr, no contact part, %d rank(s)" % ranks
    c.check(rc == 0 and s["stationarity"] <= 1e-6 and s["solver"]["kkt_steps"] >= 1 and "for the stationarity check" in out,
            "%s: stationarity %.1e after %d more solves, reported" % (tag, s["stationarity"], s["solver"]["kkt_steps"]))
    c.check(abs(s["energy"] - d["energy"]) <= 1e-8 * abs(d["energy"]), "%s: energy %.15e, the direct solve's %.15e" % (tag, s["energy"], d["energy"]))

# A tolerance below what double precision gives: the added steps end at the residual's round-off floor
# (stall.h), within their limit of 10, and the warning says so.
for space in ["p1", "cr"]:
    rc, out, _, s = run(scene("stiff-layers") + ["-space", space, "-box_coarsen", "0", "-kkt_tolerance", "1e-15"])
    line = [l for l in out.splitlines() if l.startswith(WARNING)]
    tag = "stiff-layers K=1e6 %s -kkt_tolerance 1e-15" % space
    c.check(rc == 0 and s["solver"]["converged_reason"] == "CONVERGED_ROUNDOFF_FLOOR" and 1 <= s["solver"]["kkt_steps"] <= 10,
            "%s: ends at the round-off floor (%s) after %d added steps" % (tag, s["solver"]["converged_reason"], s["solver"]["kkt_steps"]))
    c.check(len(line) == 1 and "round-off floor" in line[0] and "what double precision gives here" in line[0] and "high-contrast" not in line[0],
            "%s: one warning naming the floor: %s" % (tag, line))
# The stationarity off Gamma_C at the round-off floor: psi = 1e9 over paper-5.1 (u_D = 0), whose load moves u
# by 0.1 against the 1e9 the data make; A u sums terms of 1e9, and its round-off leaves 1e-3 of the load. The
# conditions on Gamma_C hold; one warning names the floor and that double precision gives no more.
for space in ["p1", "cr"]:
    rc, out, _, s = run(scene("paper-5.1") + ["-space", space, "-box_faces", "64", "-psi", "1e9"])
    line = [l for l in out.splitlines() if l.startswith("signorini: warning:")]
    tag = "paper-5.1 %s N = 64, psi = 1e9" % space
    c.check(rc == 0 and s["solver"]["converged_reason"] == "CONVERGED_ROUNDOFF_FLOOR" and s["kkt"]["relative"] <= 1e-6 and s["stationarity"] > 1e-6,
            "%s: %s, KKT %.1e, stationarity %.1e" % (tag, s["solver"]["converged_reason"], s["kkt"]["relative"], s["stationarity"]))
    c.check(len(line) == 1 and line[0].startswith("signorini: warning: the stationarity on the free DOFs holds only to") and "round-off floor" in line[0]
            and "that is what it gives here" in line[0], "%s: one warning naming the floor: %s" % (tag, line))
# The same without a contact part (the linear solve's restarts, u_D = 1e9 y on the bottom and top): two
# restarts that do not halve the stationarity end them at the floor (before: all 10, and no word).
for space in ["p1", "cr"]:
    rc, out, _, s = run(scene("paper-5.1") + ["-space", space, "-box_faces", "64", "-bc_contact", "", "-bc_dirichlet", "1,3", "-u_D", "1e9*y"])
    line = [l for l in out.splitlines() if l.startswith("signorini: warning:")]
    tag = "paper-5.1 %s N = 64, no contact part, u_D = 1e9 y" % space
    c.check(rc == 0 and s["stationarity"] > 1e-6 and s["solver"]["kkt_steps"] <= 4, "%s: stationarity %.1e after %d more solves" % (tag, s["stationarity"], s["solver"]["kkt_steps"]))
    c.check(len(line) == 1 and line[0].startswith("signorini: warning: the stationarity on the free DOFs holds only to") and "round-off floor" in line[0],
            "%s: one warning naming the floor: %s" % (tag, line))
# A stopping test loosened by the user: the warning names the option, not the preset. Every nested level to
# the loosened test (-solve_to full): full multigrid's coarse levels leave the finest level an active set from
# which the loose bound tolerance happens to do no harm here.
for extra, option in [(["-snes_rtol", "1e-3"], "-snes_rtol 0.001"), (["-snes_atol", "1e-3"], "-snes_atol 0.001"),
                      (["-snes_vi_zero_tolerance", "1e-2"], "-snes_vi_zero_tolerance 0.01")]:
    for space in ["p1", "cr"]:
        rc, out, _, s = run(scene("manufactured-2d") + ["-space", space, "-refine", "3", "-solve_to", "full"] + extra)
        line = [l for l in out.splitlines() if l.startswith(WARNING)]
        tag = "manufactured-2d %s -refine 3 %s" % (space, " ".join(extra))
        c.check(rc == 0 and len(line) == 1 and "the solver options %s, looser than the defaults" % option in line[0] and "tighten them" in line[0] and "high-contrast" not in line[0],
                "%s: relative KKT residual %.1e, the warning names %s and not the preset: %s" % (tag, s["kkt"]["relative"], option, line))

# Shipped scenes on fine meshes end with their KKT checks passed: no warning.
for name, extra in [("manufactured-3d", ["-refine", "3"]), ("manufactured-2d", ["-refine", "4"]), ("paper-5.1", ["-box_faces", "8", "-refine", "4"])]:
    for space in ["p1", "cr"]:
        rc, out, _, s = run(scene(name) + ["-space", space] + extra)
        c.check(rc == 0 and WARNING not in out, "%s %s %s: converged (%s), no KKT warning (relative KKT residual %.1e)"
                % (name, space, " ".join(extra), s["solver"]["converged_reason"], s["kkt"]["relative"]))
c.done()

"""Both elements satisfy the discrete KKT conditions of the Signorini problem to solver tolerance on the
paper's scene (invariants): u >= psi on Gamma_C, contact pressure >= 0, complementarity, and the equation
on all DOFs off Gamma_C and Gamma_D; the contact set is a proper, non-empty part of Gamma_C."""
from harness import Checker, run, scene

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
c.done()

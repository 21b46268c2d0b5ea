"""Both elements satisfy the discrete KKT conditions of the Signorini problem to solver tolerance on the
paper's scene (invariants): u >= psi on Gamma_C, contact pressure >= 0, complementarity, and the equation
on all DOFs off Gamma_C and Gamma_D; the contact set is a proper, non-empty part of Gamma_C.
A solve that SNES calls converged but whose KKT residuals are not small (the default stopping test on a
kappa jump of 1e6, where the stiff rows dominate the residual norm) is reported by a warning; the
high-contrast preset removes it, and a converged solve shows none."""
import os

from harness import OPTIONS, Checker, run, scene

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

WARNING = "signorini: warning: the discrete KKT conditions"
_, out, _, s = run(scene("paper-5.1") + ["-box_faces", "16"])
c.check(WARNING not in out, "paper-5.1: no KKT warning after a converged solve")
for ranks in [1, 2]:
    for space in ["p1", "cr"]:
        args = scene("stiff-layers") + ["-space", space, "-box_coarsen", "0"]  # the one-level solve (nested iteration settles it)
        rc, out, _, s = run(args, ranks=ranks)
        tag = "stiff-layers K=1e6 %s %d rank(s)" % (space, ranks)
        c.check(rc == 0 and s["kkt"]["relative"] > 1e-3 and out.count(WARNING) == 1,
                "%s, default solver: relative KKT residual %.1e reported by one warning" % (tag, s["kkt"]["relative"]))
        rc, out, _, s = run(args + ["-options_file", os.path.join(OPTIONS, "solvers", "high-contrast")], ranks=ranks)
        c.check(rc == 0 and s["kkt"]["relative"] <= 1e-6 and WARNING not in out,
                "%s, high-contrast preset: relative KKT residual %.1e, no warning" % (tag, s["kkt"]["relative"]))
c.done()

"""A fine mesh without a hierarchy (issue 18, item 3): a Gmsh file read as it is, no -refine, so the contact
solve runs on one level from u_D, where the active set moves through many Newton steps. The file is the
paper-5.1 mesh written by run/gmsh_box.py. The default solver (inexact steps while the active set moves,
BoomerAMG set-ups re-used while few DOFs change, active DOFs with small reactions freed early, release.h)
against three independent computations of the same discrete problem: the plain reduced-space rule with
every Newton step to full tolerance and a new set-up each (-vi_release_theta 0 -vi_inexact_rtol 0
-amg_reuse 0), the plain rule with the other defaults (-vi_release_theta 0), and the built-in box of the
same mesh solved with nested iteration over its refinement hierarchy. Each must give the same energy to
1e-9 (relative) and the same active set on Gamma_C; P1 and CR, 1 and 2 ranks. Also: the file gives the same
DOFs as the box, the run is on one level (no nested iteration), the default solve sets BoomerAMG up at most
once per Newton step, freeing early takes no more Newton steps than the plain rule (on 1 rank fewer),
and the KKT conditions hold to 1e-6."""
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker, run, scene

c = Checker()
N = 96


def energy_close(a, b):
    return abs(a - b) <= 1e-9 * abs(b)


with tempfile.TemporaryDirectory() as tmp:
    msh = os.path.join(tmp, "paper-5.1-N%d.msh" % N)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "run", "gmsh_box.py"), str(N), msh], capture_output=True, text=True, env=ENV)
    c.check(r.returncode == 0 and os.path.isfile(msh) and not os.path.exists(msh + ".tmp"), "run/gmsh_box.py wrote %s (%s)" % (os.path.basename(msh), r.stderr.strip() or "ok"))
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            tag = "paper-5.1 %s Gmsh N=%d, %d rank(s)" % (space, N, ranks)
            base = scene("paper-5.1") + ["-space", space]
            _, _, _, default = run(base + ["-mesh_file", msh], ranks=ranks)
            _, _, _, full = run(base + ["-mesh_file", msh, "-vi_release_theta", "0", "-vi_inexact_rtol", "0", "-amg_reuse", "0"], ranks=ranks)
            _, _, _, plain = run(base + ["-mesh_file", msh, "-vi_release_theta", "0"], ranks=ranks)
            _, _, _, box = run(base + ["-box_faces", str(N)], ranks=ranks)
            sd = default["solver"]
            c.check(not sd["nested"] and default["refine"] == 0 and default["dofs"] == box["dofs"],
                    "%s: one level (nested %s, refine %d), %d DOFs as the box's %d" % (tag, sd["nested"], default["refine"], default["dofs"], box["dofs"]))
            c.check(sd["newton_iterations"] >= 3 and 1 <= sd["amg_setups"] <= sd["newton_iterations"],
                    "%s: the active set moves (%d Newton steps), %d BoomerAMG set-ups, %d re-uses" % (tag, sd["newton_iterations"], sd["amg_setups"], sd["amg_reuses"]))
            fewer = sd["newton_iterations"] < plain["solver"]["newton_iterations"] if ranks == 1 else sd["newton_iterations"] <= plain["solver"]["newton_iterations"]
            c.check(fewer,
                    "%s: %d Newton steps, the plain rule %d" % (tag, sd["newton_iterations"], plain["solver"]["newton_iterations"]))
            for other, what in [(full, "every step to full tolerance"), (plain, "-vi_release_theta 0"), (box, "box with nested iteration")]:
                c.check(energy_close(default["energy"], other["energy"]) and default["kkt"]["active"] == other["kkt"]["active"],
                        "%s: energy %.13e vs %.13e (%s), active %d vs %d" % (tag, default["energy"], other["energy"], what, default["kkt"]["active"], other["kkt"]["active"]))
            k = default["kkt"]  # the KKT residuals as the summary measures them, against -kkt_tolerance's default
            c.check(sd["converged_reason"].startswith("CONVERGED") and k["min_gap"] >= 0 and k["relative"] <= 1e-6,
                    "%s: %s, min gap %.2e, relative KKT residual %.2e" % (tag, sd["converged_reason"], k["min_gap"], k["relative"]))
c.done()

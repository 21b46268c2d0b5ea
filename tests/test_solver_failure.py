"""A run whose SNES or KSP does not converge says so on one line and exits non-zero, writing no summary. A
tolerance below the residual's round-off floor is named as such within a few Newton steps, and the
tolerance the message advises converges (checked by running it)."""
import os
import re

from harness import OPTIONS, Checker, run, scene

c = Checker()
cases = [
    ("SNESVI stopped after one Newton step", scene("paper-5.1") + ["-box_faces", "16", "-snes_max_it", "1"], "DIVERGED_MAX_IT"),
    ("KSP stopped after one iteration (no contact part)", scene("paper-5.1") + ["-box_faces", "16", "-bc_contact", "", "-ksp_max_it", "1"], "DIVERGED_ITS"),
    ("KSP inside SNESVI stopped after one iteration", scene("paper-5.1") + ["-box_faces", "16", "-ksp_max_it", "1"], "DIVERGED"),
]
# A KSP type that cannot report the unpreconditioned residual the solves stop on: an input error naming it.
kinds = [("contact", []), ("linear, no contact part", ["-bc_contact", ""])]
for (kind, extra), (option, words) in [(k, o) for k in kinds for o in [(["-ksp_type", "minres"], "-ksp_type minres"),
                                                                      (["-ksp_type", "gmres", "-ksp_pc_side", "left"], "-ksp_pc_side LEFT")]]:
    for ranks in [1, 2]:
        rc, out, err, summary = run(scene("paper-5.1") + ["-box_faces", "8"] + extra + option, ranks=ranks, check=False)
        lines = [l for l in err.splitlines() if l.strip() and (ranks == 1 or l.startswith("signorini"))]
        c.check(rc == 1 and summary is None and len(lines) == 1 and lines[0].startswith("signorini: error: option -ksp_type") and words in lines[0],
                "%s solve, %s, %d rank(s): exit %d, one line naming the option %r" % (kind, " ".join(option), ranks, rc, lines))
for what, args, reason in cases:
    for ranks in [1, 2]:
        rc, out, err, summary = run(args, ranks=ranks, check=False)
        # On several ranks mpirun adds its own banner about the non-zero exit; only our lines are counted.
        lines = [l for l in err.splitlines() if l.strip() and (ranks == 1 or l.startswith("signorini"))]
        c.check(rc == 1, "%s, %d rank(s): exit status %d" % (what, ranks, rc))
        c.check(len(lines) == 1 and lines[0].startswith("signorini: error: solver:") and reason in lines[0],
                "%s, %d rank(s): one-line message %r" % (what, ranks, lines))
        c.check(summary is None, "%s, %d rank(s): no summary written" % (what, ranks))

# A KSP type the reduced-space contact solve cannot use (bicg applies the transpose of the inactive-set
# preconditioner, which has none; lgmres keeps vectors of a former block size; pipefcg crashed): an input
# error that lists the types it can use, before any solve. Each listed type solves the paper's scene.
usable = None
for ksp in ["bicg", "lgmres", "pipefcg"]:
    for ranks in [1, 2]:
        rc, out, err, summary = run(scene("paper-5.1") + ["-box_faces", "8", "-ksp_type", ksp], ranks=ranks, check=False)
        lines = [l for l in err.splitlines() if l.strip() and (ranks == 1 or l.startswith("signorini"))]
        m = re.search(r"use cg \(the default\) or one of (.*)$", lines[0]) if len(lines) == 1 else None
        c.check(rc == 1 and summary is None and m and lines[0].startswith("signorini: error: option -ksp_type %s: the contact solve cannot use it" % ksp),
                "-ksp_type %s, %d rank(s): exit %d, one line naming the option and the usable types %r" % (ksp, ranks, rc, lines))
        usable = m.group(1).split(", ") if m else usable
c.check(usable is not None and "cg" in usable and "gmres" in usable, "the usable types are listed: %s" % usable)
for ksp in usable or []:
    rc, out, err, s = run(scene("paper-5.1") + ["-box_faces", "8", "-ksp_type", ksp], check=False)
    c.check(rc == 0 and s["solver"]["converged_reason"].startswith("CONVERGED") and s["kkt"]["relative"] <= 1e-6 and s["stationarity"] <= 1e-6,
            "-ksp_type %s (listed as usable): exit %d, %s, KKT %.1e, stationarity %.1e" % (
                ksp, rc, s and s["solver"]["converged_reason"], s["kkt"]["relative"] if s else -1, s["stationarity"] if s else -1))

# A PETSc error inside the solve (the semismooth solver with a KSP type that needs a MATIS operator):
# exit status 2 with one line per rank. One rank finalizes without Open MPI's abort banner; several
# abort, since the others may wait in a collective call.
for ranks in [1, 2]:
    rc, out, err, summary = run(scene("paper-5.1") + ["-box_faces", "8", "-snes_type", "vinewtonssls", "-ksp_type", "fetidp"], ranks=ranks, check=False)
    ours = [l for l in err.splitlines() if l.startswith("signorini: error on rank")]
    c.check(rc == 2 and summary is None and len(ours) == ranks and all("MATIS" in l for l in ours),
            "PETSc error, %d rank(s): exit status %d, one line per rank naming the cause %r" % (ranks, rc, ours))
    if ranks == 1:
        c.check(not [l for l in err.splitlines() if l.strip() and l not in ours], "PETSc error, 1 rank: nothing else on stderr %r" % err[-300:])

# Tolerances no double-precision solve reaches: the default path (nested iteration, multigrid) and a
# single mesh (BoomerAMG), each element. Before the floor test these ran 200 Newton steps and ended with
# DIVERGED_MAX_IT and a hint about kappa jumps.
floor_cases = [
    ("-snes_rtol 1e-16, paper-5.1 nested", scene("paper-5.1") + ["-box_faces", "64", "-snes_rtol", "1e-16", "-snes_converged_reason"]),
    ("-snes_atol 1e-20 -snes_rtol 0, stiff-critical one mesh", scene("stiff-critical") + ["-box_faces", "32,32", "-nested", "0", "-snes_atol", "1e-20", "-snes_rtol", "0", "-snes_converged_reason"]),
    # preonly reports no residual of its own: the floor test measures the direct solve's
    ("-snes_rtol 1e-16, mumps preset", scene("paper-5.1") + ["-box_faces", "16", "-options_file", os.path.join(OPTIONS, "solvers", "mumps"), "-snes_rtol", "1e-16", "-snes_converged_reason"]),
]
for what, args in floor_cases:
    for element in ["p1", "cr"]:
        for ranks in [1, 2]:
            tag = "%s, %s, %d rank(s)" % (what, element, ranks)
            rc, out, err, summary = run(args + ["-space", element], ranks=ranks, check=False)
            lines = [l for l in err.splitlines() if l.strip() and (ranks == 1 or l.startswith("signorini"))]
            c.check(rc == 1 and summary is None, "%s: exit status %d, no summary" % (tag, rc))
            one = len(lines) == 1 and lines[0].startswith("signorini: error: solver:") and "round-off floor" in lines[0]
            c.check(one, "%s: one line naming the round-off floor %r" % (tag, lines))
            steps = [int(n) for n in re.findall(r"DIVERGED_\w+ iterations (\d+)", out)]
            c.check(len(steps) == 1 and steps[0] <= 20, "%s: stopped after %s Newton steps (the floor test needs 5 at the floor)" % (tag, steps))
            advice = re.search(r"ask for -snes_rtol (\S+) or -snes_atol (\S+) or more", lines[0]) if one else None
            c.check(advice is not None, "%s: the message advises a tolerance" % tag)
            if advice and ranks == 1:
                base = [a for a in args if a != "-snes_converged_reason"]
                rtol, atol = advice.group(1), advice.group(2)
                for extra in (["-snes_rtol", rtol], ["-snes_rtol", "0", "-snes_atol", atol]):
                    rc2, _, _, s2 = run(base + ["-space", element] + extra, check=False)
                    c.check(rc2 == 0 and s2 is not None and s2["solver"]["converged_reason"].startswith("CONVERGED"),
                            "%s: the advised %s converges (exit %d)" % (tag, " ".join(extra), rc2))
c.done()

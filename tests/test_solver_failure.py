"""A run whose SNES or KSP does not converge says so on one line and exits non-zero, writing no summary."""
from harness import Checker, run, scene

c = Checker()
cases = [
    ("SNESVI stopped after one Newton step", scene("paper-5.1") + ["-box_faces", "16", "-snes_max_it", "1"], "DIVERGED_MAX_IT"),
    ("KSP stopped after one iteration (no contact part)", scene("paper-5.1") + ["-box_faces", "16", "-bc_contact", "", "-ksp_max_it", "1"], "DIVERGED_ITS"),
    ("KSP inside SNESVI stopped after one iteration", scene("paper-5.1") + ["-box_faces", "16", "-ksp_max_it", "1"], "DIVERGED"),
]
for what, args, reason in cases:
    for ranks in [1, 2]:
        rc, out, err, summary = run(args, ranks=ranks, check=False)
        # On several ranks mpirun adds its own banner about the non-zero exit; only our lines are counted.
        lines = [l for l in err.splitlines() if l.strip() and (ranks == 1 or l.startswith("signorini"))]
        c.check(rc == 1, "%s, %d rank(s): exit status %d" % (what, ranks, rc))
        c.check(len(lines) == 1 and lines[0].startswith("signorini: error: solver:") and reason in lines[0],
                "%s, %d rank(s): one-line message %r" % (what, ranks, lines))
        c.check(summary is None, "%s, %d rank(s): no summary written" % (what, ranks))
c.done()

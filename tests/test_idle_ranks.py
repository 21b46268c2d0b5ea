"""Runs on more ranks than the coarse mesh can share out, so that some ranks hold no cells, give the same
result as on 1 rank (independent computation: the runs share nothing but the input). A rank without cells
still takes part in every collective step (estimate, marking, refinement, output): a step that one rank
skipped because its own arrays were empty desynchronised the collectives, and the run failed with
MPI_ERR_TRUNCATE or hung. Each run has a time limit, so a hang fails the test instead of stalling it."""
import os
import tempfile

from harness import Checker, launch, rel, scene

c = Checker()
tight = ["-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
# (scene, its mesh, ranks): 8 triangles on 3 ranks leave one without cells, 6 tetrahedra on 5 ranks two.
cases = [
    ("manufactured-2d", ["-box_faces", "2"], 3),
    ("paper-5.1", ["-box_faces", "2"], 3),
    ("manufactured-3d", ["-box_faces", "1"], 5),
]
strategies = [("one mesh", []), ("adaptive", ["-adapt_steps", "2"])]


def summary(args, ranks):
    """The run's summary, or None (its error printed) if it failed; beyond 120 s it raises (the test fails)."""
    r = launch.run(args, ranks, summary=True, timeout=120)
    if r.returncode != 0 or r.summary is None:
        print("exit %d: %s" % (r.returncode, r.error_line()))
    return r.summary


with tempfile.TemporaryDirectory() as tmp:
    for name, mesh, ranks in cases:
        for space in ["p1", "cr"]:
            for how, extra in strategies:
                tag = "%s %s %s on %d ranks" % (name, space, how, ranks)
                args = scene(name) + mesh + ["-space", space] + extra + tight
                s1 = summary(args, 1)
                out = ["-output", os.path.join(tmp, "u.h5")] if how == "one mesh" else []
                sn = summary(args + out, ranks)
                c.check(s1 is not None and sn is not None, "%s: exit 0 on 1 and on %d ranks" % (tag, ranks))
                if s1 is None or sn is None:
                    continue
                if how == "one mesh":
                    c.check(0 in sn["cells_per_rank"], "%s: a rank without cells (cells per rank %s)" % (tag, sn["cells_per_rank"]))
                c.check(s1["cells"] == sn["cells"] and s1["dofs"] == sn["dofs"], "%s: same mesh (%d cells, %d DOFs)" % (tag, s1["cells"], s1["dofs"]))
                c.check(rel(s1["energy"], sn["energy"]) <= 1e-10, "%s: energy %.15e vs %.15e" % (tag, s1["energy"], sn["energy"]))
                e1, en = s1["estimate"]["eta"], sn["estimate"]["eta"]
                c.check(rel(e1, en) <= 1e-10, "%s: eta %.15e vs %.15e" % (tag, e1, en))
c.done()

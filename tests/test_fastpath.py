"""The fast path of -box_faces (issue 16, item 9): -box_faces N builds the coarsest box whose uniform refinement
is the box asked for and refines it in parallel. Against the same mesh asked as -box_faces n -refine k, and
against the box N built directly (-box_coarsen 0): the same DOFs and the same energy to 1e-12 (an
independent computation on a mesh built another way: the energy is a property of the mesh, not of its
numbering), with nested iteration on (the fast path's default) and off; on 1 and 2 ranks. The summary says
what was asked and how it was built. Crossed squares are built directly."""
from harness import Checker, run, scene

c = Checker()
CASES = [("paper-5.1", "p1", 32, 8), ("paper-5.1", "cr", 32, 8), ("paper-5.1-3d", "p1", 16, 4), ("paper-5.1-3d", "cr", 16, 4)]


def energy_close(a, b):
    return abs(a - b) <= 1e-12 * abs(b)


for name, space, N, n in CASES:
    k = (N // n).bit_length() - 1
    for ranks in [1, 2]:
        tag = "%s %s N=%d, %d rank(s)" % (name, space, N, ranks)
        base = scene(name) + ["-space", space]
        _, _, _, fast = run(base + ["-box_faces", str(N)], ranks=ranks)
        _, _, _, asked = run(base + ["-box_faces", str(n), "-refine", str(k)], ranks=ranks)
        _, _, _, direct = run(base + ["-box_faces", str(N), "-box_coarsen", "0"], ranks=ranks)
        _, _, _, flat = run(base + ["-box_faces", str(N), "-nested", "0"], ranks=ranks)
        box = "x".join([str(N)] * fast["dim"])
        c.check(fast["mesh"].startswith("box %s" % box) and "built as box %s refined %d times" % ("x".join([str(n)] * fast["dim"]), k) in fast["mesh"] and fast["refine"] == 0,
                "%s: the summary says what was asked and how it was built: '%s', refine %d" % (tag, fast["mesh"], fast["refine"]))
        c.check(direct["mesh"] == "box %s%s" % (box, " backslash" if fast["dim"] == 2 else "") and direct["coarse_cells"] == direct["cells"],
                "%s: -box_coarsen 0 builds the box directly: '%s', %d coarse cells" % (tag, direct["mesh"], direct["coarse_cells"]))
        c.check(fast["coarse_cells"] < direct["coarse_cells"] and fast["coarse_cells"] >= 64 * ranks,
                "%s: the coarse box has %d cells, at least 64 per rank" % (tag, fast["coarse_cells"]))
        c.check(fast["cells"] == asked["cells"] == direct["cells"] == flat["cells"] and fast["dofs"] == asked["dofs"] == direct["dofs"] == flat["dofs"],
                "%s: the same cells and DOFs (%d, %d, %d, %d DOFs)" % (tag, fast["dofs"], asked["dofs"], direct["dofs"], flat["dofs"]))
        c.check(min(fast["cells_per_rank"]) > 0, "%s: every rank has cells %s" % (tag, fast["cells_per_rank"]))
        for what, other in [("-box_faces %d -refine %d" % (n, k), asked), ("-box_coarsen 0", direct), ("-nested 0", flat)]:
            c.check(energy_close(fast["energy"], other["energy"]),
                    "%s: energy %.15g against %s %.15g" % (tag, fast["energy"], what, other["energy"]))

# Crossed squares are not the refinement of coarser crossed squares: built as asked.
_, _, _, s = run(scene("paper-5.1") + ["-box_faces", "16", "-box_diagonal", "crossed"])
c.check(s["mesh"] == "box 16x16 crossed" and s["coarse_cells"] == 4 * 16 * 16 and s["refine"] == 0,
        "crossed box 16 is built directly: '%s', %d coarse cells" % (s["mesh"], s["coarse_cells"]))
# -refine on top of the fast path: box 32 refined once is box 64.
_, _, _, a = run(scene("paper-5.1") + ["-box_faces", "32", "-refine", "1"])
_, _, _, b = run(scene("paper-5.1") + ["-box_faces", "64"])
c.check(a["dofs"] == b["dofs"] and a["refine"] == 1 and energy_close(a["energy"], b["energy"]) and "built as box 8x8 refined 2 times" in a["mesh"],
        "box 32 -refine 1 is box 64 (%d / %d DOFs, energy %.15g / %.15g, '%s')" % (a["dofs"], b["dofs"], a["energy"], b["energy"], a["mesh"]))
c.done()

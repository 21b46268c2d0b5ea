"""The manufactured scenes (exact solutions with a proper contact set and a free boundary that is not on
mesh vertices) converge with order about 2 in L2 and about 1 in the broken H1 seminorm, for both elements,
in 2D and 3D. Rates are least-squares fits over the last three of four nested meshes (comparison with the
exact solution)."""
from harness import Checker, rate, run, scene

c = Checker()
studies = [
    # scene, coarse cells per side, refinements, accepted L2 and H1 rate ranges
    ("manufactured-2d", 4, [0, 1, 2, 3], (1.85, 2.3), (0.93, 1.2)),
    ("manufactured-3d", 2, [0, 1, 2, 3], (1.7, 2.4), (0.85, 1.2)),
]
for name, n0, levels, l2_range, h1_range in studies:
    for space in ["p1", "cr"]:
        hs, l2, h1 = [], [], []
        for k in levels:
            _, _, _, s = run(scene(name) + ["-space", space, "-box_faces", str(n0), "-refine", str(k)])
            hs.append(1.0 / (n0 * 2 ** k))
            l2.append(s["error"]["l2"])
            h1.append(s["error"]["h1_semi"])
            c.check(0 < s["kkt"]["active"] < s["contact_dofs"] or k == 0,
                    "%s %s N=%d: contact set is a proper part of Gamma_C (%d of %d active)" % (name, space, n0 * 2 ** k, s["kkt"]["active"], s["contact_dofs"]))
        r2, r1 = rate(hs[1:], l2[1:]), rate(hs[1:], h1[1:])
        print("%s %s: h %s\n  L2 %s\n  H1 %s" % (name, space, hs, ["%.3e" % e for e in l2], ["%.3e" % e for e in h1]))
        c.check(l2_range[0] <= r2 <= l2_range[1], "%s %s: L2 rate %.3f in [%g, %g]" % (name, space, r2, *l2_range))
        c.check(h1_range[0] <= r1 <= h1_range[1], "%s %s: broken H1 rate %.3f in [%g, %g]" % (name, space, r1, *h1_range))
c.done()

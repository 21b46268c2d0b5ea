"""An exact solution that does not solve its scene is reported, condition by condition, before the solve: the
errors and rates of a run are against -exact_u and -exact_grad as given, and a typo in them, or in an f or g
derived by hand, would otherwise make every figure wrong without a word (src/exactcheck.cpp).
Invariants: every shipped scene with an exact solution passes every check (exact_failed_checks 0, no
warning, on 1 and 2 ranks); each broken datum makes exactly the conditions it breaks fail, named with a
point and the two values, and the run goes on (exit 0). Where u lies in the discrete space (u affine, in
contact where it should be) the error is the solver's, about 1e-10, and is no reason for the warning that
eta lies below the error."""
from harness import Checker, run, scene

c = Checker()
PREFIX = "signorini: warning: "


def warnings(args, ranks=1):
    rc, out, err, s = run(args, ranks=ranks, check=False)
    return rc, [l[len(PREFIX):] for l in (out + err).splitlines() if l.startswith(PREFIX)], s


for name in ["manufactured-2d", "manufactured-3d", "stiff-layers", "stiff-layers-across", "stiff-psi", "stiff-stretched-2d", "stiff-stretched-3d"]:
    for ranks in [1, 2] if name.startswith("manufactured") else [1]:
        rc, w, s = warnings(scene(name), ranks)
        c.check(rc == 0 and not w and s.get("exact_failed_checks") == 0, "%s, %d rank(s): the exact solution passes every check (%s)" % (name, ranks, w))
rc, w, s = warnings(scene("paper-5.1") + ["-box_faces", "8"])
c.check(rc == 0 and "exact_failed_checks" not in s, "paper-5.1 has no exact solution: nothing checked")

# manufactured-2d with one datum broken at a time: the conditions it breaks (each warning's start), each
# once, and what the warnings must show.
m2 = scene("manufactured-2d")
GRAD, PDE, DIR, NEU = ("-exact_grad is not the gradient of -exact_u", "-exact_u does not solve -div(kappa grad u) = f",
                       "-exact_u does not meet u = u_D on Gamma_D", "-exact_grad does not meet kappa du/dn = g on Gamma_N")
BELOW, PRESSURE, COMPL = ("-exact_u lies below the obstacle on Gamma_C", "-exact_grad gives a negative contact pressure on Gamma_C",
                          "-exact_u is off the obstacle and pressed onto it at once on Gamma_C")
cases = [
    ("-exact_grad off by a factor", m2 + ["-exact_grad", "2 * max(x - 0.4, 0)^2 + 3 * y * max(0.4 - x, 0)^2, -max(0.4 - x, 0)^3"], [GRAD, PDE, NEU], []),
    ("f off by a factor", m2 + ["-f", "5 * (y * max(0.4 - x, 0) - max(x - 0.4, 0))"], [PDE], []),
    ("u_D shifted", m2 + ["-u_D", "0.01 + max(x - 0.4, 0)^3 - y * max(0.4 - x, 0)^3"], [DIR], ["-u_D gives"]),
    ("g with the wrong sign on the left side", m2 + ["-g", "3 * max(x - 0.4, 0)^2 + 3 * y * max(0.4 - x, 0)^2"], [NEU], [NEU + ": at (0, "]),
    ("kappa 2 for the data of kappa 1", m2 + ["-kappa", "2"], [PDE, NEU], []),
    ("the obstacle raised", m2 + ["-psi", "0.001"], [BELOW], ["-psi gives 0.001"]),
]
# On the box of paper-5.1 (Dirichlet top, Neumann sides, contact bottom), f = 0, g = 0, u affine in y: the
# contact conditions alone.
box = scene("paper-5.1") + ["-box_faces", "8", "-f", "0", "-g", "0"]
cases += [
    ("pressure of the wrong sign", box + ["-exact_u", "y", "-exact_grad", "0, 1", "-u_D", "y"], [PRESSURE], ["kappa du/dn is -1"]),
    ("off the obstacle and pressed onto it", box + ["-exact_u", "1 - y", "-exact_grad", "0, -1", "-u_D", "1 - y"], [COMPL], ["u - psi is 1 and kappa du/dn 1"]),
]
for name, args, conds, details in cases:
    for ranks in [1, 2]:
        rc, w, s = warnings(args, ranks)
        checks = [l for l in w if l.endswith("the errors are measured against the functions as given")]
        ok = rc == 0 and s.get("exact_failed_checks") == len(checks) == len(conds)
        ok = ok and sorted(conds) == sorted(next((k for k in conds if l.startswith(k + ": at (")), l) for l in checks)
        ok = ok and all(any(d in l for l in checks) for d in details)
        c.check(ok, "%s, %d rank(s): %s failed check(s), reported: %s" % (name, ranks, s.get("exact_failed_checks") if s else -1, checks))

# u = 1 - y with the obstacle at 1: in contact on the whole bottom with pressure 1, a solution of the scene
# that lies in both discrete spaces. Its checks pass, and its error (the solver's) is no reason for a warning.
for space in ["p1", "cr"]:
    rc, w, s = warnings(box + ["-exact_u", "1 - y", "-exact_grad", "0, -1", "-u_D", "1 - y", "-psi", "1", "-space", space])
    c.check(rc == 0 and not w and s.get("exact_failed_checks") == 0 and s["error"]["energy"] < 1e-6,
            "u = 1 - y in full contact, %s: energy error %.1e, no warning (%s)" % (space, s["error"]["energy"], w))
c.done()

"""Scale invariance (an invariant of the discrete problem): with psi = 0 and u_D = 0 the admissible set K_h is a
cone, so the solution for the load s f is s u(f) and its energy J(s f) = s^2 J(f). The solvers work on the data
divided by a power of 2 near the size of u, so that PETSc's absolute thresholds follow the data: every s must give
the same Newton and KSP iterations (on every nested level) and the same active set. Checked for s = 1e-60 ... 1e60
with P1 and CR: with contact and nested iteration (-refine 2, the default path; also the KSP iterations of the
-compare_linear solve), with contact without it, and
without contact (one linear solve); on 1 rank and, for P1 with nested iteration, on 2 ranks. Scaling kappa
instead divides u and J by the factor, again with the same iterations. Data whose solution
double precision cannot hold (its energy would under- or overflow) stop with one error line and write no summary.

Offset invariance (an invariant of the discrete problem): u_D and psi raised by a constant c raise u by c (constants
lie in both spaces and in the kernel of the stiffness), and J(u + c) = J(u) - c chi(1), chi(1) = int f = 0 here up to
round-off. Checked for c = 300, 1e5, 1e8 (a temperature in kelvin, a pressure in pascal) with P1 and CR, nested,
on 1 and 2 ranks: the same Newton and KSP iterations on the finest level and active set as c = 0 (the coarse
levels stop on an estimate of their algebraic error, which sees the rounding of the prolongated u ~ c: 1.5e-8
at c = 1e8), no warning, the stationarity and KKT checks within -kkt_tolerance, the energy of c = 0 to
1e-14 c + 1e-12 (chi(1) is 0 up to the round-off of the assembled load, about 1e-15, which c multiplies) and
the estimate to 1e-2 relative (computed from u ~ c, whose rounding reaches its gradients: 5e-4 at c = 1e8);
the -output active field as at c = 0. Before the shift (datascale.h), c = 1e8 ended at the round-off floor after 10
added Newton steps, with stationarity 1.6e-3, KKT 1.2e-5, 6 DOFs more counted active and J = -252.9 for -0.4617."""
import os
import tempfile

from harness import Checker, run, scene

c = Checker()
FACTORS = ["1e-60", "1e-20", "1", "1e20", "1e60"]
TOL = 1e-12  # J(s f) / s^2 against J(f): only the rounding of s f in the data separates them


def load(s):
    return ["-f", "%s*2*pi*sin(2*pi*x)" % s]


def iterations(summary):
    solver = summary["solver"]
    return (solver["newton_iterations"], solver.get("ksp_iterations"),
            [(l["newton"], l["ksp"]) for l in solver.get("levels", [])], solver.get("linear_ksp_iterations"))


def compare(tag, args, ranks=1, contact=True):
    runs = {}
    for s in FACTORS:
        _, out, _, summary = run(args + load(s), ranks=ranks)
        runs[s] = summary
        label = "%s s=%s" % (tag, s)
        c.check(summary["solver"]["converged_reason"].startswith("CONVERGED"), "%s: %s" % (label, summary["solver"]["converged_reason"]))
        c.check("warning" not in out, "%s: no warning" % label)
        if contact:
            c.check(summary["kkt"]["relative"] <= 1e-8, "%s: relative KKT residual %.1e" % (label, summary["kkt"]["relative"]))
    base = runs["1"]
    for s, summary in runs.items():
        f = float(s)
        label = "%s s=%s" % (tag, s)
        its, its1 = iterations(summary), iterations(base)
        c.check(its == its1, "%s: iterations (Newton, KSP, per level, -compare_linear KSP) %s = %s at s = 1" % (label, its, its1))
        j, j1 = summary["energy"] / (f * f), base["energy"]
        c.check(abs(j - j1) <= TOL * abs(j1), "%s: J(s f) / s^2 = %.15e, J(f) = %.15e" % (label, j, j1))
        if contact:
            k, k1 = summary["kkt"], base["kkt"]
            c.check(k["active"] == k1["active"], "%s: %d active contact DOFs (%d at s = 1)" % (label, k["active"], k1["active"]))
            g = k["max_gap"] / f
            c.check(abs(g - k1["max_gap"]) <= TOL * k1["max_gap"], "%s: max(u - psi) / s = %.15e (s = 1: %.15e)" % (label, g, k1["max_gap"]))


paper = scene("paper-5.1") + ["-box_faces", "8"]
for space in ["p1", "cr"]:
    compare("paper-5.1 %s nested -refine 2 -compare_linear" % space, paper + ["-space", space, "-refine", "2", "-compare_linear"])
    compare("paper-5.1 %s -refine 2 -nested 0" % space, paper + ["-space", space, "-refine", "2", "-nested", "0"])
    compare("paper-5.1 %s without contact" % space, paper + ["-space", space, "-refine", "1", "-bc_contact", "", "-bc_neumann", "1,2,4"], contact=False)
compare("paper-5.1 p1 nested -refine 2, 2 ranks", paper + ["-space", "p1", "-refine", "2"], ranks=2)

# kappa scaled by 1e-60 and 1e60 (the equations' scale follows the matrix): u(kappa) = u(1) / kappa, J likewise.
runs = {k: run(paper + ["-space", "cr", "-refine", "1", "-kappa", k])[3] for k in ["1e-60", "1", "1e60"]}
for k, summary in runs.items():
    base, f = runs["1"], float(k)
    label = "paper-5.1 cr nested -refine 1 kappa=%s" % k
    c.check(iterations(summary) == iterations(base), "%s: iterations %s = %s at kappa = 1" % (label, iterations(summary), iterations(base)))
    c.check(abs(summary["energy"] * f - base["energy"]) <= TOL * abs(base["energy"]), "%s: kappa J = %.15e, J(kappa = 1) = %.15e" % (label, summary["energy"] * f, base["energy"]))

# Offsets (see the top).
for space in ["p1", "cr"]:
    for ranks in [1, 2]:
        args = scene("paper-5.1") + ["-box_faces", "128", "-space", space]
        _, _, _, base = run(args, ranks=ranks)
        for offset in ["300", "1e5", "1e8"]:
            _, out, _, s = run(args + ["-u_D", offset, "-psi", offset], ranks=ranks)
            label = "paper-5.1 %s N = 128, u_D = psi = %s, %d rank(s)" % (space, offset, ranks)
            c.check("warning" not in out and s["solver"]["converged_reason"] == base["solver"]["converged_reason"],
                    "%s: %s, no warning" % (label, s["solver"]["converged_reason"]))
            finest = lambda x: iterations(x)[:2]
            c.check(finest(s) == finest(base) and s["kkt"]["active"] == base["kkt"]["active"],
                    "%s: iterations %s, %d active (c = 0: %s, %d)" % (label, iterations(s), s["kkt"]["active"], iterations(base), base["kkt"]["active"]))
            c.check(s["stationarity"] <= 1e-6 and s["kkt"]["relative"] <= 1e-6,
                    "%s: stationarity %.1e, KKT %.1e" % (label, s["stationarity"], s["kkt"]["relative"]))
            c.check(abs(s["energy"] - base["energy"]) <= 1e-14 * float(offset) + 1e-12 and abs(s["estimate"]["eta"] / base["estimate"]["eta"] - 1) <= 1e-2,
                    "%s: J %.12e (c = 0: %.12e), eta %.6e (%.6e)" % (label, s["energy"], base["energy"], s["estimate"]["eta"], base["estimate"]["eta"]))
# The output's active field follows the same rule (relative to how much u varies, not to its size: at c = 1e8
# the size counted a DOF 1e-2 off psi as active, CR 21 of 64 for the 20 of c = 0). The field is written per
# contact face (P1: at both vertices of each face), so compared with the same field at c = 0.
import h5py  # noqa: E402 (run/setup installs python3-h5py)
for space in ["p1", "cr"]:
    with tempfile.TemporaryDirectory() as tmp:
        written, counted = [], []
        for offset in ["0", "1e8"]:
            out = os.path.join(tmp, "u%s.h5" % offset)
            _, _, _, s = run(scene("paper-5.1") + ["-box_faces", "64", "-space", space, "-u_D", offset, "-psi", offset, "-output", out])
            with h5py.File(out, "r") as f:
                written.append(int(round(f["/contact/active"][:].sum())))
            counted.append(s["kkt"]["active"])
        c.check(written[0] == written[1] and counted[0] == counted[1],
                "paper-5.1 %s N = 64, u_D = psi = 0 and 1e8: active field sums %s in -output, %s active DOFs counted" % (space, written, counted))

# Out of range: one error line, exit status 1, no summary file.
# A load of 1e-320 underflows in every quadrature contribution (it would give u = 0): refused in assembly.
for s, word in [("1e-300", "the data are too small for double precision"), ("1e300", "the data are too large for double precision"),
                ("1e-320", "option -f: '1e-320*2*pi*sin(2*pi*x)' is")]:
    with tempfile.TemporaryDirectory() as tmp:
        summary = os.path.join(tmp, "run.json")
        for ranks in [1, 2]:
            rc, out, err, _ = run(paper + load(s) + ["-summary", summary], ranks=ranks, check=False)
            lines = [l for l in (out + err).splitlines() if l.strip()]
            ours = [l for l in lines if l.startswith("signorini:")]
            # On 2 ranks mpirun adds its own notice about the non-zero exit status; ours must appear once.
            c.check(rc == 1 and len(ours) == 1 and (ranks > 1 or len(lines) == 1) and "MPI_ABORT" not in err
                    and ours[0].startswith("signorini: error: " + word),
                    "load %s, %d rank(s): exit %d, one error line: %s" % (s, ranks, rc, ours))
            c.check(os.listdir(tmp) == [], "load %s, %d rank(s): no file written" % (s, ranks))
c.done()

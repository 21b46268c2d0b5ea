"""Small versions of the stiff and extreme scenes (petsc-options/stiff-*), asserting invariants of the discrete
problem rather than outputs of the code:
  * manufactured solutions under a kappa jump of 1e-6 and 1e6 (layers along and across Gamma_C) and under a
    varying obstacle: the errors against the exact solution fall at the optimal rates (L2 ~ h^2, H1 ~ h), which
    a jump represented wrongly (e.g. kappa smeared over the interface cells) would break;
  * checkerboard contrast and stretched cells (aspect 1e3, 2D and 3D): KKT residuals at roundoff level and u equal
    to a direct (LU) solve of the same discrete problem;
  * loads scaled by 1e-10 ... 1e10 with psi = 0: u(s f) = s u(f) and J(u(s f)) = s^2 J(u(f)), on 2 ranks;
  * an obstacle far below: no active DOF, u equals the plain linear solve with Gamma_C as a Neumann part;
    an obstacle above: every contact DOF active, positive pressure, u equals the Dirichlet solve u = psi;
  * the load scaling (also by 3.7e-3) and the far obstacle through 5 adaptive steps: the same meshes at every
    step, eta scaled by s, and the linear run's meshes and eta;
  * many critical points and a Dirichlet/contact junction (solution below H^2): KKT residuals and a proper
    contact set.
The default solver is checked on the checkerboard (K = 1e6 and 1e9, where its residual meets the round-off
floor). The high-contrast solver preset is used where the default solver is known to fail (see
petsc-options/solvers/ and run/stability, which shows the default and the preset side by side)."""
import math
import os
import tempfile

from harness import OPTIONS, ROOT, Checker, adapted_meshes, run, scene, scene_with

try:
    import h5py
    import numpy as np
except ImportError:  # run/setup installs python3-h5py; without it only the scalar checks run
    h5py = None

c = Checker()
HIGH_CONTRAST = ["-options_file", os.path.join(OPTIONS, "solvers", "high-contrast")]
DIRECT = ["-ksp_type", "preonly", "-pc_type", "lu"] + HIGH_CONTRAST + ["-snes_vi_zero_tolerance", "0"]
TOL = 1e-8      # identities of the discrete problem (scaling, equal solves)
TOL_KKT = 1e-6  # relative KKT residuals, as in run/stability


def solve(args, ranks=1, bottom=False):
    """Summary and DOF vector (None without h5py) of one run; with bottom, also the P1 values at the vertices
    on y = 0 sorted by x."""
    fd, out = tempfile.mkstemp(suffix=".h5", dir=TMP)
    os.close(fd)
    _, _, _, s = run(args + ["-output", out], ranks=ranks)
    if not h5py:
        return (s, None, None) if bottom else (s, None)
    with h5py.File(out, "r") as f:
        u = np.array(f["fields/u"])
        if not bottom:
            return s, u
        x = np.array(f["geometry/vertices"])
        v = np.array(f["vertex_fields/u_vertex_value"]).ravel()
    on = np.abs(x[:, 1]) < 1e-12
    return s, u, v[on][np.argsort(x[on, 0])]


def kkt(s, u):
    """Worst KKT residual on Gamma_C relative to the size of u and of the pressure."""
    k = s["kkt"]
    scale_u = max(float(abs(u).max()) if u is not None else 0.0, k["max_gap"], 1e-300)
    worst = max(0.0, -k["min_gap"]) / scale_u
    if k["active"] > 0:
        p = k["max_pressure"]
        worst = max(worst, max(0.0, -k["min_pressure"]) / p, k["max_complementarity"] / (p * max(k["max_gap"], scale_u)))
    return worst


def same(u, v, scale=1.0):
    if u is None or v is None:
        return 0.0  # scalar checks only
    return float(abs(u / scale - v).max()) / float(abs(v).max())


def check_kkt(tag, s, u, tol=TOL_KKT):
    c.check(s["solver"]["converged_reason"].startswith("CONVERGED"), "%s: %s" % (tag, s["solver"]["converged_reason"]))
    r = kkt(s, u)
    c.check(r <= tol, "%s: relative KKT residual on Gamma_C %.1e <= %.0e" % (tag, r, tol))
    c.check(s["stationarity"] <= 1e-6, "%s: stationarity off Gamma_C %.1e" % (tag, s["stationarity"]))


def rates(tag, name, token, value, extra=(), sizes=(8, 16)):
    """Errors against the exact solution on two meshes: optimal rates and KKT residuals."""
    for space in ["p1", "cr"]:
        errs = []
        for n in sizes:
            args = (scene_with(name, token, value, TMP) if token else scene(name)) + ["-space", space, "-box_faces", str(n)] + list(extra)
            s, u = solve(args)
            check_kkt("%s %s N=%d" % (tag, space, n), s, u)
            errs.append(s["error"])
        l2 = math.log2(errs[0]["l2"] / errs[1]["l2"])
        h1 = math.log2(errs[0]["h1"] / errs[1]["h1"])
        c.check(l2 >= 1.8 and h1 >= 0.9, "%s %s: rates L2 %.2f (>= 1.8), H1 %.2f (>= 0.9) against the exact solution" % (tag, space, l2, h1))


with tempfile.TemporaryDirectory() as TMP:
    # Manufactured solutions that stay exact under the jump.
    for K in ["1e-6", "1e6"]:
        rates("stiff-layers K=%s" % K, "stiff-layers", "1e6", K, HIGH_CONTRAST)
    rates("stiff-layers-across K=1e6", "stiff-layers-across", None, None, HIGH_CONTRAST)
    rates("stiff-psi", "stiff-psi", None, None)

    # Checkerboard and stretched cells: KKT and equality with a direct solve of the same discrete problem.
    for name, extra in [("stiff-checkerboard", ["-box_faces", "16"]), ("stiff-stretched-2d", ["-box_faces", "16,16"]),
                        ("stiff-stretched-3d", ["-box_faces", "4,4,4"])]:
        for space in ["p1", "cr"]:
            tag = "%s %s" % (name, space)
            s, u = solve(scene(name) + extra + ["-space", space] + HIGH_CONTRAST)
            check_kkt(tag, s, u)
            sd, ud = solve(scene(name) + extra + ["-space", space] + DIRECT)
            d = same(u, ud)
            c.check(d <= TOL, "%s: max|u - u_LU| / max|u_LU| = %.1e" % (tag, d))
            c.check(abs(s["energy"] - sd["energy"]) <= TOL * abs(sd["energy"]), "%s: energy %.12e = LU's %.12e" % (tag, s["energy"], sd["energy"]))

    # The default solver on the checkerboard, without the preset: at K = 1e6 (the scene) CR's residual stalls
    # at its round-off floor above the default target, where the solve now ends with the active set settled
    # (include/signorini/stall.h), and at K = 1e9 CG's residual grows on the way by more than PETSc's default
    # divergence test allowed (it stopped CR's first Newton step). Against the LU solve of the same problem,
    # whose own round-off sets the tolerances at K = 1e9 (its stationarity is about 2e-4 there).
    for K, tol in [("1e6", TOL), ("1e9", 1e-6)]:
        for space in ["p1", "cr"]:
            tag = "stiff-checkerboard K=%s %s, default solver" % (K, space)
            args = scene_with("stiff-checkerboard", "1e6", K, TMP) + ["-box_faces", "16", "-space", space]
            s, u = solve(args)
            sd, ud = solve(args + DIRECT)
            c.check(s["solver"]["converged_reason"].startswith("CONVERGED") and s["solver"]["newton_iterations"] <= 20,
                    "%s: %s after %d Newton steps (the preset takes 30)" % (tag, s["solver"]["converged_reason"], s["solver"]["newton_iterations"]))
            c.check(kkt(s, u) <= TOL_KKT, "%s: relative KKT residual on Gamma_C %.1e <= %.0e" % (tag, kkt(s, u), TOL_KKT))
            c.check(s["stationarity"] <= max(1e-6, 10 * sd["stationarity"]), "%s: stationarity off Gamma_C %.1e (LU's %.1e)" % (tag, s["stationarity"], sd["stationarity"]))
            d = same(u, ud)
            c.check(d <= tol, "%s: max|u - u_LU| / max|u_LU| = %.1e <= %.0e" % (tag, d, tol))
            c.check(abs(s["energy"] - sd["energy"]) <= tol * abs(sd["energy"]), "%s: energy %.12e = LU's %.12e" % (tag, s["energy"], sd["energy"]))

    # Load scaling with psi = 0 (2 ranks): u(s f) = s u(f), J = s^2 J(1).
    for space in ["p1", "cr"]:
        small = ["-box_faces", "16", "-space", space]
        s1, u1 = solve(scene_with("stiff-load", "1e10", "1", TMP) + small, ranks=2)
        for factor in ["1e-10", "1e-5", "1e5", "1e10"]:
            tag = "stiff-load s=%s %s" % (factor, space)
            s, u = solve(scene_with("stiff-load", "1e10", factor, TMP) + small, ranks=2)
            f = float(factor)
            check_kkt(tag, s, u)
            d = same(u, u1, f)
            c.check(d <= TOL, "%s: max|u/s - u(1)| / max|u(1)| = %.1e" % (tag, d))
            c.check(abs(s["energy"] - f * f * s1["energy"]) <= TOL * f * f * abs(s1["energy"]), "%s: J = s^2 J(1) (%.6e vs %.6e)" % (tag, s["energy"], f * f * s1["energy"]))
            c.check(s["solver"]["newton_iterations"] == s1["solver"]["newton_iterations"], "%s: %d Newton steps, as for s = 1 (%d)" % (tag, s["solver"]["newton_iterations"], s1["solver"]["newton_iterations"]))

    # No contact: the plain linear solve. Full contact: the Dirichlet solve u = psi on Gamma_C.
    for space in ["p1", "cr"]:
        small = ["-box_faces", "16", "-space", space]
        s, u = solve(scene("stiff-obstacle-far") + small)
        tag = "stiff-obstacle-far %s" % space
        check_kkt(tag, s, u)
        c.check(s["kkt"]["active"] == 0 and s["kkt"]["min_gap"] > 0.5, "%s: no contact (active %d, min gap %.2f)" % (tag, s["kkt"]["active"], s["kkt"]["min_gap"]))
        sl, ul = solve(scene("stiff-obstacle-far") + small + ["-bc_contact", "", "-bc_neumann", "1,2,4"])
        c.check(sl["solver"]["type"] == "ksp", "%s: the comparison is a plain linear solve (%s)" % (tag, sl["solver"]["type"]))
        d = same(u, ul)
        c.check(d <= TOL, "%s: max|u - u_linear| / max|u_linear| = %.1e" % (tag, d))
        c.check(abs(s["energy"] - sl["energy"]) <= 1e-12 * abs(sl["energy"]), "%s: energy equals the linear solve's" % tag)

        s, u = solve(scene("stiff-obstacle-above") + small)
        tag = "stiff-obstacle-above %s" % space
        check_kkt(tag, s, u)
        c.check(s["kkt"]["active"] == s["contact_dofs"], "%s: contact along all of Gamma_C (%d of %d active)" % (tag, s["kkt"]["active"], s["contact_dofs"]))
        c.check(s["kkt"]["min_pressure"] > 0, "%s: positive pressure everywhere (min %.2e)" % (tag, s["kkt"]["min_pressure"]))
        sd, ud = solve(scene("stiff-obstacle-above") + small + ["-bc_contact", "", "-bc_dirichlet", "1,3", "-u_D", "y < 0.5 ? 2 : 0"])
        d = same(u, ud)
        c.check(d <= TOL, "%s: max|u - u_Dirichlet| / max|u_Dirichlet| = %.1e" % (tag, d))

    # The same two invariants through adaptive refinement (2 ranks): the estimate scales with the load (eta(s f)
    # = s eta(f) on the cone), so the same cells are marked at every step, which a tolerance or floor of the
    # estimate, the marking or the transfer in absolute terms would break; and a contact part that is never
    # touched changes nothing, step by step, against the linear run with Gamma_C as a Neumann part.
    def worst_eta(s, ref, f=1.0):
        return max(abs(a["eta"] - f * b["eta"]) / (f * b["eta"]) for a, b in zip(s["adapt"], ref["adapt"]))

    for space in ["p1", "cr"]:
        adapt = ["-box_faces", "8", "-space", space, "-adapt_steps", "5"]
        _, _, _, s1 = run(scene_with("stiff-load", "1e10", "1", TMP) + adapt, ranks=2)
        for factor in ["1e-10", "3.7e-3", "1e10"]:  # 3.7e-3: a factor of no particular form
            tag = "adaptive stiff-load s=%s %s" % (factor, space)
            f = float(factor)
            _, _, _, s = run(scene_with("stiff-load", "1e10", factor, TMP) + adapt, ranks=2)
            c.check(adapted_meshes(s) == adapted_meshes(s1) and len(s["adapt"]) == 6, "%s: the same meshes as s = 1 at every step (%s)" % (tag, adapted_meshes(s)))
            c.check(worst_eta(s, s1, f) <= TOL, "%s: eta = s eta(1) at every step (worst %.1e)" % (tag, worst_eta(s, s1, f)))
            c.check(abs(s["energy"] - f * f * s1["energy"]) <= TOL * f * f * abs(s1["energy"]), "%s: J = s^2 J(1) on the last mesh" % tag)
        tag = "adaptive stiff-obstacle-far %s" % space
        _, _, _, s = run(scene("stiff-obstacle-far") + adapt, ranks=2)
        _, _, _, sl = run(scene("stiff-obstacle-far") + adapt + ["-bc_contact", "", "-bc_neumann", "1,2,4"], ranks=2)
        c.check(s["kkt"]["active"] == 0 and adapted_meshes(s) == adapted_meshes(sl) and len(s["adapt"]) == 6,
                "%s: no contact, the linear run's meshes at every step (%s, %s)" % (tag, adapted_meshes(s), adapted_meshes(sl)))
        # eta to the two solves' accuracy: each stops within its own tolerance, and P1's flux is equilibrated up
        # to the solver's residual (2e-9 relative here against 1e-14 between the scaled runs above)
        c.check(worst_eta(s, sl) <= 10 * TOL and abs(s["energy"] - sl["energy"]) <= 1e-12 * abs(sl["energy"]),
                "%s: the linear run's eta at every step (worst %.1e) and energy" % (tag, worst_eta(s, sl)))

    # Many critical points (k = 8: the contact set switches 2k = 16 times) and the Dirichlet/contact junction.
    for name, extra in [("stiff-critical", ["-box_faces", "64"]), ("stiff-below-h2", ["-refine", "2"])]:
        for space in ["p1", "cr"]:
            args = (scene_with(name, "64", "8", TMP) if name == "stiff-critical" else scene(name)) + extra + ["-space", space]
            if name == "stiff-below-h2":
                args += ["-mesh_file", os.path.join(ROOT, "petsc-options", "meshes", "split-bottom.msh")]
            s, u, bottom = solve(args, bottom=True)
            tag = "%s %s" % (name, space)
            check_kkt(tag, s, u)
            k = s["kkt"]
            c.check(0 < k["active"] < s["contact_dofs"], "%s: contact set a proper part of Gamma_C (%d of %d)" % (tag, k["active"], s["contact_dofs"]))
            if name == "stiff-critical" and space == "p1" and bottom is not None:
                contact = bottom <= 1e-8 * abs(bottom).max()
                n = int((contact[1:] != contact[:-1]).sum())
                c.check(n == 16, "%s: the contact set switches %d times along Gamma_C (2k = 16)" % (tag, n))
c.done()

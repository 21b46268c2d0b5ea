"""The solver presets of petsc-options/solvers (default, semismooth, gamg, mumps) solve the same discrete
problem as the built-in defaults: the same energy J(u_h) to 1e-9 relative and the same active set, with
the discrete KKT conditions to solver tolerance, for P1 and CR in 2D and 3D, on 1 and 2 ranks.
The semismooth case guards a bug that gave a wrong solution with a clean KKT report: SSLS overwrites its
Jacobian matrix with D_a + D_b A, which was the system matrix itself; and it solves the stiff scenes (kappa jumps,
stretched cells, a load of 1e10, a checkerboard of kappa 1 and 1e6) to the default solver's energy and
active set in a few Newton steps, with or without the preset's -ksp_type. -pc_type gamg, which PETSc 3.18's
reduced-space solver cannot use, stops with a one-line message that names the option to use instead."""
import os
import tempfile

from harness import OPTIONS, Checker, run, scene, scene_with

c = Checker()


def preset(name):
    return ["-options_file", os.path.join(OPTIONS, "solvers", name)]


def as_default(tag, s, ref):
    """The run converged to the default solver's solution: its energy (1e-9 relative) and active set."""
    c.check(s["solver"]["converged_reason"].startswith("CONVERGED"), "%s: %s" % (tag, s["solver"]["converged_reason"]))
    c.check(abs(s["energy"] - ref["energy"]) <= 1e-9 * abs(ref["energy"]), "%s: energy %.15e vs default %.15e" % (tag, s["energy"], ref["energy"]))
    c.check(s["kkt"]["active"] == ref["kkt"]["active"], "%s: active set %d vs %d" % (tag, s["kkt"]["active"], ref["kkt"]["active"]))


cases = [("paper-5.1", ["-box_faces", "4", "-refine", "2"]), ("paper-5.1-3d", ["-box_faces", "2", "-refine", "2"])]
for name, mesh in cases:
    for space in ["p1", "cr"]:
        for ranks in [1, 2]:
            args = scene(name) + mesh + ["-space", space]
            _, _, _, ref = run(args, ranks=ranks)
            for p in ["default", "semismooth", "gamg", "mumps"]:
                _, out, _, s = run(args + preset(p), ranks=ranks)
                tag = "%s %s %d rank(s) preset %s" % (name, space, ranks, p)
                k = s["kkt"]
                as_default(tag, s, ref)
                c.check(k["min_gap"] >= -1e-12 and k["min_pressure"] >= -1e-7 * k["max_pressure"] and s["stationarity"] <= 1e-7,
                        "%s: KKT min gap %.1e, min pressure %.1e, stationarity %.1e" % (tag, k["min_gap"], k["min_pressure"], s["stationarity"]))
                c.check("was not used" not in out, "%s: every option of the preset is used" % tag)

# Semismooth on the stiff scenes. PETSc's derivative of the Fischer-Burmeister function takes 1/2 where both its
# arguments are below 1e-6: soft rows beside a kappa jump (scaled by the stiff rows' diagonal) ended in
# DIVERGED_MAX_IT after 200 Newton steps, stretched cells crawled (54 to 128 steps, or 200 and failed), until
# each row was scaled by its own diagonal entry and u by 2^20; and a load of 1e10 made the "no bound" of
# the other DOFs, a finite number, a bound when scaled (DIVERGED_FNORM_NAN). Each case against the default
# solver: the same energy and active set, KKT within 1e-6 and no warning, in at most 20 Newton steps.
with tempfile.TemporaryDirectory() as tmp:
    stiff = [("stiff-layers-across K=%s" % K, scene_with("stiff-layers-across", "1e6", K, tmp) + ["-box_faces", "8", "-refine", "1"]) for K in ["1e2", "1e6"]]
    stiff += [("stiff-stretched-2d", scene("stiff-stretched-2d") + ["-box_faces", "3", "-refine", "3"]),
              ("stiff-stretched-3d", scene("stiff-stretched-3d") + ["-box_faces", "2", "-refine", "1"]),
              ("stiff-load", scene("stiff-load") + ["-box_faces", "8"]),
              ("stiff-checkerboard", scene("stiff-checkerboard"))]
    # The checkerboard's kappa jumps made GMRES lose orthogonality (DIVERGED_BREAKDOWN in the first step, CR)
    # until its Gram-Schmidt got a second pass; -snes_type vinewtonssls alone kept CG, which broke down on
    # the Jacobian, not symmetric, until it chose GMRES too.
    variants = {name: [("preset semismooth", preset("semismooth"))] for name, _ in stiff}
    variants["stiff-checkerboard"].append(("-snes_type vinewtonssls", ["-snes_type", "vinewtonssls"]))
    for name, base in stiff:
        for space in ["p1", "cr"]:
            for ranks in [1, 2]:
                args = base + ["-space", space]
                _, _, _, ref = run(args, ranks=ranks)
                for what, options in variants[name]:
                    tag = "%s %s %d rank(s) %s" % (name, space, ranks, what)
                    rc, out, err, s = run(args + options, ranks=ranks, check=False)
                    if rc != 0:
                        c.check(False, "%s: %s" % (tag, err.strip()[-200:]))
                        continue
                    k = s["kkt"]
                    as_default(tag, s, ref)
                    c.check(k["relative"] <= 1e-6 and s["stationarity"] <= 1e-6 and "warning" not in out + err,
                            "%s: KKT relative %.1e, stationarity %.1e, no warning" % (tag, k["relative"], s["stationarity"]))
                    c.check(s["solver"]["newton_iterations"] <= 20, "%s: %d Newton steps" % (tag, s["solver"]["newton_iterations"]))

# A Krylov method for symmetric operators given to the semismooth solver: the failure's line names the cause.
rc, out, err, s = run(scene("stiff-checkerboard") + ["-space", "cr", "-box_faces", "8", "-snes_type", "vinewtonssls", "-ksp_type", "cg"], check=False)
lines = [l for l in err.splitlines() if l.startswith("signorini: error:")]
c.check(rc == 1 and len(lines) == 1 and "-ksp_type cg needs a symmetric operator" in lines[0], "-snes_type vinewtonssls -ksp_type cg: one line naming the cause: %r" % lines)

rc, out, err, s = run(scene("paper-5.1") + ["-box_faces", "8", "-pc_type", "gamg"], check=False)
lines = [l for l in err.splitlines() if l.strip()]
c.check(rc == 1 and len(lines) == 1 and "-pc_type gamg" in lines[0] and "-vi_pc_type gamg" in lines[0] and s is None,
        "-pc_type gamg: exit %d, one line naming -vi_pc_type: %r" % (rc, lines))
c.done()

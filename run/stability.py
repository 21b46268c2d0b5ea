"""Stability report: the stiff and extreme scenes (petsc-options/stiff-*) with both elements, one row each:
scene, element, solver settings, DOFs, Newton and KSP iterations, KKT residuals, energy, error (when known),
time and status, printed as a table and written as CSV (default results/stability.csv).

  run/stability [--ranks P] [--csv FILE] [--only TEXT] [--full] [--finest]

What each row checks (status "ok", or "FAIL" with the reason in the notes):
  * every single solve: it converged; the KKT residuals relative to the size of u and of the contact pressure
    (min(u - psi) / max|u|, -min pressure / max pressure, max |(u - psi) pressure| / (max gap max pressure))
    and the stationarity off Gamma_C (relative to the load, as the executable reports it) are below 1e-6
    (the stationarity: or below 10 times the direct solve's, where that one is compared and its own lies
    above 1e-6, the round-off level of a kappa contrast of 1e9);
  * high contrast, stretched cells, varying psi: u equals a direct solve of the same discrete problem (MUMPS LU,
    30 full Newton steps) to 1e-6 max|u|, so a solver that stops early is caught even when the KKT residuals
    of the stiff rows hide it; manufactured scenes also show the error against the exact solution;
  * load scaling (psi = 0): u(s f) / s equals u(f) to 1e-8 for s = 1e-10 ... 1e10, the energy scales by s^2;
  * obstacle far below: no active DOF and u equals the plain linear solve (Gamma_C made a Neumann part) to 1e-7;
    obstacle above: every contact DOF active, u equals the Dirichlet solve u = psi on Gamma_C to 1e-7, pressure > 0;
  * convergence studies (many critical points, a solution below H^2): errors against a finer reference and the
    observed rates; a rate below the optimal one is reported as "lower rate", which is not a failure.
The a posteriori estimate eta (estimate.h) is in every row (eta: single solves, the finest level of a study, the
last step of an adaptive run). Where the exact solution is known, the efficiency index eta / energy error is
judged in every single solve, at every level of a study and at every step of an adaptive run: eta < error (the
guaranteed bound broken) is a FAIL, an index above 3 reads "index > 3" (reliable but coarse: not a failure).
  * the kappa jump (contrast-estimate: stiff-layers, stiff-layers-across, K = 1e-6 and 1e6): the index across
    the jump in a uniform study (N = 8, 16, 32) and in an adaptive run of 12 steps, both elements;
  * cells of aspect ratio 1e3 (stiff-stretched-2d/3d) in an adaptive run of 4 (2D) and 3 (3D) steps, both
    elements: the index at every step;
  * stiff-below-h2 by adaptive refinement (both elements, u ~ r^(1/2)): a run until eta falls below the energy
    error of the study's finest uniform level (against the reference; no exact solution is known, so eta >= error
    stands in for the adaptive error), with the fitted slope of log eta against log DOFs over the last decade of
    DOFs, <= -0.45 or FAIL; and the run time the adaptive refinement takes to reach the energy error of a
    uniform run (the study's finest level; with --full, -refine 8: 1.05 M DOFs for P1, 3.15 M for CR) against
    that run's time (ratio of the runs' own totals, each the fastest of three alternate runs, target <= 0.1;
    "above target" otherwise, which is not a failure). Both errors are measured against solutions adaptively
    refined further from the runs' own meshes.
Where the default solver fails, the row of the preset that fixes it (petsc-options/solvers/high-contrast)
follows, and the default row's status reads "fail -> PRESET" (before and after); it counts as a
failure only if the preset fails too. The exit status is 1 if any row has status FAIL.

--full runs the many-critical-points studies for k = 1, 2, 4, ..., 64 with both loads (about 13 minutes), the
checkerboard with K = 1e9, the stiff-below-h2 study to -refine 6 (reference -refine 8, about 2 minutes), and
the adaptive time against the uniform run -refine 8 (about 5 minutes, 7 GB); --finest adds the finest 2D and 3D meshes
(manufactured-2d/3d) that fit in 24 GiB on the ranks used, predicted from the memory per DOF of two smaller runs,
and solves the largest of them that also fits about 5 minutes and the memory this machine has free (about
12 minutes in all)."""
import argparse
import csv
import json
import math
import os
import shlex
import sys
import tempfile
import time

import launch
from launch import EXE, OPTIONS, ROOT

TOL_KKT = 1e-6      # KKT residuals and stationarity, relative
TOL_DIRECT = 1e-6   # max|u - u_direct| / max|u_direct|
TOL_EXACT = 1e-8    # identities that hold exactly in the discrete problem (scaling, no contact, full contact)
INDEX_MAX = 3       # efficiency index eta / error above this: reported as its own status (issue 17: 1 <= index <= 3)
SLOPE_MAX = -0.45   # adaptive refinement on stiff-below-h2: eta (and error) ~ DOFs^slope, slope <= this (2D optimum -1/2)
TIME_RATIO = 0.1    # target: adaptive time to reach the uniform finest level's error / that level's time
TIME_REFINE_FULL = 8  # --full: the uniform run the adaptive one is timed against (P1 1.05 M DOFs, CR 3.15 M)
ELEMENTS = ["p1", "cr"]
DIRECT = ["-ksp_type", "preonly", "-pc_type", "lu", "-pc_factor_mat_solver_type", "mumps", "-snes_convergence_test", "skip",
          "-snes_max_it", "30", "-snes_linesearch_type", "basic", "-snes_rtol", "0", "-snes_vi_zero_tolerance", "0"]


def preset(name):
    return ["-options_file", os.path.join(OPTIONS, "solvers", name)]


def scene(name, replace=None):
    """The options of petsc-options/NAME as a list; replace = (token, value) substitutes in every value (the
    stiff scenes write their parameter, e.g. the contrast 1e6, as one literal token)."""
    args = []
    with open(os.path.join(OPTIONS, name)) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            parts = shlex.split(line)
            if replace:
                parts = parts[:1] + [p.replace(*replace) for p in parts[1:]]
            args += parts
    if "-mesh_file" in args:  # scene files name their mesh relative to the repository root
        i = args.index("-mesh_file") + 1
        args[i] = os.path.join(ROOT, args[i])
    return args


class Runner:
    """Runs signorini in a scratch folder; single runs return the summary and u (from -output), studies the JSON."""

    def __init__(self, ranks, tmp):
        self.ranks, self.tmp, self.count = ranks, tmp, 0

    def _exec(self, args):
        r = launch.run(args, self.ranks, cwd=ROOT)
        return r.returncode, r.error_line() if r.returncode else "", r.seconds

    def solve(self, args, output=True):
        """A single run; output=False leaves out the -output file (u is then None)."""
        self.count += 1
        base = os.path.join(self.tmp, "run%d" % self.count)
        rc, message, seconds = self._exec(args + ["-summary", base + ".json"] + (["-output", base + ".h5"] if output else []))
        result = {"rc": rc, "message": message, "seconds": seconds, "summary": None, "u": None}
        if rc == 0:
            with open(base + ".json") as f:
                result["summary"] = json.load(f)
            if output:
                result["u"] = read_u(base + ".h5")
        return result

    def study(self, args, profiles=False):
        """A convergence study; with profiles, also the finest level's contact profile per element (CSV path)."""
        self.count += 1
        path = os.path.join(self.tmp, "study%d.json" % self.count)
        prefix = os.path.join(self.tmp, "profile%d" % self.count)
        rc, message, seconds = self._exec(args + ["-study_output", path] + (["-study_profiles", prefix] if profiles else []))
        data = None
        if rc == 0:
            with open(path) as f:
                data = json.load(f)
        return {"rc": rc, "message": message, "seconds": seconds, "study": data, "profiles": prefix + "-%s-contact.csv"}


def read_u(path):
    """The DOF vector of a run (same mesh, element and ranks give the same ordering), or None without h5py."""
    try:
        import h5py
        import numpy as np
    except ImportError:
        return None
    with h5py.File(path, "r") as f:
        return np.array(f["fields/u"])


def max_abs(u):
    return float(abs(u).max()) if u is not None and len(u) else 0.0


def rel_diff(u, v, scale=1.0):
    """max|u/scale - v| / max|v|, or None when a vector is missing."""
    if u is None or v is None or len(u) != len(v):
        return None
    return max_abs(u / scale - v) / max(max_abs(v), 1e-300)


def kkt_residual(s, u):
    """The worst relative KKT residual on Gamma_C (see the module docstring) and the reason it is judged on."""
    k = s.get("kkt")
    if not k:
        return 0.0
    scale_u = max(max_abs(u), k["max_gap"], 1e-300)
    worst = max(0.0, -k["min_gap"]) / scale_u
    if k["active"] > 0:  # pressure and complementarity mean something only where there is contact
        p = max(k["max_pressure"], 1e-300)
        worst = max(worst, max(0.0, -k["min_pressure"]) / p, k["max_complementarity"] / (p * max(k["max_gap"], scale_u)))
    return worst


def row_from(name, variant, element, solver, result):
    r = {"scene": name, "variant": variant, "element": element, "solver": solver, "seconds": result["seconds"],
         "status": "ok", "check": "", "notes": []}
    s = result["summary"]
    if result["rc"] != 0 or s is None:
        r["status"] = "FAIL"
        r["notes"].append(result["message"])
        return r
    k = s.get("kkt", {})
    r.update(dofs=s["dofs"], newton=s["solver"]["newton_iterations"], ksp=s["solver"]["ksp_iterations"],
             reason=s["solver"]["converged_reason"], active=k.get("active"), contact_dofs=s["contact_dofs"],
             min_gap=k.get("min_gap"), min_pressure=k.get("min_pressure"), max_pressure=k.get("max_pressure"),
             max_complementarity=k.get("max_complementarity"), stationarity=s["stationarity"], energy=s["energy"],
             kkt=kkt_residual(s, result["u"]), max_u=max_abs(result["u"]))
    if "error" in s:
        r["l2"], r["h1"], r["energy_error"] = s["error"]["l2"], s["error"]["h1"], s["error"]["energy"]
    require(r, r["kkt"] <= TOL_KKT, "KKT residual %.1e > %.0e" % (r["kkt"], TOL_KKT))
    if "estimate" in s:
        r["eta"] = s["estimate"]["eta"]
        if "error" in s:
            judge_index(r, [("", r["eta"], s["error"]["energy"])])
    return r


def judge_index(row, cases):
    """The efficiency index eta / energy error of each (where, eta, error) in cases: the worst ones in the row
    ("index" for one case, else index_min and index_max); eta < error (the guaranteed bound broken) is a
    FAIL, an index above INDEX_MAX its own status "index > 3" (the estimate is reliable but coarse there)."""
    indices = [(eta / error if error > 0 else math.inf, where) for where, eta, error in cases]
    low, high = min(indices), max(indices)
    if len(cases) == 1:
        row["index"] = low[0]
    else:
        row["index_min"], row["index_max"] = low[0], high[0]
    require(row, low[0] >= 1, "eta / error = %.3f < 1%s: the estimate is below the true error" % (low[0], low[1] and " at " + low[1]))
    if high[0] > INDEX_MAX:
        row["notes"].append("eta / error = %.2f > %g%s" % (high[0], INDEX_MAX, high[1] and " at " + high[1]))
        if row["status"] == "ok":
            row["status"] = "index > %g" % INDEX_MAX


def require(row, ok, why):
    if not ok:
        row["status"] = "FAIL"
        row["notes"].append(why)


def compare(row, what, diff, tol):
    """Records a comparison of u with another solution in the row's check column; fails above tol."""
    if row["status"] == "FAIL" and "dofs" not in row:
        return
    if diff is None:
        row["notes"].append("%s: no vector to compare (python3-h5py missing?)" % what)
        return
    row["check"] = (row["check"] + "; " if row["check"] else "") + "%s %.1e" % (what, diff)
    require(row, diff <= tol, "%s: max|u - u_%s| / max|u| = %.1e > %.0e" % (what, what, diff, tol))


class Report:
    def __init__(self, runner):
        self.run, self.rows = runner, []

    def add(self, row):
        self.rows.append(row)
        return row

    def with_preset(self, name, variant, args, presets, check):
        """Default solver and, for each element, the presets that fix it; check(row, result, element) adds the
        case's own comparisons. A default row that fails while a preset row passes reads 'fail -> PRESET'."""
        for element in ELEMENTS:
            default = self.checked(name, variant, element, "default", args + ["-space", element], check)
            for p in presets:
                fixed = self.checked(name, variant, element, p, args + ["-space", element] + preset(p), check)
                if default["status"] == "FAIL" and fixed["status"] != "FAIL":
                    default["status"] = "fail -> " + p

    def checked(self, name, variant, element, solver, args, check):
        result = self.run.solve(args)
        row = row_from(name, variant, element, solver, result)
        check(row, result, element)
        if "stationarity" in row:
            # Where the direct solve of the same problem (direct_check) cannot reach TOL_KKT either, its own
            # stationarity is the round-off level (kappa contrast 1e9: about 2e-4), and 10 times it the bound.
            bound = max(TOL_KKT, 10 * row.get("direct_stationarity", 0))
            require(row, row["stationarity"] <= bound, "stationarity %.1e > %.1e" % (row["stationarity"], bound))
        return self.add(row)


def direct_check(runner, args):
    """check(row, result, element) comparing u with the direct solve of the same discrete problem."""
    cache, stationarity = {}, {}

    def check(row, result, element):
        if element not in cache:
            ref = runner.solve(args + ["-space", element] + DIRECT)
            cache[element] = ref["u"] if ref["rc"] == 0 and kkt_residual(ref["summary"], ref["u"]) <= TOL_KKT else None
            stationarity[element] = ref["summary"]["stationarity"] if cache[element] is not None else 0
            if ref["rc"] != 0:
                row["notes"].append("direct solve failed: " + ref["message"])
        if result["u"] is not None:
            compare(row, "direct", rel_diff(result["u"], cache[element]), TOL_DIRECT)
        row["direct_stationarity"] = stationarity[element]
    return check


def contrast(rep, full):
    cases = [("stiff-layers", [1e-9, 1e-6, 1.0, 1e6, 1e9, 1e12]), ("stiff-layers-across", [1e-6, 1e6]),
             ("stiff-checkerboard", [1e-6, 1e6] + ([1e9] if full else []))]
    for name, values in cases:
        for K in values:
            args = scene(name, ("1e6", "%g" % K))
            rep.with_preset(name, "K=%g" % K, args, ["high-contrast"], direct_check(rep.run, args))


def stretched(rep):
    for name in ["stiff-stretched-2d", "stiff-stretched-3d"]:
        args = scene(name)
        rep.with_preset(name, "aspect 1e3", args, ["high-contrast"], direct_check(rep.run, args))
    # Adaptive refinement keeps the cells' angles (bisect.cpp): the error falls and the index stays at its
    # uniform value at every step (Rivara's closure cut the long edges and made angles near 180 degrees).
    # 3D: 3 steps. The preconditioners are not robust to the aspect ratio: the KSP iterations per Newton step
    # double with every refinement, uniform or adaptive (uniform -refine 1, 2, 3: 33, 74, 142).
    for name, faces, steps in [("stiff-stretched-2d", "16,16", 4), ("stiff-stretched-3d", "4,4,4", 3)]:
        for element in ELEMENTS:
            adaptive_row(rep, name, "aspect 1e3 adaptive %d steps" % steps, element,
                         scene(name) + ["-box_faces", faces, "-adapt_steps", str(steps)])


def psi(rep):
    args = scene("stiff-psi")
    rep.with_preset("stiff-psi", "psi=0.1 sin(2 pi x)", args, [], direct_check(rep.run, args))


def load_scaling(rep):
    base = {}
    for element in ELEMENTS:
        r = rep.run.solve(scene("stiff-load", ("1e10", "1")) + ["-space", element])
        base[element] = r if r["rc"] == 0 else None
    for s in [1e-10, 1e-5, 1.0, 1e5, 1e10]:
        def check(row, result, element, s=s):
            b = base[element]
            if result["summary"] is None:
                return
            if b is None:
                require(row, False, "the s = 1 solve failed: nothing to compare with")
                return
            compare(row, "u(s)/s", rel_diff(result["u"], b["u"], s), TOL_EXACT)
            e, e1 = result["summary"]["energy"], b["summary"]["energy"] * s * s
            require(row, abs(e - e1) <= TOL_EXACT * abs(e1), "energy %.6e != s^2 J(1) = %.6e" % (e, e1))
            n1 = b["summary"]["solver"]["newton_iterations"]
            if row["newton"] > 2 * n1:
                row["notes"].append("converged, but in %d Newton steps against %d for s = 1" % (row["newton"], n1))
        rep.with_preset("stiff-load", "s=%g" % s, scene("stiff-load", ("1e10", "%g" % s)), [], check)


def obstacles(rep):
    far = scene("stiff-obstacle-far")
    linear = far + ["-bc_contact", "", "-bc_neumann", "1,2,4"]

    def check_far(row, result, element):
        if result["summary"] is None:
            return
        require(row, row["active"] == 0, "%d active contact DOFs, expected none" % row["active"])
        ref = rep.run.solve(linear + ["-space", element])
        compare(row, "linear", rel_diff(result["u"], ref["u"]) if ref["rc"] == 0 else None, TOL_EXACT * 10)
    rep.with_preset("stiff-obstacle-far", "psi=-1", far, [], check_far)

    above = scene("stiff-obstacle-above")
    dirichlet = above + ["-bc_contact", "", "-bc_dirichlet", "1,3", "-u_D", "y < 0.5 ? 2 : 0"]

    def check_above(row, result, element):
        if result["summary"] is None:
            return
        require(row, row["active"] == row["contact_dofs"], "%d of %d contact DOFs active, expected all" % (row["active"], row["contact_dofs"]))
        require(row, row["min_pressure"] > 0, "min pressure %.2e, expected > 0" % row["min_pressure"])
        ref = rep.run.solve(dirichlet + ["-space", element])
        compare(row, "dirichlet", rel_diff(result["u"], ref["u"]) if ref["rc"] == 0 else None, TOL_EXACT * 10)
    rep.with_preset("stiff-obstacle-above", "psi=2", above, [], check_above)


def switches(profile):
    """Number of changes between contact (u - psi <= 1e-8 max(u - psi)) and no contact along Gamma_C, from a
    contact profile sorted by coordinates (2D: along the side), or None if there is none."""
    if not os.path.exists(profile):
        return None
    with open(profile) as f:
        gaps = [float(r["u"]) - float(r["psi"]) for r in csv.DictReader(f)]
    tol = 1e-8 * max(max(gaps), 1e-300)
    active = [g <= tol for g in gaps]
    return sum(a != b for a, b in zip(active, active[1:]))


def study_rows(rep, name, variant, args, optimal=(2.0, 1.0), solver="default"):
    """One row per element from a convergence study: the finest level's figures, its errors against the reference
    or exact solution, the observed rates (last two levels, and the least-squares slope over all), the estimate
    of the finest level, the efficiency index at every level (where the exact solution is known) and the number
    of switches of the contact set along Gamma_C on the finest level. Returns the study's result."""
    r = rep.run.study(args, profiles=True)
    if r["rc"] != 0:
        for element in ELEMENTS:
            rep.add({"scene": name, "variant": variant, "element": element, "solver": solver, "seconds": r["seconds"],
                     "status": "FAIL", "check": "", "notes": [r["message"]]})
        return r
    for element in ELEMENTS:
        levels = [x for x in r["study"]["rows"] if x["element"] == element]
        key = "error_reference" if "error_reference" in levels[-1] else "error_exact"
        hs = [x["h"] for x in levels]
        last = levels[-1]
        row = {"scene": name, "variant": variant, "element": element, "solver": solver, "seconds": r["seconds"],
               "status": "ok", "check": "", "notes": [], "dofs": last["dofs"], "newton": last["newton_iterations"],
               "ksp": last["ksp_iterations"], "reason": last["converged_reason"], "active": last["active"],
               "energy": last["energy"], "l2": last[key]["l2"], "h1": last[key]["h1"], "energy_error": last[key]["energy"]}
        for norm in ["l2", "h1"]:
            errs = [x[key][norm] for x in levels]
            row["rate_" + norm] = math.log(errs[-2] / errs[-1]) / math.log(hs[-2] / hs[-1])
            row["fit_" + norm] = slope(hs, errs)
        if "estimate" in last:
            row["eta"] = last["estimate"]["eta"]
            if key == "error_exact":
                judge_index(row, [("N=%d" % x["N"], x["estimate"]["eta"], x[key]["energy"]) for x in levels])
        row["switches"] = switches(r["profiles"] % element)
        row["check"] = "rates L2 %.2f H1 %.2f (fit %.2f / %.2f) vs %s, h %.3g..%.3g, %s switches" % (
            row["rate_l2"], row["rate_h1"], row["fit_l2"], row["fit_h1"], key.split("_")[1], hs[0], hs[-1], row["switches"])
        if row["status"] == "ok" and (row["rate_h1"] < 0.9 * optimal[1] or row["rate_l2"] < 0.9 * optimal[0]):
            row["status"] = "lower rate"
        rep.add(row)
    return r


def slope(hs, errs):
    xs, ys = [math.log(h) for h in hs], [math.log(e) for e in errs]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def adaptive_row(rep, name, variant, element, args, solver="default"):
    """One adaptive run (args include -adapt_steps) as a row: the last mesh's figures, the fitted slopes of eta
    and, where the exact solution is known, of the error against the DOFs over the last decade of DOFs
    (slope_eta, slope_error), and the efficiency index at every step. Returns the row and the run's result."""
    result = rep.run.solve(args + ["-space", element], output=False)
    row = {"scene": name, "variant": variant, "element": element, "solver": solver, "seconds": result["seconds"],
           "status": "ok", "check": "", "notes": []}
    s = result["summary"]
    if result["rc"] != 0 or s is None or not s.get("adapt"):
        require(row, False, result["message"] or "no adaptive rows in the summary")
        return rep.add(row), result
    steps = s["adapt"]
    last = steps[-1]
    row.update(dofs=last["dofs"], newton=last["newton"], ksp=last["ksp"], reason=s["solver"]["converged_reason"],
               energy=s["energy"], eta=last["eta"], steps=len(steps))
    fit = [x for x in steps if 10 * x["dofs"] >= last["dofs"]]  # the last decade of DOFs
    row["check"] = "%d steps, %d..%d DOFs" % (len(steps), steps[0]["dofs"], last["dofs"])
    if len(fit) >= 3:
        row["slope_eta"] = slope([x["dofs"] for x in fit], [x["eta"] for x in fit])
        row["check"] += "; eta ~ DOFs^%.3f" % row["slope_eta"]
    known = [x for x in steps if x.get("error") is not None]
    if known and len(known) == len(steps) and len(fit) >= 3:
        row["slope_error"] = slope([x["dofs"] for x in fit], [x["error"] for x in fit])
        row["check"] += ", error ~ DOFs^%.3f" % row["slope_error"]
    if len(fit) >= 3:
        row["check"] += " (fit over the last %d steps, DOFs >= %d)" % (len(fit), fit[0]["dofs"])
    if known:
        row["energy_error"] = known[-1]["error"]
        judge_index(row, [("step %d" % k, x["eta"], x["error"]) for k, x in enumerate(steps) if x.get("error") is not None])
        row["check"] += "; eta/error %.2f..%.2f over %d steps" % (row["index_min"], row["index_max"], len(known))
    return rep.add(row), result


def contrast_estimate(rep):
    """The estimate across the kappa jump, on the scenes with an exact solution: the efficiency index at every
    level of a uniform study (N = 8, 16, 32) and at every step of an adaptive run, for K = 1e-6 and 1e6, with the
    default solver."""
    for name in ["stiff-layers", "stiff-layers-across"]:
        for K in [1e-6, 1e6]:
            args = scene(name, ("1e6", "%g" % K)) + ["-box_faces", "8"]
            study_rows(rep, name, "K=%g uniform N=8..32" % K, args + ["-study_levels", "3"])
            for element in ELEMENTS:
                adaptive_row(rep, name, "K=%g adaptive 12 steps" % K, element, args + ["-adapt_steps", "12"])


def critical_points(rep, full):
    """f = 2 pi cos(2 pi k x): 2k switches (the scene); f = 2 pi sin(2 pi k x), the paper's load: far fewer."""
    ks = [1, 2, 4, 8, 16, 32, 64] if full else [1, 4, 16]

    def levels(k):
        # the coarsest level has at least 2 cells per period 1/k (coarser ones alias the load), the reference
        # is 4 times finer than the finest level
        n0 = max(16, 2 * k)
        return ["-box_faces", str(n0), "-study_levels", "4" if n0 == 16 else "3", "-reference_refine", "2"]
    for k in ks:
        study_rows(rep, "stiff-critical", "k=%d cos" % k, scene("stiff-critical", ("64", str(k))) + levels(k))
    for k in (ks if full else [16]):
        study_rows(rep, "stiff-critical", "k=%d sin (paper's load)" % k,
                   scene("stiff-critical", ("cos(2*pi*64*x)", "sin(2*pi*%d*x)" % k)) + levels(k))


def below_h2(rep, full):
    refine, count = 1, (6 if full else 4)
    levels = ["-refine", str(refine), "-study_levels", str(count), "-reference_refine", "2"]
    study = study_rows(rep, "stiff-below-h2", "D|C junction, f=-2pi cos", scene("stiff-below-h2") + levels)
    adaptive_vs_uniform(rep, study, TIME_REFINE_FULL if full else refine + count - 1)
    # the same mesh and parts with contact next to the junction: there u = 0 on both sides, no singularity
    study_rows(rep, "stiff-below-h2", "contact at junction, f=2pi sin", scene("stiff-below-h2") + levels + ["-f", "2*pi*sin(2*pi*x)"])


def adaptive_vs_uniform(rep, study, uniform_refine):
    """stiff-below-h2 (u ~ r^(1/2)) by adaptive refinement, per element, from the scene's mesh, as two rows.
    "adaptive": one run until its estimate eta falls below the energy error (against the reference) of the
    study's finest level, with eta ~ DOFs^slope and slope <= SLOPE_MAX (FAIL otherwise); eta >= error stands
    in for the error there. "time vs uniform": see compare_times, against the uniform run -refine
    uniform_refine."""
    name = "stiff-below-h2"
    for element in ELEMENTS:
        target = None
        if study["study"]:
            target = [x for x in study["study"]["rows"] if x["element"] == element][-1]
        if target is None or "error_reference" not in target:
            rep.add({"scene": name, "variant": "adaptive", "element": element, "solver": "default", "seconds": 0,
                     "status": "FAIL", "check": "", "notes": ["no uniform study to compare with"]})
            continue
        tol = target["error_reference"]["energy"]
        row, _ = adaptive_row(rep, name, "adaptive, eta < uniform E", element,
                              scene(name) + ["-adapt_steps", "100", "-adapt_tol", "%.17g" % tol])
        if "slope_eta" not in row:
            if row["status"] != "FAIL":
                require(row, False, "too few steps in the last decade of DOFs to fit a slope")
            continue
        require(row, row["slope_eta"] <= SLOPE_MAX, "eta ~ DOFs^%.3f, slope above %g" % (row["slope_eta"], SLOPE_MAX))
        if "slope_error" in row:
            require(row, row["slope_error"] <= SLOPE_MAX, "error ~ DOFs^%.3f, slope above %g" % (row["slope_error"], SLOPE_MAX))
        compare_times(rep, name, uniform_refine, element)


# The uniform run's error: measured against the solution of UNIFORM_REFERENCE_STEPS adaptive steps from its
# mesh (Doerfler parameter UNIFORM_REFERENCE_THETA). The adapted meshes refine the uniform one, so the error is
# computed exactly against that solution, and near the singularity, where the error is, the reference is many
# times finer than the uniform mesh for a fraction of the DOFs a uniform reference would need (stiff-below-h2
# P1 -refine 6: 1.52e-2 against 160 k DOFs adapted, 1.38e-2 against 1.05 M uniform, -refine 8). Its own eta
# bounds how far off the measured error can be (triangle inequality), and the row shows it.
UNIFORM_REFERENCE_STEPS = 6
UNIFORM_REFERENCE_THETA = 0.8
# The adaptive run's error: against the solution REFERENCE_STEPS adaptive steps further than its last
# compared step.
REFERENCE_STEPS = 4


def compare_times(rep, name, uniform_refine, element):
    """The row "time vs uniform": the uniform run -refine uniform_refine (a single run, default options) and
    the adaptive run from the scene's mesh up to the first step whose energy error is below the uniform one's.
    Both errors are against a reference solution on a refinement of the run's own meshes (see
    UNIFORM_REFERENCE_STEPS, REFERENCE_STEPS), and slightly below the true ones. The adaptive time is the
    step's "run_seconds" (from the first mesh to that step's estimate); the uniform time is that run's own
    total (mesh to estimate). Neither includes process start-up; each is the fastest of TIME_REPEATS runs
    (best_times). Target: ratio <= TIME_RATIO ("above target" otherwise, not a failure). The conservative
    comparison (the first adaptive step whose eta is below the uniform error) is in the check column too."""
    base = scene(name) + ["-space", element]
    uniform_args = base + ["-refine", str(uniform_refine)]
    uniform = rep.run.solve(uniform_args, output=False)
    row = {"scene": name, "variant": "time vs uniform -refine %d" % uniform_refine, "element": element,
           "solver": "default", "seconds": uniform["seconds"], "status": "ok", "check": "", "notes": []}
    u = uniform["summary"]
    if uniform["rc"] != 0 or u is None:
        require(row, False, uniform["message"] or "the uniform run failed")
        return rep.add(row)
    measured = rep.run.solve(base + ["-refine", str(uniform_refine), "-adapt_steps", "1", "-adapt_max_dofs", "1", "-adapt_theta",
                                     str(UNIFORM_REFERENCE_THETA), "-adapt_reference_steps", str(UNIFORM_REFERENCE_STEPS)], output=False)
    ref = (measured["summary"] or {}).get("adapt") if measured["rc"] == 0 else None
    error = ref[0]["error_reference"] if ref else None
    if error is None:
        require(row, False, measured["message"] or "the uniform run's reference run failed")
        return rep.add(row)
    # eta >= error: the first step with eta below the uniform error has reached it; no more than the uniform DOFs
    adaptive = rep.run.solve(base + ["-adapt_steps", "100", "-adapt_tol", "%.17g" % error, "-adapt_max_dofs", str(u["dofs"]),
                                     "-adapt_reference_steps", str(REFERENCE_STEPS)], output=False)
    row["seconds"] += measured["seconds"] + adaptive["seconds"]
    if adaptive["rc"] != 0 or adaptive["summary"] is None or not adaptive["summary"].get("adapt"):
        require(row, False, adaptive["message"] or "the adaptive run failed")
        return rep.add(row)
    first, last = ref[0], ref[-1]
    if first["dofs"] != u["dofs"]:  # the reference run's step 0 must be the uniform run's mesh
        require(row, False, "step 0 of the reference run has %d DOFs, the uniform run %d" % (first["dofs"], u["dofs"]))
        return rep.add(row)
    row.update(dofs=u["dofs"], newton=u["solver"]["newton_iterations"], ksp=u["solver"]["ksp_iterations"], energy=u["energy"],
               eta=u["estimate"]["eta"], energy_error=error, reference_eta=last["eta"])
    steps = [r for r in adaptive["summary"]["adapt"] if not r.get("reference_step")]
    reached = next((r for r in steps if r.get("error_reference") is not None and r["error_reference"] <= error), None)
    # The adaptive error's rate (issue 17: error and estimate ~ DOFs^-1/2), over the last decade of DOFs of
    # the compared steps. Against a reference 4 steps further (about 8 times the DOFs) the last step's error
    # reads about 6 % low, which steepens the fitted slope by about 0.03.
    known = [r for r in steps if r.get("error_reference") is not None]
    fit = [r for r in known if 10 * r["dofs"] >= known[-1]["dofs"]] if known else []
    if len(fit) >= 3:
        row["slope_error"] = slope([r["dofs"] for r in fit], [r["error_reference"] for r in fit])
        require(row, row["slope_error"] <= SLOPE_MAX, "adaptive error ~ DOFs^%.3f, slope above %g" % (row["slope_error"], SLOPE_MAX))
    else:
        require(row, False, "too few adaptive steps with a reference error to fit a slope")
    by_eta = next((r for r in steps if r["eta"] <= error), None)
    if reached is None:
        require(row, False, "the adaptive error does not reach %.3e within %d DOFs" % (error, u["dofs"]))
        tu = u["time"]["total"]
    else:
        step = steps.index(reached)
        prev = steps[step - 1] if step > 0 else None
        tu, ta, tb = best_times(rep, row, uniform_args, u, base + ["-adapt_steps", str(max(step, 1)), "-adapt_max_dofs", str(u["dofs"])],
                                step, reached, prev)
        row["time_ratio"] = ta / tu
        curve = curve_time(prev, tb, reached, ta, error)
        if curve is not None:
            row["curve_ratio"] = curve / tu
    conservative = ("by eta < E: %d DOFs in %.3f s, ratio %.3f" % (by_eta["dofs"], by_eta["run_seconds"], by_eta["run_seconds"] / tu)
                    if by_eta else "eta not below E within %d DOFs" % u["dofs"])
    row["check"] = "uniform %d DOFs, error %.3e (vs %d adapted DOFs, eta %.2e) in %.3f s; " % (
        u["dofs"], error, last["dofs"], last["eta"], tu)
    if reached is None:
        row["check"] += conservative
        return rep.add(row)
    row["check"] += ("adaptive %d DOFs, error %.3e (vs adaptive reference) in %.3f s: time ratio %.3f, target <= %g (%s)" % (
        reached["dofs"], reached["error_reference"], ta, row["time_ratio"], TIME_RATIO, conservative))
    if "curve_ratio" in row:
        row["check"] += "; on the adaptive error-time curve, between step %d and %d: ratio %.3f" % (step - 1, step, row["curve_ratio"])
    row["check"] += "; fastest of %d alternate runs each, uniform %s s, adaptive %s s" % (
        TIME_REPEATS, "/".join("%.3f" % x for x in row["uniform_seconds"]), "/".join("%.3f" % x for x in row["adaptive_seconds"]))
    if "slope_error" in row:
        row["check"] += "; adaptive error ~ DOFs^%.3f over %d..%d DOFs" % (row["slope_error"], fit[0]["dofs"], fit[-1]["dofs"])
    if row["status"] == "ok" and row["time_ratio"] > TIME_RATIO:
        row["status"] = "above target"
    rep.add(row)


# The time ratio's two sides are timed this many times each, alternately, and compared by their fastest
# runs: on a shared or virtual machine the wall time of one command varies by up to 2x from run to run,
# and the fastest run is the one least disturbed by others.
TIME_REPEATS = 3


def best_times(rep, row, uniform_args, u, adaptive_args, step, reached, prev):
    """The fastest of TIME_REPEATS timings of the uniform run (first: its summary u) and of the adaptive run
    up to its step `step` (first: that step's row `reached`, and `prev` the row of the step before, None
    for step 0), the others by runs of the same commands alternately, without their references (which
    come after the timed part). Each repeat must give the same DOFs. Records both lists in row; returns
    (uniform, adaptive) seconds and the fastest time of the same adaptive runs up to step `step` - 1
    (None for step 0)."""
    before = [prev["run_seconds"]] if prev else []

    def uniform_time(s):
        return s["time"]["total"] if s["dofs"] == u["dofs"] else None

    def adaptive_time(s):
        steps = s.get("adapt") or []
        if not (len(steps) > step and steps[step]["dofs"] == reached["dofs"]):
            return None
        if step > 0:
            before.append(steps[step - 1]["run_seconds"])
        return steps[step]["run_seconds"]
    sides = [("uniform", uniform_args, uniform_time, [u["time"]["total"]]),
             ("adaptive", adaptive_args, adaptive_time, [reached["run_seconds"]])]
    for _ in range(TIME_REPEATS - 1):
        for what, args, time_of, times in sides:
            again = rep.run.solve(args, output=False)
            row["seconds"] += again["seconds"]
            t = time_of(again["summary"]) if again["rc"] == 0 and again["summary"] else None
            if t is None:
                require(row, False, again["message"] or "a repeat of the %s run ended on another mesh" % what)
            else:
                times.append(t)
    row["uniform_seconds"], row["adaptive_seconds"] = sides[0][3], sides[1][3]
    return min(sides[0][3]), min(sides[1][3]), (min(before) if before else None)


def curve_time(prev, t_prev, reached, t_reached, error):
    """The time at which the adaptive run's error would reach `error` on its error-time curve, interpolated
    log-log between the step before the first step below it (prev, timed t_prev) and that step (reached,
    t_reached); None without the step before. The steps grow the mesh by a factor each, so the first step
    below a given error lies anywhere up to that factor beyond it; this figure leaves out where the steps
    happen to fall (the time ratio proper does not)."""
    if prev is None or t_prev is None or prev.get("error_reference") is None:  # (above `error`, when known)
        return None
    e0, e1 = prev["error_reference"], reached["error_reference"]
    f = math.log(e0 / error) / math.log(e0 / e1)
    return t_prev * (t_reached / t_prev) ** f


def available_memory():
    """MemAvailable of this machine in bytes (Linux), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def finest(rep, budget_seconds=300.0, memory=24 * 2**30):
    """Memory per DOF from two probe runs per (dimension, element), the largest uniform refinement predicted to
    fit in `memory` on the runner's ranks, and a solve of the largest one that also fits the time budget and
    60 % of the memory this machine has available now."""
    usable = min(memory, 0.6 * (available_memory() or memory))
    for name, base, probe in [("manufactured-2d", ["-box_faces", "64"], [2, 3]), ("manufactured-3d", ["-box_faces", "8"], [1, 2])]:
        dim = 3 if name.endswith("3d") else 2
        for element in ELEMENTS:
            probes = []
            for refine in probe:
                r = rep.run.study(scene(name) + base + ["-refine", str(refine), "-study_levels", "1", "-study_spaces", element])
                if r["rc"] == 0:
                    x = r["study"]["rows"][0]
                    probes.append((x["dofs"], x["peak_rss_bytes"], r["seconds"], refine))
            if len(probes) < 2:
                rep.add({"scene": name, "variant": "finest", "element": element, "solver": "default", "seconds": 0,
                         "status": "FAIL", "check": "", "notes": ["probe runs failed"]})
                continue
            (d1, m1, _, _), (d2, m2, t2, r2) = probes
            ranks = rep.run.ranks
            per_dof = max((m2 - m1) / (d2 - d1) * ranks, 1.0)  # marginal bytes per DOF, all ranks together
            fixed = m2 - per_dof * d2 / ranks                   # per rank, independent of the size
            growth = 2 ** dim
            fit_dofs = (memory / ranks - fixed) / per_dof * ranks
            fit_refine = r2 + int(math.floor(math.log(fit_dofs / d2) / math.log(growth)))
            refine, dofs, seconds = r2, d2, t2
            while (fixed + per_dof * dofs * growth / ranks) * ranks <= usable and seconds * growth * 1.3 <= budget_seconds:
                refine, dofs, seconds = refine + 1, dofs * growth, seconds * growth * 1.3
            r = rep.run.study(scene(name) + base + ["-refine", str(refine), "-study_levels", "1", "-study_spaces", element])
            row = {"scene": name, "variant": "finest (-refine %d)" % refine, "element": element, "solver": "default",
                   "seconds": r["seconds"], "status": "ok" if r["rc"] == 0 else "FAIL", "check": "",
                   "notes": [] if r["rc"] == 0 else [r["message"]]}
            if r["rc"] == 0:
                x = r["study"]["rows"][0]
                row.update(dofs=x["dofs"], newton=x["newton_iterations"], ksp=x["ksp_iterations"], energy=x["energy"],
                           l2=x["error_exact"]["l2"], h1=x["error_exact"]["h1"], peak_rss=x["peak_rss_bytes"],
                           bytes_per_dof=x["peak_rss_bytes"] * ranks / x["dofs"])
                row["check"] = ("peak %.2f GiB per rank = %.0f B/DOF (marginal %.0f B/DOF); 24 GiB on %d ranks holds "
                                "about %.3g DOFs: %s -refine %d" % (x["peak_rss_bytes"] / 2**30, row["bytes_per_dof"],
                                                                   per_dof, ranks, fit_dofs, " ".join(base), fit_refine))
            rep.add(row)


COLUMNS = ["scene", "variant", "element", "solver", "dofs", "newton", "ksp", "reason", "active", "contact_dofs", "min_gap",
           "min_pressure", "max_pressure", "max_complementarity", "kkt", "stationarity", "energy", "l2", "h1", "energy_error",
           "eta", "index", "index_min", "index_max", "rate_l2", "rate_h1", "fit_l2", "fit_h1", "steps", "slope_eta",
           "slope_error", "time_ratio", "curve_ratio", "reference_eta", "switches", "max_u", "peak_rss", "bytes_per_dof", "seconds", "status", "check", "notes"]


def write_csv(rows, path):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(dict(r, notes="; ".join(r["notes"])))
    os.replace(path + ".tmp", path)


def fmt(v, spec):
    return "" if v is None else spec % v


def index_text(r):
    """The efficiency index of a row: one value, or the range over the levels or steps."""
    if "index" in r:
        return "%.2f" % r["index"]
    if "index_min" in r:
        return "%.2f-%.2f" % (r["index_min"], r["index_max"])
    return ""


def print_table(rows):
    head = "%-21s %-26s %-3s %-13s %8s %4s %5s %8s %8s %12s %9s %9s %9s %9s %-9s %-16s %6s  %s" % (
        "scene", "variant", "el", "solver", "DOFs", "Nwt", "KSP", "KKT", "station", "energy", "L2", "H1", "energy-E",
        "eta", "eta/E", "status", "time", "check")
    print(head)
    print("-" * len(head))
    for r in rows:
        print("%-21s %-26s %-3s %-13s %8s %4s %5s %8s %8s %12s %9s %9s %9s %9s %-9s %-16s %6.1f  %s" % (
            r["scene"], r["variant"][:26], r["element"], r["solver"], fmt(r.get("dofs"), "%d"), fmt(r.get("newton"), "%d"),
            fmt(r.get("ksp"), "%d"), fmt(r.get("kkt"), "%.1e"), fmt(r.get("stationarity"), "%.1e"),
            fmt(r.get("energy"), "%.5e"), fmt(r.get("l2"), "%.3e"), fmt(r.get("h1"), "%.3e"), fmt(r.get("energy_error"), "%.3e"),
            fmt(r.get("eta"), "%.3e"), index_text(r), r["status"], r["seconds"], r["check"]))
    notes = [(r, n) for r in rows for n in r["notes"]]
    if notes:
        print("\nnotes:")
        for r, n in notes:
            print("  %s %s %s %s: %s" % (r["scene"], r["variant"], r["element"], r["solver"], n))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=launch.count, default=2, help="MPI ranks per run (default 2)")
    ap.add_argument("--csv", default=os.path.join(ROOT, "results", "stability.csv"))
    ap.add_argument("--only", default="", help="run only the groups whose name contains this text: contrast, "
                    "contrast-estimate, stretched, psi, load, obstacle, critical, below-h2, finest")
    ap.add_argument("--full", action="store_true", help="k = 1 ... 64 for the critical points on finer meshes, K = 1e9 checkerboard")
    ap.add_argument("--finest", action="store_true", help="also the finest meshes that fit in 24 GiB, with memory per DOF")
    args = ap.parse_args()
    groups = [("contrast", lambda rep: contrast(rep, args.full)), ("contrast-estimate", contrast_estimate),
              ("stretched", stretched), ("psi", psi),
              ("load", load_scaling), ("obstacle", obstacles), ("critical", lambda rep: critical_points(rep, args.full)),
              ("below-h2", lambda rep: below_h2(rep, args.full))]
    if args.finest or args.only == "finest":
        groups.append(("finest", finest))
    if not any(args.only in name for name, _ in groups):  # a mistyped group ran nothing and wrote an empty table
        names = [name for name, _ in groups] + ([] if any(name == "finest" for name, _ in groups) else ["finest"])
        ap.error("--only %s: no group's name contains it (groups: %s)" % (args.only, ", ".join(names)))
    if os.path.isdir(args.csv):
        ap.error("--csv %s: a folder, not a file name" % args.csv)
    launch.output_folder(ap, "--csv", args.csv, os.path.dirname(os.path.abspath(args.csv)))
    t0 = time.time()
    with tempfile.TemporaryDirectory(prefix="stability-") as tmp:
        rep = Report(Runner(args.ranks, tmp))
        for name, group in groups:
            if args.only in name:
                print("running %s ..." % name, file=sys.stderr, flush=True)
                group(rep)
    print("Stability report (%d ranks, %s; %d runs in %.0f s). KKT: worst relative residual on Gamma_C; station: "
          "max|r|/max|load| off Gamma_C; L2/H1: error vs exact or reference.\n" % (args.ranks, EXE, rep.run.count, time.time() - t0))
    print_table(rep.rows)
    write_csv(rep.rows, args.csv)
    failed = [r for r in rep.rows if r["status"] == "FAIL"]
    print("\n%d rows, %d ok, %d lower rate, %d fixed by a preset, %d FAIL; written to %s" % (
        len(rep.rows), sum(r["status"] == "ok" for r in rep.rows), sum(r["status"] == "lower rate" for r in rep.rows),
        sum(r["status"].startswith("fail ->") for r in rep.rows), len(failed), args.csv))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()

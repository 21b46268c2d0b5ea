"""Uniform against adaptive refinement of one scene: the rows of both strategies side by side (DOFs, error,
estimate eta, efficiency index, iterations, run time so far), one table, CSV and JSON, plots of error and
estimate against DOFs and against run time, and the picture of the adapted mesh. Used by run/study and run/demo.

Run time of a row: uniform, the run up to that level (refinement of the mesh to it, and the set-up, solve
and estimate of every level of the element so far, each level started from the one before: the study's
total_seconds, about what a run of that level alone costs); adaptive, the wall time of the run from the first mesh up to that
step's estimate (every earlier step's set-up, solve, estimate, marking, refinement and transfer included:
the summary's run_seconds), without the error computations.

The error is the energy error: against the exact solution where the scene has one; otherwise, for uniform
rows, against the study's reference (-reference_refine), and for adaptive rows against the solution of an
adaptive run continued for a few more steps (-adapt_reference_steps m, or fewer where a mesh has reached
-adapt_reference_dofs times the run's last DOFs: the adapted meshes are nested, so
every step is compared with it exactly, cell by cell). That reference is only a few steps finer, so the
errors of the last steps before it are too low (for a conforming linear problem by the factor
sqrt(1 - (E_ref / E)^2)); the table marks the reference steps "r" and the plots leave them out."""
import csv
import json
import os
import sys

import launch

# signorini options that belong to the convergence study only (each takes a value)
STUDY_ONLY = {"-study_levels", "-reference_refine", "-reference_space", "-study_spaces", "-study_output", "-study_profiles", "-space"}
REFERENCE_STEPS = 6  # default -adapt_reference_steps without an exact solution: the last step's error is then about 5-10 % low
# -adapt_reference_dofs: the reference ends earlier, at the first mesh with this many times the DOFs of the
# run's last step. In 2D the 6 steps end first (a step grows the mesh 1.6 to 1.8 times: 17 to 31 times the
# DOFs); in 3D a step grows it 3 to 4 times, so 6 steps asked for up to 4000 times the DOFs (paper-5.1-3d P1
# from 8 k DOFs: the run was killed for memory), and 3 or 4 steps reach this factor, where the last step's
# error, falling like DOFs^-1/3, reads about 5 % low, as in 2D.
REFERENCE_DOFS = 32
FIELDS = ["strategy", "element", "step", "reference_step", "cells", "dofs", "error", "error_against", "eta", "efficiency", "newton", "ksp", "seconds"]


def without_study_options(options):
    out, skip = [], False
    for o in options:
        if skip:
            skip = False
        elif o in STUDY_ONLY:
            skip = True
        else:
            out.append(o)
    return out


def _index(eta, error):
    return eta / error if eta is not None and error else None


def uniform_rows(study):
    """The rows of a convergence study (run/study.py's study.json)."""
    rows = []
    for r in study["rows"]:
        key = "error_reference" if "error_reference" in r else "error_exact"
        error = r[key]["energy"] if key in r else None
        eta = r["estimate"]["eta"] if "estimate" in r else None
        rows.append({"strategy": "uniform", "element": r["element"], "step": r["level"], "reference_step": False, "cells": r["cells"], "dofs": r["dofs"],
                     "error": error, "error_against": key.split("_")[1] if key in r else None, "eta": eta, "efficiency": _index(eta, error),
                     "newton": r["newton_iterations"], "ksp": r["ksp_iterations"], "seconds": r["total_seconds"]})
    return rows


def run_adaptive(scene, options, element, out_dir, ranks=1, steps=None, max_dofs=None, theta=None, reference_steps=0,
                 reference_dofs=REFERENCE_DOFS):
    """One adaptive run of `element`; returns its summary. Without `steps` it refines until the DOFs reach
    max_dofs. Writes adapt-ELEMENT.json and the last mesh's solution adapt-ELEMENT.h5 (with its indicators)."""
    summary = os.path.join(out_dir, "adapt-%s.json" % element)
    args = launch.scene(scene) + without_study_options(options) + ["-space", element, "-output", os.path.join(out_dir, "adapt-%s.h5" % element)]
    args += ["-adapt_steps", str(steps)] if steps else ["-adapt_steps", "200", "-adapt_max_dofs", str(max_dofs)]
    if theta is not None:
        args += ["-adapt_theta", repr(theta)]
    if reference_steps:
        args += ["-adapt_reference_steps", str(reference_steps), "-adapt_reference_dofs", repr(reference_dofs)]
    r = launch.run(args, ranks, summary=summary)
    if r.returncode != 0:
        sys.stderr.write(r.stdout + r.stderr)
        sys.exit("adaptive run of %s with %s failed (exit %d): %s" % (scene, element, r.returncode, " ".join(r.cmd)))
    return r.summary


def adaptive_rows(element, summary):
    rows = []
    for k, a in enumerate(summary["adapt"]):
        error, against = (a["error"], "exact") if a["error"] is not None else (a.get("error_reference"), "adaptive reference")
        rows.append({"strategy": "adaptive", "element": element, "step": k, "reference_step": a.get("reference_step", False), "cells": a["cells"], "dofs": a["dofs"],
                     "error": error, "error_against": against if error is not None else None, "eta": a["eta"], "efficiency": _index(a["eta"], error),
                     "newton": a["newton"], "ksp": a["ksp"], "seconds": a["run_seconds"]})
    return rows


def adaptive(scene, options, study, out_dir, ranks=1, steps=None, theta=None, reference_steps=None, reference_dofs=REFERENCE_DOFS):
    """The adaptive run of every element of the study, from the study's first mesh, to about the DOFs of
    its finest level (or `steps` steps); returns their rows and summaries."""
    has_exact = all("error_exact" in r for r in study["rows"])
    if reference_steps is None:
        reference_steps = 0 if has_exact else REFERENCE_STEPS
    rows, summaries = [], {}
    for element in dict.fromkeys(r["element"] for r in study["rows"]):
        finest = max(r["dofs"] for r in study["rows"] if r["element"] == element)
        s = run_adaptive(scene, options, element, out_dir, ranks, steps, finest, theta, reference_steps, reference_dofs)
        summaries[element] = s
        rows += adaptive_rows(element, s)
    return rows, summaries


def _fmt(v, f):
    return f % v if v is not None else "-"


def table(rows):
    lines = ["%-8s %-4s %5s %9s %12s %12s %6s %6s %6s %9s  %s" % ("strategy", "elem", "step", "DOFs", "error", "eta", "eta/E", "Newton", "KSP", "time[s]", "error against")]
    for r in rows:
        step = "%d%s" % (r["step"], "r" if r["reference_step"] else "")
        lines.append("%-8s %-4s %5s %9d %12s %12s %6s %6d %6d %9.3f  %s" % (r["strategy"], r["element"], step, r["dofs"], _fmt(r["error"], "%.4e"), _fmt(r["eta"], "%.4e"),
                     _fmt(r["efficiency"], "%.2f"), r["newton"], r["ksp"], r["seconds"], r["error_against"] or "-"))
    return "\n".join(lines)


def notes(rows):
    """What the table cannot show: adaptive steps without an error (before a redistribution on several ranks)."""
    out = []
    for element in dict.fromkeys(r["element"] for r in rows):
        missing = [r["step"] for r in rows if r["strategy"] == "adaptive" and r["element"] == element and r["error"] is None and not r["reference_step"]]
        if missing:
            out.append("%s: no adaptive reference error for steps %d to %d: a later mesh was redistributed, so a cell's parent may be on another rank"
                       % (element, missing[0], missing[-1]))
    return out


def reached(rows, element, key):
    """(target, uniform seconds, adaptive seconds or None, adaptive DOFs): the first adaptive step whose `key`
    (error or eta) is at most that of the finest uniform level, and when."""
    uni = [r for r in rows if r["strategy"] == "uniform" and r["element"] == element and r[key] is not None]
    ada = [r for r in rows if r["strategy"] == "adaptive" and r["element"] == element and not r["reference_step"] and r[key] is not None]
    if not uni or not ada:
        return None
    finest = max(uni, key=lambda r: r["dofs"])
    hit = next((r for r in ada if r[key] <= finest[key]), None)
    return finest[key], finest["seconds"], hit["seconds"] if hit else None, hit["dofs"] if hit else None, finest["dofs"]


def reach_lines(rows):
    """One line per element: when the adaptive run reaches the finest uniform error and estimate."""
    out = []
    for element in dict.fromkeys(r["element"] for r in rows):
        parts = []
        for key, name in [("error", "error"), ("eta", "estimate")]:
            r = reached(rows, element, key)
            if r is None:
                continue
            target, tu, ta, dofs, udofs = r
            if ta is None:
                parts.append("the uniform finest %s %.3e (%d DOFs, %.3f s) not reached" % (name, target, udofs, tu))
            else:
                parts.append("the uniform finest %s %.3e in %.3f s (%d DOFs) versus %.3f s (%d DOFs)" % (name, target, ta, dofs, tu, udofs))
        if parts:
            out.append("%s: the adaptive run reaches %s" % (element, "; ".join(parts)))
    return out


def write(rows, out_dir, name="compare"):
    """compare.csv and compare.json with all rows."""
    with open(os.path.join(out_dir, name + ".json.tmp"), "w") as f:
        json.dump({"rows": rows}, f, indent=1)
    os.replace(os.path.join(out_dir, name + ".json.tmp"), os.path.join(out_dir, name + ".json"))
    tmp = os.path.join(out_dir, name + ".csv.tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r[k] is None else r[k]) for k in FIELDS})
    os.replace(tmp, os.path.join(out_dir, name + ".csv"))


def pictures(rows, summaries, out_dir, title):
    """The comparison plots and, in 2D, the last adapted mesh of every element; returns the files written."""
    import plot

    written = []
    for x, xlabel, name in [("dofs", "DOFs", "compare-vs-dofs.png"), ("seconds", "run time so far [s]", "compare-vs-time.png")]:
        plot.plot_compare(rows, os.path.join(out_dir, name), title, x, xlabel)
        written.append(name)
    for element, s in summaries.items():
        # the -output of an adaptive run is its last step (not the reference's, when one follows)
        last = max(k for k, a in enumerate(s["adapt"]) if not a.get("reference_step"))
        what = "adapted mesh after %d steps" % last
        name = "adapted-mesh-%s.png" % element
        if plot.plot_mesh(os.path.join(out_dir, "adapt-%s.h5" % element), os.path.join(out_dir, name), "%s, %s: %s" % (title, element, what)):
            written.append(name)
    return written

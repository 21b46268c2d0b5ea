"""Uniform against adaptive refinement of a scene, with both elements (or those of -study_spaces).

  run/study SCENE [--ranks P] [--out DIR] [--adapt-steps K] [--theta T] [--reference-steps M] [--reference-dofs F]
            [signorini options...]

  run/study manufactured-2d -box_faces 4 -study_levels 5
  run/study paper-5.1 -box_faces 2 -study_levels 6 -reference_refine 3 -load_quadrature centroid

1. The convergence study (uniform refinement, -study_levels): errors, rates, iterations, times and memory
   (study.csv, study.json, error-vs-h.png, error-vs-time.png, solution.png, contact.png). Errors against the
   exact solution when the scene has one; against a reference solution (-reference_refine m,
   -reference_space p1|cr) otherwise.
2. An adaptive run per element from the same first mesh (-adapt_steps K, default: until the DOFs of the
   finest uniform level; -adapt_theta T), its errors against the exact solution or, without one, against
   an adaptive reference M steps further (default 6), or fewer where its mesh has F times the last
   step's DOFs (default 32: 3D steps grow the mesh about 4 times; see run/compare.py).
3. One table of both strategies (compare.csv, compare.json), error and estimate against DOFs and against run
   time (compare-vs-dofs.png, compare-vs-time.png), the last adapted mesh of each element in 2D with its
   indicators and the contact set (adapted-mesh-ELEMENT.png), and when the adaptive run reaches the finest
   uniform error. Extra options go to signorini (see signorini -help)."""
import argparse
import csv
import json
import os
import sys
import time

import compare
import launch
from launch import ROOT


def run_study(scene, options, out_dir, ranks=1, quiet=False):
    """Runs signorini in study mode; returns the study dict and writes study.json/.csv and the plots."""
    import plot

    os.makedirs(out_dir, exist_ok=True)
    json_path = os.path.join(out_dir, "study.json")
    args = launch.scene(scene)
    if "-study_levels" not in options:
        args += ["-study_levels", "5"]
    profiles = os.path.join(out_dir, "finest")
    args += list(options) + ["-study_output", json_path, "-study_profiles", profiles]
    r = launch.run(args, ranks)
    if r.returncode != 0:
        sys.stderr.write(r.stdout + r.stderr)
        sys.exit("run/study: signorini failed (exit %d)" % r.returncode)
    if not quiet:
        sys.stdout.write(r.stdout)
    with open(json_path) as f:
        study = json.load(f)
    write_csv(study, os.path.join(out_dir, "study.csv"))
    title = "%s (%d rank%s)" % (study["scene"], study["ranks"], "s" if study["ranks"] > 1 else "")
    plot.plot_error_vs_h(study, os.path.join(out_dir, "error-vs-h.png"), title)
    plot.plot_work_precision(study, os.path.join(out_dir, "error-vs-time.png"), title)
    # the free boundary, for 2D scenes with a contact part: finest level of each element
    elements = sorted({r["element"] for r in study["rows"]})
    finest = max(r["N"] for r in study["rows"])
    h5 = {e: "%s-%s.h5" % (profiles, e) for e in elements}
    plot.plot_solution(h5, os.path.join(out_dir, "solution.png"), "%s, N = %d" % (study["scene"], finest))
    contact = {e: "%s-%s-contact.csv" % (profiles, e) for e in elements}
    if all(os.path.exists(f) for f in contact.values()):
        plot.plot_contact(contact, os.path.join(out_dir, "contact.png"), "%s: the free boundary on Gamma_C, N = %d" % (study["scene"], finest))
    return study


def write_csv(study, path):
    fields = ["element", "N", "h", "cells", "dofs", "l2", "h1_semi", "h1", "energy", "eta", "efficiency", "newton_iterations", "ksp_iterations",
              "solve_seconds", "total_seconds", "peak_rss_bytes", "error_against"]
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for r in study["rows"]:
            key = "error_reference" if "error_reference" in r else "error_exact"
            row = {k: r[k] for k in fields if k in r}
            row.update(r.get(key, {}))
            if "estimate" in r:  # the estimate of the energy error and eta / error (efficiency index)
                row.update({k: r["estimate"][k] for k in ["eta", "efficiency"] if k in r["estimate"]})
            row["error_against"] = key.split("_")[1]
            w.writerow(row)
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", help="options file in petsc-options/")
    ap.add_argument("--ranks", type=launch.count, default=1)
    ap.add_argument("--out", default=None, help="output folder (default results/SCENE)")
    ap.add_argument("--adapt-steps", type=launch.count, default=None, help="adaptive steps (default: until the DOFs of the finest uniform level)")
    ap.add_argument("--theta", type=launch.number_in(0, 1, low_open=True), default=None, help="Doerfler parameter of the adaptive run (-adapt_theta)")
    ap.add_argument("--reference-steps", type=launch.integer_from(0), default=None,
                    help="steps beyond the adaptive run for its reference (default: none with an exact solution, else %d)" % compare.REFERENCE_STEPS)
    ap.add_argument("--reference-dofs", type=launch.number_in(0), default=compare.REFERENCE_DOFS,
                    help="the reference ends earlier, at the first mesh with this many times the DOFs of the run's last step (0: no such end; default %g)" % compare.REFERENCE_DOFS)
    args, options = ap.parse_known_args()
    out = args.out or os.path.join(ROOT, "results", args.scene)
    launch.output_folder(ap, "--out", out)
    started = time.time()
    study = run_study(args.scene, options, out, args.ranks)
    rows, summaries = compare.adaptive(args.scene, options, study, out, args.ranks, args.adapt_steps, args.theta, args.reference_steps, args.reference_dofs)
    rows = compare.uniform_rows(study) + rows
    print("\nuniform against adaptive refinement (error: energy norm; time: run time up to that mesh; r: adaptive step for the reference only)")
    print(compare.table(rows))
    for line in compare.notes(rows) + compare.reach_lines(rows):
        print(line)
    compare.write(rows, out)
    compare.pictures(rows, summaries, out, study["scene"])
    # this run's files only: an earlier study in the same folder (other elements, another scene) left its own
    written = [f for f in os.listdir(out) if f.endswith((".json", ".csv", ".png")) and os.path.getmtime(os.path.join(out, f)) >= started]
    print("wrote in %s: %s" % (out, ", ".join(sorted(written))))


if __name__ == "__main__":
    main()

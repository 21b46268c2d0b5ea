"""`run/bench --nohier`: the contact solve on a fine mesh without a refinement hierarchy (issue 18: a Gmsh file
read as it is, no -refine), as the ratio contact solve / one CG + BoomerAMG linear solve of the same operator
measured in the same run (-compare_linear). Target: <= 4.

  run/bench --nohier [--quick] [--elements p1,cr] [--ranks P] [--repeat K] [--out DIR] [--nohier-n2 1024]

For every element and N: run/gmsh_box.py writes the paper-5.1 mesh with N x N squares (the mesh of
`-box_faces N`) as a Gmsh file into DIR (removed after the runs), and signorini solves
`-options_file petsc-options/paper-5.1 -mesh_file FILE -space E -compare_linear -log_view`; the solve then
starts from u_D on one level, with no nested iteration. Prints DOFs, Newton steps, CG iterations, BoomerAMG
set-ups and re-uses, the Solve stage, the linear solve and the ratio (with --repeat K, medians of the K
runs' ratios, each from one run). Each run's summary JSON and -log_view are kept in DIR; the rows go to
DIR/nohier.csv. Other options go to signorini."""
import argparse
import csv
import os
import statistics
import subprocess
import sys

import launch
from launch import ROOT

TARGET = 4.0


def run(element, N, msh, ranks, out, tag, extra):
    return launch.run_kept(launch.scene("paper-5.1") + ["-mesh_file", msh, "-space", element, "-compare_linear"] + list(extra), ranks, out, tag)


def case(element, N, msh, ranks, repeat, out, extra):
    runs = []
    for k in range(repeat):
        s = run(element, N, msh, ranks, out, "nohier-%s-N%d-np%d-run%d" % (element, N, ranks, k + 1), extra)
        if s is None:
            return {"element": element, "N": N, "status": "failed"}
        runs.append(s)
    v = runs[0]["solver"]
    med = lambda f: statistics.median(f(s) for s in runs)
    return {"element": element, "N": N, "dofs": runs[0]["dofs"], "newton": v["newton_iterations"], "ksp": v["ksp_iterations"],
            "amg_setups": v["amg_setups"], "amg_reuses": v["amg_reuses"], "solve_s": med(lambda s: s["time"]["solve"]),
            "linear_s": med(lambda s: s["solver"]["linear_solve_seconds"]), "ratio": med(lambda s: s["solver"]["solve_linear_ratio"]),
            "energy": runs[0]["energy"], "repeats": repeat, "status": "ok"}


def main(bench_args, extra):
    ap = argparse.ArgumentParser(prog="run/bench --nohier")
    ap.add_argument("--nohier-n2", default=None, help="squares per side of the Gmsh files (default 1024, --quick 64)")
    args, extra = ap.parse_known_args(extra)
    sizes = launch.list_option(ap, "--nohier-n2", args.nohier_n2 or ("64" if bench_args.quick else "1024"), convert=launch.count)
    elements = bench_args.elements.split(",")
    rows = []
    for N in sizes:
        msh = os.path.join(bench_args.out, "paper-5.1-N%d.msh" % N)
        subprocess.run([sys.executable, os.path.join(ROOT, "run", "gmsh_box.py"), str(N), msh], check=True)
        try:
            rows += [case(e, N, msh, bench_args.ranks, bench_args.repeat, bench_args.out, extra) for e in elements]
        finally:
            os.remove(msh)
    note = "; medians of %d runs" % bench_args.repeat if bench_args.repeat > 1 else ""
    print("\nfine mesh without a hierarchy: paper-5.1 from a Gmsh file, no -refine (%d rank%s%s); target contact solve / linear solve <= %g"
          % (bench_args.ranks, "s" if bench_args.ranks > 1 else "", note, TARGET))
    print("%-4s %5s %10s %6s %5s %6s %6s %9s %9s  %s" % ("elem", "N", "DOFs", "Newton", "KSP", "set-up", "re-use", "solve", "linear", "solve / linear"))
    for r in rows:
        if r["status"] != "ok":
            print("%-4s %5d  %s" % (r["element"], r["N"], r["status"]))
            continue
        print("%-4s %5d %10d %6d %5d %6d %6d %9.3f %9.3f  %.2f %s %g" % (r["element"], r["N"], r["dofs"], r["newton"], r["ksp"], r["amg_setups"], r["amg_reuses"],
                                                                       r["solve_s"], r["linear_s"], r["ratio"], "<=" if r["ratio"] <= TARGET else ">", TARGET))
    if launch.nothing_succeeded(rows, bench_args.out, ["nohier.csv"]):
        return 1
    path = os.path.join(bench_args.out, "nohier.csv")
    keys = ["element", "N", "dofs", "newton", "ksp", "amg_setups", "amg_reuses", "solve_s", "linear_s", "ratio", "energy", "repeats", "status"]
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
    os.replace(path + ".tmp", path)
    print("\nwrote %s" % path)
    return 1 if any(r["status"] != "ok" for r in rows) else 0

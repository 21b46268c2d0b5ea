"""`run/bench --estimate`: what error control costs, as ratios measured within one run, against issue 17's targets.

  run/bench --estimate [--quick] [--dims 2,3] [--elements cr,p1] [--ranks P] [--repeat K] [--out DIR]
                       [--est-n2 1024] [--est-n3 48] [--adapt-n2 512] [--adapt-n3 48] [--adapt-steps 3]
                       [--est-p1-n2 1024] [--est-p1-n3 100] [--adapt-p1-n2 1024] [--adapt-p1-n3 80]

1. The estimate: for every element, `-options_file petsc-options/SCENE -box_faces N -space E -log_view`
   (paper-5.1 at --est-n2 in 2D, paper-5.1-3d at --est-n3 in 3D; P1 at --est-p1-n2 / --est-p1-n3, so that it
   too has about 1 M DOFs) and the ratio of its Estimate stage to its
   Solve stage (the -log_view stages; the summary's "time" holds the same clocks). Target: <= 10 %.
2. Adaptive refinement: the same scenes with -adapt_steps K (for every element: CR from --adapt-n2 / --adapt-n3,
   P1 from --adapt-p1-n2 / --adapt-p1-n3, where its steps too pass 1 M DOFs: P1 has a third of CR's DOFs per
   cell in 2D, a twelfth in 3D; from 3D N = 80 its third mesh holds 23 M cells, about 15 GB) and, for every
   step that goes on to a next mesh, the overhead (estimate + mark + refine + redistribute + transfer, the
   summary's "adapt" rows) over that step's solve. Target: <= 50 % at 1 M DOFs and more (smaller steps are
   shown, marked "below 1 M DOFs").
--quick: small sizes (2D 128 and 64, 3D 12; P1 2D 128, 3D 24), a few seconds each. With --repeat K every case runs K times and
each ratio is the median of the K runs' ratios (each from one run). Each run's summary JSON and -log_view are
kept in DIR; the rows go to DIR/estimate-cost.csv and DIR/adapt-overhead.csv. Other options go to signorini."""
import argparse
import csv
import os
import statistics

import launch

ESTIMATE_TARGET, ADAPT_TARGET, MIN_DOFS = 0.10, 0.50, 1000000
OVERHEAD = ["estimate", "mark", "refine", "redistribute", "transfer"]


def scene(dim):
    return "paper-5.1" if dim == 2 else "paper-5.1-3d"


def run(dim, element, N, ranks, out, tag, extra):
    """One run of the command a user types, its summary and -log_view kept under `tag`; None if it failed."""
    return launch.run_kept(launch.scene(scene(dim)) + ["-box_faces", str(N), "-space", element] + list(extra), ranks, out, tag)


def estimate_case(dim, element, N, ranks, repeat, out, extra):
    runs = []
    for k in range(repeat):
        s = run(dim, element, N, ranks, out, "estimate-%dd-%s-N%d-np%d-run%d" % (dim, element, N, ranks, k + 1), extra)
        if s is None:
            return {"dim": dim, "element": element, "N": N, "status": "failed"}
        runs.append(s)
    med = lambda f: statistics.median(f(s) for s in runs)
    return {"dim": dim, "element": element, "N": N, "dofs": runs[0]["dofs"], "solve_s": med(lambda s: s["time"]["solve"]),
            "estimate_s": med(lambda s: s["time"]["estimate"]), "ratio": med(lambda s: s["time"]["estimate"] / s["time"]["solve"]),
            "repeats": repeat, "status": "ok"}


def step_overhead(a):
    return sum(a[k + "_seconds"] for k in OVERHEAD)


def adapt_case(dim, element, N, steps, ranks, repeat, out, extra):
    """One row per step that goes on to a next mesh (the last step has no overhead to speak of)."""
    runs = []
    for k in range(repeat):
        s = run(dim, element, N, ranks, out, "adapt-%dd-%s-N%d-np%d-run%d" % (dim, element, N, ranks, k + 1), ["-adapt_steps", str(steps)] + list(extra))
        if s is None or "adapt" not in s:
            return [{"dim": dim, "element": element, "N": N, "step": 0, "status": "failed"}]
        runs.append(s)
    rows = []
    for step in range(min(len(s["adapt"]) for s in runs) - 1):
        med = lambda f: statistics.median(f(s["adapt"][step]) for s in runs)
        row = {"dim": dim, "element": element, "N": N, "step": step, "dofs": runs[0]["adapt"][step]["dofs"], "solve_s": med(lambda a: a["solve_seconds"])}
        for k in OVERHEAD:
            row[k + "_s"] = med(lambda a: a[k + "_seconds"])
        row.update({"overhead_s": med(step_overhead), "ratio": med(lambda a: step_overhead(a) / a["solve_seconds"]), "repeats": repeat, "status": "ok"})
        rows.append(row)
    return rows


def verdict(ratio, target, applies=True):
    if not applies:
        return "%.3f (below 1 M DOFs)" % ratio
    return "%.3f %s %.2f" % (ratio, "<=" if ratio <= target else ">  MISSED", target)


def write_csv(rows, path):
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)
    os.replace(path + ".tmp", path)


def main(bench_args, extra):
    ap = argparse.ArgumentParser(prog="run/bench --estimate")
    ap.add_argument("--est-n2", type=launch.count, default=None, help="2D cells per side of the estimate runs (default 1024, --quick 128)")
    ap.add_argument("--est-n3", type=launch.count, default=None, help="3D cells per side of the estimate runs (default 48, --quick 12)")
    ap.add_argument("--adapt-n2", type=launch.count, default=None, help="2D cells per side of the first adaptive mesh (default 512, --quick 64)")
    ap.add_argument("--adapt-n3", type=launch.count, default=None, help="3D cells per side of the first adaptive mesh (default 48, --quick 12)")
    ap.add_argument("--est-p1-n2", type=launch.count, default=None, help="2D cells per side of P1's estimate run (default 1024, --quick 128)")
    ap.add_argument("--est-p1-n3", type=launch.count, default=None, help="3D cells per side of P1's estimate run (default 100, --quick 24)")
    ap.add_argument("--adapt-p1-n2", type=launch.count, default=None, help="2D cells per side of P1's first adaptive mesh (default 1024, --quick 128)")
    ap.add_argument("--adapt-p1-n3", type=launch.count, default=None, help="3D cells per side of P1's first adaptive mesh (default 80, --quick 24)")
    ap.add_argument("--adapt-steps", type=launch.count, default=None, help="adaptive refinements (default 3 in 2D, 2 in 3D; --quick 1)")
    args, extra = ap.parse_known_args(extra)
    quick = bench_args.quick
    n = {("cr", 2): args.est_n2 or (128 if quick else 1024), ("cr", 3): args.est_n3 or (12 if quick else 48),
         ("p1", 2): args.est_p1_n2 or (128 if quick else 1024), ("p1", 3): args.est_p1_n3 or (24 if quick else 100)}
    na = {("cr", 2): args.adapt_n2 or (64 if quick else 512), ("cr", 3): args.adapt_n3 or (12 if quick else 48),
          ("p1", 2): args.adapt_p1_n2 or (128 if quick else 1024), ("p1", 3): args.adapt_p1_n3 or (24 if quick else 80)}
    steps = {d: args.adapt_steps or (1 if quick else (3 if d == 2 else 2)) for d in (2, 3)}
    dims, elements = [int(d) for d in bench_args.dims.split(",")], bench_args.elements.split(",")
    est = [estimate_case(d, e, n[(e, d)], bench_args.ranks, bench_args.repeat, bench_args.out, extra) for d in dims for e in elements]
    ada = [r for d in dims for e in elements for r in adapt_case(d, e, na[(e, d)], steps[d], bench_args.ranks, bench_args.repeat, bench_args.out, extra)]
    note = "; medians of %d runs" % bench_args.repeat if bench_args.repeat > 1 else ""
    print("\nestimate cost: Estimate stage / Solve stage of one run (-log_view; %d rank%s%s), target <= %.0f %% at >= 1 M DOFs" % (bench_args.ranks, "s" if bench_args.ranks > 1 else "", note, 100 * ESTIMATE_TARGET))
    print("%-3s %-4s %5s %10s %9s %9s  %s" % ("dim", "elem", "N", "DOFs", "solve", "estimate", "estimate / solve"))
    for r in est:
        if r["status"] != "ok":
            print("%-3s %-4s %5d  %s" % ("%dD" % r["dim"], r["element"], r["N"], r["status"]))
            continue
        print("%-3s %-4s %5d %10d %9.3f %9.3f  %s" % ("%dD" % r["dim"], r["element"], r["N"], r["dofs"], r["solve_s"], r["estimate_s"], verdict(r["ratio"], ESTIMATE_TARGET, r["dofs"] >= MIN_DOFS)))
    print("\nadaptive overhead per step: (%s) / the step's solve, target <= %.0f %% at >= 1 M DOFs" % (" + ".join(OVERHEAD), 100 * ADAPT_TARGET))
    print("%-3s %-4s %5s %4s %10s %9s" % ("dim", "elem", "N", "step", "DOFs", "solve") + "".join("%9s" % k[:8] for k in OVERHEAD) + " %9s  %s" % ("overhead", "overhead / solve"))
    for r in ada:
        if r["status"] != "ok":
            print("%-3s %-4s %5d %4d  %s" % ("%dD" % r["dim"], r["element"], r["N"], r["step"], r["status"]))
            continue
        text = "%-3s %-4s %5d %4d %10d %9.3f" % ("%dD" % r["dim"], r["element"], r["N"], r["step"], r["dofs"], r["solve_s"])
        text += "".join("%9.3f" % r[k + "_s"] for k in OVERHEAD) + " %9.3f  " % r["overhead_s"]
        print(text + verdict(r["ratio"], ADAPT_TARGET, r["dofs"] >= MIN_DOFS))
    if not launch.nothing_succeeded(est + ada, bench_args.out, ["estimate-cost.csv", "adapt-overhead.csv"]):
        write_csv(est, os.path.join(bench_args.out, "estimate-cost.csv"))
        write_csv(ada, os.path.join(bench_args.out, "adapt-overhead.csv"))
        print("\nwrote %s and %s" % (os.path.join(bench_args.out, "estimate-cost.csv"), os.path.join(bench_args.out, "adapt-overhead.csv")))
    return 1 if any(r["status"] != "ok" for r in est + ada) else 0

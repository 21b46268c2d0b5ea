"""Benchmark: cost of every stage, per DOF, for P1 and CR on growing meshes, with the contact (VI) solve
compared with one plain CG + BoomerAMG solve of the same operator measured in the same run.

  run/bench [--dims 2,3] [--elements p1,cr] [--n2 256,512,1024,2048] [--n3 12,24,48,96] [--ranks P]
            [--presets] [--repeat K] [--out DIR] [signorini options...]
  run/bench --quick            # small sizes only (a minute): checks that everything runs
  run/bench --peer dolfinx     # whole process against dolfinx on the same discrete problem (run/peer.py)
  run/bench --estimate         # estimate / solve and adaptive overhead / solve per step (run/bench_estimate.py)
  run/bench --error            # exact-error integration / solve on the manufactured scenes
  run/bench --nohier           # contact / linear solve on a Gmsh file without a hierarchy (run/bench_nohier.py)

Scenes: paper-5.1 in 2D (N x N squares), paper-5.1-3d in 3D (N x N x N cubes, 6 tetrahedra each).
Each run's summary JSON and -log_view are kept in DIR (default results/bench). Prints one row per run:
DOFs, Newton steps on the finest level (and in all levels of nested iteration), KSP iterations, the
-log_view stages, set-up (mesh + distribute + refine + setup + assemble), the ratio VI solve / linear
solve, microseconds per DOF (set-up + solve) and bytes per DOF (peak RSS summed over ranks, and PETSc's own
malloc peak, which leaves out hypre's and the application's allocations); then the
targets of issue 18 (contact solve, set-up and memory) with the measured figures. Writes bench.csv and time-per-dof.png.
With --presets, also runs every option file of petsc-options/solvers on one mid-size mesh per dimension.
Before the first run the free memory is touched once (see warm_memory; --no-warm-memory skips it), and each
timed solve starts with the memory freed before it given back to the system (-compare_linear), so that the
contact solve and the linear solve it is compared with start alike. On a shared or noisy machine, --repeat K
runs every case K times and reports the median of each time and of the K ratios (each from one run) and
the largest memory; each run's JSON and log are kept (NAME-runK)."""
import argparse
import csv
import glob
import os
import statistics
import subprocess
import sys

import launch
from launch import ROOT, count, list_option

STAGES = ["mesh", "distribute", "refine", "setup", "assemble", "solve"]
SETUP = ["mesh", "distribute", "refine", "setup", "assemble"]


def mesh_args(dim, N):
    """The coarse box is built on one rank with 8 (2D) or 6 (3D) cells per side and refined in parallel;
    an N that is not such a multiple of a power of 2 is built directly."""
    base, refine = (8 if dim == 2 else 6), 0
    while (base << (refine + 1)) <= N:
        refine += 1
    if base << refine != N:
        base, refine = N, 0
    return ["-box_faces", str(base), "-refine", str(refine)]


WARM_CHILD = """
import sys
n, page = int(sys.argv[1]), 4096
for _ in range(n):
    b = bytearray(1 << 30)
    b[::page] = b"\\1" * ((1 << 30) // page)  # one write per page: the kernel must back every page
    del b
"""


def warm_memory():
    """Touches the free memory once, in a child process, before anything is timed. On a virtual machine
    the host backs a guest page only when it is first touched, which costs several times more than the
    kernel's own zeroing (measured on the 2-core development VM: a contact solve at 3.1 M DOFs took
    10.9 s before and 8.5 s after); without this, whichever run first reaches a new memory high-water
    mark pays for it, and the figures depend on the order of the runs. Costs a few seconds per GB."""
    try:
        with open("/proc/meminfo") as f:
            info = {l.split(":")[0]: int(l.split()[1]) for l in f if l.split()}
        gb = max(0, info.get("MemAvailable", 0) // (1 << 20) - 1)
    except (OSError, ValueError):
        return
    if gb > 0:
        print("warming %d GB of free memory (--no-warm-memory skips this)" % gb, flush=True)
        subprocess.run([sys.executable, "-c", WARM_CHILD, str(gb)], check=False)


def run_case(dim, element, N, ranks, out_dir, extra, preset=None, repeat=1):
    """One row per case; with repeat > 1 the case runs that many times and the row holds the median of each
    time and of each run's VI / linear ratio (every ratio still measured within one run), and the largest
    peak memory, so that one run disturbed by the machine does not decide a figure."""
    runs = [run_once(dim, element, N, ranks, out_dir, extra, preset, "-run%d" % (k + 1) if repeat > 1 else "") for k in range(repeat)]
    failed = [r for r in runs if r["status"] != "ok"]
    if failed:
        return failed[0]
    return runs[0] if repeat == 1 else median_row(runs)


def median_row(runs):
    row = dict(runs[0])
    for k in [k + "_s" for k in STAGES] + ["setup_total_s", "linear_s", "ratio", "us_per_dof"]:
        values = [r[k] for r in runs if r[k] is not None]
        row[k] = statistics.median(values) if values else None
    for k in ["bytes_per_dof", "petsc_bytes_per_dof"]:
        values = [r[k] for r in runs if r[k] is not None]
        row[k] = max(values) if values else None
    row["repeats"] = len(runs)
    return row


def run_once(dim, element, N, ranks, out_dir, extra, preset, suffix):
    scene = "paper-5.1" if dim == 2 else "paper-5.1-3d"
    tag = "%dd-%s-N%d-np%d%s%s" % (dim, element, N, ranks, "-" + os.path.basename(preset) if preset else "", suffix)
    args = launch.scene(scene) + ["-space", element] + mesh_args(dim, N)
    if preset:
        args += ["-options_file", preset]
    # -malloc_dump switches on PETSc's tracing allocator (cheap without -malloc_debug), so the summary holds
    # PETSc's own malloc peak next to the peak RSS; it also reports any PETSc object the run leaks.
    s = launch.run_kept(args + ["-compare_linear", "-malloc_dump"] + list(extra), ranks, out_dir, tag)
    if s is None:
        return {"scene": scene, "dim": dim, "element": element, "N": N, "ranks": ranks, "preset": os.path.basename(preset) if preset else "default", "status": "failed"}
    return row_from_summary(s, dim, element, N, ranks, preset)


def row_from_summary(s, dim, element, N, ranks, preset):
    solver, t = s["solver"], s["time"]
    setup = sum(t.get(k, 0.0) for k in SETUP)
    dofs = s["dofs"]
    memory = s.get("memory", {})
    rss, petsc = memory.get("peak_rss_bytes_sum"), memory.get("petsc_malloc_peak_bytes")
    row = {
        "scene": s["scene"], "dim": dim, "element": element, "N": N, "ranks": ranks,
        "preset": os.path.basename(preset) if preset else "default", "dofs": dofs,
        "newton": solver.get("newton_iterations"), "newton_total": solver.get("newton_iterations_total", solver.get("newton_iterations")),
        "ksp": solver.get("ksp_iterations_total", solver.get("ksp_iterations")), "reason": solver.get("converged_reason"),
        "setup_total_s": setup, "solve_s": t["solve"], "linear_s": solver.get("linear_solve_seconds"),
        "ratio": solver.get("solve_linear_ratio"), "energy": s.get("energy"),
        "us_per_dof": 1e6 * (setup + t["solve"]) / dofs,
        "bytes_per_dof": rss / dofs if rss else None,
        "petsc_bytes_per_dof": petsc / dofs if petsc else None,
        "matrix_bytes_per_dof": memory.get("matrix_bytes") / dofs if memory.get("matrix_bytes") else None,
        "repeats": 1, "status": "ok",
    }
    for k in STAGES:
        row[k + "_s"] = t.get(k, 0.0)
    return row


def cell(v, spec, width):
    return (format(v, spec) if isinstance(v, (int, float)) and v is not None else "-").rjust(width)


def header():
    head = "%-3s %-4s %-13s %5s %10s %6s %5s %6s" % ("dim", "elem", "preset", "N", "DOFs", "Newton", "all", "KSP")
    return head + "".join("%9s" % k[:8] for k in STAGES) + "%9s %9s %6s %8s %8s %8s  %s" % ("set-up", "linear", "VI/lin", "us/DOF", "B/DOF", "PETSc B", "status")


def line(r):
    text = "%-3s %-4s %-13s %5d" % ("%dD" % r["dim"], r["element"], r.get("preset", "default")[:13], r["N"])
    if r["status"] != "ok":
        return text + "  " + r["status"]
    text += cell(r["dofs"], "d", 11) + cell(r["newton"], "d", 7) + cell(r["newton_total"], "d", 6) + cell(r["ksp"], "d", 7)
    text += "".join(cell(r[k + "_s"], ".3f", 9) for k in STAGES)
    text += cell(r["setup_total_s"], ".3f", 9) + cell(r["linear_s"], ".3f", 10) + cell(r["ratio"], ".2f", 7)
    return text + cell(r["us_per_dof"], ".2f", 9) + cell(r["bytes_per_dof"], ".0f", 9) + cell(r.get("petsc_bytes_per_dof"), ".0f", 9) + "  " + r["status"]


def print_table(rows):
    print(header())
    for r in rows:
        print(line(r))


def print_targets(rows):
    """Issue 18's targets against what was measured (default solver only): the contact solve no dearer than
    one CG + BoomerAMG solve of the same operator (2D N >= 256, 3D N >= 24), at most 400 B of resident memory
    per CR DOF at the largest sizes, and the set-up no dearer than the linear solve. The peer ratio is
    `--peer dolfinx`, the error stage `--error`, and the 2-rank efficiency run/scaling."""
    ok = [r for r in rows if r["status"] == "ok" and r.get("preset", "default") == "default"]
    if not ok:
        return
    print("\ntargets (default solver):")
    for r in ok:
        checks = []
        if r["ratio"] is not None and r["N"] >= (256 if r["dim"] == 2 else 24):
            checks.append("VI/linear %.2f %s 1.0" % (r["ratio"], "<=" if r["ratio"] <= 1.0 else ">"))
        if r["linear_s"]:
            checks.append("set-up/linear %.2f %s 1" % (r["setup_total_s"] / r["linear_s"], "<=" if r["setup_total_s"] <= r["linear_s"] else ">"))
        if r["bytes_per_dof"] and r["element"] == "cr":
            checks.append("%.0f B/DOF %s 400 (PETSc's own mallocs %s)" % (r["bytes_per_dof"], "<=" if r["bytes_per_dof"] <= 400 else ">", "%.0f" % r["petsc_bytes_per_dof"] if r.get("petsc_bytes_per_dof") else "-"))
        print("  %dD %s N=%-5d %9d DOFs: %s" % (r["dim"], r["element"], r["N"], r["dofs"], "; ".join(checks)))


ERROR_CASES = [("manufactured-3d", "p1", 3), ("manufactured-3d", "cr", 3), ("manufactured-2d", "p1", 5), ("manufactured-2d", "cr", 5)]


def error_cost(ranks, out_dir, extra, quick=False):
    """The exact-error integration against the contact solve of the same run (target: error stage <= solve
    stage), on the manufactured scenes whose exact solution is integrated with a high-degree rule; --quick
    refines twice less."""
    print("error integration (target: Error stage <= Solve stage):")
    failed = 0
    for scene, element, refine in ERROR_CASES:
        mesh = ["-refine", str(refine - 2 if quick else refine)]
        s = launch.run_kept(launch.scene(scene) + ["-space", element] + mesh + list(extra), ranks, out_dir, "error-%s-%s-np%d" % (scene, element, ranks))
        if s is None:
            print("  %-16s %-3s failed" % (scene, element))
            failed += 1
            continue
        t = s["time"]
        ratio = t["error"] / t["solve"]
        print("  %-16s %-3s %s %9d DOFs: error %.3f s, solve %.3f s, error/solve %.2f %s 1" % (scene, element, " ".join(mesh), s["dofs"], t["error"], t["solve"], ratio, "<=" if ratio <= 1 else ">"))
    return 1 if failed else 0


def write_csv(rows, path):
    keys = ["scene", "dim", "element", "preset", "N", "ranks", "dofs", "newton", "newton_total", "ksp", "reason"] + [k + "_s" for k in STAGES]
    keys += ["setup_total_s", "linear_s", "ratio", "us_per_dof", "bytes_per_dof", "petsc_bytes_per_dof", "matrix_bytes_per_dof", "energy", "repeats", "status"]
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)
    os.replace(tmp, path)


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for dim in (2, 3):
        for element, marker in (("p1", "o"), ("cr", "s")):
            rs = [r for r in rows if r["status"] == "ok" and r["dim"] == dim and r["element"] == element and r.get("preset", "default") == "default"]
            if not rs:
                continue
            rs.sort(key=lambda r: r["dofs"])
            style = "-" if dim == 2 else "--"
            ax.loglog([r["dofs"] for r in rs], [r["us_per_dof"] for r in rs], marker + style, label="%dD %s, set-up + solve" % (dim, element.upper()))
            ax.loglog([r["dofs"] for r in rs], [1e6 * r["solve_s"] / r["dofs"] for r in rs], marker + ":", alpha=0.6, label="%dD %s, solve only" % (dim, element.upper()))
    ax.set_xlabel("DOFs")
    ax.set_ylabel("time per DOF [us]")
    ax.set_title("signorini: time per DOF (%d rank%s)" % (rows[0]["ranks"], "s" if rows[0]["ranks"] > 1 else ""))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    save_png(fig, path)


def save_png(fig, path):
    """Writes a matplotlib figure to path through a temporary name, so no half-written plot is left."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path + ".tmp.png", dpi=120)
    plt.close(fig)
    os.replace(path + ".tmp.png", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dims", default="2,3")
    ap.add_argument("--elements", default="p1,cr")
    ap.add_argument("--n2", default="256,512,1024,2048", help="2D cells per side")
    ap.add_argument("--n3", default="12,24,48,96", help="3D cells per side")
    ap.add_argument("--ranks", type=count, default=1)
    ap.add_argument("--presets", action="store_true", help="also run each petsc-options/solvers preset on a mid-size mesh")
    ap.add_argument("--quick", action="store_true", help="small sizes only")
    ap.add_argument("--out", default=os.path.join(ROOT, "results", "bench"))
    ap.add_argument("--repeat", type=count, default=1, help="run each case this many times and report medians (times, VI/linear) and the largest memory")
    ap.add_argument("--no-warm-memory", action="store_true", help="do not touch the free memory once before the runs (see warm_memory)")
    ap.add_argument("--peer", choices=["dolfinx"], help="instead: whole process against dolfinx on the same scene and mesh (run/peer.py: --peer-elements, --peer-n2, --peer-n3)")
    ap.add_argument("--error", action="store_true", help="instead: the exact-error integration against the solve on the manufactured scenes")
    ap.add_argument("--estimate", action="store_true", help="instead: the estimate's cost and the adaptive overhead per step, as ratios to the solve of the same run (run/bench_estimate.py: --est-n2, --est-n3, --adapt-n2, --adapt-n3, --est-p1-n2, --est-p1-n3, --adapt-p1-n2, --adapt-p1-n3, --adapt-steps)")
    ap.add_argument("--nohier", action="store_true", help="instead: contact solve / linear solve on a fine Gmsh file read without -refine (run/bench_nohier.py: --nohier-n2)")
    args, extra = ap.parse_known_args()
    if args.quick:
        args.n2, args.n3 = "64,128", "12,24"
    dims = list_option(ap, "--dims", args.dims, [2, 3], int)
    elements = list_option(ap, "--elements", args.elements, ["p1", "cr"])
    sizes = {2: list_option(ap, "--n2", args.n2, convert=count), 3: list_option(ap, "--n3", args.n3, convert=count)}
    launch.output_folder(ap, "--out", args.out)
    if not args.no_warm_memory:
        warm_memory()
    if args.peer:
        import peer

        return peer.main(args, extra)
    if args.error:
        return error_cost(args.ranks, args.out, extra, args.quick)
    if args.estimate:
        import bench_estimate

        return bench_estimate.main(args, extra)
    if args.nohier:
        import bench_nohier

        return bench_nohier.main(args, extra)
    rows = []
    print(header(), flush=True)
    for dim in dims:
        for element in elements:
            for N in sizes[dim]:
                rows.append(run_case(dim, element, N, args.ranks, args.out, extra, repeat=args.repeat))
                print(line(rows[-1]), flush=True)
    if args.presets:
        presets = sorted(glob.glob(os.path.join(ROOT, "petsc-options", "solvers", "*")))
        for dim in dims:
            N = sizes[dim][len(sizes[dim]) // 2 - 1] if len(sizes[dim]) > 1 else sizes[dim][0]
            for element in elements:
                for preset in presets:
                    rows.append(run_case(dim, element, N, args.ranks, args.out, extra, preset, args.repeat))
                    print(line(rows[-1]), flush=True)
    print("\nsummary (%d rank%s; times in seconds from the -log_view stages%s):" % (args.ranks, "s" if args.ranks > 1 else "", "; medians of %d runs each" % args.repeat if args.repeat > 1 else ""))
    print_table(rows)
    print_targets(rows)
    if not launch.nothing_succeeded(rows, args.out, ["bench.csv", "time-per-dof.png"]):
        write_csv(rows, os.path.join(args.out, "bench.csv"))
        plot(rows, os.path.join(args.out, "time-per-dof.png"))
        print("\nwrote %s and %s" % (os.path.join(args.out, "bench.csv"), os.path.join(args.out, "time-per-dof.png")))
    return 1 if any(r["status"] != "ok" for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())

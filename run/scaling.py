"""Strong and weak scaling studies with mpirun: efficiency tables and plots, each run's -log_view kept.

  run/scaling [--ranks 1,2,4,...] [--max-ranks P] [--dim 2|3] [--element cr|p1] [--strong-n N] [--weak-n N]
              [--kind strong,weak] [--mpiexec "mpirun"] [--mpiexec-args "..."] [--out DIR] [signorini options...]

Strong scaling: one fixed mesh (the paper's scene, N x N cells in 2D or N^3 cubes in 3D) on 1, 2, 4, ... P
ranks. Weak scaling: a fixed number of DOFs per rank: with p ranks the domain is p unit squares (cubes) side
by side in x, each with N x N cells, so the mesh, the data (f is 1-periodic in x) and the cells per rank do
not change. P defaults to the cores of this machine; on a cluster, run the script inside a batch job and
give --max-ranks (or --ranks) and --mpiexec (e.g. "srun", or "mpirun --bind-to core"); the script only builds
command lines. Efficiency: strong T(1) / (p T(p)), weak T(1) / T(p), from the solve stage, from the
whole run (set-up + solve), and, as the reference the machine allows, from one CG + BoomerAMG solve of the
same operator in the same run (-compare_linear). Right before each run, signorini-stream measures the
memory bandwidth BW (STREAM triad) of its rank count with the same mpiexec; BW(p) / (p BW(1)) is printed as
the ceiling of the efficiency of a solve limited by memory bandwidth, as CG + BoomerAMG is (--no-stream
skips it)."""
import argparse
import csv
import os
import re
import sys

import launch
from bench import SETUP, mesh_args, save_png, warm_memory
from launch import ROOT, count, list_option


def mpiexec(args):
    """The launcher with its arguments, as one string for launch.command."""
    return args.mpiexec + " " + args.mpiexec_args


def bandwidth(args, ranks):
    """STREAM triad bandwidth of `ranks` ranks together in GB/s (None on failure)."""
    r = launch.run([], ranks, exe=launch.STREAM_EXE, mpiexec=mpiexec(args))
    m = re.search(r"triad bandwidth: ([0-9.]+) GB/s", r.stdout)
    if r.returncode != 0 or not m:
        sys.stderr.write(" ".join(r.cmd) + "\n" + r.stdout + r.stderr)
        return None
    return float(m.group(1))


def efficiencies(rows, strong):
    """Efficiency against the first run that worked (base b): strong T(b) b / (T(p) p), weak T(b) / T(p); and
    the ceiling a solve limited by memory bandwidth can reach, (BW(p) / p) / (BW(b) / b), the same for both
    kinds (in both, each rank's share of the work is done at its share of the bandwidth)."""
    base = next((r for r in rows if r["status"] == "ok"), None)
    for r in rows:
        if base and r["status"] == "ok":
            scale = base["ranks"] / r["ranks"] if strong else 1.0
            for k in ["solve", "total", "linear"]:
                r["eff_" + k] = base[k + "_s"] * scale / r[k + "_s"]
            if r.get("bw_gbs") and base.get("bw_gbs"):
                r["eff_ceiling"] = (r["bw_gbs"] / r["ranks"]) / (base["bw_gbs"] / base["ranks"])


def solve(args, ranks, options, tag):
    """Runs signorini on `ranks` ranks; returns its summary dict (None on failure)."""
    summary, log = os.path.join(args.out, tag + ".json"), os.path.join(args.out, tag + ".log")
    r = launch.run(options + ["-compare_linear", "-log_view", ":" + log], ranks, summary=summary, mpiexec=mpiexec(args))
    if r.returncode != 0 or r.summary is None:
        sys.stderr.write(" ".join(r.cmd) + "\n" + r.stdout + r.stderr)
        return None
    return r.summary


def scene_options(dim, element):
    scene = "paper-5.1" if dim == 2 else "paper-5.1-3d"
    return launch.scene(scene) + ["-space", element]


def times(s):
    t = s["time"]
    return t["solve"], sum(t.get(k, 0.0) for k in SETUP) + t["solve"]


def strong(args, extra):
    rows = []
    for p in args.ranks:
        opts = scene_options(args.dim, args.element) + mesh_args(args.dim, args.strong_n) + extra
        bw = None if args.no_stream else bandwidth(args, p)  # measured next to the run: a shared machine's bandwidth drifts
        s = solve(args, p, opts, "strong-%dd-%s-N%d-np%d" % (args.dim, args.element, args.strong_n, p))
        rows.append(row("strong", p, s, bw))
    efficiencies(rows, strong=True)
    return rows


def weak(args, extra):
    rows = []
    for p in args.ranks:
        mesh = mesh_args(args.dim, args.weak_n)
        base = int(mesh[1])
        faces = [str(base * p)] + [str(base)] * (args.dim - 1)
        upper = [str(p)] + ["1"] * (args.dim - 1)
        opts = scene_options(args.dim, args.element) + ["-box_faces", ",".join(faces), "-refine", mesh[3], "-box_upper", ",".join(upper)] + extra
        bw = None if args.no_stream else bandwidth(args, p)
        s = solve(args, p, opts, "weak-%dd-%s-N%d-np%d" % (args.dim, args.element, args.weak_n, p))
        rows.append(row("weak", p, s, bw))
    efficiencies(rows, strong=False)
    return rows


def row(kind, ranks, s, bw):
    if s is None:
        return {"kind": kind, "ranks": ranks, "status": "failed", "bw_gbs": bw}
    solve, total = times(s)
    per_rank = s.get("cells_per_rank", [])
    imbalance = max(per_rank) / (sum(per_rank) / len(per_rank)) if per_rank else 1.0
    return {"kind": kind, "ranks": ranks, "status": "ok", "dofs": s["dofs"], "newton": s["solver"]["newton_iterations"],
            "ksp": s["solver"].get("ksp_iterations_total", s["solver"]["ksp_iterations"]), "solve_s": solve, "total_s": total,
            "linear_s": s["solver"]["linear_solve_seconds"],
            "edge_cut": s.get("edge_cut", -1), "imbalance": imbalance, "energy": s["energy"], "bw_gbs": bw}


def print_rows(title, rows):
    print("\n%s" % title)
    print("%6s %11s %11s %6s %6s %9s %9s %9s %8s %8s %8s %8s %8s %9s %9s" % ("ranks", "DOFs", "DOFs/rank", "Newton", "KSP", "solve[s]", "total[s]", "linear[s]", "eff(sol)", "eff(tot)", "eff(lin)", "BW[GB/s]", "ceiling", "edge cut", "imbalance"))
    for r in rows:
        if r["status"] != "ok":
            print("%6d  failed" % r["ranks"])
            continue
        bw = "%8.2f" % r["bw_gbs"] if r.get("bw_gbs") else "%8s" % "-"
        ceiling = "%7.0f%%" % (100 * r["eff_ceiling"]) if "eff_ceiling" in r else "%8s" % "-"
        print("%6d %11d %11d %6d %6d %9.3f %9.3f %9.3f %7.0f%% %7.0f%% %7.0f%% %s %s %9d %9.3f" % (r["ranks"], r["dofs"], r["dofs"] // r["ranks"], r["newton"], r["ksp"], r["solve_s"], r["total_s"], r["linear_s"],
                                                                                                100 * r.get("eff_solve", 0), 100 * r.get("eff_total", 0), 100 * r.get("eff_linear", 0), bw, ceiling, r["edge_cut"], r["imbalance"]))


def write_csv(rows, path):
    keys = ["kind", "ranks", "dofs", "newton", "ksp", "solve_s", "total_s", "linear_s", "eff_solve", "eff_total", "eff_linear", "bw_gbs", "eff_ceiling", "edge_cut", "imbalance", "energy", "status"]
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    os.replace(path + ".tmp", path)


def plot(results, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for kind, rows in results.items():
        ok = [r for r in rows if r["status"] == "ok"]
        if not ok:
            continue
        ps = [r["ranks"] for r in ok]
        axes[0].plot(ps, [r["solve_s"] for r in ok], "o-", label="%s: solve" % kind)
        axes[0].plot(ps, [r["total_s"] for r in ok], "s--", label="%s: set-up + solve" % kind)
        axes[1].plot(ps, [100 * r["eff_solve"] for r in ok], "o-", label="%s: solve" % kind)
        axes[1].plot(ps, [100 * r["eff_total"] for r in ok], "s--", label="%s: set-up + solve" % kind)
        axes[1].plot(ps, [100 * r["eff_linear"] for r in ok], "^:", label="%s: one linear solve" % kind)
        if all("eff_ceiling" in r for r in ok):
            axes[1].plot(ps, [100 * r["eff_ceiling"] for r in ok], "k" + ("--" if kind == "strong" else "-."), lw=0.8, label="%s: memory-bandwidth ceiling" % kind)
    if "strong" in results and any(r["status"] == "ok" for r in results["strong"]):
        ok = [r for r in results["strong"] if r["status"] == "ok"]
        axes[0].plot([r["ranks"] for r in ok], [ok[0]["solve_s"] * ok[0]["ranks"] / r["ranks"] for r in ok], "k:", label="ideal strong (solve)")
    axes[0].set_xscale("log", base=2)
    axes[0].set_yscale("log")
    axes[0].set_xlabel("ranks")
    axes[0].set_ylabel("time [s]")
    axes[1].set_xscale("log", base=2)
    axes[1].set_xlabel("ranks")
    axes[1].set_ylabel("parallel efficiency [%]")
    axes[1].axhline(100, color="k", lw=0.5)
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title)
    save_png(fig, path)


def print_target(results):
    """Issue 18's parallel target: on 2 (or more) ranks the solve's efficiency is at least 90 % of the
    memory-bandwidth ceiling measured right before it."""
    print("\ntarget: solve efficiency >= 90 % of the ceiling:")
    for kind, rows in results.items():
        for r in rows:
            if r["ranks"] > 1 and r["status"] == "ok" and "eff_ceiling" in r and "eff_solve" in r:
                share = r["eff_solve"] / r["eff_ceiling"]
                print("  %s, %d ranks: %.1f %% of a %.0f %% ceiling = %.0f %% %s 90 %%" % (kind, r["ranks"], 100 * r["eff_solve"], 100 * r["eff_ceiling"], 100 * share, ">=" if share >= 0.9 else "<"))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", help="comma-separated rank counts (default 1, 2, 4, ... up to --max-ranks)")
    ap.add_argument("--max-ranks", type=count, default=os.cpu_count() or 1)
    ap.add_argument("--dim", type=int, default=2, choices=(2, 3))
    ap.add_argument("--element", default="cr", choices=("cr", "p1"))
    ap.add_argument("--strong-n", type=count, help="cells per side of the strong-scaling mesh (default 2048 in 2D, 96 in 3D)")
    ap.add_argument("--weak-n", type=count, help="cells per side of each rank's unit square/cube (default 512 in 2D, 48 in 3D)")
    ap.add_argument("--kind", default="strong,weak")
    ap.add_argument("--mpiexec", default=os.environ.get("MPIEXEC", "mpirun"))
    ap.add_argument("--mpiexec-args", default="")
    ap.add_argument("--out", default=os.path.join(ROOT, "results", "scaling"))
    ap.add_argument("--no-stream", action="store_true", help="do not measure the memory bandwidth of each rank count (signorini-stream)")
    ap.add_argument("--no-warm-memory", action="store_true", help="do not touch the free memory once before the runs (a virtual machine's first touch is slow; see run/bench.py)")
    args, extra = ap.parse_known_args()
    args.kind = list_option(ap, "--kind", args.kind, ["strong", "weak"])
    if args.ranks:
        args.ranks = list_option(ap, "--ranks", args.ranks, convert=count)
    else:
        args.ranks = [1]
        while args.ranks[-1] * 2 <= args.max_ranks:
            args.ranks.append(args.ranks[-1] * 2)
        if args.ranks[-1] != args.max_ranks:
            args.ranks.append(args.max_ranks)
    args.strong_n = args.strong_n or (2048 if args.dim == 2 else 96)
    args.weak_n = args.weak_n or (512 if args.dim == 2 else 48)
    launch.output_folder(ap, "--out", args.out)
    if not args.no_warm_memory:
        warm_memory()
    results = {}
    title = "%dD %s, paper-5.1 scene" % (args.dim, args.element.upper())
    if "strong" in args.kind:
        results["strong"] = strong(args, extra)
        print_rows("strong scaling, %s, N = %d:" % (title, args.strong_n), results["strong"])
    if "weak" in args.kind:
        results["weak"] = weak(args, extra)
        print_rows("weak scaling, %s, N = %d per rank (domain [0, p] x [0, 1]):" % (title, args.weak_n), results["weak"])
    if not args.no_stream:
        print("\nceiling: STREAM bandwidth of p ranks / (p x that of one rank), the efficiency a solve that is limited by")
        print("memory bandwidth (CG + BoomerAMG) can reach on this machine; efficiencies above it come from work that is not.")
        print_target(results)
    rows = [r for rs in results.values() for r in rs]
    if launch.nothing_succeeded(rows, args.out, ["scaling.csv", "scaling.png"]):
        return 1
    write_csv(rows, os.path.join(args.out, "scaling.csv"))
    plot(results, os.path.join(args.out, "scaling.png"), title)
    print("\nwrote %s, %s and each run's -log_view (*.log) in %s" % (os.path.join(args.out, "scaling.csv"), os.path.join(args.out, "scaling.png"), args.out))
    return 1 if any(r["status"] != "ok" or (not args.no_stream and r.get("bw_gbs") is None) for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())

"""`run/bench --peer dolfinx`: signorini against a general FE framework on the paper's scene, whole process.

  run/bench --peer dolfinx [--quick] [--ranks P] [--repeat K] [--out DIR]
            [--peer-elements cr[,p1]] [--peer-n2 1024] [--peer-n3 64]

For every case (paper-5.1 in 2D at --peer-n2, paper-5.1-3d at --peer-n3; --quick: 128 and 16) it runs, K
times (default 3) and alternately, what a user types,
  signorini -options_file petsc-options/SCENE -box_faces N -space E
and run/peer_dolfinx.py, which solves the same discrete problem with dolfinx (see its docstring), each
timed from outside as a whole process. It fails loudly (exit status 1) unless both have the same number of
DOFs and energies J = 1/2 a(u,u) - l(u) equal to 1e-8 relative in every run. Prints the medians and the
ratio of the whole-process times dolfinx / signorini, with the issue's targets (>= 10 in 2D, >= 5 in 3D);
writes peer-dolfinx.csv in DIR. Debian's python3-dolfinx is installed first if /usr/bin/python3 cannot
import dolfinx. One untimed run of each at a small size first fills FFCx's cache of compiled forms (a
user's second run finds it there) and the page cache."""
import argparse
import csv
import os
import statistics
import subprocess
import sys

import launch
from launch import ROOT, list_option

PYTHON = "/usr/bin/python3"  # Debian's: the one python3-dolfinx installs into
SCRIPT = os.path.join(ROOT, "run", "peer_dolfinx.py")
ENERGY_RTOL = 1e-8


def ensure_dolfinx():
    """Installs Debian's python3-dolfinx when /usr/bin/python3 cannot import it."""
    if subprocess.run([PYTHON, "-c", "import dolfinx"], capture_output=True).returncode == 0:
        return
    print("installing Debian's python3-dolfinx (apt-get)", flush=True)
    sudo = [] if os.geteuid() == 0 else ["sudo"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    install = sudo + ["apt-get", "install", "-y", "python3-dolfinx"]
    if subprocess.run(install, env=env).returncode != 0:
        subprocess.run(sudo + ["apt-get", "update"], env=env, check=True)
        subprocess.run(install, env=env, check=True)


def run_signorini(dim, element, N, ranks, path):
    args = launch.scene("paper-5.1" if dim == 2 else "paper-5.1-3d") + ["-box_faces", str(N), "-space", element]
    r = launch.run(args, ranks, summary=path)
    if r.returncode != 0 or r.summary is None:
        raise RuntimeError("signorini failed (exit %d): %s\n%s" % (r.returncode, " ".join(r.cmd), r.stdout + r.stderr))
    s = r.summary
    return {"seconds": r.seconds, "energy": s["energy"], "dofs": s["dofs"], "newton": s["solver"].get("newton_iterations"),
            "ksp": s["solver"].get("ksp_iterations_total", s["solver"].get("ksp_iterations")), "solve": s["time"]["solve"],
            "setup": sum(s["time"].get(k, 0.0) for k in ("mesh", "distribute", "refine", "setup", "assemble"))}


def run_dolfinx(dim, element, N, ranks, path):
    args = [SCRIPT, "-dim", str(dim), "-box_faces", str(N), "-space", element]
    r = launch.run(args, ranks, summary=path, exe=PYTHON)
    if r.returncode != 0 or r.summary is None:
        raise RuntimeError("dolfinx peer failed (exit %d): %s\n%s" % (r.returncode, " ".join(r.cmd), r.stdout + r.stderr))
    s, t = r.summary, r.summary["time"]
    return {"seconds": r.seconds, "energy": s["energy"], "dofs": s["dofs"], "newton": s["newton_iterations"],
            "ksp": s["ksp_iterations_total"], "solve": t["solve"],
            "setup": t["mesh"] + t["space"] + t["forms"] + t["assemble"], "import": t["import"]}


def check_same_problem(a, b, what):
    """The two runs solved the same discrete problem: equal DOF counts, energies to ENERGY_RTOL."""
    rel = abs(a["energy"] - b["energy"]) / abs(a["energy"])
    if a["dofs"] != b["dofs"] or not rel <= ENERGY_RTOL:
        raise RuntimeError("%s: not the same discrete problem: signorini %d DOFs, J = %.15e; dolfinx %d DOFs, J = %.15e (relative difference %.2e > %g)"
                           % (what, a["dofs"], a["energy"], b["dofs"], b["energy"], rel, ENERGY_RTOL))
    return rel


def run_case(dim, element, N, ranks, repeat, out):
    what = "%dD %s N=%d" % (dim, element.upper(), N)
    runs, worst = {"signorini": [], "dolfinx": []}, 0.0
    for k in range(repeat):
        tag = os.path.join(out, "peer-%dd-%s-N%d-np%d-run%d" % (dim, element, N, ranks, k + 1))
        s = run_signorini(dim, element, N, ranks, tag + "-signorini.json")
        d = run_dolfinx(dim, element, N, ranks, tag + "-dolfinx.json")
        worst = max(worst, check_same_problem(s, d, what))
        runs["signorini"].append(s)
        runs["dolfinx"].append(d)
        print("  %s run %d: signorini %.2f s, dolfinx %.2f s (energies %.15e, %.15e)" % (what, k + 1, s["seconds"], d["seconds"], s["energy"], d["energy"]), flush=True)
    med = {who: {key: statistics.median(r[key] for r in rs) for key in ("seconds", "setup", "solve", "newton", "ksp")} for who, rs in runs.items()}
    return {"dim": dim, "element": element, "N": N, "ranks": ranks, "dofs": runs["signorini"][0]["dofs"], "repeats": repeat,
            "energy": runs["signorini"][0]["energy"], "energy_rel_diff": worst,
            **{"%s_%s" % (who, key): v for who, m in med.items() for key, v in m.items()},
            "ratio": med["dolfinx"]["seconds"] / med["signorini"]["seconds"]}


def print_rows(rows):
    print("\nwhole process (timed from outside), medians; set-up = mesh + spaces + assembly (dolfinx: + forms)")
    print("%-3s %-4s %5s %9s | %9s %8s %8s %4s %5s | %9s %8s %8s %4s %5s | %8s %9s" % (
        "dim", "elem", "N", "DOFs", "signorini", "set-up", "solve", "SNES", "KSP", "dolfinx", "set-up", "solve", "SNES", "KSP", "|dJ|/|J|", "dolfinx/s"))
    for r in rows:
        line = "%-3s %-4s %5d %9d" % ("%dD" % r["dim"], r["element"], r["N"], r["dofs"])
        for who in ("signorini", "dolfinx"):
            line += " | %9.2f %8.2f %8.2f %4d %5d" % tuple(r["%s_%s" % (who, k)] for k in ("seconds", "setup", "solve", "newton", "ksp"))
        print(line + " | %8.1e %9.2f" % (r["energy_rel_diff"], r["ratio"]))
    print("\ntargets (whole process, dolfinx / signorini):")
    for r in rows:
        goal = 10 if r["dim"] == 2 else 5
        print("  %dD %s N=%d: %.2f %s %d" % (r["dim"], r["element"], r["N"], r["ratio"], ">=" if r["ratio"] >= goal else "<", goal))


def main(bench_args, extra):
    ap = argparse.ArgumentParser(prog="run/bench --peer dolfinx")
    ap.add_argument("--peer-elements", default="cr", help="elements to compare (cr,p1)")
    ap.add_argument("--peer-n2", type=launch.count, default=None, help="2D cells per side (default 1024, --quick 128)")
    ap.add_argument("--peer-n3", type=launch.count, default=None, help="3D cells per side (default 64: about as many CR DOFs as 2D N = 1024; --quick 16)")
    args = ap.parse_args(extra)
    n2 = args.peer_n2 or (128 if bench_args.quick else 1024)
    n3 = args.peer_n3 or (16 if bench_args.quick else 64)
    dims = list_option(ap, "--dims", bench_args.dims, [2, 3], int)
    args.peer_elements = ",".join(list_option(ap, "--peer-elements", args.peer_elements, ["p1", "cr"]))
    repeat = bench_args.repeat if bench_args.repeat > 1 else 3
    ensure_dolfinx()
    try:
        for dim in dims:  # untimed: FFCx compiles the forms of each case once
            for element in args.peer_elements.split(","):
                tag = os.path.join(bench_args.out, "peer-warm")
                check_same_problem(run_signorini(dim, element, 8, 1, tag + "-s.json"), run_dolfinx(dim, element, 8, 1, tag + "-d.json"), "warm-up %dD %s N=8" % (dim, element))
        rows = []
        for dim in dims:
            for element in args.peer_elements.split(","):
                rows.append(run_case(dim, element, n2 if dim == 2 else n3, bench_args.ranks, repeat, bench_args.out))
    except RuntimeError as e:
        print("run/bench --peer dolfinx: FAILED: %s" % e, file=sys.stderr)
        return 1
    print_rows(rows)
    path = os.path.join(bench_args.out, "peer-dolfinx.csv")
    with open(path + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    os.replace(path + ".tmp", path)
    print("\nwrote %s" % path)
    return 0

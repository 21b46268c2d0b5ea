"""The main job: the paper's experiment (Hua & Wang, problem (5.1), Table 5.1) in one command.

1. paper-5.1 solved with P1 and CR for N = 2 ... 64 and compared with a P1 reference on N = 512, set up as the
   paper did: "\\" diagonals, the load integrated with the one-point centroid rule in every solve (the
   reference included), errors integrated exactly on the fine mesh, H1 = full norm sqrt(L2^2 + |.|_1,h^2).
   Our 24 numbers are printed beside the paper's with the relative difference of each, and beside them the
   estimate eta of the energy error and the efficiency index eta / (energy error against the reference).
2. The same study with the accurate load rule, for comparison.
3. The paper's scene by adaptive refinement (both elements, centroid rule, from N = 2 until the DOFs of
   N = 64), its errors against an adaptive reference a few steps further, and when it reaches the finest
   uniform error and estimate (run/compare.py).
4. Tables as CSV/JSON and plots (error against h, error and estimate against DOFs and run time, the adapted
   meshes) under results/.
Extra arguments go to signorini (e.g. --ranks 2 runs on 2 MPI ranks)."""
import argparse
import csv
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import launch  # noqa: E402 (after the path to run/)

PAPER_SLOPES = {("p1", "l2"): 1.89, ("cr", "l2"): 2.10, ("p1", "h1"): 0.98, ("cr", "h1"): 1.02}


def paper_table():
    with open(os.path.join(HERE, "paper-table-5.1.csv")) as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header, data = rows[0], rows[1:]
    table = {}
    for r in data:
        d = dict(zip(header, r))
        n = int(d["N"])
        table[("p1", n)] = (float(d["l2_cf"]), float(d["h1_cf"]))
        table[("cr", n)] = (float(d["l2_ncf"]), float(d["h1_ncf"]))
    return table


def slope(rows, element, norm):
    rs = [r for r in rows if r["element"] == element]
    e0, e1 = rs[0]["error_reference"][norm], rs[-1]["error_reference"][norm]
    return math.log(e0 / e1) / math.log(rs[0]["h"] / rs[-1]["h"])


def adaptive(study, options, out, ranks):
    """The adaptive runs of both elements beside the uniform study: their rows and when they reach the
    finest uniform error and estimate; the comparison files and plots in `out`."""
    import compare

    rows, summaries = compare.adaptive("paper-5.1", options, study, out, ranks)
    print("%4s %5s %8s %12s %12s %6s %8s" % ("elem", "step", "DOFs", "eta", "error", "eta/E", "time[s]"))
    for r in rows:
        print("%4s %4d%s %8d %12.4e %12s %6s %8.3f" % (r["element"], r["step"], "r" if r["reference_step"] else " ", r["dofs"], r["eta"],
                                                   "%.4e" % r["error"] if r["error"] is not None else "-", "%.2f" % r["efficiency"] if r["efficiency"] else "-", r["seconds"]))
    print("(error: energy norm against the last step r, the adaptive reference; time: the run so far; uniform: energy error against P1 N = 512, time of the run up to that level)")
    rows = compare.uniform_rows(study) + rows
    for line in compare.notes(rows) + compare.reach_lines(rows):
        print(line)
    compare.write(rows, out)
    compare.pictures(rows, summaries, out, "paper-5.1")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=launch.count, default=1)
    args, extra = ap.parse_known_args()
    from study import run_study

    base = ["-box_faces", "2", "-study_levels", "6", "-reference_refine", "3", "-reference_space", "p1"] + extra
    print("== paper-5.1 as in the paper: centroid load rule, P1 reference on N = 512")
    out1 = os.path.join(ROOT, "results", "paper-5.1-centroid")
    study = run_study("paper-5.1", base + ["-load_quadrature", "centroid"], out1, args.ranks)

    paper = paper_table()
    print("\nTable 5.1 reproduced (ours | paper | relative difference):")
    print("%4s %4s  %-38s  %-38s  %-11s %5s" % ("elem", "N", "L2 error", "H1 error (full norm)", "eta", "eta/E"))
    worst = 0.0
    for r in study["rows"]:
        key = (r["element"], r["N"])
        if key not in paper:
            continue
        ours = (r["error_reference"]["l2"], r["error_reference"]["h1"])
        cells = []
        for o, p in zip(ours, paper[key]):
            d = abs(o - p) / p
            worst = max(worst, d)
            cells.append("%.8f | %.8f | %.1e" % (o, p, d))
        # the estimate of the energy error and its efficiency index against the reference's energy error
        est = r.get("estimate", {})
        index = est["eta"] / r["error_reference"]["energy"] if "eta" in est else None
        print("%4s %4d  %-38s  %-38s  %-11s %5s" % (r["element"], r["N"], cells[0], cells[1], "%.5e" % est["eta"] if est else "-", "%.2f" % index if index else "-"))
    compared = sum(1 for r in study["rows"] if (r["element"], r["N"]) in paper)
    ok = compared == 12 and worst <= 1e-4
    print("%d entries compared, largest relative difference %.1e: %s" % (2 * compared, worst, "all agree to 1e-4" if ok else "MISMATCH"))
    print("\nAverage slopes N = 2 ... 64 (ours | paper):")
    for element in ["p1", "cr"]:
        print("  %s: L2 %.2f | %.2f   H1 %.2f | %.2f" % (element, slope(study["rows"], element, "l2"), PAPER_SLOPES[(element, "l2")], slope(study["rows"], element, "h1"), PAPER_SLOPES[(element, "h1")]))

    print("\n== the same study with the accurate load rule (degree-4 quadrature), for comparison")
    out2 = os.path.join(ROOT, "results", "paper-5.1-accurate")
    run_study("paper-5.1", base, out2, args.ranks, quiet=True)
    print("(table in %s/study.csv)" % out2)

    print("\n== paper-5.1 by adaptive refinement (centroid rule, from N = 2 to the DOFs of N = 64)")
    adaptive(study, ["-box_faces", "2", "-load_quadrature", "centroid"] + extra, out1, args.ranks)
    print("\nTables and plots: %s/ and %s/" % (out1, out2))
    print("  study.csv, study.json: the tables; error-vs-h.png: convergence; error-vs-time.png: error against run time;")
    print("  solution.png: u_h on N = 64; contact.png: u_h and the contact pressure along Gamma_C with the critical points;")
    print("  and in %s/ only (the adaptive run uses the centroid rule):" % out1)
    print("  compare.csv, compare.json, compare-vs-dofs.png, compare-vs-time.png: uniform against adaptive refinement;")
    print("  adapted-mesh-p1.png, adapted-mesh-cr.png: the last adapted meshes with their indicators and the contact set")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()

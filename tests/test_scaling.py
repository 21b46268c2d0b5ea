"""run/scaling on a small mesh, 1 and 2 ranks, strong and weak:
- it exits 0 and writes scaling.csv, scaling.png and each run's -log_view, and no *.tmp file;
- the strong runs solve one discrete problem, so their energies agree (1 and 2 ranks, to solver tolerance);
  the weak runs have twice the DOFs on 2 ranks, less those of the side the two unit squares share;
- the efficiencies in the CSV are the ones defined by the times in the same CSV (strong T1 / (2 T2), weak
  T1 / T2), and the bandwidth ceiling is (BW2 / 2) / BW1 from the measured bandwidths, which are positive;
- an unknown --kind is a usage error before any run, and nothing is written."""
import csv
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker

c = Checker()
with tempfile.TemporaryDirectory() as tmp:
    cmd = [sys.executable, os.path.join(ROOT, "run", "scaling.py"), "--ranks", "1,2", "--strong-n", "32", "--weak-n", "16", "--no-warm-memory", "--out", tmp]
    p = subprocess.run(cmd, capture_output=True, text=True, env=ENV)
    c.check(p.returncode == 0, "run/scaling exit status %d %s" % (p.returncode, p.stderr[-500:]))
    files = sorted(os.listdir(tmp))
    logs = [f for f in files if f.endswith(".log")]
    c.check("scaling.csv" in files and "scaling.png" in files and not any(f.endswith(".tmp") for f in files), "run/scaling wrote %s" % files)
    c.check(len(logs) == 4 and all("Summary of Stages" in open(os.path.join(tmp, f)).read() for f in logs), "a -log_view per run: %s" % logs)
    with open(os.path.join(tmp, "scaling.csv")) as f:
        rows = list(csv.DictReader(f))
    by = {(r["kind"], int(r["ranks"])): r for r in rows}
    c.check(sorted(by) == [("strong", 1), ("strong", 2), ("weak", 1), ("weak", 2)] and all(r["status"] == "ok" for r in rows), "rows: %s" % sorted(by))
    s1, s2, w1, w2 = by[("strong", 1)], by[("strong", 2)], by[("weak", 1)], by[("weak", 2)]
    e1, e2 = float(s1["energy"]), float(s2["energy"])
    c.check(abs(e1 - e2) <= 1e-8 * abs(e1), "strong scaling: one discrete problem on 1 and 2 ranks, energies %.12e, %.12e" % (e1, e2))
    d1, d2 = int(w1["dofs"]), int(w2["dofs"])
    c.check(2 * d1 - 64 <= d2 < 2 * d1, "weak scaling: %d DOFs on 1 rank, %d on 2" % (d1, d2))
    for k in ["solve", "total", "linear"]:
        strong = float(s1[k + "_s"]) / (2 * float(s2[k + "_s"]))
        weak = float(w1[k + "_s"]) / float(w2[k + "_s"])
        c.check(abs(float(s2["eff_" + k]) - strong) <= 1e-9 * strong and abs(float(w2["eff_" + k]) - weak) <= 1e-9 * weak,
                "efficiency of %s: strong %s = %.4f, weak %s = %.4f" % (k, s2["eff_" + k], strong, w2["eff_" + k], weak))
    for a, b in [(s1, s2), (w1, w2)]:
        bw1, bw2 = float(a["bw_gbs"]), float(b["bw_gbs"])
        ceiling = (bw2 / 2) / bw1
        c.check(bw1 > 0 and bw2 > 0 and abs(float(b["eff_ceiling"]) - ceiling) <= 1e-9 * ceiling and float(a["eff_ceiling"]) == 1.0,
                "%s: bandwidth %.2f / %.2f GB/s, ceiling %s = %.4f" % (a["kind"], bw1, bw2, b["eff_ceiling"], ceiling))
# A mistyped kind ran nothing and wrote an empty table and plot over the last ones: now refused first.
with tempfile.TemporaryDirectory() as tmp:
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "scaling.py"), "--kind", "strog", "--ranks", "1", "--no-warm-memory", "--out", tmp], capture_output=True, text=True, env=ENV)
    c.check(p.returncode == 2 and "--kind strog: 'strog' is not one of strong, weak" in p.stderr and not os.listdir(tmp),
            "--kind strog: exit %d, %s, nothing written" % (p.returncode, p.stderr.strip().splitlines()[-1:]))
# Every run failed (kappa < 0): exit 1, the last table and plot left as they were.
with tempfile.TemporaryDirectory() as tmp:
    for name in ["scaling.csv", "scaling.png"]:
        with open(os.path.join(tmp, name), "w") as f:
            f.write("earlier results\n")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "scaling.py"), "--ranks", "1,2", "--strong-n", "32", "--weak-n", "16", "--no-warm-memory", "--no-stream",
                        "--out", tmp, "-kappa", "-1"], capture_output=True, text=True, env=ENV)
    kept = all(open(os.path.join(tmp, name)).read() == "earlier results\n" for name in ["scaling.csv", "scaling.png"])
    c.check(p.returncode == 1 and kept and "no run succeeded" in p.stdout, "every run failing: exit %d, scaling.csv and scaling.png left as they were: %s" % (p.returncode, kept))
c.done()

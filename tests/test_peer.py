"""The dolfinx peer of run/bench (run/peer_dolfinx.py) solves the same discrete problem as signorini, checked
against signorini as an independent computation (another FE framework assembling on its own):
- 2D and 3D, CR and P1 on small boxes: dolfinx's cells are signorini's box cells (-check_mesh), the DOF
  counts are equal and the energies J = 1/2 a(u,u) - l(u) agree to 1e-8 relative;
- run/bench --peer dolfinx at tiny sizes writes its table with those agreements, and refuses two runs whose
  energies differ.
Runs only where Debian's /usr/bin/python3 imports dolfinx (python3-dolfinx); elsewhere it says so and passes
without checking anything: CI does not install dolfinx."""
import csv
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker, run, scene

sys.path.insert(0, os.path.join(ROOT, "run"))
import launch  # noqa: E402
import peer  # noqa: E402

if subprocess.run([peer.PYTHON, "-c", "import dolfinx"], capture_output=True).returncode != 0:
    print("skipped: %s cannot import dolfinx (apt-get install python3-dolfinx)" % peer.PYTHON)
    sys.exit(0)

c = Checker()
for dim, element, N in [(2, "cr", 8), (2, "p1", 8), (3, "cr", 4), (3, "p1", 4)]:
    _, _, _, s = run(scene("paper-5.1" if dim == 2 else "paper-5.1-3d") + ["-box_faces", str(N), "-space", element])
    d = launch.run([peer.SCRIPT, "-dim", str(dim), "-box_faces", str(N), "-space", element, "-check_mesh"], summary=True, exe=peer.PYTHON, timeout=300)
    what = "%dD %s N=%d" % (dim, element, N)
    if d.summary is None:
        c.check(False, "%s: dolfinx peer ran (exit %d): %s" % (what, d.returncode, d.stderr[-2000:]))
        continue
    p = d.summary
    rel = abs(s["energy"] - p["energy"]) / abs(s["energy"])
    c.check(p["mesh_matches"] is True, "%s: dolfinx's cells are signorini's box cells" % what)
    c.check(p["dofs"] == s["dofs"], "%s: DOFs signorini %d, dolfinx %d" % (what, s["dofs"], p["dofs"]))
    c.check(p["converged_reason"].startswith("CONVERGED"), "%s: dolfinx SNESVI %s" % (what, p["converged_reason"]))
    c.check(rel <= 1e-8, "%s: energies %.15e and %.15e agree to %.1e" % (what, s["energy"], p["energy"], rel))

with tempfile.TemporaryDirectory() as tmp:
    cmd = [sys.executable, os.path.join(ROOT, "run", "bench.py"), "--peer", "dolfinx", "--no-warm-memory", "--repeat", "2",
           "--peer-n2", "16", "--peer-n3", "4", "--peer-elements", "cr,p1", "--out", tmp]
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=600)
    c.check(r.returncode == 0, "run/bench --peer dolfinx exits 0 (%d)%s" % (r.returncode, "" if r.returncode == 0 else ": " + r.stderr[-2000:]))
    path = os.path.join(tmp, "peer-dolfinx.csv")
    rows = list(csv.DictReader(open(path))) if os.path.exists(path) else []
    c.check(sorted((int(x["dim"]), x["element"], int(x["N"])) for x in rows) == [(2, "cr", 16), (2, "p1", 16), (3, "cr", 4), (3, "p1", 4)], "bench rows: %s" % [(x["dim"], x["element"], x["N"]) for x in rows])
    c.check(all(float(x["energy_rel_diff"]) <= 1e-8 and float(x["ratio"]) > 0 and int(x["repeats"]) == 2 for x in rows), "bench rows: energies agree, ratios measured over 2 runs")
    c.check(not any(f.endswith(".tmp") for f in os.listdir(tmp)), "no temporary file left")

try:
    peer.check_same_problem({"energy": -0.5, "dofs": 10}, {"energy": -0.5 * (1 + 1e-7), "dofs": 10}, "differing energies")
    c.check(False, "energies differing by 1e-7 are refused")
except RuntimeError as e:
    c.check("not the same discrete problem" in str(e), "energies differing by 1e-7 are refused: %s" % e)
c.done()

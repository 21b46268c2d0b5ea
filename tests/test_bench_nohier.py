"""run/bench --nohier on small Gmsh files (recomputed from the per-run summaries it keeps): each row's Newton
steps, CG iterations, set-ups and ratio contact solve / linear solve are those of the run's JSON, the run read
the file without -refine (one level), and the generated mesh files are removed afterwards."""
import csv
import json
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker

c = Checker()
BENCH = os.path.join(ROOT, "run", "bench.py")

with tempfile.TemporaryDirectory() as tmp:
    cmd = [sys.executable, BENCH, "--nohier", "--nohier-n2", "32", "--elements", "p1,cr", "--no-warm-memory", "--out", tmp]
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV)
    c.check(r.returncode == 0, "run/bench --nohier exits 0 (%s)" % (r.stderr.strip()[-300:] or "ok"))
    with open(os.path.join(tmp, "nohier.csv")) as f:
        rows = list(csv.DictReader(f))
    c.check([row["element"] for row in rows] == ["p1", "cr"] and all(row["status"] == "ok" for row in rows), "one row per element: %s" % [(row["element"], row["status"]) for row in rows])
    for row in rows:
        with open(os.path.join(tmp, "nohier-%s-N32-np1-run1.json" % row["element"])) as f:
            s = json.load(f)
        v = s["solver"]
        same = (int(row["dofs"]) == s["dofs"] and int(row["newton"]) == v["newton_iterations"] and int(row["ksp"]) == v["ksp_iterations"]
                and int(row["amg_setups"]) == v["amg_setups"] and abs(float(row["ratio"]) - v["solve_linear_ratio"]) <= 1e-9 * v["solve_linear_ratio"])
        c.check(same and not v["nested"] and s["refine"] == 0 and s["mesh"].endswith(".msh"),
                "%s: row against its JSON (ratio %s, mesh %s, nested %s)" % (row["element"], row["ratio"], s["mesh"], v["nested"]))
    left = [f for f in os.listdir(tmp) if f.endswith(".msh") or f.endswith(".tmp")]
    c.check(not left, "no mesh file or temporary file left: %s" % left)
c.done()

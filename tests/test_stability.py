"""run/stability --only below-h2 on 1 rank (a few seconds): the adaptive rows of stiff-below-h2 (u ~ r^(1/2)),
checked against the report's own uniform rows rather than against fixed numbers:
  * the run exits 0 and writes its CSV, with the two study rows and, per element, the adaptive row and the
    time comparison row;
  * the adaptive run stopped with its estimate eta below the energy error (against the reference) of the study's
    finest uniform level of the same element, the tolerance it was given, and eta falls like DOFs^s, s <= -0.45;
  * the time comparison row measures the error of the uniform run it times (the study's finest level) against
    an adaptive refinement of that run's mesh: no more than the run's own estimate plus the reference's (the
    triangle inequality, with eta bounding each true error), the adaptive error (against the adaptive run
    carried further) falls like DOFs^s, s <= -0.45, and a positive time ratio (its size is reported,
    not tested: timing is never a pass/fail test), with the time interpolated on the adaptive error-time
    curve no later than the step it is interpolated towards (an invariant of the interpolation);
  * a group name that matches none (--only below-h3) is refused before any run, the earlier table kept."""
import csv
import os
import subprocess
import sys
import tempfile

from harness import ENV, ROOT, Checker

c = Checker()
with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "stability.csv")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "stability.py"), "--only", "below-h2", "--ranks", "1", "--csv", path],
                       capture_output=True, text=True, env=ENV)
    c.check(p.returncode == 0, "run/stability --only below-h2 exits 0 (%d): %s" % (p.returncode, p.stderr[-500:]))
    rows = list(csv.DictReader(open(path))) if os.path.exists(path) else []
    for element in ["p1", "cr"]:
        mine = [r for r in rows if r["element"] == element]
        study = [r for r in mine if r["variant"].startswith("D|C junction")]
        adaptive = [r for r in mine if r["variant"].startswith("adaptive")]
        timing = [r for r in mine if r["variant"].startswith("time vs uniform")]
        found = len(study) == 1 and len(adaptive) == 1 and len(timing) == 1
        c.check(found, "%s: study, adaptive and time rows (%d, %d, %d)" % (element, len(study), len(adaptive), len(timing)))
        if not found:
            continue
        uniform, a, t = float(study[0]["energy_error"]), adaptive[0], timing[0]
        c.check(a["status"] == "ok", "%s adaptive: status %s (%s)" % (element, a["status"], a["notes"]))
        c.check(float(a["eta"]) < uniform, "%s adaptive: eta %s below the uniform finest error %.4e" % (element, a["eta"], uniform))
        c.check(a["slope_eta"] != "" and float(a["slope_eta"]) <= -0.45, "%s adaptive: eta ~ DOFs^%s, <= -0.45" % (element, a["slope_eta"]))
        c.check(int(a["steps"]) >= 5, "%s adaptive: %s steps" % (element, a["steps"]))
        bound = float(study[0]["eta"]) + float(t["reference_eta"])
        c.check(t["dofs"] == study[0]["dofs"] and float(t["energy_error"]) <= bound,
                "%s time row: uniform %s DOFs (study %s), error %s <= eta + reference eta %.4e" % (element, t["dofs"], study[0]["dofs"], t["energy_error"], bound))
        c.check(float(t["time_ratio"]) > 0, "%s time row: ratio %s" % (element, t["time_ratio"]))
        # interpolated between the step before and the timed step, from the same runs: below the latter's time
        if t["curve_ratio"] != "":
            c.check(0 < float(t["curve_ratio"]) <= float(t["time_ratio"]), "%s time row: curve ratio %s in (0, time ratio %s]" % (element, t["curve_ratio"], t["time_ratio"]))
        c.check(t["slope_error"] != "" and float(t["slope_error"]) <= -0.45, "%s time row: adaptive error ~ DOFs^%s, <= -0.45" % (element, t["slope_error"]))
        c.check(t["status"] in ("ok", "above target"), "%s time row: status %s (%s)" % (element, t["status"], t["notes"]))

# A group that does not exist is refused before any run, and the table of an earlier run is left as it was.
with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "stability.csv")
    open(path, "w").write("earlier table\n")
    p = subprocess.run([sys.executable, os.path.join(ROOT, "run", "stability.py"), "--only", "below-h3", "--csv", path], capture_output=True, text=True, env=ENV)
    c.check(p.returncode == 2 and "--only below-h3: no group's name contains it" in p.stderr and open(path).read() == "earlier table\n",
            "run/stability --only below-h3: exit %d, %s, the earlier table kept" % (p.returncode, p.stderr.strip().splitlines()[-1] if p.stderr.strip() else "nothing on stderr"))
c.done()

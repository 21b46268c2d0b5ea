"""Options are read as what they are, a mistyped option stops the run before the mesh is built, and -help
lists every component's options.

- Integers beyond the range of PetscInt are refused, not wrapped modulo 2^32 (PETSc 3.18's own reader gives
  -box_faces 4294967304 = 8, -refine 4294967297 = 1).
- -box_faces, -box_lower and -box_upper take one value (all directions) or exactly dim values.
- An option that no component reads and that is not of a PETSc family is an error naming the closest
  application option; an unknown PETSc-family option (-snes_monitr) is left to PETSc (a warning at the end).
- -help exits 0 and lists options of every component, also with a bad scene on the command line.
Each error case: exit status 1, exactly one line "signorini: error: ..." naming the option (and the value),
nothing in the output directory, and no -dm_view output (the mesh was never built)."""
import os
import tempfile

import harness
from harness import Checker, run, scene

c = Checker()
base = scene("paper-5.1") + ["-box_faces", "8"]
PREFIX = "signorini: error:"

# (what, options, texts the one error line must contain)
cases = [
    ("-box_faces wraps to 8", ["-box_faces", "4294967304"], ["-box_faces", "4294967304"]),
    ("-refine wraps to 1", ["-refine", "4294967297"], ["-refine", "4294967297"]),
    ("-bc_contact wraps to part 1", ["-bc_contact", "4294967297"], ["-bc_contact", "4294967297"]),
    ("-box_faces with 2 counts in 3D", ["-dim", "3", "-box_faces", "2,2"], ["-box_faces", "2 values", "3D"]),
    ("-box_faces with 4 counts in 2D", ["-box_faces", "2,3,4,5"], ["-box_faces", "4 values", "2D"]),
    ("-box_lower with 2 values in 3D", ["-dim", "3", "-box_lower", "0,0"], ["-box_lower", "2 values", "3D"]),
    ("-box_upper with 3 values in 2D", ["-box_upper", "1,1,1"], ["-box_upper", "3 values", "2D"]),
    ("-box_faces not a number", ["-box_faces", "8,x"], ["-box_faces", "'x'"]),
    ("-refine not an integer", ["-refine", "1.5"], ["-refine", "'1.5'"]),
    ("-kkt_tolerance not a number", ["-kkt_tolerance", "1e-6x"], ["-kkt_tolerance", "1e-6x"]),
    ("-nested not a boolean", ["-nested", "maybe"], ["-nested", "maybe"]),
    ("mistyped -refine", ["-refin", "3"], ["unknown option -refin", "did you mean -refine?"]),
    ("mistyped -kappa", ["-kapa", "2"], ["unknown option -kapa", "did you mean -kappa?"]),
    ("mistyped option after a PETSc word", ["-vi_pc_typo", "hypre"], ["unknown option -vi_pc_typo", "did you mean -vi_pc_type?"]),
]
for what, extra, texts in cases:
    for ranks in [1, 2] if what.startswith("mistyped -refine") else [1]:
        label = "%s, %d rank(s)" % (what, ranks)
        with tempfile.TemporaryDirectory() as out:
            args = base + ["-dm_view", "-summary", os.path.join(out, "s.json"), "-output", os.path.join(out, "u.h5")] + extra
            rc, stdout, err, _ = run(args, ranks=ranks, check=False)
            left = sorted(os.listdir(out))
        lines = [l for l in err.splitlines() if l.strip()]
        ours = [l for l in lines if l.startswith(PREFIX)]
        c.check(rc == 1, "%s: exit status %d" % (label, rc))
        c.check(len(ours) == 1 and (ranks > 1 or len(lines) == 1), "%s: one error line: %s" % (label, lines))
        c.check(len(ours) == 1 and all(t in ours[0] for t in texts), "%s: the line names %s" % (label, texts))
        c.check("DM Object" not in stdout, "%s: stopped before the mesh was built (no -dm_view output)" % label)
        c.check(not left, "%s: nothing written (%s)" % (label, left))

# The same check for options from an options file and from PETSC_OPTIONS.
with tempfile.TemporaryDirectory() as tmp:
    path = os.path.join(tmp, "typo")
    with open(path, "w") as f:
        f.write("-refin 3\n")
    rc, _, err, _ = run(base + ["-options_file", path], check=False)
    c.check(rc == 1 and err.strip() == "signorini: error: unknown option -refin (did you mean -refine?)", "-refin in an options file: %s" % err.strip())
    env = dict(harness.ENV, PETSC_OPTIONS="-box_face 4")
    p = harness.launch.run(base + ["-summary", os.path.join(tmp, "s.json")], env=env, timeout=600)
    c.check(p.returncode == 1 and p.stderr.strip() == "signorini: error: unknown option -box_face (did you mean -box_faces?)", "-box_face in PETSC_OPTIONS: %s" % p.stderr.strip())
    c.check(os.listdir(tmp) == ["typo"], "mistyped options in a file or PETSC_OPTIONS: nothing written")

# An unknown option of a PETSc family keeps PETSc's behaviour: the run goes on, and it is reported unused.
rc, out, err, summary = run(base + ["-snes_monitr"], check=False)
c.check(rc == 0 and summary is not None, "-snes_monitr: the run completes (exit %d)" % rc)
c.check("option -snes_monitr was not used" in out, "-snes_monitr: reported unused at the end")
# One value for every direction, negative coordinates: the box is [-1, 2]^2 (side 3, 8 cells: h = 3/8 * sqrt 2).
rc, out, err, summary = run(base + ["-box_lower", "-1", "-box_upper", "2"], check=False)
c.check(rc == 0 and summary["cells"] == 128, "-box_lower -1 -box_upper 2: a box of 8 x 8 squares (exit %d)" % rc)

# -help: exit 0, and options of every component are listed, whatever else is on the command line.
names = ["-box_faces", "-mesh_file", "-refine", "-space", "-f", "-psi", "-kappa", "-load_quadrature", "-error_quadrature_degree",
         "-summary", "-output", "-study_levels", "-reference_refine", "-kkt_tolerance", "-compare_linear", "-nested",
         "-nested_levels", "-amg_reuse", "-vi_pc_type", "-snes_type", "-ksp_type"]
bad_scene = ["-bc_dirichlet", "", "-bc_contact", "7", "-refine", "4294967297", "-f", "2*sin(", "-dim", "3", "-box_faces", "2,2", "-refin", "3"]
for what, args in [("-help alone", ["-help"]), ("-help with a bad scene", ["-help"] + bad_scene)]:
    with tempfile.TemporaryDirectory() as out:
        rc, stdout, err, _ = run(args + ["-summary", os.path.join(out, "s.json")], check=False)
        left = os.listdir(out)
    listed = {l.split()[0] for l in stdout.splitlines() if l.startswith("  -")}
    missing = [n for n in names if n not in listed]
    c.check(rc == 0, "%s: exit status %d (stderr: %s)" % (what, rc, err.strip()[:200]))
    c.check(not missing, "%s: lists the options of every component (missing: %s)" % (what, missing))
    c.check(not left, "%s: nothing written" % what)
c.done()

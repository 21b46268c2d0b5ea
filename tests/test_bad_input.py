"""Bad input: every case exits with status 1 (not 2, not a hang), prints exactly one line
"signorini: error: ..." on stderr that names the offending option or file, and leaves neither a summary
nor any output file (.h5, .xmf, *.tmp) behind. Mesh-file, boundary-label and kappa cases, whose failure
can be found on one rank only, also run on 2 ranks."""
import os
import subprocess
import tempfile

import harness
from harness import ROOT, Checker, scene

c = Checker()
base = scene("paper-5.1") + ["-box_faces", "8"]
PREFIX = "signorini: error:"

with tempfile.TemporaryDirectory() as inputs:
    square = os.path.join(ROOT, "tests", "data", "square.msh")
    missing = os.path.join(inputs, "missing.msh")
    empty = os.path.join(inputs, "empty.msh")
    text = os.path.join(inputs, "notes.msh")
    truncated = os.path.join(inputs, "truncated.msh")
    open(empty, "w").close()
    with open(text, "w") as f:
        f.write("This is a text file, not a mesh.\nx y z\n1 2 3\n")
    with open(square) as f:
        msh = f.read()
    start, end = msh.index("$Elements\n"), msh.index("$EndElements")
    with open(truncated, "w") as f:
        f.write(msh[: start + (end - start) // 2])  # cut in the middle of $Elements (and of a line)
    nodir = os.path.join(inputs, "no-such-directory", "out.h5")

    # (name, extra options, text the message must contain, also on 2 ranks)
    cases = [
        ("missing mesh file", ["-mesh_file", missing], missing, True),
        ("empty mesh file", ["-mesh_file", empty], empty, True),
        ("text file as mesh", ["-mesh_file", text], text, True),
        ("truncated mesh file", ["-mesh_file", truncated], truncated, True),
        ("unknown boundary label", ["-bc_contact", "7"], "-bc_contact", True),
        ("expression does not parse", ["-f", "2*sin("], "option -f:", False),
        ("unknown variable", ["-f", "w"], "option -f:", False),
        ("kappa <= 0 somewhere", ["-kappa", "x - 0.5"], "-kappa", True),
        ("kappa <= 0 on the right only", ["-kappa", "x > 0.5 ? -1 : 1"], "-kappa", True),
        ("kappa <= 0 on the left only", ["-kappa", "x < 0.5 ? 0 : 1"], "-kappa", True),
        ("kappa NaN", ["-kappa", "sqrt(-1)"], "-kappa", True),
        ("zero cell count", ["-box_faces", "0,4"], "-box_faces", False),
        ("negative refine", ["-refine", "-1"], "-refine", False),
        ("dim 4", ["-dim", "4"], "-dim", False),
        ("unknown space", ["-space", "q2"], "-space", True),
        ("output in a missing directory", ["-output", nodir], nodir, False),
    ]

    for name, extra, names, parallel in cases:
        for ranks in [1, 2] if parallel else [1]:
            what = "%s, %d rank(s)" % (name, ranks)
            with tempfile.TemporaryDirectory() as out:
                args = base + ["-output", os.path.join(out, "out.h5")] + extra
                try:
                    rc, _, err, summary = harness.run(args, ranks=ranks, check=False)
                except subprocess.TimeoutExpired:
                    c.check(False, "%s: finished (it hung until the harness timeout)" % what)
                    continue
                left = sorted(os.listdir(out))
            lines = [l for l in err.splitlines() if l.strip()]
            ours = [l for l in lines if l.startswith(PREFIX)]
            msg = ours[0] if ours else (lines[0] if lines else "(nothing on stderr)")
            c.check(rc == 1, "%s: exit status %d" % (what, rc))
            # On 2 ranks mpirun adds its own notice about the non-zero exit status; ours must appear once.
            c.check(len(ours) == 1 and (ranks > 1 or len(lines) == 1),
                    "%s: one error line (%d of ours, %d lines in all): %s" % (what, len(ours), len(lines), msg))
            c.check(len(ours) == 1 and names in ours[0], "%s: the message names '%s'" % (what, names))
            c.check("MPI_ABORT" not in err, "%s: no MPI_Abort" % what)
            c.check(summary is None and not left, "%s: no summary, nothing left in the output directory %s" % (what, left))
    c.check(not os.path.exists(os.path.dirname(nodir)), "the missing output directory was not created")
c.done()

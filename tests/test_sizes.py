"""Sizes are checked before the work (issue 16, item 3): a run whose mesh would overflow the 32-bit indices
of the PETSc build, or whose predicted peak exceeds the machine's memory, stops with exit status 1 and one
line naming the option that sets the size (and, for indices, the 64-bit PETSc build) before anything is
built. The runs are made under an address-space limit of 4 GB, so a run that started building the mesh
could not end with that line; no file is created in the working directory; a size that fits still runs;
-memory_limit sets the memory of a node in place of the machine's."""
import os
import resource
import tempfile

from harness import Checker, launch, scene

c = Checker()
B = scene("paper-5.1") + ["-box_faces", "8"]
LIMIT = 4 << 30


def limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT, LIMIT))


def run(args, ranks=1):
    """Runs in an empty directory with an output (a study: none, it refuses -output) and a summary there;
    returns (rc, output, files left)."""
    output = [] if "-study_levels" in args else ["-output", "u.h5"]
    with tempfile.TemporaryDirectory() as tmp:
        p = launch.run(args + output + ["-summary", "run.json", "-dm_view"], ranks, cwd=tmp, timeout=300,
                       preexec_fn=limit_memory if ranks == 1 else None)
        return p.returncode, p.stdout + p.stderr, sorted(os.listdir(tmp))


def refused(args, names, index, ranks=1):
    rc, out, files = run(args, ranks)
    lines = [l for l in out.splitlines() if l.strip()]
    ours = [l for l in lines if l.startswith("signorini:")]
    tag = "%s (%d rank(s))" % (" ".join(args[2:]), ranks)
    c.check(rc == 1, "%s: exit status %d" % (tag, rc))
    # On 2 ranks mpirun adds its own notice about the non-zero exit status; ours must appear once.
    c.check(len(ours) == 1 and ours[0].startswith("signorini: error: sizes:") and (ranks > 1 or len(lines) == 1) and "MPI_ABORT" not in out,
            "%s: one error line: %s" % (tag, out.strip()[:300]))
    c.check("DM Object" not in out, "%s: stopped before building the mesh (no -dm_view output)" % tag)
    c.check(all(n in out for n in names), "%s: the line names %s" % (tag, ", ".join(names)))
    c.check(("64-bit PETSc build" in out and "libpetsc64-real3.18-dev" in out) == index, "%s: the 64-bit build %s" % (tag, "named" if index else "not named (a memory case)"))
    c.check(files == [], "%s: no file written (%s)" % (tag, files))
    return out


# Beyond 32-bit indices (this check only applies to a build with 32-bit PetscInt).
refused(B + ["-refine", "40"], ["-refine 40"], True)
refused(B + ["-box_faces", "2", "-refine", "15"], ["box 2x2", "-refine 15"], True)
refused(B + ["-study_levels", "40"], ["-study_levels 40"], True)
refused(B + ["-refine", "12"], ["-refine 12"], True)
refused(B + ["-box_faces", "100000,100000"], ["box 100000x100000"], True)
refused(B + ["-refine", "40"], ["-refine 40"], True, ranks=2)
refused(scene("paper-5.1-3d") + ["-box_faces", "8", "-refine", "9"], ["box 8x8x8", "-refine 9"], True)
# A Gmsh file: predicted from the read coarse mesh, before it is distributed.
refused(scene("paper-5.1") + ["-mesh_file", os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "square.msh"), "-refine", "14", "-bc_dirichlet", "1", "-bc_contact", "2", "-bc_neumann", ""],
        ["square.msh", "-refine 14"], True)
# -memory_check 0 does not lift the index limit, and leaves memory out of the line.
out = refused(B + ["-refine", "12", "-memory_check", "0"], ["-refine 12"], True)
c.check("memory" not in out, "-refine 12 -memory_check 0: the line does not speak of memory")
# Fits 32-bit indices, not the memory of this machine (2D CR box 8 -refine 10: 2e8 DOFs, ~120 GB).
refused(B + ["-refine", "10"], ["-refine 10", "-memory_check 0"], False)
refused(B + ["-refine", "10"], ["-refine 10", "-memory_check 0"], False, ranks=2)
refused(B + ["-refine", "7", "-study_levels", "3", "-reference_refine", "1"], ["-study_levels 3", "-reference_refine 1"], False)
# -memory_limit (GB per node) in place of the machine's memory: box 8 -refine 5 (CR, 197 k DOFs, about 0.17 GB
# on 1 rank) is refused under 0.15 GB, on 1 and 2 ranks, and runs under 0.3 GB.
refused(B + ["-refine", "5", "-memory_limit", "0.15"], ["-refine 5", "0.15 GB", "-memory_check 0"], False)
refused(B + ["-refine", "5", "-memory_limit", "0.15"], ["-refine 5", "0.15 GB", "-memory_check 0"], False, ranks=2)
rc, out, files = run(B + ["-refine", "5", "-memory_limit", "0.3"])
c.check(rc == 0 and "run.json" in files, "box 8 -refine 5 -memory_limit 0.3 runs (exit %d)" % rc)

# A size that fits runs.
rc, out, files = run(B + ["-refine", "2"])
c.check(rc == 0 and "run.json" in files and "u.h5" in files and "DM Object" in out, "box 8 -refine 2 runs and writes its files (exit %d, %s)" % (rc, files))
c.done()

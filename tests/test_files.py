"""Output never harms a file (files.h). Each case compares the directory before and after the run (names,
types, sizes, modification times, modes, link targets, and the content of the user's files):
- refused before the run, with exit status 1 and one line "signorini: error: ..." naming the option and the
  path, and no file created, changed or left behind: two outputs of one run on one file (-summary on the
  HDF5 file or on one of its XDMF files, study files on each other, the same file under two names), a
  directory, a device node (a null device made in the test directory, as root) and a pipe (type and mode
  stay; also behind a link), a read-only file (content and
  mode stay), a missing directory, and -output u.h5 where u.xmf is a directory (no u.h5);
- written: a symbolic link stays a link and the file it points to gets the content (also a link to a file
  that does not exist yet); an existing file keeps its mode; a user's own u.h5.tmp and run.json.tmp are not
  touched by a run that succeeds or by one that fails; two runs writing the same -output at once each
  exit 0 and the file is complete (mesh and fields, read by meshio);
- interrupted: SIGTERM and SIGINT to the process (and to mpirun with 2 ranks) while the temporary HDF5 file
  exists leave nothing behind and the previous u.h5 as it was; a run whose XDMF file cannot be renamed at
  the end (a directory appears in its place during the run) leaves the previous u.h5 as it was."""
import os
import signal
import stat
import subprocess
import tempfile
import time

import harness
from harness import ENV, Checker, command, scene

c = Checker()
BASE = scene("paper-5.1") + ["-box_faces", "8"]
SLOW = scene("paper-5.1") + ["-box_faces", "8", "-refine", "7"]  # a few seconds: time to interrupt it


def run(args, cwd, ranks=1):
    r = harness.launch.run(args, ranks, cwd=cwd, timeout=300)
    return r.returncode, r.stderr


def snapshot(top):
    """Every entry below `top` with what a harmful write would change."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(top):
        for name in dirnames + filenames:
            path = os.path.join(dirpath, name)
            st = os.lstat(path)
            entry = (stat.S_IFMT(st.st_mode), stat.S_IMODE(st.st_mode), st.st_size, st.st_mtime_ns)
            if stat.S_ISLNK(st.st_mode):
                entry += (os.readlink(path),)
            elif stat.S_ISCHR(st.st_mode):
                entry += (st.st_rdev,)
            elif stat.S_ISREG(st.st_mode):
                with open(path, "rb") as f:
                    entry += (f.read(),)
            out[os.path.relpath(path, top)] = entry
    return out


def one_error_line(stderr, *names, ranks=1):
    """Our one line; on 2 ranks mpirun adds its own notice about the exit status."""
    lines = [l for l in stderr.splitlines() if l.strip()]
    ours = [l for l in lines if l.startswith("signorini: error:")]
    ok = len(ours) == 1 and (ranks > 1 or len(lines) == 1) and all(n in ours[0] for n in names) and "MPI_ABORT" not in stderr
    return ok, ours or lines[-3:]


def refused(tag, args, names, setup=None, ranks=1):
    with tempfile.TemporaryDirectory() as tmp:
        if setup:
            setup(tmp)
        before = snapshot(tmp)
        rc, err = run(args, tmp, ranks)
        ok, lines = one_error_line(err, *names, ranks=ranks)
        c.check(rc == 1 and ok, "%s (%d rank(s)): exit %d, one line naming %s: %s" % (tag, ranks, rc, names, lines))
        after = snapshot(tmp)
        changed = sorted(n for n in set(after) | set(before) if after.get(n) != before.get(n))
        c.check(not changed, "%s (%d rank(s)): nothing created, changed or left behind%s" % (tag, ranks, ": %s" % changed if changed else ""))


def mkdir(*names):
    return lambda tmp: [os.mkdir(os.path.join(tmp, n)) for n in names]


def write(name, text, mode=None):
    def setup(tmp):
        path = os.path.join(tmp, name)
        with open(path, "w") as f:
            f.write(text)
        if mode is not None:
            os.chmod(path, mode)
    return setup


# ---- refused before the run
for ranks in [1, 2]:
    refused("-output and -summary on one file", BASE + ["-output", "a.h5", "-summary", "a.h5"], ["-output", "-summary", "a.h5"], ranks=ranks)
    refused("-summary on the XDMF file of -output", BASE + ["-output", "a.h5", "-summary", "a.xmf"], ["-output", "-summary", "a.xmf"], ranks=ranks)
    refused("u.xmf is a directory", BASE + ["-output", "u.h5"], ["-output", "u.xmf"], setup=mkdir("u.xmf"), ranks=ranks)
refused("-summary on the contact XDMF file of -output", BASE + ["-output", "a.h5", "-summary", "a-contact.xmf"], ["-output", "-summary", "a-contact.xmf"])
refused("-summary on the CR DOF XDMF file of -output", BASE + ["-space", "cr", "-output", "a.h5", "-summary", "a-dofs.xmf"], ["-output", "-summary", "a-dofs.xmf"])
refused("one file under two names", BASE + ["-summary", "./sub/../run.json", "-study_output", "run.json"], ["-summary", "-study_output", "run.json"], setup=mkdir("sub"))
refused("one file under a link and its own name", BASE + ["-summary", "link.json", "-study_output", "run.json"], ["-summary", "-study_output", "run.json"],
        setup=lambda tmp: os.symlink("run.json", os.path.join(tmp, "link.json")))
study = scene("manufactured-2d") + ["-box_faces", "4", "-study_levels", "1"]
refused("-study_output on a -study_profiles file", study + ["-study_profiles", "pr", "-study_output", "pr-cr.h5"], ["-study_output", "-study_profiles", "pr-cr.h5"])
refused("-study_output on a contact profile", study + ["-study_profiles", "pr", "-study_output", "pr-p1-contact.csv"], ["-study_output", "-study_profiles", "pr-p1-contact.csv"])
refused("-output on a -study_profiles file", study + ["-study_profiles", "pr", "-output", "pr-p1.h5"], ["-output", "-study_profiles", "pr-p1.h5"])
refused("a -study_profiles XDMF file is a directory", study + ["-study_profiles", "pr", "-study_spaces", "cr"], ["-study_profiles", "pr-cr-dofs.xmf"], setup=mkdir("pr-cr-dofs.xmf"))
refused("a ':' in the -output name, which XDMF readers split at", BASE + ["-output", "a:b.h5"], ["-output", "a:b.h5"])
refused("-summary is a directory", BASE + ["-summary", "d"], ["-summary", "'d'"], setup=mkdir("d"))
refused("-summary in a missing directory", BASE + ["-summary", "none/run.json"], ["-summary", "none/run.json"])
# Device nodes and pipes: made in the test's own directory (a null device where the test may make one, as
# root), never the system's /dev/null, which a writer that renames over its target would replace.
def make_node(kind):
    def setup(tmp):
        path = os.path.join(tmp, "node")
        if kind == "fifo":
            os.mkfifo(path)
        else:
            null = os.stat("/dev/null")
            os.mknod(path, 0o666 | stat.S_IFCHR, null.st_rdev)
    return setup


kinds = ["fifo"] + (["device"] if os.geteuid() == 0 else [])
for kind in kinds:
    refused("-summary on a %s" % kind, BASE + ["-summary", "node"], ["-summary", "node"], setup=make_node(kind))
    refused("-output on a link to a %s" % kind, BASE + ["-output", "u.h5"], ["-output", "u.h5", "node"],
            setup=lambda tmp, k=kind: (make_node(k)(tmp), os.symlink("node", os.path.join(tmp, "u.h5"))))
for ranks in [1, 2]:
    refused("a read-only -summary file", BASE + ["-summary", "ro.json"], ["-summary", "ro.json"], setup=write("ro.json", "mine", 0o444), ranks=ranks)
refused("a read-only -output file", BASE + ["-output", "u.h5"], ["-output", "u.h5"], setup=write("u.h5", "mine", 0o440))

# ---- written
with tempfile.TemporaryDirectory() as tmp:
    os.mkdir(os.path.join(tmp, "data"))
    os.symlink("data/real.json", os.path.join(tmp, "link.json"))  # points to a file that does not exist yet
    rc, err = run(BASE + ["-summary", "link.json"], tmp)
    c.check(rc == 0 and os.path.islink(os.path.join(tmp, "link.json")) and os.path.getsize(os.path.join(tmp, "data", "real.json")) > 0,
            "a link to a file not yet there: the link stays, the file it points to gets the summary")
    rc, err = run(BASE + ["-summary", "link.json", "-output", "u.h5", "-snes_rtol", "1e-9"], tmp)
    import json
    with open(os.path.join(tmp, "data", "real.json")) as f:
        rewritten = json.load(f)
    c.check(rc == 0 and os.path.islink(os.path.join(tmp, "link.json")) and "-snes_rtol" in rewritten.get("command_line", []),
            "a link to an existing file: the link stays, the file gets the new summary")
    c.check(rewritten.get("command_line", [])[1:] == BASE + ["-summary", "link.json", "-output", "u.h5", "-snes_rtol", "1e-9"]
            and rewritten.get("expressions") == {"f": "2*pi*sin(2*pi*x)", "g": "0", "u_D": "0", "psi": "0", "kappa": "1"},
            "the summary records the command line and the expressions of the scene: %s" % rewritten.get("expressions"))
    c.check(sorted(os.listdir(tmp)) == ["data", "link.json", "u-contact.xmf", "u-dofs.xmf", "u.h5", "u.xmf"] and os.listdir(os.path.join(tmp, "data")) == ["real.json"],
            "written through a link: no other file: %s" % sorted(os.listdir(tmp)))
for ranks in [1, 2]:
    with tempfile.TemporaryDirectory() as tmp:
        for name, mode in (("u.h5", 0o640), ("u.xmf", 0o604), ("run.json", 0o600)):
            write(name, "old", mode)(tmp)
        write("u.h5.tmp", "the user's own file")(tmp)
        write("run.json.tmp", "the user's own file")(tmp)
        rc, _ = run(BASE + ["-output", "u.h5", "-summary", "run.json"], tmp, ranks)
        modes = {n: stat.S_IMODE(os.stat(os.path.join(tmp, n)).st_mode) for n in ("u.h5", "u.xmf", "run.json")}
        c.check(rc == 0 and modes == {"u.h5": 0o640, "u.xmf": 0o604, "run.json": 0o600} and os.path.getsize(os.path.join(tmp, "u.h5")) > 100,
                "%d rank(s): files replaced keep their modes: %s" % (ranks, {k: oct(v) for k, v in modes.items()}))
        kept = snapshot(tmp)
        c.check(kept["u.h5.tmp"][-1] == kept["run.json.tmp"][-1] == b"the user's own file" and sorted(kept) == ["run.json", "run.json.tmp", "u-contact.xmf", "u-dofs.xmf", "u.h5", "u.h5.tmp", "u.xmf"],
                "%d rank(s): a successful run leaves the user's u.h5.tmp and run.json.tmp alone and nothing else behind" % ranks)
        rc, err = run(BASE + ["-output", "u.h5", "-summary", "run.json", "-snes_max_it", "1", "-snes_rtol", "1e-14"], tmp, ranks)
        c.check(rc == 1 and snapshot(tmp) == kept, "%d rank(s): a failed solve (exit %d) changes nothing, the user's *.tmp included" % (ranks, rc))

# Two runs writing the same -output at once: each writes its own temporary file, so both succeed and the
# file is a complete one (the last rename wins).
with tempfile.TemporaryDirectory() as tmp:
    args = scene("paper-5.1") + ["-box_faces", "8", "-refine", "4", "-output", "u.h5"]
    procs = [subprocess.Popen(command(args, 1), cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV) for _ in range(2)]
    codes = [p.wait(timeout=300) for p in procs]
    complete = False
    try:
        import h5py
        import meshio
        with h5py.File(os.path.join(tmp, "u.h5"), "r") as f:
            complete = all(k in f for k in ("/geometry/vertices", "/viz/topology/cells", "/vertex_fields/u_vertex_value", "/fields/u", "/contact/pressure"))
        complete = complete and len(meshio.read(os.path.join(tmp, "u.xmf")).points) == 129 * 129
    except ImportError:
        complete = os.path.getsize(os.path.join(tmp, "u.h5")) > 1000
    c.check(codes == [0, 0] and complete and sorted(os.listdir(tmp)) == ["u-contact.xmf", "u-dofs.xmf", "u.h5", "u.xmf"],
            "two runs writing u.h5 at once: exit %s, a complete file, nothing else: %s" % (codes, sorted(os.listdir(tmp))))


# ---- interrupted
def start_and_wait(args, tmp, ranks):
    """Starts the run and waits until its temporary HDF5 file has the mesh in it."""
    p = subprocess.Popen(command(args, ranks), cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV, text=True)
    deadline = time.time() + 120
    while p.poll() is None and time.time() < deadline:
        for name in (n for n in os.listdir(tmp) if n.startswith("u.h5.tmp-")):
            try:  # the options-time check creates and removes a temporary of its own at once
                if os.path.getsize(os.path.join(tmp, name)) > 0:
                    return p, name
            except FileNotFoundError:
                pass
        time.sleep(0.01)
    return p, None


for ranks, sig in ((r, s) for r in [1, 2] for s in [signal.SIGTERM, signal.SIGINT]):
    with tempfile.TemporaryDirectory() as tmp:
        write("u.h5", "old")(tmp)
        before = snapshot(tmp)
        p, temp = start_and_wait(SLOW + ["-output", "u.h5", "-summary", "run.json"], tmp, ranks)
        if temp:
            p.send_signal(sig)  # to the process, or to mpirun, which forwards it
        p.communicate(timeout=120)
        after = snapshot(tmp)
        c.check(temp is not None and p.returncode != 0 and after == before,
                "%s to %s (%d rank(s)) while %s existed: exit %s, nothing left behind, u.h5 as it was: %s" % (
                    sig.name, "mpirun" if ranks > 1 else "the process", ranks, temp, p.returncode, sorted(after)))

# The XDMF file cannot take its name at the end (a directory appeared there): the pair is not written,
# and the previous u.h5 is back.
for ranks in [1, 2]:
    with tempfile.TemporaryDirectory() as tmp:
        write("u.h5", "old")(tmp)
        p, temp = start_and_wait(scene("paper-5.1") + ["-box_faces", "8", "-refine", "6", "-output", "u.h5"], tmp, ranks)
        if temp:
            os.mkdir(os.path.join(tmp, "u.xmf"))
        _, err = p.communicate(timeout=300)
        ok, lines = one_error_line(err, "u.xmf", ranks=ranks)
        left = sorted(os.listdir(tmp))
        with open(os.path.join(tmp, "u.h5")) as f:
            old = f.read() == "old"
        c.check(temp is not None and p.returncode == 1 and ok and old and left == ["u.h5", "u.xmf"],
                "%d rank(s): u.xmf cannot be renamed at the end: exit %s, %s, u.h5 as it was (%s), left %s" % (ranks, p.returncode, lines, old, left))
c.done()

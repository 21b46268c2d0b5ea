"""How every script in run/ and tests/ starts signorini: the executable, the MPI launcher and its environment,
and the JSON summary the run writes. Standard library only, so that the tests run with any python3.

  SIGNORINI_EXE      the executable (default build/signorini)
  SIGNORINI_MPIEXEC  the MPI launcher, with its own arguments (default "mpirun")"""
import argparse
import json
import os
import shlex
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OPTIONS = os.path.join(ROOT, "petsc-options")
EXE = os.environ.get("SIGNORINI_EXE", os.path.join(ROOT, "build", "signorini"))
STREAM_EXE = os.path.join(os.path.dirname(EXE), "signorini-stream")
MPIEXEC = os.environ.get("SIGNORINI_MPIEXEC", "mpirun")
# Open MPI refuses to run as root, and more ranks than cores, unless told; other launchers ignore these.
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")


def integer_from(low):
    """argparse type of an integer of at least `low`."""
    def convert(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError("'%s' is not an integer" % text)
        if value < low:
            raise argparse.ArgumentTypeError("%d is not a positive count" % value if low == 1 else "%d is below %d" % (value, low))
        return value
    return convert


# The argparse type of a count (ranks, cells per side, steps, repeats). A 0 ran `run/bench --n2 0` into a
# traceback and `--ranks 0` into runs on one rank that said nothing of it.
count = integer_from(1)


def number_in(low, high=float("inf"), low_open=False):
    """argparse type of a real number in [low, high] ((low, high] with low_open): checked before any run, where
    signorini would refuse it only in the run that uses it, after the others (run/study --theta 0: after the
    whole uniform study)."""
    def convert(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError("'%s' is not a number" % text)
        if not (low < value <= high if low_open else low <= value <= high):
            raise argparse.ArgumentTypeError("%s is not in %s%g, %g]" % (text, "(" if low_open else "[", low, high))
        return value
    return convert


def output_folder(ap, option, value, path=None):
    """Makes the folder a script writes its results in (`path`, default the value of `option`), or an argparse
    error naming the option (exit 2) before any run: one that could not be made or written ended the script
    in a traceback, after its runs where it writes at the end (run/stability --csv)."""
    path = path or value
    if os.path.exists(path) and not os.path.isdir(path):
        ap.error("%s %s: %s is not a folder" % (option, value, path))
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as e:
        ap.error("%s %s: cannot make the folder %s (%s)" % (option, value, path, e.strerror))
    if not os.access(path, os.W_OK | os.X_OK):
        ap.error("%s %s: the folder %s cannot be written" % (option, value, path))


def nothing_succeeded(rows, out_dir, names):
    """Whether every run of a benchmark failed (rows with "status"); if so, says that its files `names` in
    out_dir are left as they were: a table of failures and an empty plot would replace the last results."""
    if any(r.get("status") == "ok" for r in rows):
        return False
    print("\nno run succeeded: %s in %s left as they were" % (", ".join(names), out_dir))
    return True


def list_option(ap, option, text, allowed=None, convert=str):
    """The comma-separated values of a script's option, each converted and, where `allowed` is given, one of
    them; none twice and at least one, or an argparse error naming the option (exit 2): a mistyped value
    otherwise ran nothing and wrote an empty table over the last one."""
    values = []
    for item in (text or "").split(","):
        item = item.strip()
        try:
            value = convert(item)
        except argparse.ArgumentTypeError as e:
            ap.error("%s %s: %s" % (option, text, e))
        except ValueError:
            ap.error("%s %s: '%s' is not a valid value" % (option, text, item))
        if allowed is not None and value not in allowed:
            ap.error("%s %s: '%s' is not one of %s" % (option, text, item, ", ".join(str(a) for a in allowed)))
        if value in values:
            ap.error("%s %s: '%s' is given twice" % (option, text, item))
        values.append(value)
    return values


def scene(name):
    """The options of the scene petsc-options/NAME."""
    return ["-options_file", os.path.join(OPTIONS, name)]


def command(args, ranks=1, exe=None, mpiexec=None):
    """The command line of `exe` (default signorini) with `args`, under the MPI launcher when ranks > 1 or when
    a launcher is named (e.g. "srun", or "mpirun --bind-to core")."""
    cmd = [exe or EXE] + list(args)
    if ranks > 1 or mpiexec:
        cmd = shlex.split(mpiexec or MPIEXEC) + ["-n", str(ranks)] + cmd
    return cmd


class Result:
    """A finished run: its exit status, output, wall time and, when asked for, its summary (None if it wrote none)."""

    def __init__(self, cmd, p, seconds, summary):
        self.cmd, self.returncode, self.stdout, self.stderr = cmd, p.returncode, p.stdout, p.stderr
        self.seconds, self.summary = seconds, summary

    def error_line(self):
        """The run's one-line error (without the "signorini: error: " prefix), or the last line of its output."""
        out = (self.stderr + self.stdout).splitlines()
        lines = [l for l in out if "error" in l.lower()] or out[-1:]
        return lines[0].replace("signorini: error: ", "") if lines else "exit %d" % self.returncode


def run(args, ranks=1, summary=False, exe=None, mpiexec=None, env=None, **kwargs):
    """Runs signorini (or `exe`) with `args` on `ranks` ranks. summary: False (none asked for), True (a temporary
    -summary file, read and removed) or a path (written there and read). Other keywords go to subprocess.run
    (cwd, timeout, preexec_fn, ...)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = summary if isinstance(summary, str) else os.path.join(tmp, "summary.json") if summary else None
        cmd = command(list(args) + (["-summary", path] if path else []), ranks, exe, mpiexec)
        t0 = time.time()
        p = subprocess.run(cmd, capture_output=True, text=True, env=env or ENV, **kwargs)
        seconds = time.time() - t0
        data = None
        if path and not os.path.isabs(path) and kwargs.get("cwd"):
            path = os.path.join(kwargs["cwd"], path)
        if path and os.path.exists(path):
            with open(path) as f:
                data = json.load(f)
    return Result(cmd, p, seconds, data)


def run_kept(args, ranks, out_dir, tag):
    """A benchmark's run: signorini with `args`, its JSON summary and -log_view kept in out_dir under `tag`.
    Returns the summary, or None after one line on stderr naming the run and its error."""
    summary, log = os.path.join(out_dir, tag + ".json"), os.path.join(out_dir, tag + ".log")
    r = run(list(args) + ["-log_view", ":" + log], ranks, summary=summary)
    if r.returncode != 0 or r.summary is None:
        sys.stderr.write("%s failed (exit %d): %s\n" % (tag, r.returncode, r.error_line()))
        return None
    return r.summary

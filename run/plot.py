"""Plots of convergence studies (matplotlib, Debian python3-matplotlib). No numerics here: the figures come
from the study JSON written by `signorini -study_output`."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MARKERS = {"p1": "o", "cr": "s"}
NAMES = {"p1": "P1 (conforming)", "cr": "CR (nonconforming)"}


def _series(rows, key):
    out = {}
    for r in rows:
        if key in r:
            out.setdefault(r["element"], []).append(r)
    return out


def error_key(rows):
    return "error_reference" if any("error_reference" in r for r in rows) else "error_exact"


def plot_error_vs_h(study, path, title):
    rows, key = study["rows"], error_key(study["rows"])
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for element, rs in _series(rows, key).items():
        h = [r["h"] for r in rs]
        ax.loglog(h, [r[key]["l2"] for r in rs], MARKERS.get(element, "^") + "-", label="%s, L2" % NAMES.get(element, element))
        ax.loglog(h, [r[key]["h1_semi"] for r in rs], MARKERS.get(element, "^") + "--", label="%s, broken H1 seminorm" % NAMES.get(element, element))
    hs = sorted({r["h"] for r in rows})
    if hs:
        h0, h1 = hs[0], hs[-1]
        ref = max(r[key]["h1_semi"] for r in rows if key in r)
        ax.loglog([h0, h1], [ref * (h0 / h1), ref], "k:", label="slope 1")
        ref2 = max(r[key]["l2"] for r in rows if key in r)
        ax.loglog([h0, h1], [ref2 * (h0 / h1) ** 2, ref2], "k-.", label="slope 2")
    ax.set_xlabel("h")
    ax.set_ylabel("error" + (" against the reference" if key == "error_reference" else " against the exact solution"))
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_work_precision(study, path, title):
    rows, key = study["rows"], error_key(study["rows"])
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for element, rs in _series(rows, key).items():
        t = [max(r["total_seconds"], 1e-6) for r in rs]
        ax.loglog(t, [r[key]["l2"] for r in rs], MARKERS.get(element, "^") + "-", label="%s, L2" % NAMES.get(element, element))
        ax.loglog(t, [r[key]["h1_semi"] for r in rs], MARKERS.get(element, "^") + "--", label="%s, broken H1 seminorm" % NAMES.get(element, element))
    ax.set_xlabel("run time to solution [s] (mesh, set-up, assembly, solve)")
    ax.set_ylabel("error")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)

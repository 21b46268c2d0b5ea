"""Plots of convergence studies (matplotlib, Debian python3-matplotlib). No numerics here: the figures come
from the study JSON written by `signorini -study_output`."""
import matplotlib
import matplotlib.colors

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


def _errors_against(ax, rows, key, x):
    """L2 and broken H1 errors of each element against x(row) on log-log axes; without errors (no exact
    solution, no reference) the estimate eta of the energy error."""
    if not _series(rows, key):
        for element, rs in _series(rows, "estimate").items():
            ax.loglog([x(r) for r in rs], [r["estimate"]["eta"] for r in rs], MARKERS.get(element, "^") + "--", label="%s, estimate eta" % NAMES.get(element, element))
        return
    for element, rs in _series(rows, key).items():
        xs, m, name = [x(r) for r in rs], MARKERS.get(element, "^"), NAMES.get(element, element)
        ax.loglog(xs, [r[key]["l2"] for r in rs], m + "-", label="%s, L2" % name)
        ax.loglog(xs, [r[key]["h1_semi"] for r in rs], m + "--", label="%s, broken H1 seminorm" % name)


def _finish(fig, ax, path, title, xlabel, ylabel):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_error_vs_h(study, path, title):
    rows, key = study["rows"], error_key(study["rows"])
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    _errors_against(ax, rows, key, lambda r: r["h"])
    hs = sorted({r["h"] for r in rows})
    measured = bool(_series(rows, key))
    # guides through the largest error (or estimate): slope 1 for the H1 seminorm, slope 2 for L2
    guides = [("h1_semi", 1, "k:"), ("l2", 2, "k-.")] if measured else [("eta", 1, "k:")]
    source = key if measured else "estimate"
    for field, slope, style in guides if hs and _series(rows, source) else []:
        h0, h1, ref = hs[0], hs[-1], max(r[source][field] for r in rows if source in r)
        ax.loglog([h0, h1], [ref * (h0 / h1) ** slope, ref], style, label="slope %d" % slope)
    if not measured:
        against = " (estimated: no exact solution or reference)"
    else:
        against = " against the reference" if key == "error_reference" else " against the exact solution"
    _finish(fig, ax, path, title, "h", "error" + against)


def plot_work_precision(study, path, title):
    rows, key = study["rows"], error_key(study["rows"])
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    _errors_against(ax, rows, key, lambda r: max(r["total_seconds"], 1e-6))
    _finish(fig, ax, path, title, "run time to solution [s] (mesh, set-up, assembly, solve)", "error" if _series(rows, key) else "estimated error eta")


STRATEGY_COLORS = {"uniform": "tab:blue", "adaptive": "tab:red"}


def plot_compare(rows, path, title, x, xlabel):
    """Uniform against adaptive refinement (rows of run/compare.py): per element one axes with the energy
    error (solid) and the estimate eta (dashed) of both strategies against x (DOFs or run time). The
    adaptive steps solved only for the reference are left out."""
    elements = list(dict.fromkeys(r["element"] for r in rows))
    fig, axes = plt.subplots(1, len(elements), figsize=(5.6 * len(elements), 4.8), squeeze=False)
    for ax, element in zip(axes[0], elements):
        for strategy, color in STRATEGY_COLORS.items():
            rs = [r for r in rows if r["element"] == element and r["strategy"] == strategy and not r["reference_step"]]
            m = MARKERS.get(element, "^")
            xs = [max(r[x], 1e-6) for r in rs]
            err = [(xv, r["error"]) for xv, r in zip(xs, rs) if r["error"] is not None]
            if err:
                against = rs[-1]["error_against"] or ""
                ax.loglog(*zip(*err), m + "-", color=color, ms=3, label="%s: error (solid, against %s)" % (strategy, against))
            eta = [(xv, r["eta"]) for xv, r in zip(xs, rs) if r["eta"] is not None]
            if eta:
                ax.loglog(*zip(*eta), m + "--", color=color, ms=3, mfc="none", label="%s: estimate eta (dashed)" % strategy)
        ax.set_title("%s, %s" % (title, NAMES.get(element, element)), fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("energy error / estimate")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_solution(h5_files, path, title):
    """u_h over a 2D domain, one panel per element (vertex values from the HDF5 output). Returns False in 3D."""
    import h5py

    panels = []
    for element, f in h5_files.items():
        with h5py.File(f, "r") as h5:
            X = h5["/geometry/vertices"][:]
            if X.shape[1] != 2:
                return False
            panels.append((element, X, h5["/viz/topology/cells"][:], h5["/vertex_fields/u_vertex_value"][:]))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), squeeze=False)
    for ax, (element, X, cells, u) in zip(axes[0], panels):
        t = ax.tripcolor(X[:, 0], X[:, 1], cells, u, shading="gouraud", cmap="viridis")
        ax.set_aspect("equal")
        ax.set_title("%s: u_h" % NAMES.get(element, element))
        fig.colorbar(t, ax=ax, shrink=0.85)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True


def plot_mesh(h5_file, path, title):
    """The mesh of a 2D run (e.g. an adapted one) from its HDF5 output, cells coloured by the error indicator
    when the file has it, and Gamma_C drawn over it: red where the contact is active, blue where it is not.
    Returns False in 3D."""
    import h5py
    from matplotlib.collections import LineCollection

    with h5py.File(h5_file, "r") as h5:
        X = h5["/geometry/vertices"][:]
        if X.shape[1] != 2:
            return False
        cells = h5["/viz/topology/cells"][:]
        eta = h5["/cell_fields/eta"][:] if "/cell_fields/eta" in h5 else None
        contact = None
        if "/contact/cells" in h5:
            CX, CC, active = h5["/contact/vertices"][:], h5["/contact/cells"][:], h5["/contact/active"][:]
            if len(active) == len(CX) != len(CC):  # P1: per vertex; a face is in contact where both its ends are
                active = active[CC].min(axis=1)
            contact = (CX[CC], active)
    fig, ax = plt.subplots(figsize=(6.4, 5.6))
    if eta is not None:
        # on a log scale: on an adapted mesh a few cells at a singularity would take the whole linear scale
        top = float(eta.max())
        norm = matplotlib.colors.LogNorm(vmin=max(float(eta.min()), 1e-4 * top), vmax=top) if top > 0 else None
        t = ax.tripcolor(X[:, 0], X[:, 1], cells, facecolors=eta, cmap="magma_r", norm=norm, edgecolors="k", linewidth=0.1)
        fig.colorbar(t, ax=ax, shrink=0.85, label="indicator eta_T")
    else:
        ax.triplot(X[:, 0], X[:, 1], cells, color="k", lw=0.2)
    if contact is not None:
        segments, active = contact
        colors = ["tab:red" if a > 0.5 else "tab:blue" for a in active]
        ax.add_collection(LineCollection(segments, colors=colors, linewidths=3))
        ax.plot([], [], color="tab:red", lw=3, label="Gamma_C, active")
        ax.plot([], [], color="tab:blue", lw=3, label="Gamma_C, inactive")
        ax.legend(fontsize=8, loc="upper right")
    ax.set_aspect("equal")
    ax.set_title("%s (%d cells)" % (title, len(cells)))
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return True


def _read_profile(path):
    import csv

    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]} if rows else None


def critical_points(s, gap):
    """Where the contact region begins and ends: midpoints between neighbouring DOFs where u = psi switches."""
    scale = max(1.0, max(abs(g) for g in gap))
    active = [g <= 1e-8 * scale for g in gap]
    return [0.5 * (s[i] + s[i + 1]) for i in range(len(s) - 1) if active[i] != active[i + 1]]


def plot_contact(csv_files, path, title):
    """u_h, psi and the contact pressure kappa du/dn along a straight Gamma_C (2D), both elements on one plot,
    with the critical points (ends of the contact region) marked."""
    fig, (ax_u, ax_p) = plt.subplots(2, 1, figsize=(7, 6.4), sharex=True)
    for n, (element, f) in enumerate(csv_files.items()):
        p = _read_profile(f)
        if p is None or "z" in p:
            plt.close(fig)
            return False
        # arc length along Gamma_C: x for a horizontal part, y for a vertical one
        s = p["x"] if max(p["x"]) - min(p["x"]) >= max(p["y"]) - min(p["y"]) else p["y"]
        m = MARKERS.get(element, "^")
        ax_u.plot(s, p["u"], m + "-", ms=3, label="%s: u_h" % NAMES.get(element, element))
        ax_p.plot(s, p["pressure"], m + "-", ms=3, label="%s: pressure" % NAMES.get(element, element))
        if n == 0:
            ax_u.plot(s, p["psi"], "k--", lw=1, label="obstacle psi")
        for k, x in enumerate(critical_points(s, [a - b for a, b in zip(p["u"], p["psi"])])):
            for ax in (ax_u, ax_p):
                ax.axvline(x, color="C%d" % n, ls=":", lw=1.2, label=("%s: critical point" % element) if (k == 0 and ax is ax_u) else None)
    ax_u.set_ylabel("u_h on Gamma_C")
    ax_p.set_ylabel("kappa du/dn (reaction / boundary measure)")
    ax_p.set_xlabel("position along Gamma_C")
    ax_u.set_title(title)
    for ax in (ax_u, ax_p):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return True

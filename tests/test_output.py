"""-output writes HDF5 + XDMF 3 that a viewer can open: every XDMF file parses, points at datasets that exist
with the stated shapes, and is read by meshio (Debian python3-meshio); for a linear exact solution the
vertex field equals u at the vertices and the cell field equals u at the cell centroids (comparison with
the exact solution), for both elements, on 1 and 2 ranks, on a 2D coarse mesh and on refined 2D and 3D
meshes. The Gamma_C grid (FILE-contact.xmf) holds u = psi = the expression at the contact DOFs, all of them
active, with the pressure equal to the exact normal flux (3 in 2D, 0 in 3D); the CR DOF grid
(FILE-dofs.xmf) has one point per DOF at the face midpoints, with u there. On paper-5.1 (partly active)
the contact fields satisfy the KKT conditions (u >= psi, pressure >= 0, complementarity) and count as
many active DOFs as the summary. Without a contact part no contact file is written. No temporary file is
left behind. The mesh goes into the file before the solve (and is freed
then), the fields after it: the same run with and without -output gives the same solve (invariant: one
discrete problem, so the same energy, KKT residuals and iterations), and a run whose solve fails after the
mesh was written leaves no file at all."""
import os
import tempfile
import xml.etree.ElementTree as ET

from harness import Checker, run, scene

c = Checker()
try:
    import h5py
    import numpy as np
except ImportError:  # run/setup installs python3-h5py; without it only the file checks run
    h5py = None
try:
    import meshio
except ImportError:  # run/setup installs python3-meshio
    meshio = None
c.check(meshio is not None and h5py is not None, "h5py and meshio can be imported (run/setup installs python3-h5py and python3-meshio)")


def expected_files(space, contact=True):
    return sorted(["sol.h5", "sol.xmf"] + (["sol-contact.xmf"] if contact else []) + (["sol-dofs.xmf"] if space == "cr" else []))


def read_all(tmp, tag):
    """meshio reads every .xmf file of the directory; returns {name: mesh}."""
    meshes = {}
    for name in sorted(os.listdir(tmp)):
        if not name.endswith(".xmf"):
            continue
        try:
            meshes[name] = meshio.read(os.path.join(tmp, name))
        except Exception as e:  # a file meshio cannot read is the failure reported
            c.check(False, "%s: meshio reads %s: %s" % (tag, name, e))
    return meshes

u = "1 + 2*x - 3*y"
base = ["-dim", "2", "-box_faces", "6,4", "-bc_dirichlet", "3", "-bc_neumann", "2,4", "-bc_contact", "1",
        "-u_D", u, "-g", "x < 0.5 ? -2 : 2", "-psi", "1 + 2*x", "-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
# The same linear u in 3D: Dirichlet on the top (2), contact on the bottom (1, psi = u there, pressure 0),
# kappa du/dn on the four sides (3 front y = 0, 4 back, 5 right x = 1, 6 left).
base3d = ["-dim", "3", "-box_faces", "3,2,2", "-bc_dirichlet", "2", "-bc_neumann", "3,4,5,6", "-bc_contact", "1",
          "-u_D", u, "-g", "y < 1e-9 ? 3 : (y > 1 - 1e-9 ? -3 : (x > 0.5 ? 2 : -2))", "-psi", u,
          "-ksp_rtol", "1e-13", "-snes_rtol", "1e-13"]
# Refined meshes are written from the DMPlex that the refinement built (refine.h), not from a cell list.
meshes = [("2D", base), ("2D refined", base + ["-refine", "1"]), ("3D refined", base3d + ["-refine", "1"])]
for (mesh, args), space, ranks in ((m, sp, r) for m in meshes for sp in ["p1", "cr"] for r in [1, 2]):
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "sol.h5")
        kept = run(args + ["-space", space, "-output", out], ranks=ranks)[3]
        freed = run(args + ["-space", space], ranks=ranks)[3]
        tag = "%s %s on %d rank(s)" % (mesh, space, ranks)
        same = abs(kept["energy"] - freed["energy"]) <= 1e-13 * abs(kept["energy"]) and kept["kkt"] == freed["kkt"] and all(
            kept["solver"][k] == freed["solver"][k] for k in ("converged_reason", "newton_iterations", "ksp_iterations"))
        c.check(same, "%s: the solve is the same with the mesh kept (-output) and freed: energy %r / %r" % (tag, kept["energy"], freed["energy"]))
        files = sorted(os.listdir(tmp))
        c.check(files == expected_files(space), "%s: files %s" % (tag, files))
        for name in files:
            if not name.endswith(".xmf"):
                continue
            root = ET.parse(os.path.join(tmp, name)).getroot()
            c.check(root.get("Version") == "3.0", "%s: %s is XDMF 3" % (tag, name))
            items = {d.text.split(":")[1]: tuple(int(n) for n in d.get("Dimensions").split()) for d in root.iter("DataItem")}
            if h5py is None:
                continue
            with h5py.File(out, "r") as f:
                shapes_ok = all(path in f and f[path].shape == dims for path, dims in items.items())
            c.check(shapes_ok, "%s: every DataItem of %s exists in the HDF5 file with its shape" % (tag, name))
        if h5py is None or meshio is None:
            continue
        exact = lambda p: 1 + 2 * p[..., 0] - 3 * p[..., 1]
        m = read_all(tmp, tag)
        dim = 3 if "3D" in mesh else 2
        if "sol.xmf" in m:
            mm = m["sol.xmf"]
            c.check(mm.cells[0].type == ("tetra" if dim == 3 else "triangle") and mm.points.shape[1] == dim, "%s: meshio reads the mesh" % tag)
            c.check(np.max(np.abs(mm.point_data["u_h (vertex)"] - exact(mm.points))) < 1e-10, "%s: meshio: vertex field = u at the vertices" % tag)
            centroids = mm.points[mm.cells[0].data].mean(axis=1)
            c.check(np.max(np.abs(mm.cell_data["u_h (cell mean)"][0] - exact(centroids))) < 1e-10, "%s: meshio: cell field = u at the centroids" % tag)
        if "sol-contact.xmf" in m:
            mc = m["sol-contact.xmf"]
            faces = mc.cells[0].data
            c.check(mc.cells[0].type == ("triangle" if dim == 3 else "line") and np.all(np.abs(mc.points[:, dim - 1]) < 1e-14),
                    "%s: the contact grid is made of the faces on the bottom" % tag)
            if space == "p1":  # DOFs at the face vertices
                data, where = mc.point_data, mc.points
            else:  # one DOF per face, at its midpoint
                data, where = {k: v[0] for k, v in mc.cell_data.items()}, mc.points[faces].mean(axis=1)
            flux = 3 if dim == 2 else 0  # kappa du/dn of u = 1 + 2x - 3y on the bottom (outward normal -y or -z)
            ok = (np.max(np.abs(data["psi"] - exact(where))) < 1e-12 and np.max(np.abs(data["u_h"] - exact(where))) < 1e-10
                  and np.all(data["active"] == 1) and np.max(np.abs(data["pressure"] - flux)) < 1e-8)
            c.check(ok, "%s: contact grid: u = psi = exact at the contact DOFs, all active, pressure = %g" % (tag, flux))
            dofs = len(faces) if space == "cr" else len(np.unique(np.round(mc.points, 12), axis=0))
            c.check(dofs == kept["contact_dofs"], "%s: the contact grid carries the %d contact DOFs" % (tag, kept["contact_dofs"]))
        if "sol-dofs.xmf" in m:
            md = m["sol-dofs.xmf"]
            c.check(md.cells[0].type == "vertex" and len(md.points) == kept["dofs"], "%s: the DOF grid has one point per DOF" % tag)
            c.check(np.max(np.abs(md.point_data["u_h"] - exact(md.points))) < 1e-10, "%s: the DOF grid holds u at the face midpoints" % tag)
        with h5py.File(out, "r") as f:
            X = f["/geometry/vertices"][:]
            cells = f["/viz/topology/cells"][:]
            uv = f["/vertex_fields/u_vertex_value"][:]
            uc = f["/cell_fields/u_cell_value"][:]
        c.check(np.max(np.abs(uv - exact(X))) < 1e-10, "%s: vertex field = u at the vertices" % tag)
        centroids = X[cells].mean(axis=1)
        c.check(np.max(np.abs(uc - exact(centroids))) < 1e-10, "%s: cell field = u at the centroids" % tag)
# A partly active contact set: the contact fields satisfy the discrete KKT conditions, and the active set is
# the one the summary counts.
for space, ranks in ((sp, r) for sp in ["p1", "cr"] for r in [1, 2]):
    with tempfile.TemporaryDirectory() as tmp:
        summary = run(scene("paper-5.1") + ["-box_faces", "8", "-space", space, "-output", os.path.join(tmp, "sol.h5")], ranks=ranks)[3]
        tag = "paper-5.1 %s on %d rank(s)" % (space, ranks)
        if meshio is None:
            continue
        mc = read_all(tmp, tag).get("sol-contact.xmf")
        if mc is None:
            c.check(False, "%s: contact grid written" % tag)
            continue
        data = mc.point_data if space == "p1" else {k: v[0] for k, v in mc.cell_data.items()}
        if space == "p1":  # a vertex shared by two faces appears twice: count each DOF once
            _, first = np.unique(np.round(mc.points, 12), axis=0, return_index=True)
            data = {k: v[first] for k, v in data.items()}
        gap, p, active = data["u_h"] - data["psi"], data["pressure"], data["active"]
        scale = np.max(np.abs(p))
        ok = (np.min(gap) > -1e-10 and np.min(p) > -1e-6 * scale and np.max(np.abs(gap * p)) < 1e-8 * scale
              and np.all((active == 1) == (gap <= 1e-10)) and 0 < int(active.sum()) < len(active))
        c.check(ok, "%s: u >= psi, pressure >= 0, (u - psi) pressure = 0, active where u = psi (%d of %d)" % (tag, int(active.sum()), len(active)))
        c.check(int(active.sum()) == summary["kkt"]["active"] and len(active) == summary["contact_dofs"],
                "%s: %d active of %d contact DOFs, as in the summary (%d of %d)" % (tag, int(active.sum()), len(active), summary["kkt"]["active"], summary["contact_dofs"]))
# Without a contact part no contact file (Dirichlet on the bottom instead).
for space in ["p1", "cr"]:
    with tempfile.TemporaryDirectory() as tmp:
        args = ["-dim", "2", "-box_faces", "6,4", "-bc_dirichlet", "1,3", "-bc_neumann", "2,4", "-u_D", u, "-g", "x < 0.5 ? -2 : 2"]
        run(args + ["-space", space, "-output", os.path.join(tmp, "sol.h5")])
        files = sorted(os.listdir(tmp))
        c.check(files == expected_files(space, contact=False), "no contact part, %s: files %s" % (space, files))
        if meshio is not None:
            c.check(len(read_all(tmp, "no contact part, %s" % space)) == len(files) - 1, "no contact part, %s: meshio reads every .xmf" % space)
for ranks in [1, 2]:
    with tempfile.TemporaryDirectory() as tmp:
        rc = run(base + ["-space", "cr", "-snes_max_it", "1", "-output", os.path.join(tmp, "sol.h5")], ranks=ranks, check=False)[0]
        left = sorted(os.listdir(tmp))
        c.check(rc == 1 and not left, "failed solve on %d rank(s): exit status %d, files left %s" % (ranks, rc, left))
c.done()

"""-output writes HDF5 + XDMF that a viewer can open: the XDMF parses and points at datasets that exist with
the stated shapes, and for a linear exact solution the vertex field equals u at the vertices and the cell
field equals u at the cell centroids (comparison with the exact solution), for both elements, on 1 and 2
ranks, on a 2D coarse mesh and on refined 2D and 3D meshes. No temporary file is left behind. The mesh goes into the file before the solve (and is freed
then), the fields after it: the same run with and without -output gives the same solve (invariant: one
discrete problem, so the same energy, KKT residuals and iterations), and a run whose solve fails after the
mesh was written leaves no file at all."""
import os
import tempfile
import xml.etree.ElementTree as ET

from harness import Checker, run

c = Checker()
try:
    import h5py
    import numpy as np
except ImportError:  # run/setup installs python3-h5py; without it only the file checks run
    h5py = None

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
        c.check(files == ["sol.h5", "sol.xmf"], "%s: files %s" % (tag, files))
        root = ET.parse(os.path.join(tmp, "sol.xmf")).getroot()
        items = {d.text.split(":")[1]: tuple(int(n) for n in d.get("Dimensions").split()) for d in root.iter("DataItem")}
        c.check(len(items) == 4, "%s: XDMF names topology, geometry and two fields" % tag)
        if h5py is None:
            continue
        with h5py.File(out, "r") as f:
            shapes_ok = all(path in f and np.prod(f[path].shape) == np.prod(dims) for path, dims in items.items())
            c.check(shapes_ok, "%s: every XDMF DataItem exists in the HDF5 file with its size" % tag)
            X = f["/geometry/vertices"][:]
            cells = f["/viz/topology/cells"][:]
            uv = f["/vertex_fields/u_vertex_value"][:]
            uc = f["/cell_fields/u_cell_value"][:]
        exact = lambda p: 1 + 2 * p[..., 0] - 3 * p[..., 1]
        c.check(np.max(np.abs(uv - exact(X))) < 1e-10, "%s: vertex field = u at the vertices" % tag)
        centroids = X[cells].mean(axis=1)
        c.check(np.max(np.abs(uc - exact(centroids))) < 1e-10, "%s: cell field = u at the centroids" % tag)
for ranks in [1, 2]:
    with tempfile.TemporaryDirectory() as tmp:
        rc = run(base + ["-space", "cr", "-snes_max_it", "1", "-output", os.path.join(tmp, "sol.h5")], ranks=ranks, check=False)[0]
        left = sorted(os.listdir(tmp))
        c.check(rc == 1 and not left, "failed solve on %d rank(s): exit status %d, files left %s" % (ranks, rc, left))
c.done()

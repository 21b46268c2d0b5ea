"""The paper's scene solved with dolfinx (Debian's python3-dolfinx 0.5), the general FE framework a user
would pick instead of signorini: the peer of `run/bench --peer dolfinx`.

  /usr/bin/python3 run/peer_dolfinx.py [-dim 2|3] [-box_faces N] [-space cr|p1] [-summary FILE] [-check_mesh]

It solves the same discrete problem as
  signorini -options_file petsc-options/paper-5.1[-3d] -box_faces N -space cr|p1
on the unit square (cube): -Laplace u = f = 2 pi sin(2 pi x), u = 0 on the top (y = 1, in 3D z = 1),
du/dn = 0 on the sides, u >= psi = 0 on the bottom (y = 0, z = 0), kappa = 1.
- the mesh: dolfinx's unit square with DiagonalType.left cuts every square from (1,0) to (0,1), signorini's
  -box_diagonal backslash; its unit cube cuts every cube into the 6 Kuhn tetrahedra around the diagonal
  (0,0,0)-(1,1,1), as signorini's box does (-check_mesh compares both cell sets with the one built here
  after src/mesh.cpp, by vertex coordinates);
- the space: Crouzeix-Raviart (DOFs at face midpoints, so the contact DOFs are the midpoints of the faces on
  Gamma_C) or P1 (DOFs at vertices);
- the load: f * v integrated with signorini's default load rule (degree 4: the 6-point rule per triangle,
  the 14-point degree-5 rule per tetrahedron, see src/quadrature.cpp), given to FFCx as a custom rule, so
  that both load vectors agree to round-off; the stiffness is exact in both;
- Dirichlet rows: eliminated symmetrically with 1 on the diagonal, as signorini does;
- the solver: F(u) = A u - b with A and b assembled once, PETSc's SNESVI reduced-space Newton
  (vinewtonrsls, full steps, snes_rtol 1e-9, bound tolerance 1e-14, at most 200 steps) from u = 0, CG with
  BoomerAMG (HMIS, ext+i, P_max 4, in 3D one level of aggressive coarsening) to ksp_rtol 1e-10 in the
  unpreconditioned norm: the tolerances and preconditioner of signorini's defaults
  (petsc-options/solvers/default), without its nested iteration and AMG re-use.
Prints the discrete energy J = 1/2 a(u,u) - l(u), the Newton and KSP iteration counts and the time of each
stage, and of the whole process since the interpreter started; -summary writes them as JSON."""
import argparse
import json
import os
import sys
import time


def process_seconds():
    """Seconds since this process started (from /proc; includes the interpreter's start), or None."""
    try:
        with open("/proc/self/stat") as f:
            start_ticks = float(f.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return uptime - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


STARTED = process_seconds()  # before the heavy imports
T0 = time.perf_counter()

import numpy as np  # noqa: E402


def load_rule(dim):
    """signorini's default load rule on the reference simplex (weights summing to its measure): the
    symmetric degree-4 rule of 6 points on triangles, the degree-5 rule of 14 points on tetrahedra, each
    given by its orbits of barycentric points (vertex orbit (a, ..., a, 1 - d a), edge orbit
    (a, a, 1/2 - a, 1/2 - a)), with the published constants."""
    import itertools
    import math

    if dim == 2:
        orbits = [("v", 0.44594849091596489, 0.22338158967801125), ("v", 0.091576213509770896, 0.10995174365532205)]
    else:
        orbits = [("v", 0.3108859192633005, 0.11268792571801556), ("v", 0.092735250310891235, 0.073493043116361984),
                  ("e", 0.45449629587435025, 0.042546020777081597)]
    points, weights = [], []
    for kind, a, w in orbits:
        bary = [a] * dim + [1 - dim * a] if kind == "v" else [a, a, 0.5 - a, 0.5 - a]
        for p in sorted(set(itertools.permutations(bary))):
            points.append(p[1:])  # reference coordinates are the barycentric ones of vertices 1..dim
            weights.append(w / math.factorial(dim))
    return np.array(points), np.array(weights)


def box_cells(dim, N):
    """The cells of signorini's box (src/mesh.cpp) as sorted tuples of vertex grid indices: 2D backslash
    squares {a, b, d}, {b, c, d}; 3D the Kuhn split, one tetrahedron per monotone path from corner 000 to 111."""
    import itertools

    cells = set()
    if dim == 2:
        for j in range(N):
            for i in range(N):
                a, b, c, d = (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)
                cells.add(tuple(sorted((a, b, d))))
                cells.add(tuple(sorted((b, c, d))))
        return cells
    for k in range(N):
        for j in range(N):
            for i in range(N):
                for perm in itertools.permutations(range(3)):
                    pos, path = [i, j, k], [(i, j, k)]
                    for axis in perm:
                        pos[axis] += 1
                        path.append(tuple(pos))
                    cells.add(tuple(sorted(path)))
    return cells


def check_mesh(mesh, dim, N):
    """Whether dolfinx's cells are signorini's (serial only): the same vertex sets, by grid coordinates."""
    x = mesh.geometry.x[:, :dim]
    dofmap = mesh.geometry.dofmap
    grid = np.rint(x * N).astype(np.int64)
    ours = set()
    for c in range(dofmap.num_nodes):
        ours.add(tuple(sorted(tuple(int(v) for v in grid[i]) for i in dofmap.links(c))))
    return ours == box_cells(dim, N)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-dim", type=int, choices=(2, 3), default=2)
    ap.add_argument("-box_faces", type=int, default=64, help="cells per side")
    ap.add_argument("-space", choices=("cr", "p1"), default="cr")
    ap.add_argument("-summary", help="write the results as JSON to this file")
    ap.add_argument("-check_mesh", action="store_true", help="check that the cells are signorini's (serial; slow for large N)")
    args = ap.parse_args()
    dim, N = args.dim, args.box_faces
    times = {}

    t = time.perf_counter()
    import logging

    import ufl
    from dolfinx import fem, mesh as dmesh
    from dolfinx.fem import petsc as fpetsc
    from mpi4py import MPI
    from petsc4py import PETSc
    times["import"] = time.perf_counter() - t
    # UFL warns that it hashes the custom rule's arrays through str(); the rule is fixed, so that is safe.
    logging.getLogger("UFL").setLevel(logging.ERROR)

    comm = MPI.COMM_WORLD
    t = time.perf_counter()
    if dim == 2:
        msh = dmesh.create_unit_square(comm, N, N, dmesh.CellType.triangle, diagonal=dmesh.DiagonalType.left)
    else:
        msh = dmesh.create_unit_cube(comm, N, N, N, dmesh.CellType.tetrahedron)
    times["mesh"] = time.perf_counter() - t
    mesh_ok = None
    if args.check_mesh:
        mesh_ok = comm.size == 1 and check_mesh(msh, dim, N)

    # Space and boundary DOFs: CR DOFs live on faces (entities of dimension dim - 1), P1 DOFs on vertices.
    t = time.perf_counter()
    V = fem.FunctionSpace(msh, ("CR" if args.space == "cr" else "P", 1))
    entity_dim = dim - 1 if args.space == "cr" else 0
    top = dmesh.locate_entities_boundary(msh, entity_dim, lambda x: np.isclose(x[dim - 1], 1.0))
    bottom = dmesh.locate_entities_boundary(msh, entity_dim, lambda x: np.isclose(x[dim - 1], 0.0))
    dirichlet_dofs = fem.locate_dofs_topological(V, entity_dim, top)
    contact_dofs = fem.locate_dofs_topological(V, entity_dim, bottom)
    bc = fem.dirichletbc(PETSc.ScalarType(0), dirichlet_dofs, V)
    times["space"] = time.perf_counter() - t

    # Forms (FFCx compiles them on first use and keeps them in its cache).
    t = time.perf_counter()
    points, weights = load_rule(dim)
    dx_load = ufl.Measure("dx", domain=msh, metadata={"quadrature_rule": "custom", "quadrature_degree": 4,
                                                       "quadrature_points": points, "quadrature_weights": weights})
    x = ufl.SpatialCoordinate(msh)
    f = 2 * ufl.pi * ufl.sin(2 * ufl.pi * x[0])
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    a = fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx)
    L = fem.form(f * v * dx_load)
    uh = fem.Function(V)
    energy_form = fem.form(0.5 * ufl.inner(ufl.grad(uh), ufl.grad(uh)) * ufl.dx - f * uh * dx_load)
    times["forms"] = time.perf_counter() - t

    t = time.perf_counter()
    A = fpetsc.assemble_matrix(a, bcs=[bc])
    A.assemble()
    b = fpetsc.assemble_vector(L)
    fpetsc.apply_lifting(b, [a], bcs=[[bc]])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fpetsc.set_bc(b, [bc])
    times["assemble"] = time.perf_counter() - t

    t = time.perf_counter()
    reason, newton, ksp_its = solve(A, b, uh, V, contact_dofs, dim, PETSc)
    times["solve"] = time.perf_counter() - t

    t = time.perf_counter()
    uh.x.scatter_forward()
    J = comm.allreduce(fem.assemble_scalar(energy_form), op=MPI.SUM)
    times["energy"] = time.perf_counter() - t
    times["in_script"] = time.perf_counter() - T0
    total = process_seconds()
    if total is not None and STARTED is not None:
        times["process"] = total  # since the interpreter started, as the kernel counts it

    dofs = V.dofmap.index_map.size_global
    result = {"peer": "dolfinx", "dolfinx_version": __import__("dolfinx").__version__, "dim": dim, "N": N,
              "space": args.space, "dofs": dofs, "ranks": comm.size, "energy": J, "converged_reason": reason,
              "newton_iterations": newton, "ksp_iterations_total": ksp_its, "time": times, "mesh_matches": mesh_ok}
    if comm.rank == 0:
        print("dolfinx %s: %dD %s N=%d, %d DOFs on %d rank%s" % (result["dolfinx_version"], dim, args.space.upper(), N, dofs, comm.size, "s" if comm.size > 1 else ""))
        print("energy J = 1/2 a(u,u) - l(u) = %.15e" % J)
        print("SNES %s after %d Newton steps, %d KSP iterations" % (reason, newton, ksp_its))
        print("times [s]: " + ", ".join("%s %.3f" % kv for kv in times.items()))
        if mesh_ok is not None:
            print("cells equal to signorini's box: %s" % ("yes" if mesh_ok else "NO"))
        if args.summary:
            tmp = args.summary + ".tmp"
            with open(tmp, "w") as out:
                json.dump(result, out, indent=1)
            os.replace(tmp, args.summary)
    return 0 if reason.startswith("CONVERGED") and mesh_ok is not False else 1


def solve(A, b, uh, V, contact_dofs, dim, PETSc):
    """SNESVI (reduced space) on F(u) = A u - b with u >= 0 at the contact DOFs; returns (reason, Newton
    steps, KSP iterations)."""
    lower, upper = A.createVecRight(), A.createVecRight()
    lower.set(PETSc.NINFINITY)
    upper.set(PETSc.INFINITY)
    owned = V.dofmap.index_map.size_local  # the global vectors hold the owned DOFs, which come first
    lower.array[contact_dofs[contact_dofs < owned]] = 0.0  # psi = 0

    def residual(snes, x, F):
        A.mult(x, F)
        F.axpy(-1.0, b)

    opts = PETSc.Options()
    opts["snes_vi_zero_tolerance"] = 1e-14  # PETSc 3.18 reads it only from the options
    opts["snes_linesearch_type"] = "basic"  # full steps, as signorini takes them
    for key, value in [("pc_hypre_boomeramg_coarsen_type", "HMIS"), ("pc_hypre_boomeramg_interp_type", "ext+i"),
                       ("pc_hypre_boomeramg_P_max", 4), ("pc_hypre_boomeramg_agg_nl", 1 if dim == 3 else 0)]:
        opts[key] = value
    snes = PETSc.SNES().create(A.getComm())
    snes.setType("vinewtonrsls")
    F = A.createVecLeft()
    snes.setFunction(residual, F)
    snes.setJacobian(lambda snes, x, J, P: None, A, A)  # the problem is linear: A is the Jacobian
    snes.setVariableBounds(lower, upper)
    snes.setTolerances(rtol=1e-9, stol=1e-14, max_it=200)
    ksp = snes.getKSP()
    ksp.setType("cg")
    ksp.setTolerances(rtol=1e-10, atol=1e-50, max_it=1000)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    pc = ksp.getPC()
    pc.setType("hypre")
    pc.setHYPREType("boomeramg")
    snes.setFromOptions()
    x = uh.vector
    x.set(0.0)
    snes.solve(None, x)
    reasons = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
    reason = snes.getConvergedReason()
    return reasons.get(reason, str(reason)), snes.getIterationNumber(), snes.getLinearSolveIterations()


if __name__ == "__main__":
    sys.exit(main())

#include "signorini/mesh.h"
#include "signorini/gmsh.h"
#include "signorini/refine.h"
#include "signorini/stages.h"

#include <metis.h>
#include <petscdmplextransform.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

static_assert(sizeof(idx_t) == sizeof(PetscInt), "METIS idx_t and PetscInt must have the same width");

namespace signorini {

PetscErrorCode MeshOptionsFromCommandLine(MPI_Comm comm, MeshOptions &o)
{
  char        file[PETSC_MAX_PATH_LEN] = "", part[64] = "metis";
  const char *diagonals[]              = {"slash", "backslash", "crossed"};
  const char *refinements[]            = {"direct", "transform"};
  PetscInt    diag = (PetscInt)o.diagonal, nfaces = 3, nlo = 3, nhi = 3, how = (PetscInt)o.refinement;
  PetscBool   setFaces = PETSC_FALSE;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Mesh options", "signorini");
  PetscCall(PetscOptionsString("-mesh_file", "Gmsh .msh file (physical groups name boundary parts); default: built-in box", "", file, file, sizeof file, NULL));
  PetscCall(PetscOptionsInt("-dim", "Dimension of the built-in box (2 or 3)", "", o.dim, &o.dim, NULL));
  PetscCall(PetscOptionsIntArray("-box_faces", "Cells per direction of the coarse box, e.g. 64,64", "", o.faces, &nfaces, &setFaces));
  PetscCall(PetscOptionsRealArray("-box_lower", "Lower corner of the box", "", o.lower, &nlo, NULL));
  PetscCall(PetscOptionsRealArray("-box_upper", "Upper corner of the box", "", o.upper, &nhi, NULL));
  PetscCall(PetscOptionsEList("-box_diagonal", "2D: how each square is cut: slash (0,0)-(1,1), backslash (1,0)-(0,1), crossed (4 triangles)", "", diagonals, 3, diagonals[diag], &diag, NULL));
  PetscCall(PetscOptionsInt("-refine", "Uniform refinements in parallel after distribution", "", o.refine, &o.refine, NULL));
  PetscCall(PetscOptionsEList("-mesh_refinement", "How the mesh is refined: direct (the fine DMPlex built from the coarse one) or transform (PETSc's DMPlexTransform; the same mesh, slower)", "", refinements, 2, refinements[how], &how, NULL));
  PetscCall(PetscOptionsString("-mesh_partitioner", "metis (libmetis on the coarse cell graph) or a PetscPartitioner type (ptscotch, simple)", "", part, part, sizeof part, NULL));
  PetscOptionsEnd();
  o.file        = file;
  o.partitioner = part;
  o.diagonal    = (Diagonal)diag;
  o.refinement  = (Refinement)how;
  if (o.file.empty()) {
    if (o.dim != 2 && o.dim != 3) SIGNORINI_INPUT_ERROR(comm, "option -dim: must be 2 or 3, got %" PetscInt_FMT, o.dim);
    if (setFaces && nfaces == 1)
      for (PetscInt d = 1; d < 3; ++d) o.faces[d] = o.faces[0]; // "-box_faces 16" means 16 in every direction
    for (PetscInt d = 0; d < o.dim; ++d) {
      if (o.faces[d] <= 0) SIGNORINI_INPUT_ERROR(comm, "option -box_faces: cell counts must be positive, got %" PetscInt_FMT " in direction %" PetscInt_FMT, o.faces[d], d);
      if (!(o.lower[d] < o.upper[d])) SIGNORINI_INPUT_ERROR(comm, "options -box_lower/-box_upper: lower %g is not below upper %g in direction %" PetscInt_FMT, (double)o.lower[d], (double)o.upper[d], d);
    }
  }
  if (o.refine < 0) SIGNORINI_INPUT_ERROR(comm, "option -refine: must be >= 0, got %" PetscInt_FMT, o.refine);
  PetscFunctionReturn(0);
}

// Signed measure factor (determinant of the edge matrix) of a simplex given by dim+1 vertex indices.
static PetscReal SimplexDet(PetscInt dim, const PetscInt *v, const std::vector<PetscReal> &X)
{
  PetscReal e[3][3] = {{0}};
  for (PetscInt i = 0; i < dim; ++i)
    for (PetscInt d = 0; d < dim; ++d) e[i][d] = X[v[i + 1] * dim + d] - X[v[0] * dim + d];
  if (dim == 2) return e[0][0] * e[1][1] - e[0][1] * e[1][0];
  return e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
}

// Cell list of the coarse box. PETSc wants triangles counter-clockwise (det > 0) and tetrahedra with
// det < 0, so each cell is reoriented by swapping two vertices when needed.
static void BoxCellList(const MeshOptions &o, std::vector<PetscInt> &cells, std::vector<PetscReal> &X)
{
  const PetscInt dim = o.dim, N = o.faces[0], M = o.faces[1], L = dim == 3 ? o.faces[2] : 1;
  PetscReal      h[3];
  for (PetscInt d = 0; d < dim; ++d) h[d] = (o.upper[d] - o.lower[d]) / o.faces[d];
  auto vid = [&](PetscInt i, PetscInt j, PetscInt k) { return (k * (M + 1) + j) * (N + 1) + i; };
  for (PetscInt k = 0; k <= (dim == 3 ? L : 0); ++k)
    for (PetscInt j = 0; j <= M; ++j)
      for (PetscInt i = 0; i <= N; ++i) {
        const PetscInt idx[3] = {i, j, k};
        for (PetscInt d = 0; d < dim; ++d) X.push_back(idx[d] == o.faces[d] ? o.upper[d] : o.lower[d] + idx[d] * h[d]);
      }
  if (dim == 2) {
    const PetscInt nGrid = (N + 1) * (M + 1);
    for (PetscInt j = 0; j < M; ++j)
      for (PetscInt i = 0; i < N; ++i) {
        PetscInt a = vid(i, j, 0), b = vid(i + 1, j, 0), c = vid(i + 1, j + 1, 0), d = vid(i, j + 1, 0);
        if (o.diagonal == Diagonal::Slash) cells.insert(cells.end(), {a, b, c, a, c, d});
        else if (o.diagonal == Diagonal::Backslash) cells.insert(cells.end(), {a, b, d, b, c, d});
        else {
          PetscInt m = nGrid + j * N + i;
          X.push_back(o.lower[0] + (i + 0.5) * h[0]);
          X.push_back(o.lower[1] + (j + 0.5) * h[1]);
          cells.insert(cells.end(), {a, b, m, b, c, m, c, d, m, d, a, m});
        }
      }
  } else {
    // Kuhn (Freudenthal) split: one tetrahedron per monotone path from corner 000 to corner 111.
    const PetscInt perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (PetscInt k = 0; k < L; ++k)
      for (PetscInt j = 0; j < M; ++j)
        for (PetscInt i = 0; i < N; ++i)
          for (const auto &p : perms) {
            PetscInt pos[3] = {i, j, k};
            cells.push_back(vid(pos[0], pos[1], pos[2]));
            for (PetscInt s = 0; s < 3; ++s) {
              pos[p[s]]++;
              cells.push_back(vid(pos[0], pos[1], pos[2]));
            }
          }
  }
  const PetscInt nc = (PetscInt)cells.size() / (dim + 1);
  for (PetscInt c = 0; c < nc; ++c) {
    PetscInt *v   = &cells[c * (dim + 1)];
    PetscReal det = SimplexDet(dim, v, X);
    if ((dim == 2 && det < 0) || (dim == 3 && det > 0)) std::swap(v[1], v[2]);
  }
}

// Number the box sides in "Face Sets" (see mesh.h). Only rank 0 holds cells at this point.
static PetscErrorCode LabelBoxSides(DM dm, const MeshOptions &o)
{
  DMLabel  faceSets;
  PetscInt fStart, fEnd, dim = o.dim;
  PetscFunctionBeginUser;
  PetscCall(DMCreateLabel(dm, "Face Sets"));
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));

  for (PetscInt f = fStart; f < fEnd; ++f) {
    PetscInt nsupp;
    PetscCall(DMPlexGetSupportSize(dm, f, &nsupp));
    if (nsupp != 1) continue;
    PetscReal area, c[3] = {0, 0, 0}, n[3];
    PetscCall(DMPlexComputeCellGeometryFVM(dm, f, &area, c, n));
    // side numbers of (axis, lower) / (axis, upper)
    static const PetscInt side2[2][2] = {{4, 2}, {1, 3}}, side3[3][2] = {{6, 5}, {3, 4}, {1, 2}};
    PetscInt              value       = -1;
    for (PetscInt d = 0; d < dim && value < 0; ++d) {
      const PetscReal tol = 1e-10 * (o.upper[d] - o.lower[d]);
      if (std::fabs(c[d] - o.lower[d]) < tol) value = dim == 2 ? side2[d][0] : side3[d][0];
      else if (std::fabs(c[d] - o.upper[d]) < tol) value = dim == 2 ? side2[d][1] : side3[d][1];
    }
    if (value > 0) PetscCall(DMLabelSetValue(faceSets, f, value));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode CreateBox(MPI_Comm comm, const MeshOptions &o, DM *dm, std::string &description)
{
  PetscMPIInt            rank;
  std::vector<PetscInt>  cells;
  std::vector<PetscReal> X;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) BoxCellList(o, cells, X);
  const PetscInt nc = (PetscInt)cells.size() / (o.dim + 1), nv = (PetscInt)X.size() / o.dim;
  PetscCall(DMPlexCreateFromCellListPetsc(comm, o.dim, nc, nv, o.dim + 1, PETSC_TRUE, cells.data(), o.dim, X.data(), dm));
  PetscCall(LabelBoxSides(*dm, o));
  static const char *diag[] = {"slash", "backslash", "crossed"};
  description               = o.dim == 2 ? Format("box %dx%d %s", (int)o.faces[0], (int)o.faces[1], diag[(int)o.diagonal]) : Format("box %dx%dx%d", (int)o.faces[0], (int)o.faces[1], (int)o.faces[2]);
  PetscFunctionReturn(0);
}

PetscErrorCode SimplexVertices(DM dm, PetscInt p, PetscInt depth, PetscInt verts[4])
{
  const PetscInt *cone;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetCone(dm, p, &cone));
  if (depth == 1) {
    verts[0] = cone[0];
    verts[1] = cone[1];
    PetscFunctionReturn(0);
  }
  PetscInt second[4];
  PetscCall(SimplexVertices(dm, cone[0], depth - 1, verts));
  PetscCall(SimplexVertices(dm, cone[1], depth - 1, second));
  for (PetscInt i = 0; i < depth; ++i)
    if (std::find(verts, verts + depth, second[i]) == verts + depth) verts[depth] = second[i];
  PetscFunctionReturn(0);
}

PetscErrorCode CellVertices(DM dm, PetscInt p, PetscInt dim, PetscInt verts[4])
{
  const PetscInt *cone;
  PetscInt        face[3][3], all[4];
  PetscFunctionBeginUser;
  // The vertices of faces 0 .. dim-1 decide everything (3 cone lookups per triangle, 10 per tetrahedron,
  // instead of 8 and 19 through SimplexVertices of the cell and of every face): the cell's vertices are
  // face 0's and the one of face 1 that is not on face 0, vertex k (k < dim) is the one not on face k, and
  // the last is the one left.
  PetscCall(DMPlexGetCone(dm, p, &cone));
  for (PetscInt k = 0; k < dim; ++k) PetscCall(SimplexVertices(dm, cone[k], dim - 1, face[k]));
  const auto on = [dim](const PetscInt *f, PetscInt v) { return std::find(f, f + dim, v) != f + dim; };
  std::copy(face[0], face[0] + dim, all);
  for (PetscInt i = 0; i < dim; ++i)
    if (!on(face[0], face[1][i])) all[dim] = face[1][i];
  bool used[4] = {false, false, false, false};
  for (PetscInt k = 0; k < dim; ++k)
    for (PetscInt j = 0; j <= dim; ++j)
      if (!on(face[k], all[j])) verts[k] = all[j], used[j] = true;
  for (PetscInt j = 0; j <= dim; ++j)
    if (!used[j]) verts[dim] = all[j];
  PetscFunctionReturn(0);
}

// A mesh that folds over itself (an inverted cell: a vertex moved across an opposite face) has cells of
// positive measure, so the measure check does not see it, yet the solution on it is wrong. In a valid mesh
// the two cells of every interior face lie on opposite sides of it; the orientation in which the file
// lists a cell's vertices does not matter.
static std::string CheckNoFolds(DM dm, const std::string &name)
{
  PetscInt           dim, fStart, fEnd;
  Vec                coords;
  PetscSection       csec;
  const PetscScalar *x;
  std::string        problem;
  if (DMGetDimension(dm, &dim) || DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd) || DMGetCoordinatesLocal(dm, &coords) || DMGetCoordinateSection(dm, &csec) || VecGetArrayRead(coords, &x)) return name + ": cannot query the mesh faces";
  auto point = [&](PetscInt v, PetscInt d) {
    PetscInt off = 0;
    PetscSectionGetOffset(csec, v, &off);
    return PetscRealPart(x[off + d]);
  };
  PetscInt fv[4], cv[4];
  for (PetscInt f = fStart; f < fEnd && problem.empty(); ++f) {
    PetscInt        ns;
    const PetscInt *supp;
    if (DMPlexGetSupportSize(dm, f, &ns) || DMPlexGetSupport(dm, f, &supp) || ns != 2) continue;
    if (SimplexVertices(dm, f, dim - 1, fv)) return name + ": cannot query the mesh faces";
    PetscReal side[2];
    for (int k = 0; k < 2; ++k) {
      if (SimplexVertices(dm, supp[k], dim, cv)) return name + ": cannot query the mesh cells";
      PetscInt opp = -1;
      for (PetscInt i = 0; i <= dim; ++i)
        if (std::find(fv, fv + dim, cv[i]) == fv + dim) opp = cv[i];
      // signed measure of the simplex (face vertices, opposite vertex): its sign says which side opp is on
      std::vector<PetscReal> X;
      for (PetscInt i = 0; i <= dim; ++i)
        for (PetscInt d = 0; d < dim; ++d) X.push_back(point(i < dim ? fv[i] : opp, d));
      const PetscInt order[4] = {0, 1, 2, 3};
      side[k]                 = SimplexDet(dim, order, X);
    }
    if (side[0] * side[1] >= 0) problem = Format("%s: cells %d and %d lie on the same side of their common face (an inverted cell: the mesh folds over itself)", name.c_str(), (int)supp[0], (int)supp[1]);
  }
  VecRestoreArrayRead(coords, &x);
  return problem;
}

// A 2D mesh read with all three coordinates must lie in a plane z = const: PETSc would otherwise drop z
// and silently solve on the projection of a curved surface.
static std::string CheckFlat(DM dm, const std::string &name)
{
  PetscInt           dim, cdim, n;
  Vec                coords;
  const PetscScalar *x;
  if (DMGetDimension(dm, &dim) || DMGetCoordinateDim(dm, &cdim) || DMGetCoordinatesLocal(dm, &coords) || VecGetLocalSize(coords, &n) || VecGetArrayRead(coords, &x)) return name + ": cannot query the coordinates";
  std::string problem;
  for (PetscInt i = 0; i < n && problem.empty(); ++i)
    if (i % cdim >= dim && PetscRealPart(x[i]) != PetscRealPart(x[i % cdim])) problem = Format("%s: a %dD mesh that is not flat (coordinate %d varies: a surface mesh?); only planar 2D or 3D volume meshes are supported", name.c_str(), (int)dim, (int)(i % cdim));
  VecRestoreArrayRead(coords, &x);
  return problem;
}

// Checks a mesh held on one process: simplices of one dimension (2 or 3), all of positive measure, no folds.
static std::string CheckCoarseMesh(DM dm, const std::string &name)
{
  PetscInt dim, cStart, cEnd;
  if (DMGetDimension(dm, &dim) || DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd)) return name + ": cannot query the mesh";
  if (dim != 2 && dim != 3) return Format("%s: mesh dimension is %d, expected 2 or 3", name.c_str(), (int)dim);
  if (std::string flat = CheckFlat(dm, name); !flat.empty()) return flat;
  if (cEnd <= cStart) return Format("%s: the mesh has no cells of dimension %d", name.c_str(), (int)dim);
  PetscReal vmax = 0;
  std::vector<PetscReal> vol(cEnd - cStart);
  for (PetscInt c = cStart; c < cEnd; ++c) {
    DMPolytopeType ct;
    PetscReal      centroid[3], normal[3];
    if (DMPlexGetCellType(dm, c, &ct)) return name + ": cannot query the cell type";
    if (ct != (dim == 2 ? DM_POLYTOPE_TRIANGLE : DM_POLYTOPE_TETRAHEDRON)) return Format("%s: cell %d is a %s, only %s are supported", name.c_str(), (int)(c - cStart), DMPolytopeTypes[ct], dim == 2 ? "triangles" : "tetrahedra");
    if (DMPlexComputeCellGeometryFVM(dm, c, &vol[c - cStart], centroid, normal)) return name + ": cannot compute cell volumes";
    vmax = std::max(vmax, std::fabs(vol[c - cStart]));
  }
  for (PetscInt c = cStart; c < cEnd; ++c)
    if (!(std::fabs(vol[c - cStart]) > 1e-12 * vmax)) return Format("%s: cell %d has zero measure (degenerate)", name.c_str(), (int)(c - cStart));
  return CheckNoFolds(dm, name);
}

// Reads a Gmsh file. Rank 0 first checks the file and reads it alone to check the mesh, so that a missing,
// truncated, malformed or non-mesh file gives one clear message on every rank instead of an error on rank 0
// while the others wait.
static PetscErrorCode CreateFromGmsh(MPI_Comm comm, const MeshOptions &o, DM *dm, std::string &description)
{
  PetscMPIInt rank;
  std::string problem;
  const std::string name = "mesh file '" + o.file + "'";
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) {
    GmshNodes nodes;
    problem = GmshCheckFile(o.file, name, nodes);
    if (problem.empty()) {
      // read all three coordinates, so that CheckCoarseMesh can see whether a 2D mesh is flat
      DM        test = nullptr;
      PetscBool userSpaceDim;
      PetscCall(PetscOptionsHasName(NULL, NULL, "-dm_plex_gmsh_spacedim", &userSpaceDim));
      if (!userSpaceDim) PetscCall(PetscOptionsSetValue(NULL, "-dm_plex_gmsh_spacedim", "3"));
      PetscErrorCode ierr = DMPlexCreateGmshFromFile(PETSC_COMM_SELF, o.file.c_str(), PETSC_TRUE, &test);
      if (ierr) {
        // PETSc's reason is the first error; destroying the half-built mesh may raise another one (such as
        // "Work array still checked out"), which must neither hide it nor end the run.
        problem = name + ": cannot be read as a Gmsh mesh: " + LastPetscError(ierr);
        if (test) (void)DMDestroy(&test);
      }
      if (!userSpaceDim) PetscCall(PetscOptionsClearValue(NULL, "-dm_plex_gmsh_spacedim"));
      if (!ierr) {
        problem = CheckCoincidentVertices(test, name, nodes);
        if (problem.empty()) problem = CheckCoarseMesh(test, name);
        PetscCall(DMDestroy(&test));
      }
    }
  }
  PetscCall(CheckAll(comm, problem.empty(), problem));
  PetscCall(DMPlexCreateGmshFromFile(comm, o.file.c_str(), PETSC_TRUE, dm));
  description = o.file;
  PetscFunctionReturn(0);
}

// METIS k-way partition of the coarse cell graph, handed to DMPlex through a shell partitioner.
static PetscErrorCode PartitionWithMetis(DM dm, PetscInt &edgeCut)
{
  MPI_Comm    comm;
  PetscMPIInt size;
  PetscInt    nv, *offsets = nullptr, *adjacency = nullptr;
  IS          globalNumbering;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectGetComm((PetscObject)dm, &comm));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(DMPlexCreatePartitionerGraph(dm, 0, &nv, &offsets, &adjacency, &globalNumbering));
  std::vector<idx_t> part(nv, 0);
  idx_t              objval = 0;
  int                status = METIS_OK;
  if (nv > size) {
    idx_t nvtx = nv, ncon = 1, nparts = size, options[METIS_NOPTIONS];
    METIS_SetDefaultOptions(options);
    options[METIS_OPTION_NUMBERING] = 0;
    status = METIS_PartGraphKway(&nvtx, &ncon, offsets, adjacency, NULL, NULL, NULL, &nparts, NULL, NULL, options, &objval, part.data());
  } else {
    for (PetscInt i = 0; i < nv; ++i) part[i] = (idx_t)i; // fewer cells than ranks: one cell each
  }
  PetscCall(CheckAll(comm, status == METIS_OK, Format("METIS_PartGraphKway failed with status %d", status)));
  std::vector<PetscInt> sizes(size, 0), points(nv), start(size + 1, 0);
  for (PetscInt i = 0; i < nv; ++i) sizes[part[i]]++;
  for (PetscMPIInt p = 0; p < size; ++p) start[p + 1] = start[p] + sizes[p];
  for (PetscInt i = 0; i < nv; ++i) points[start[part[i]]++] = i;
  PetscPartitioner partitioner;
  PetscCall(DMPlexGetPartitioner(dm, &partitioner));
  PetscCall(PetscPartitionerSetType(partitioner, PETSCPARTITIONERSHELL));
  PetscCall(PetscPartitionerShellSetPartition(partitioner, size, sizes.data(), points.data()));
  PetscCall(PetscFree(offsets));
  PetscCall(PetscFree(adjacency));
  PetscCall(ISDestroy(&globalNumbering));
  PetscInt cut = (PetscInt)objval;
  PetscCallMPI(MPI_Allreduce(&cut, &edgeCut, 1, MPIU_INT, MPI_MAX, comm));
  PetscFunctionReturn(0);
}

// -mesh_partitioner names metis (PartitionWithMetis) or a registered PetscPartitioner type, less the shell
// (which needs a partition made in code) and those whose external package this PETSc lacks: checked before
// the mesh is built, since PETSc finds a wrong name only when it distributes the mesh.
static PetscErrorCode CheckPartitioner(MPI_Comm comm, const std::string &partitioner)
{
  const char **types;
  int          n;
  std::string  valid = "metis";
  bool         found = partitioner == "metis";
  PetscFunctionBeginUser;
  PetscCall(PetscPartitionerInitializePackage());
  PetscCall(PetscFunctionListGet(PetscPartitionerList, &types, &n));
  for (int i = 0; i < n && types[i]; ++i) {
    const std::string type = types[i];
    PetscBool         have = PETSC_TRUE;
    if (type == PETSCPARTITIONERSHELL) continue;
    if (type == PETSCPARTITIONERPARMETIS || type == PETSCPARTITIONERPTSCOTCH || type == PETSCPARTITIONERCHACO) PetscCall(PetscHasExternalPackage(types[i], &have));
    if (!have) continue;
    valid += ", " + type;
    found = found || partitioner == type;
  }
  PetscCall(PetscFree(types));
  if (!found) SIGNORINI_INPUT_ERROR(comm, "option -mesh_partitioner: '%s' is not an available partitioner (valid: %s)", partitioner.c_str(), valid.c_str());
  PetscFunctionReturn(0);
}

PetscErrorCode MeshSize(DM dm, PetscReal *hmax)
{
  PetscInt           eStart, eEnd, cdim;
  Vec                coords;
  PetscSection       csec;
  const PetscScalar *x;
  PetscReal          h = 0;
  PetscFunctionBeginUser;
  PetscCall(DMGetCoordinateDim(dm, &cdim));
  PetscCall(DMPlexGetDepthStratum(dm, 1, &eStart, &eEnd));
  PetscCall(DMGetCoordinatesLocal(dm, &coords));
  PetscCall(DMGetCoordinateSection(dm, &csec));
  PetscCall(VecGetArrayRead(coords, &x));
  for (PetscInt e = eStart; e < eEnd; ++e) {
    const PetscInt *cone;
    PetscInt        o0, o1;
    PetscCall(DMPlexGetCone(dm, e, &cone));
    PetscCall(PetscSectionGetOffset(csec, cone[0], &o0));
    PetscCall(PetscSectionGetOffset(csec, cone[1], &o1));
    PetscReal d2 = 0;
    for (PetscInt d = 0; d < cdim; ++d) d2 += PetscSqr(PetscRealPart(x[o1 + d] - x[o0 + d]));
    h = PetscMax(h, PetscSqrtReal(d2));
  }
  PetscCall(VecRestoreArrayRead(coords, &x));
  PetscCallMPI(MPI_Allreduce(&h, hmax, 1, MPIU_REAL, MPI_MAX, PetscObjectComm((PetscObject)dm)));
  PetscFunctionReturn(0);
}

PetscErrorCode LabelFaces(DM dm, DMLabel label, PetscInt value, std::vector<PetscInt> &faces)
{
  PetscInt fStart, fEnd;
  IS       is = nullptr;
  PetscFunctionBeginUser;
  faces.clear();
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));
  if (label) PetscCall(DMLabelGetStratumIS(label, value, &is));
  if (!is) PetscFunctionReturn(0);
  PetscInt        n;
  const PetscInt *pts;
  PetscCall(ISGetLocalSize(is, &n));
  PetscCall(ISGetIndices(is, &pts));
  for (PetscInt j = 0; j < n; ++j)
    if (pts[j] >= fStart && pts[j] < fEnd) faces.push_back(pts[j]);
  PetscCall(ISRestoreIndices(is, &pts));
  PetscCall(ISDestroy(&is));
  PetscFunctionReturn(0);
}

// PETSc's regular refinement. The transform is kept until the parent map is read: it knows the source
// point of every new point.
static PetscErrorCode RefineWithTransform(DM coarse, DM *fine, std::vector<PetscInt> *parent)
{
  DMPlexTransform tr;
  PetscFunctionBeginUser;
  PetscCall(DMPlexTransformCreate(PetscObjectComm((PetscObject)coarse), &tr));
  PetscCall(DMPlexTransformSetDM(tr, coarse));
  PetscCall(DMPlexTransformSetType(tr, DMPLEXREFINEREGULAR));
  PetscCall(DMPlexTransformSetUp(tr));
  PetscCall(DMPlexTransformApply(tr, coarse, fine));
  if (parent) {
    PetscInt fStart, fEnd, cStart;
    PetscCall(DMPlexGetHeightStratum(coarse, 0, &cStart, NULL));
    PetscCall(DMPlexGetHeightStratum(*fine, 0, &fStart, &fEnd));
    parent->resize(fEnd - fStart);
    for (PetscInt c = fStart; c < fEnd; ++c) {
      DMPolytopeType ct, rct;
      PetscInt       source, replica;
      PetscCall(DMPlexTransformGetSourcePoint(tr, c, &ct, &rct, &source, &replica));
      (*parent)[c - fStart] = source - cStart;
    }
  }
  PetscCall(DMPlexTransformDestroy(&tr));
  PetscFunctionReturn(0);
}

PetscErrorCode MeshRefine(DM coarse, DM *fine, std::vector<PetscInt> *parent, Refinement how)
{
  PetscFunctionBeginUser;
  if (how == Refinement::Direct) PetscCall(RefineSimplices(coarse, fine, parent));
  else PetscCall(RefineWithTransform(coarse, fine, parent));
  PetscCall(DMPlexSetRegularRefinement(*fine, PETSC_TRUE));
  PetscCall(PetscObjectSetName((PetscObject)*fine, "mesh"));
  PetscFunctionReturn(0);
}

PetscErrorCode MeshLevelsDestroy(MeshLevels &levels)
{
  PetscFunctionBeginUser;
  for (DM &l : levels.dm) PetscCall(DMDestroy(&l));
  levels = MeshLevels();
  PetscFunctionReturn(0);
}

PetscErrorCode MeshCreate(MPI_Comm comm, const MeshOptions &o, DM *dm, MeshInfo &info, MeshLevels *levels, PetscInt keep, const std::function<PetscErrorCode(DM)> &checkCoarse)
{
  PetscMPIInt size;
  PetscInt    cStart, cEnd;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(CheckPartitioner(comm, o.partitioner));

  PetscCall(StagePush(Stage::Mesh));
  if (o.file.empty()) PetscCall(CreateBox(comm, o, dm, info.description));
  else PetscCall(CreateFromGmsh(comm, o, dm, info.description));
  PetscCall(PetscObjectSetName((PetscObject)*dm, "mesh"));
  PetscCall(DMPlexGetHeightStratum(*dm, 0, &cStart, &cEnd));
  PetscInt local = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(&local, &info.coarseCells, 1, MPIU_INT, MPI_SUM, comm));
  PetscCall(StagePop(Stage::Mesh));

  PetscCall(StagePush(Stage::Distribute));
  if (size > 1) {
    if (o.partitioner == "metis") PetscCall(PartitionWithMetis(*dm, info.edgeCut));
    else {
      PetscPartitioner partitioner;
      PetscCall(DMPlexGetPartitioner(*dm, &partitioner));
      PetscCall(PetscPartitionerSetType(partitioner, o.partitioner.c_str()));
    }
    DM dist = nullptr;
    PetscCall(DMPlexDistribute(*dm, 0, NULL, &dist)); // overlap 0: every local cell is owned, none counted twice
    if (dist) {
      PetscCall(DMDestroy(dm));
      *dm = dist;
    }
  }
  PetscCall(StagePop(Stage::Distribute));
  if (checkCoarse) PetscCall(checkCoarse(*dm));

  PetscCall(StagePush(Stage::Refine));
  // Level k (0 = distributed coarse mesh) is kept when it is among the `keep` levels below the fine one.
  const PetscInt first = levels ? (keep < 0 ? 0 : PetscMax(0, o.refine - keep)) : o.refine;
  if (levels) {
    PetscCall(MeshLevelsDestroy(*levels));
    levels->parent.emplace_back();
  }
  for (PetscInt k = 0; k < o.refine; ++k) {
    DM                    fine = nullptr;
    std::vector<PetscInt> parent;
    PetscCall(MeshRefine(*dm, &fine, k >= first ? &parent : nullptr, o.refinement));
    if (k >= first) {
      levels->dm.push_back(*dm); // the level's reference moves into `levels`
      levels->parent.push_back(std::move(parent));
    } else PetscCall(DMDestroy(dm));
    *dm = fine;
  }
  PetscCall(PetscObjectSetName((PetscObject)*dm, "mesh"));
  if (levels) {
    PetscCall(PetscObjectReference((PetscObject)*dm));
    levels->dm.push_back(*dm);
  }
  PetscCall(StagePop(Stage::Refine));

  PetscCall(DMPlexGetHeightStratum(*dm, 0, &cStart, &cEnd));
  local = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(&local, &info.cells, 1, MPIU_INT, MPI_SUM, comm));
  info.cellsPerRank.assign(size, 0);
  PetscCallMPI(MPI_Allgather(&local, 1, MPIU_INT, info.cellsPerRank.data(), 1, MPIU_INT, comm));
  PetscCall(DMViewFromOptions(*dm, NULL, "-dm_view"));
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/mesh.h"
#include "signorini/gmsh.h"
#include "signorini/localrefine.h"
#include "signorini/options.h"
#include "signorini/refine.h"
#include "signorini/sizes.h"
#include "signorini/stages.h"

#include <metis.h>
#include <petsc/private/dmpleximpl.h> // DM_Plex and its cone section: CellVertexReader reads the cones directly

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

namespace signorini {

// Counts and corners of the box: one value for every direction, or exactly one per direction.
template <typename T>
static PetscErrorCode BoxValues(MPI_Comm comm, const char *option, PetscInt dim, bool set, const std::vector<T> &given, T values[3])
{
  PetscFunctionBeginUser;
  if (!set) PetscFunctionReturn(0);
  if (given.size() != 1 && (PetscInt)given.size() != dim) SIGNORINI_INPUT_ERROR(comm, "option %s: %d values for a %dD box; give one value (all directions) or %d", option, (int)given.size(), (int)dim, (int)dim);
  for (PetscInt d = 0; d < 3; ++d) values[d] = given.size() == 1 ? given[0] : d < dim ? given[d] : values[d];
  PetscFunctionReturn(0);
}

PetscErrorCode MeshOptionsFromCommandLine(MPI_Comm comm, MeshOptions &o)
{
  PetscInt               diag = (PetscInt)o.diagonal, how = (PetscInt)o.refinement;
  bool                   setFaces = false, setLower = false, setUpper = false;
  PetscMPIInt            size;
  std::vector<PetscInt>  faces;
  std::vector<PetscReal> lower, upper;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Mesh options", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-mesh_file", "Gmsh .msh file (physical groups name boundary parts); default: built-in box", o.file));
  PetscCall(OptionInt(PetscOptionsObject, "-dim", "Dimension of the built-in box (2 or 3); with -mesh_file, the dimension the file's mesh must have", o.dim, 2, 3, &o.dimSet));
  faces.assign(o.faces, o.faces + o.dim); // the defaults, as -help shows them
  lower.assign(o.lower, o.lower + o.dim);
  upper.assign(o.upper, o.upper + o.dim);
  PetscCall(OptionIntList(PetscOptionsObject, "-box_faces", "Cells per direction of the box: one count for every direction (64) or one per direction (64,32); built as the coarsest box that refines to it, see -box_coarsen", faces, 1, PETSC_MAX_INT, &setFaces));
  PetscCall(OptionRealList(PetscOptionsObject, "-box_lower", "Lower corner of the box: one coordinate for every direction or one per direction", lower, &setLower));
  PetscCall(OptionRealList(PetscOptionsObject, "-box_upper", "Upper corner of the box: one coordinate for every direction or one per direction", upper, &setUpper));
  PetscCall(OptionEList(PetscOptionsObject, "-box_diagonal", "2D: how each square is cut: slash (0,0)-(1,1), backslash (1,0)-(0,1), crossed (4 triangles; built directly, without -box_coarsen)", {"slash", "backslash", "crossed"}, diag));
  PetscCall(OptionBool(PetscOptionsObject, "-box_coarsen", "Build the box as the coarsest box whose uniform refinement is the same mesh (slash, backslash, 3D), refined in parallel (0: build it on rank 0 as asked)", o.coarsen));
  PetscCall(OptionInt(PetscOptionsObject, "-refine", "Uniform refinements in parallel after distribution", o.refine, 0, PETSC_MAX_INT));
  PetscCall(OptionEList(PetscOptionsObject, "-mesh_refinement", "How the mesh is refined: direct (the fine DMPlex built from the coarse one) or transform (PETSc's DMPlexTransform; the same mesh, slower)", {"direct", "transform"}, how));
  PetscCall(OptionBool(PetscOptionsObject, "-memory_check", "Refuse, before building anything, a run whose predicted peak memory exceeds the memory of the machine (per rank: its node's memory over the ranks on the node)", o.memoryCheck));
  PetscCall(OptionReal(PetscOptionsObject, "-memory_limit", "Memory of each node in GB that the memory checks assume, e.g. a job's limit (0: the machine's, or its control group's limit)", o.memoryLimit, 0));
  PetscCall(OptionString(PetscOptionsObject, "-mesh_partitioner", "metis (libmetis on the coarse cell graph) or a PetscPartitioner type (ptscotch, simple)", o.partitioner));
  PetscOptionsEnd();
  o.diagonal   = (Diagonal)diag;
  o.refinement = (Refinement)how;
  if (o.file.empty()) {
    PetscCall(BoxValues(comm, "-box_faces", o.dim, setFaces, faces, o.faces));
    PetscCall(BoxValues(comm, "-box_lower", o.dim, setLower, lower, o.lower));
    PetscCall(BoxValues(comm, "-box_upper", o.dim, setUpper, upper, o.upper));
    for (PetscInt d = 0; d < o.dim; ++d)
      if (!(o.lower[d] < o.upper[d])) SIGNORINI_INPUT_ERROR(comm, "options -box_lower/-box_upper: lower %g is not below upper %g in direction %" PetscInt_FMT, (double)o.lower[d], (double)o.upper[d], d);
  }
  PetscCallMPI(MPI_Comm_size(comm, &size));
  CoarsenBox(o, size);
  PetscFunctionReturn(0);
}

// METIS balances the coarse cells to within a few per cent, and each refinement keeps the proportions:
// some tens of coarse cells per rank give every rank its share of the fine mesh. Fewer make the partition
// coarse-grained (one cell more or less is a large fraction), more make the serial start larger for
// nothing: 64 puts 2D N = 64 at box 8 (128 cells) on 1 and 2 ranks, the fast path documented before.
static const PetscInt kMinCoarseCellsPerRank = 64;

void CoarsenBox(MeshOptions &o, PetscMPIInt ranks)
{
  o.coarsened = 0;
  if (!o.file.empty() || !o.coarsen || (o.dim == 2 && o.diagonal == Diagonal::Crossed)) return;
  const auto cells = [&o](PetscInt k) {
    PetscInt64 n = o.dim == 2 ? 2 : 6;
    for (PetscInt d = 0; d < o.dim; ++d) n *= o.faces[d] >> k;
    return n;
  };
  const auto halves = [&o](PetscInt k) { // every count is n 2^(k+1) with n >= 1
    for (PetscInt d = 0; d < o.dim; ++d)
      if ((o.faces[d] >> k) % 2) return false;
    return true;
  };
  PetscInt k = 0;
  while (halves(k) && cells(k + 1) >= kMinCoarseCellsPerRank * (PetscInt64)ranks && o.refine + k < PETSC_MAX_INT) ++k;
  for (PetscInt d = 0; d < o.dim; ++d) o.faces[d] >>= k;
  o.refine += k;
  o.coarsened = k;
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
    // Kuhn (Freudenthal) split: one tetrahedron per monotone path x0 = corner 000, x1, x2, x3 = corner 111.
    // Listed as (x0, x2, x1, x3): both refinements cut the inner octahedron along the diagonal between the
    // midpoints of v0v1 and v2v3, here m02-m13, and that cut makes the eight children the Kuhn cells of the
    // box with twice the cells (also in their own refinements): a refined Kuhn box is the finer Kuhn box
    // (tests/unit_fastpath.cpp), which the fast path of -box_faces relies on. The orientation fix below
    // swaps v2 and v3, which keeps the two pairs.
    const PetscInt perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (PetscInt k = 0; k < L; ++k)
      for (PetscInt j = 0; j < M; ++j)
        for (PetscInt i = 0; i < N; ++i)
          for (const auto &p : perms) {
            PetscInt pos[3] = {i, j, k}, x[4];
            x[0] = vid(pos[0], pos[1], pos[2]);
            for (PetscInt s = 0; s < 3; ++s) {
              pos[p[s]]++;
              x[s + 1] = vid(pos[0], pos[1], pos[2]);
            }
            cells.insert(cells.end(), {x[0], x[2], x[1], x[3]});
          }
  }
  const PetscInt nc = (PetscInt)cells.size() / (dim + 1);
  for (PetscInt c = 0; c < nc; ++c) {
    PetscInt *v   = &cells[c * (dim + 1)];
    PetscReal det = SimplexDet(dim, v, X);
    if (dim == 2 && det < 0) std::swap(v[1], v[2]);
    if (dim == 3 && det > 0) std::swap(v[2], v[3]);
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

std::string BoxName(const MeshOptions &o)
{
  const PetscInt k = o.coarsened;
  if (o.dim == 2) return Format("box %" PetscInt_FMT "x%" PetscInt_FMT, o.faces[0] << k, o.faces[1] << k);
  return Format("box %" PetscInt_FMT "x%" PetscInt_FMT "x%" PetscInt_FMT, o.faces[0] << k, o.faces[1] << k, o.faces[2] << k);
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
  // What was asked, and how it was built.
  static const char *diag[] = {"slash", "backslash", "crossed"};
  MeshOptions        built  = o;
  built.coarsened           = 0;
  description               = BoxName(o) + (o.dim == 2 ? std::string(" ") + diag[(int)o.diagonal] : std::string());
  if (o.coarsened > 0) description += Format(" (built as %s refined %d times)", BoxName(built).c_str(), (int)o.coarsened);
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
  CellVertexReader reader;
  PetscFunctionBeginUser;
  PetscCall(reader.Init(dm, false));
  PetscCheck(reader.Dim() == dim, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "CellVertices: a %d-dimensional mesh, not %d", (int)reader.Dim(), (int)dim);
  reader.Vertices(p, verts);
  PetscFunctionReturn(0);
}

PetscErrorCode CellVertexReader::Init(DM dm, bool strides)
{
  PetscBool plex;
  PetscInt  cStart, cEnd, fStart, fEnd, eStart, eEnd;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)dm, DMPLEX, &plex));
  PetscCheck(plex, PetscObjectComm((PetscObject)dm), PETSC_ERR_ARG_WRONG, "CellVertexReader: not a DMPlex");
  PetscCall(DMGetDimension(dm, &dim_));
  PetscCheck(dim_ == 2 || dim_ == 3, PetscObjectComm((PetscObject)dm), PETSC_ERR_SUP, "CellVertexReader: a %d-dimensional mesh", (int)dim_);
  // The cone of p starts at the cone section's offset of p (PetscSectionGetOffset reads the same entry).
  const DM_Plex *mesh = (const DM_Plex *)dm->data;
  pStart_  = mesh->coneSection->pStart;
  offsets_ = mesh->coneSection->atlasOff;
  cones_   = mesh->cones;
  cell_ = face_ = edge_ = Kind();
  if (!strides) PetscFunctionReturn(0);
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));
  PetscCall(DMPlexGetDepthStratum(dm, 1, &eStart, &eEnd));
  PetscCall(InitKind(cStart, cEnd, dim_ + 1, cell_));
  PetscCall(InitKind(fStart, fEnd, dim_, face_));
  PetscCall(InitKind(eStart, eEnd, 2, edge_));
  PetscFunctionReturn(0);
}

// Strided if every point's offset is the first one's plus size per point before it (one pass over the
// stratum's offsets, in order: a few milliseconds at 10^6 cells).
PetscErrorCode CellVertexReader::InitKind(PetscInt start, PetscInt end, PetscInt size, Kind &k) const
{
  PetscFunctionBeginUser;
  k = Kind();
  if (start >= end) PetscFunctionReturn(0);
  const PetscInt *off  = offsets_ + (start - pStart_);
  bool            even = true;
  for (PetscInt p = 0; p < end - start; ++p) even = even && off[p] == off[0] + p * size;
  if (even) k.start = start, k.base = off[0], k.stride = size;
  PetscFunctionReturn(0);
}

namespace {
// Whether v is among the n vertices f.
template <int N>
inline bool On(const PetscInt *f, PetscInt v)
{
  bool on = false;
  for (int i = 0; i < N; ++i) on = on || f[i] == v;
  return on;
}
} // namespace

// The vertices of faces 0 .. D-1 decide everything: the cell's vertices are face 0's and the one of face 1
// that is not on face 0, vertex k (k < D) is the one not on face k, and the last is the one left. A face's
// vertices are found as SimplexVertices finds them (an edge: its cone; a triangle: its first edge's and
// the vertex of its second edge not on the first).
template <int D>
void CellVertexReader::Vertices(PetscInt p, PetscInt verts[4]) const
{
  const PetscInt *cone = Cone(cell_, p);
  PetscInt        face[D][D], all[D + 1] = {};
  for (int k = 0; k < D; ++k) {
    const PetscInt *f = Cone(face_, cone[k]);
    if (D == 2) face[k][0] = f[0], face[k][1] = f[1];
    else {
      const PetscInt *a = Cone(edge_, f[0]), *b = Cone(edge_, f[1]);
      face[k][0] = a[0], face[k][1] = a[1];
      face[k][D - 1] = On<2>(a, b[0]) ? b[1] : b[0];
    }
  }
  for (int i = 0; i < D; ++i) all[i] = face[0][i];
  for (int i = 0; i < D; ++i)
    if (!On<D>(face[0], face[1][i])) all[D] = face[1][i];
  bool used[D + 1] = {};
  for (int k = 0; k < D; ++k)
    for (int j = 0; j <= D; ++j)
      if (!On<D>(face[k], all[j])) verts[k] = all[j], used[j] = true;
  for (int j = 0; j <= D; ++j)
    if (!used[j]) verts[D] = all[j];
}

template <int D>
void CellVertexReader::Prefetch(PetscInt p, int round) const
{
  const PetscInt *cone = Cone(cell_, p);
  for (int k = 0; k < D; ++k) {
    const PetscInt *f = Cone(face_, cone[k]);
    if (round == 0) __builtin_prefetch(f);
    else if (D == 3) __builtin_prefetch(Cone(edge_, f[0])), __builtin_prefetch(Cone(edge_, f[1]));
  }
}
template void CellVertexReader::Vertices<2>(PetscInt, PetscInt[4]) const;
template void CellVertexReader::Vertices<3>(PetscInt, PetscInt[4]) const;
template void CellVertexReader::Prefetch<2>(PetscInt, int) const;
template void CellVertexReader::Prefetch<3>(PetscInt, int) const;

PetscErrorCode VertexCoordinates(DM dm, std::vector<PetscReal> &x)
{
  PetscInt           dim, vStart, vEnd;
  Vec                coords;
  PetscSection       csec;
  const PetscScalar *xa;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vStart, &vEnd));
  PetscCall(DMGetCoordinatesLocal(dm, &coords));
  PetscCall(DMGetCoordinateSection(dm, &csec));
  PetscCall(VecGetArrayRead(coords, &xa));
  x.resize((vEnd - vStart) * dim);
  for (PetscInt v = vStart; v < vEnd; ++v) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(csec, v, &off));
    for (PetscInt d = 0; d < dim; ++d) x[(v - vStart) * dim + d] = PetscRealPart(xa[off + d]);
  }
  PetscCall(VecRestoreArrayRead(coords, &xa));
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
        // A scene's -dim with another file's mesh: its data and options were written for the other dimension.
        PetscInt dim;
        PetscCall(DMGetDimension(test, &dim));
        if (problem.empty() && o.dimSet && dim != o.dim) problem = Format("options -dim %d and -mesh_file: the mesh of '%s' is %dD; give -dim %d, or no -dim", (int)o.dim, o.file.c_str(), (int)dim, (int)dim);
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
  // METIS has its own index type (32-bit in Debian's libmetis) and PetscInt may be 64-bit: the coarse
  // graph is small (the coarse mesh is), so it is copied rather than cast.
  const PetscInt arcs = nv > 0 ? offsets[nv] : 0;
  PetscCall(CheckAll(comm, arcs <= (PetscInt)std::numeric_limits<idx_t>::max(), Format("the coarse cell graph has %" PetscInt_FMT " arcs, beyond the index range of METIS; use -mesh_partitioner ptscotch", arcs)));
  if (nv > size) {
    std::vector<idx_t> xadj(offsets, offsets + nv + 1), adjncy(adjacency, adjacency + arcs);
    idx_t              nvtx = (idx_t)nv, ncon = 1, nparts = size, options[METIS_NOPTIONS];
    METIS_SetDefaultOptions(options);
    options[METIS_OPTION_NUMBERING] = 0;
    status = METIS_PartGraphKway(&nvtx, &ncon, xadj.data(), adjncy.data(), NULL, NULL, NULL, &nparts, NULL, NULL, options, &objval, part.data());
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

PetscErrorCode MeshRefine(DM coarse, DM *fine, std::vector<PetscInt> *parent, Refinement how)
{
  PetscFunctionBeginUser;
  if (how == Refinement::Direct) PetscCall(RefineSimplices(coarse, fine, parent));
  else PetscCall(TransformRefine(coarse, DMPLEXREFINEREGULAR, nullptr, fine, parent)); // PETSc's regular refinement
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

PetscErrorCode MeshCreate(MPI_Comm comm, const MeshOptions &o, DM *dm, MeshInfo &info, MeshLevels *levels, PetscInt keep, const std::function<PetscErrorCode(DM)> &checkCoarse,
                          const std::function<PetscErrorCode(const MeshCounts &)> &checkSizes)
{
  PetscMPIInt size;
  PetscInt    cStart, cEnd;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(CheckPartitioner(comm, o.partitioner));

  PetscCall(StagePush(Stage::Mesh));
  if (o.file.empty()) {
    if (checkSizes) PetscCall(checkSizes(BoxCounts(o)));
    PetscCall(CreateBox(comm, o, dm, info.description));
  } else {
    PetscCall(CreateFromGmsh(comm, o, dm, info.description));
    if (checkSizes) {
      MeshCounts counts;
      PetscCall(CountMesh(*dm, counts));
      PetscCall(checkSizes(counts));
    }
  }
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

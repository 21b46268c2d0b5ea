// The fast path of -box_faces (see CoarsenBox in mesh.h): a box refined k times must be the very mesh of
// the box with 2^k times the cells per direction built directly. Compared as sets of cells, each cell
// given by its sorted vertex coordinates, gathered from every rank; also that each refined box passes
// DMPlexCheck-style orientation (positive measure: PETSc's check of the direct build).
#include "signorini/mesh.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

using Cell = std::array<double, 12>; // up to 4 vertices, 3 coordinates, sorted lexicographically by vertex

// Every cell of the mesh (all ranks) as its sorted vertex coordinates, rounded to a grid far finer than
// the cells, then sorted.
static PetscErrorCode GatherCells(DM dm, std::vector<Cell> &cells)
{
  PetscInt     dim, cStart, cEnd;
  Vec          coords;
  PetscSection csec;
  const PetscScalar *x;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMGetCoordinatesLocal(dm, &coords));
  PetscCall(DMGetCoordinateSection(dm, &csec));
  PetscCall(VecGetArrayRead(coords, &x));
  std::vector<double> mine;
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscInt v[4];
    PetscCall(CellVertices(dm, c, dim, v));
    std::array<std::array<double, 3>, 4> p{};
    for (PetscInt i = 0; i <= dim; ++i) {
      PetscInt off;
      PetscCall(PetscSectionGetOffset(csec, v[i], &off));
      for (PetscInt d = 0; d < dim; ++d) p[i][d] = std::round(PetscRealPart(x[off + d]) * 1e9) / 1e9;
    }
    std::sort(p.begin(), p.begin() + (dim == 2 ? 3 : 4));
    for (PetscInt i = 0; i < 4; ++i)
      for (PetscInt d = 0; d < 3; ++d) mine.push_back(p[i][d]);
  }
  PetscCall(VecRestoreArrayRead(coords, &x));
  PetscMPIInt size, n = (PetscMPIInt)mine.size();
  MPI_Comm    comm = PetscObjectComm((PetscObject)dm);
  PetscCallMPI(MPI_Comm_size(comm, &size));
  std::vector<PetscMPIInt> counts(size), displs(size, 0);
  PetscCallMPI(MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (PetscMPIInt r = 1; r < size; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(displs[size - 1] + counts[size - 1]);
  PetscCallMPI(MPI_Allgatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm));
  cells.resize(all.size() / 12);
  for (size_t c = 0; c < cells.size(); ++c) std::copy(all.begin() + 12 * c, all.begin() + 12 * (c + 1), cells[c].begin());
  std::sort(cells.begin(), cells.end());
  PetscFunctionReturn(0);
}

static PetscErrorCode Compare(unit::Checker &ck, std::string tag, MeshOptions coarse, PetscInt k, bool expectSame)
{
  if (coarse.refinement == Refinement::Transform) tag += " (PETSc's transform)";
  MeshOptions direct = coarse;
  for (PetscInt d = 0; d < coarse.dim; ++d) direct.faces[d] = coarse.faces[d] << k;
  direct.refine = 0;
  coarse.refine = k;
  DM                a, b;
  MeshInfo          ia, ib;
  std::vector<Cell> ca, cb;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(PETSC_COMM_WORLD, coarse, &a, ia));
  PetscCall(MeshCreate(PETSC_COMM_WORLD, direct, &b, ib));
  PetscCall(GatherCells(a, ca));
  PetscCall(GatherCells(b, cb));
  const bool same = ca == cb;
  ck.Check(same == expectSame, tag, "refined %d cells, direct %d cells: %s", (int)ca.size(), (int)cb.size(), same ? "the same mesh" : "different meshes");
  PetscCall(DMDestroy(&a));
  PetscCall(DMDestroy(&b));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  {
    MeshOptions o;
    o.faces[0] = 2, o.faces[1] = 3;
    for (Diagonal diag : {Diagonal::Slash, Diagonal::Backslash, Diagonal::Crossed}) {
      o.diagonal            = diag;
      const std::string tag = diag == Diagonal::Slash ? "slash" : diag == Diagonal::Backslash ? "backslash" : "crossed";
      for (PetscInt k = 1; k <= 3; ++k) PetscCall(Compare(ck, Format("2D %s box 2x3 refined %d times = box %dx%d", tag.c_str(), (int)k, 2 << k, 3 << k), o, k, diag != Diagonal::Crossed));
    }
    o.dim      = 3;
    o.faces[0] = 1, o.faces[1] = 2, o.faces[2] = 3;
    for (Refinement how : {Refinement::Direct, Refinement::Transform}) {
      o.refinement = how;
      for (PetscInt k = 1; k <= 3; ++k) PetscCall(Compare(ck, Format("3D Kuhn box 1x2x3 refined %d times = box %dx%dx%d", (int)k, 1 << k, 2 << k, 3 << k), o, k, true));
    }
  }
  const int failed = ck.Finish();
  PetscCall(PetscFinalize());
  return failed;
}

// The transfer of a discrete solution (values and active set) from a mesh to a nested finer one, made by
// uniform refinement (nested iteration) or by the refinement of marked cells (adaptive refinement):
// parent[c] is the coarse cell (c - cStart) containing fine cell c, on the same rank (refinement is local).
// The rules, the same for both kinds of refinement:
//   values: every fine DOF gets the coarse u_h of its parent cell at the DOF's point (Space::Value). P1
//     functions are reproduced exactly; a CR function is reproduced exactly inside every coarse cell, and
//     at fine faces on a coarse face, where it may jump, uh takes the mean of the two sides: exactly one
//     fine cell on each side holds such a face, as the fine mesh is conforming. The mean is the usual
//     choice (it prefers neither cell and keeps affine functions, which are continuous, exact). It is
//     made as the sum over all fine cells of all ranks divided by their count, so it does not depend on
//     which rank owns the DOF.
//   active set: a fine contact DOF whose point lies on coarse contact DOFs that are all active (uH = psi
//     there: the coarse vertices of the smallest coarse face containing it for P1, the coarse face
//     containing it for CR) gets uh = psi (lowerh). The values alone would leave half of them off the
//     obstacle for CR (its restriction to a contact face is only zero at the face's centroid).
// uh is not yet projected onto the constraints (Solve does that).
#pragma once

#include "signorini/mesh.h"
#include "signorini/space.h"

namespace signorini {

// The values, onto the fine space.
PetscErrorCode Prolongate(const Space &coarse, Vec uH, const Space &fine, const std::vector<PetscInt> &parent, Vec uh);
// The active set, onto uh (lowerH, lowerh: the contact bounds of the two spaces, ContactLowerBound).
PetscErrorCode TransferActiveSet(const Space &coarse, Vec uH, Vec lowerH, const Space &fine, const std::vector<PetscInt> &parent, Vec lowerh, Vec uh);

// Adaptive refinement may redistribute the fine mesh before its space is built, to balance the load.
// Then the coarse function is evaluated on the fine cells first, and the values travel with their cells.
struct CellValues {
  PetscInt nb = 0; // DOFs per cell
  // Per fine cell (c - cStart): the nb values of the parent's u_h at the cell's DOF points, in the order
  // of the space's cell tables (CellVertices, which the migration keeps), then nb active flags (1: the
  // point lies on active coarse contact DOFs only).
  std::vector<PetscReal> data;
};
// The cells of a mesh that has no space on it yet: their vertices in the order of the cell tables a
// space on it will have (CellVertices), and the vertex coordinates, read straight from the mesh.
class MeshCells {
public:
  PetscErrorCode Init(DM mesh);
  PetscInt       NumCells() const { return cEnd_ - cStart_; }
  // The vertex coordinates of cell c (c - cStart) in the order of the cell tables. For a loop over the
  // cells in order: it starts loading the cones of the cells ahead (CellVertexReader::Prefetch).
  Space::Coords X(PetscInt c) const
  {
    PetscInt      v[4];
    Space::Coords X;
    reader_.PrefetchAhead(cStart_ + c, cEnd_);
    reader_.Vertices(cStart_ + c, v);
    // entry by entry: GCC turns a loop over d into a call of memcpy per vertex
    for (PetscInt k = 0; k <= dim_; ++k) {
      const PetscReal *xv = &x_[(v[k] - vStart_) * dim_];
      X.x[k * dim_] = xv[0], X.x[k * dim_ + 1] = xv[1];
      if (dim_ == 3) X.x[k * dim_ + 2] = xv[2];
    }
    return X;
  }

private:
  CellVertexReader       reader_;
  std::vector<PetscReal> x_; // dim per vertex (v - vStart)
  PetscInt               dim_ = 0, cStart_ = 0, cEnd_ = 0, vStart_ = 0;
};
// On the fine mesh alone (no space on it yet). Without lowerH no DOF is flagged active. With the corners
// of a bisection (RefineMarkedBisection) the DOF points are placed in their parents by them, else by the
// fine mesh's coordinates.
PetscErrorCode EvaluateOnCells(const Space &coarse, Vec uH, Vec lowerH, DM fine, const std::vector<PetscInt> &parent, CellValues &cv, const std::vector<char> *corners = nullptr);
// Collective: the distribution of `mesh` by PETSc's parallel partitioner (PTScotch; nothing is gathered
// on one rank): *dist is the redistributed mesh and *migration the star forest from the points of `mesh`
// to those of *dist (both null on one rank).
PetscErrorCode RedistributeMesh(DM mesh, DM *dist, PetscSF *migration);
// Moves cv from the cells of `from` to those of `to` along the migration of RedistributeMesh.
PetscErrorCode MigrateCellValues(DM from, PetscSF migration, DM to, CellValues &cv);
// uh on the fine space from the values of its cells; with lowerh also the active set.
PetscErrorCode ApplyCellValues(const Space &fine, const CellValues &cv, Vec lowerh, Vec uh);

} // namespace signorini

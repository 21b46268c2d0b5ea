// Nested iteration for the contact solve: the problem is solved on the coarsest mesh of the refinement
// hierarchy first, each solution is prolongated to the next finer mesh (values and active set) and
// projected onto its constraints, and serves there as the initial guess, up to the finest mesh. The
// active set is then nearly right before the first Newton step on the finest mesh, so the number of
// Newton steps there stays small as the mesh is refined. Every level stops at the absolute residual its
// own solve from u_D would reach (see Solve), so the final discrete solution is the same to solver
// tolerance as without nested iteration.
#pragma once

#include "signorini/mesh.h"
#include "signorini/pipeline.h"

namespace signorini {

struct NestedOptions {
  bool     enabled = true; // -nested: used when there is a contact part and a coarser level (-refine > 0)
  PetscInt levels  = -1;   // -nested_levels: coarse levels solved before the finest one (-1: every refinement level)
};
PetscErrorCode NestedOptionsFromCommandLine(MPI_Comm comm, NestedOptions &o);

// Prolongation P from the space on a mesh (coarse) to the same kind of space on its uniform refinement
// (fine), parent[c] = the coarse cell (c - cStart) containing fine cell c: uh = P uH interpolates the
// coarse function at the fine DOF points (vertices for P1, face centroids for CR). P1 functions are
// reproduced exactly; a CR function is reproduced exactly inside every coarse cell, and at fine faces on
// a coarse face, where it may jump, uh takes the mean of the two sides. Parallel: refinement is local,
// so every fine cell's parent is on the same rank. uh is not yet projected onto the constraints.
PetscErrorCode Prolongate(const Space &coarse, Vec uH, const Space &fine, const std::vector<PetscInt> &parent, Vec uh);

// Active-set transfer: a fine contact DOF whose point lies on coarse contact DOFs that are all active
// (uH = psi there: the coarse vertices of the smallest coarse face containing it for P1, the coarse face
// containing it for CR) gets uh = psi (lowerh). The prolongated values alone would leave half of them off
// the obstacle for CR (its restriction to a contact face is only zero at the face's centroid).
PetscErrorCode TransferActiveSet(const Space &coarse, Vec uH, Vec lowerH, const Space &fine, const std::vector<PetscInt> &parent, Vec lowerh, Vec uh);

// The whole contact solve with nested iteration: levels.dm[0 .. Count()-2] are set up and solved through
// the pipeline (pipeline.h), each from the prolongation of the one before, and the finest level, which
// the caller has set up (PipelineSetUp), is solved from the last prolongation. The coarse levels use the
// options o without the linear comparison and the KKT warning. fine.result receives the finest solve plus
// one entry per level in result.levels and the time of all solves together in result.solveSeconds. Each
// coarse mesh of `levels` is destroyed (its entry set to NULL) once its level's space is built, and each
// parent map once it has been used, so that the solves, and above all the finest one, the peak of the
// run's memory, do not hold them.
PetscErrorCode NestedSolve(MeshLevels &levels, const Problem &problem, const PipelineOptions &o, MeshSolution &fine);
} // namespace signorini

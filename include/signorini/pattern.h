// The stiffness matrix of a space, created with its exact nonzero pattern computed from the cell-to-DOF
// table: DOF i couples with DOF j exactly when some cell holds both. This replaces DMCreateMatrix, whose
// generic preallocation (DMPlexPreallocate) walks the mesh topology and costs seconds per million DOFs.
//
// With an overlap-0 distribution a row may receive contributions from cells of other ranks (a shared
// vertex or face): each rank sends the columns its own cells give to the rows it does not own to their
// owners, which merge them into their counts.
#pragma once

#include "signorini/space.h"

namespace signorini {

// Per owned row: the number of distinct columns inside (diag) and outside (offdiag) the owned column range.
struct RowCounts {
  std::vector<PetscInt> diag, offdiag;
};

// Collective. Counts of the rows owned by this rank.
PetscErrorCode ComputeRowCounts(const Space &space, RowCounts &counts);

// Collective. An AIJ matrix (SEQAIJ on one rank, MPIAIJ on several) preallocated exactly, carrying the DM's
// local-to-global mapping (for MatSetValuesLocal with local DOF indices), marked symmetric, and set to fail
// on any insertion outside the pattern (MAT_NEW_NONZERO_ALLOCATION_ERR).
PetscErrorCode CreateStiffnessMatrix(const Space &space, Mat *A);

} // namespace signorini

// The stiffness matrix of a space, created with its exact nonzero pattern computed from the cell-to-DOF
// table: DOF i couples with DOF j exactly when some cell holds both. This replaces DMCreateMatrix, whose
// generic preallocation (DMPlexPreallocate) walks the mesh topology and costs seconds per million DOFs.
//
// With an overlap-0 distribution a row may receive contributions from cells of other ranks (a shared
// vertex or face): each rank sends the columns its own cells give to the rows it does not own to their
// owners, which merge them into their rows.
#pragma once

#include "signorini/space.h"

namespace signorini {

// Collective. An AIJ matrix (SEQAIJ on one rank, MPIAIJ on several) preallocated exactly, its owned rows
// complete with their column indices (values zero, not yet assembled: fill it with StiffnessFill, or
// MatSetValues, then MatAssemblyBegin/End), carrying the space's local-to-global mapping (for
// MatSetValuesLocal with local DOF indices), marked symmetric, and set to fail on any insertion outside
// the pattern (MAT_NEW_NONZERO_ALLOCATION_ERR).
PetscErrorCode CreateStiffnessMatrix(const Space &space, Mat *A);

// Adds element matrices into a matrix from CreateStiffnessMatrix before its assembly by writing into its
// value arrays: an entry of a row this rank owns is found among the few columns of that row, where
// MatSetValuesLocal maps and searches every entry and inserts into rows still growing; a row
// another rank owns goes through MatSetValues to its owner at the assembly, as before. Each value is added
// where and in the order MatSetValuesLocal would add it, so the matrix is the same bit for bit.
class StiffnessFill {
public:
  PetscErrorCode Begin(const Space &space, Mat A);
  // Ke: Nb x Nb, row-major, for the local DOFs dofs[0 .. Nb).
  PetscErrorCode Add(const PetscInt *dofs, const PetscReal *Ke);
  // Before MatAssemblyBegin.
  PetscErrorCode End();

private:
  Mat                   A_ = nullptr, blocks_[2] = {nullptr, nullptr}; // the diagonal and off-diagonal blocks
  PetscInt              nb_ = 0;
  const PetscInt       *ia_[2] = {nullptr, nullptr}, *ja_[2] = {nullptr, nullptr};
  PetscScalar          *va_[2] = {nullptr, nullptr};
  std::vector<PetscInt> global_; // global index of each local DOF
  std::vector<PetscInt> row_;    // owned row of each local DOF (global - first owned), -1 for another rank's
};

} // namespace signorini

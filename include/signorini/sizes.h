// Sizes are checked before the work: from the coarse mesh (a box: arithmetically, before its cells are
// listed; a Gmsh file: once read) and the refinements asked for (-refine, and a study's -study_levels and
// -reference_refine), the run predicts the points of its finest mesh, the DOFs of its elements, the matrix
// nonzeros and the memory at its peak. A count beyond the 32-bit index range of the PETSc build, or a
// peak beyond the memory of the machine, stops the run with one line before anything is built, instead
// of an index overflow deep inside PETSc or the kernel's out-of-memory killer minutes later.
//
// Counts are doubles: exact to 2^53, and a refinement count of 40 gives 10^25 points without overflow.
#pragma once

#include "signorini/mesh.h"
#include "signorini/space.h"
#include "signorini/study.h"

namespace signorini {

// The points of a simplex mesh by dimension (f: faces of a 3D mesh; 0 in 2D).
struct MeshCounts {
  PetscInt dim = 2;
  double   v = 0, e = 0, f = 0, c = 0;
  double   Points() const { return v + e + f + c; }
  // Cone entries (cells, faces and edges with their cones): the largest array a DMPlex indexes.
  double ConeEntries() const { return dim == 2 ? 3 * c + 2 * e : 4 * c + 3 * f + 2 * e; }
};

// The coarse box of `o` (its `faces`, not yet refined), from the grid: no cell list needed.
MeshCounts BoxCounts(const MeshOptions &o);
// Collective: the points of a mesh, summed over the ranks (exact before distribution, when no point is
// shared).
PetscErrorCode CountMesh(DM dm, MeshCounts &m);
// After `times` uniform refinements: 2D V' = V + E, E' = 2E + 3C, C' = 4C; 3D V' = V + E,
// E' = 2E + 3F + C, F' = 4F + 8C, C' = 8C (each edge gets a midpoint and two halves, each triangle three
// inner edges, each tetrahedron eight inner faces and one inner edge).
MeshCounts Refined(MeshCounts m, PetscInt times);
double     Dofs(const MeshCounts &m, Element e);
double     Nonzeros(const MeshCounts &m, Element e); // of the stiffness matrix, Dirichlet rows included
// The predicted peak resident memory of a rank is FixedBytes() plus its share of SolveBytes (below).

// Collective: the check itself, called with the coarse mesh's counts (MeshCreate's size hook). `o` says
// what was asked (the box or file, the refinements); the element and the study say what is solved.
// Raises a one-line input error on every rank.
PetscErrorCode CheckSizes(MPI_Comm comm, const MeshOptions &o, const MeshCounts &coarse, Element element, const StudyOptions &study);

// The memory a solve of `dofs` DOFs adds (summed over the ranks), beyond the fixed part of every rank
// (see sizes.cpp).
double SolveBytes(PetscInt dim, Element e, double dofs);
// The fixed part of every rank's memory (MPI, PETSc, hypre).
double FixedBytes();
// Collective: whether `variable` bytes (summed over the ranks, shared equally) and the fixed part of every
// rank fit the memory of the nodes of `comm` (limitGB > 0: -memory_limit, per node, instead of the
// machine's); need: how much, against what, for a message.
PetscErrorCode MemoryFits(MPI_Comm comm, double variable, double limitGB, bool &fits, std::string &need);

} // namespace signorini

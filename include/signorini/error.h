// Errors of a discrete solution against the exact solution: L2 norm, broken H1 seminorm (sum over cells
// of |grad(u - u_h)|^2, the natural norm for the nonconforming CR element), the full broken H1 norm, and
// the energy norm ||kappa^{1/2} grad_h (u - u_h)|| that the estimate (estimate.h) bounds.
#pragma once

#include "signorini/assembly.h"

namespace signorini {

struct ErrorNorms {
  PetscReal l2 = 0, h1semi = 0, h1 = 0, energy = 0;
  PetscReal exactEnergy = 0; // ||kappa^{1/2} grad u|| of the exact solution (ErrorAgainstExact; 0 elsewhere)
};

// Degree of the quadrature used for error integrals (exact for polynomial integrands of that degree).
PetscErrorCode ErrorOptionsFromCommandLine(MPI_Comm comm, PetscInt &degree);
// Pushes the Error stage. The energy norm takes kappa per cell from sys (sys.kappa, which SystemDestroy keeps).
PetscErrorCode ErrorAgainstExact(const Space &space, const Problem &problem, const System &sys, Vec u, PetscInt degree, ErrorNorms &e);

// Error of a coarse solution uH against a reference uh on a nested refinement of the same distributed mesh:
// parent[c] is the coarse cell (c - cStart) containing fine cell c. Both functions are affine on every fine
// cell, so the integrals are computed exactly (degree-2 rule on the fine cells). Fully parallel: the
// refinement is local to each rank, so every fine cell's parent is on the same rank. kappa per fine cell
// from fineSys.
PetscErrorCode ErrorAgainstReference(const Space &coarse, Vec uH, const Space &fine, const System &fineSys, Vec uh, const std::vector<PetscInt> &parent, ErrorNorms &e);

} // namespace signorini

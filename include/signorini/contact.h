// The solve: with a contact part, the variational inequality A u >= b-type problem u in K_h is solved by
// SNESVINEWTONRSLS (reduced-space active-set Newton) with lower bounds psi on the contact DOFs; without
// one, a single KSP solve and none of the VI machinery. Default KSP: CG with hypre BoomerAMG. Every
// default can be overridden with the usual -snes_*, -ksp_* and -pc_* options.
//
// After the solve the discrete KKT conditions on Gamma_C are measured. The reaction r = A u - b at a
// contact DOF is divided by the boundary measure that DOF carries (|F| for CR, the lumped sum of |F|/d
// for P1), which approximates the contact pressure kappa du/dn and does not change with the mesh size.
#pragma once

#include "signorini/assembly.h"

namespace signorini {

struct SolveResult {
  bool        vi = false;
  PetscInt    newtonIts = 0, kspIts = 0;
  std::string reason; // SNES (VI) or KSP converged reason
  // KKT on the contact DOFs (only with a contact part)
  PetscReal primal = 0;          // min (u - psi): >= 0
  PetscReal dual = 0;            // min pressure r/m: >= 0
  PetscReal complementarity = 0; // max |(u - psi) * r/m|: 0
  PetscReal pressureMax = 0, gapMax = 0;
  PetscInt  active = 0; // contact DOFs with u = psi
  PetscReal stationarity = 0; // max |r| over DOFs that are neither Dirichlet nor contact, relative to max |load|
  PetscReal energy = 0;
};

// With -help: lists the SNES, KSP and PC options of the default solver without solving anything.
PetscErrorCode SolverOptionsHelp(MPI_Comm comm);
// Writes u_h, psi and the contact pressure at every contact DOF as CSV (x, y[, z], u, psi, pressure),
// sorted by coordinates, gathered on rank 0: the free boundary seen along Gamma_C.
PetscErrorCode WriteContactProfile(const Space &space, const Problem &problem, const System &sys, Vec u, const std::string &file);
// u: global vector of the space, overwritten with the solution. Pushes the Solve stage.
PetscErrorCode Solve(const Space &space, const Problem &problem, const System &sys, Vec u, SolveResult &result);

} // namespace signorini

// The stopping test of -solve_to (nested.h) for the reduced-space contact solve.
//
// SolveOptions::energyError and startError: the solve stops once its algebraic error in the energy norm
// is below a bound. For an admissible v, J(v) - J(u_h) >= |||v - u_h|||^2 / 2 (u_h the discrete
// solution), with equality once v has u_h's active set; so where an iteration contracts this excess
// energy by 1/2 or better per step, the energy decrease of a step, J_{k-1} - J_k, is at least the excess
// left after it, and a decrease below bound^2 / 2 leaves an error below the bound (one step later than an
// oracle would stop). This holds for the Newton steps (full reduced-space steps from a prolongated guess:
// the residual falls by 3 to 60 a step) and for the CG iterations inside one (the multigrid V-cycle: 10
// and more an iteration): a Newton step's linear solve stops at the same decrease, so that it does not
// solve beyond the bound either. With startError the bound is that fraction of the error of the start,
// whose excess energy the first Newton step's decrease J_0 - J_1 measures. The energy of the step's CG
// iterate x is J(u - x) - J(u) = x.A x / 2 - F.x, one product with the block an iteration; at a Newton
// iterate J = (u.F - b.u) / 2 from the residual F the SNES holds.
#pragma once

#include "signorini/contact.h"
#include "signorini/datascale.h"

#include <petscsnes.h>

namespace signorini {

// The state of one solve's test; lives until SNESSolve has returned.
struct EnergyStop {
  Vec       b        = nullptr; // the right-hand side (solver's units)
  PetscReal decrease = 0;       // the energy decrease that ends a solve, in the solver's units (0: none yet)
  PetscReal relative = 0;       // startError: decrease = relative^2 (J_0 - J_1), set after the first step
  PetscReal cg = 0, newton = 0; // the energy of the previous CG iterate and of the previous Newton iterate
  bool      stopped  = false;   // the Newton iteration ended by the energy test
  Vec       Ax       = nullptr; // work vectors of the block's size
  Vec       x        = nullptr;
  void     *kspDefault = nullptr;
  PetscErrorCode Destroy();
};

// Installs the test on snes (a SNESVINEWTONRSLS) and its KSP, for the bounds of opts (energyError and
// startError in the data's units; scale converts them to the solver's).
PetscErrorCode EnergyStopInstall(SNES snes, const System &sys, const SolveOptions &opts, const DataScale &scale, EnergyStop &e);

} // namespace signorini

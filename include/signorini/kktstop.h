// The contact solve ends when its own checks pass: the discrete KKT conditions on Gamma_C and the
// stationarity on the free DOFs (SolveResult::kktRelative, ::stationarity) within -kkt_tolerance.
//
// Why: SNESVI stops on the 2-norm of A u - b over the inactive set, and where some rows are far stiffer
// than others (a kappa jump, stretched cells) the stiff rows dominate that norm. Its test then passes while
// the soft rows still carry residuals of the size of their load: a wrong contact pressure, even a wrong
// active set, and solutions (so estimates, so adapted meshes) that differ with the number of ranks, whose
// smoothers leave different residuals. On meshes of one material and sound cells the checks mostly hold
// where the residual test passes (on fine meshes the pressure, a reaction divided by a boundary measure of
// about h^(d-1), may take one step more), and reading them once costs a pass over the owned DOFs.
//
// How: where the wrapped test says converged and the checks fail, the solve goes on, each further
// Newton step's linear solve asked for a residual lowered in proportion to how far the checks miss
// (measured, not assumed: the next step checks again), for at most kMaxSteps steps; the round-off floor
// (stall.h, installed after this) ends a solve that cannot get there. The checks' own measure: max norms,
// each relative to its own scale, so the stiff rows do not hide the soft ones.
#pragma once

#include "signorini/contact.h"
#include "signorini/snestest.h"

namespace signorini {

struct KKTStop {
  static constexpr PetscInt kMaxSteps = 10; // Newton steps beyond the wrapped test
  // The residual (2-norm) the next linear solve is asked for, from one of `norm` whose checks reached
  // `worst` against `tolerance`: lowered as far as they miss, with a margin of 100 for the max norms they
  // use against the 2-norm the solvers use, and no lower than 1e-10 of it.
  static PetscReal Lowered(PetscReal norm, PetscReal tolerance, PetscReal worst) { return norm * PetscMax((PetscReal)1e-10, 1e-2 * tolerance / worst); }
  WrappedTest    wrap;
  const Space   *space      = nullptr;
  const Problem *problem    = nullptr;
  const System  *sys        = nullptr;
  Vec            lower      = nullptr; // the bounds, in the solver's units
  Vec            measure    = nullptr; // ContactMeasure, made at the first check
  Vec            rowScale   = nullptr; // where the solver's F is A u - b with its rows scaled by it (SSLS)
  Vec            residual   = nullptr; // A u - b from such an F
  PetscReal      loadFactor = 1;       // the load in the solver's units
  PetscReal      tolerance  = 0;
  PetscInt       steps      = 0; // Newton steps taken beyond the wrapped test
  PetscErrorCode Destroy();
};

// Wraps snes's current convergence test (install it before the stall guard, after every other one) with
// the checks at tolerance; nothing where that test is -snes_convergence_test skip. loadFactor: the load
// in the units of the solve (DataScale). A SNESVINEWTONRSLS only. Collective.
PetscErrorCode KKTStopInstall(SNES snes, const Space &space, const Problem &problem, const System &sys, Vec lower, PetscReal loadFactor, PetscReal tolerance, KKTStop &k);

} // namespace signorini

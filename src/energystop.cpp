#include "signorini/energystop.h"

#include <cmath>

namespace signorini {

PetscErrorCode EnergyStop::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&Ax));
  PetscCall(VecDestroy(&x));
  if (kspDefault) PetscCall(KSPConvergedDefaultDestroy(kspDefault));
  kspDefault = nullptr;
  PetscFunctionReturn(0);
}


static PetscErrorCode EnergyKSPTest(KSP ksp, PetscInt it, PetscReal rnorm, KSPConvergedReason *reason, void *ctx)
{
  auto       *e = static_cast<EnergyStop *>(ctx);
  Mat         A;
  Vec         x, b, with[2];
  PetscScalar dots[2];
  PCSide      side;
  PetscFunctionBeginUser;
  PetscCall(KSPConvergedDefault(ksp, it, rnorm, reason, e->kspDefault));
  PetscCall(KSPGetRhs(ksp, &b));
  PetscCall(KSPGetOperators(ksp, &A, NULL));
  if (it == 0) { // every Newton step has its own block (layout)
    PetscCall(VecDestroy(&e->Ax));
    PetscCall(VecDestroy(&e->x));
    PetscCall(VecDuplicate(b, &e->Ax));
    PetscCall(VecDuplicate(b, &e->x));
  }
  // With a right preconditioner (bcgs, tfqmr, ...) the iterate is built into a vector of ours; with a left
  // one (cg) it is the KSP's own, and no copy is made.
  PetscCall(KSPGetPCSide(ksp, &side));
  PetscCall(KSPBuildSolution(ksp, side == PC_RIGHT ? e->x : NULL, &x));
  PetscCall(MatMult(A, x, e->Ax));
  with[0] = e->Ax;
  with[1] = b;
  PetscCall(VecMDot(x, 2, with, dots));
  const PetscReal energy = 0.5 * PetscRealPart(dots[0]) - PetscRealPart(dots[1]);
  if (it > 0 && *reason == KSP_CONVERGED_ITERATING && e->cg - energy < e->decrease) *reason = KSP_CONVERGED_ATOL;
  e->cg = energy;
  PetscFunctionReturn(0);
}

static PetscErrorCode EnergySNESTest(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm, SNESConvergedReason *reason, void *ctx)
{
  auto       *e = static_cast<EnergyStop *>(ctx);
  Vec         u, F, with[2];
  PetscScalar dots[2];
  PetscFunctionBeginUser;
  PetscCall(SNESConvergedDefault(snes, it, xnorm, snorm, fnorm, reason, NULL));
  PetscCall(SNESGetSolution(snes, &u));
  PetscCall(SNESGetFunction(snes, &F, NULL, NULL));
  with[0] = F;
  with[1] = e->b;
  PetscCall(VecMDot(u, 2, with, dots));
  const PetscReal energy = 0.5 * (PetscRealPart(dots[0]) - PetscRealPart(dots[1]));
  // a step that raised the energy (the projection onto the bounds may) says nothing of the error
  const PetscReal down = e->newton - energy;
  if (it == 1 && e->relative > 0) e->decrease = e->relative * e->relative * PetscMax(down, 0);
  else if (it > 0 && *reason == SNES_CONVERGED_ITERATING && down >= 0 && down < e->decrease) {
    *reason    = SNES_CONVERGED_ITS; // PETSc 3.18 has no reason for a user's test; stoppedBy says which
    e->stopped = true;
  }
  e->newton = energy;
  PetscFunctionReturn(0);
}

PetscErrorCode EnergyStopInstall(SNES snes, const System &sys, const SolveOptions &opts, const DataScale &scale, EnergyStop &e)
{
  KSP ksp;
  PetscFunctionBeginUser;
  e.b        = sys.b;
  e.relative = opts.startError;
  // J in the solver's units is J / (U^2 R) (datascale.h)
  if (opts.energyError > 0) e.decrease = std::ldexp(0.5 * opts.energyError * opts.energyError, -(int)(2 * scale.u + scale.rows));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPConvergedDefaultCreate(&e.kspDefault));
  PetscCall(KSPSetConvergenceTest(ksp, EnergyKSPTest, &e, NULL));
  PetscCall(SNESSetConvergenceTest(snes, EnergySNESTest, &e, NULL));
  PetscFunctionReturn(0);
}

} // namespace signorini

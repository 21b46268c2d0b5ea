#include "signorini/stall.h"

#include <petsc/private/snesimpl.h> // the test in place, to wrap it: PETSc 3.18 has no getter for it

namespace signorini {

PetscErrorCode StallGuard::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(ISDestroy(&before[0]));
  PetscCall(ISDestroy(&before[1]));
  if (innerDestroy) PetscCall(innerDestroy(innerCtx));
  innerDestroy = nullptr;
  PetscFunctionReturn(0);
}

static PetscErrorCode StallTest(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm, SNESConvergedReason *reason, void *ctx)
{
  auto *g = static_cast<StallGuard *>(ctx);
  Vec   x, F;
  IS    active;
  PetscFunctionBeginUser;
  PetscCall(g->inner(snes, it, xnorm, snorm, fnorm, reason, g->innerCtx));
  if (*reason != SNES_CONVERGED_ITERATING) PetscFunctionReturn(0);
  PetscCall(SNESGetSolution(snes, &x));
  PetscCall(SNESGetFunction(snes, &F, NULL, NULL));
  PetscCall(SNESVIGetActiveSetIS(snes, x, F, &active)); // the set the next step will use
  PetscBool same = PETSC_FALSE, same2 = PETSC_FALSE;
  if (g->before[0] && g->before[1]) {
    PetscCall(ISEqualUnsorted(active, g->before[0], &same));
    PetscCall(ISEqualUnsorted(g->before[0], g->before[1], &same2));
  }
  KSP                ksp;
  KSPConvergedReason kspReason;
  KSPNormType        normType;
  PetscReal          kspNorm;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetConvergedReason(ksp, &kspReason));
  PetscCall(KSPGetNormType(ksp, &normType));
  PetscCall(KSPGetResidualNorm(ksp, &kspNorm));
  const bool flat = it > 0 && same && same2 && kspReason > 0 && normType == KSP_NORM_UNPRECONDITIONED && fnorm > StallGuard::kGap * kspNorm && fnorm > 0.5 * g->lastNorm;
  g->stalled      = flat ? g->stalled + 1 : 0;
  g->floor        = g->stalled == 1 ? fnorm : PetscMin(g->floor, fnorm);
  if (g->stalled >= StallGuard::kStalledSteps) {
    *reason    = SNES_DIVERGED_LOCAL_MIN; // PETSc 3.18 has no reason for a stall; stopped says which
    g->stopped = true;
  }
  PetscCall(ISDestroy(&g->before[1]));
  g->before[1] = g->before[0];
  g->before[0] = active;
  g->lastNorm  = fnorm;
  PetscFunctionReturn(0);
}

PetscErrorCode StallGuardInstall(SNES snes, StallGuard &g)
{
  PetscFunctionBeginUser;
  if (snes->ops->converged == SNESConvergedSkip) PetscFunctionReturn(0); // the user asked for -snes_max_it steps
  g.inner        = snes->ops->converged;
  g.innerCtx     = snes->cnvP;
  g.innerDestroy = snes->ops->convergeddestroy;
  snes->ops->convergeddestroy = nullptr; // now the guard's to destroy
  PetscCall(SNESSetConvergenceTest(snes, StallTest, &g, NULL));
  PetscFunctionReturn(0);
}

} // namespace signorini

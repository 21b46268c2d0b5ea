#include "signorini/stall.h"

namespace signorini {

PetscErrorCode StallGuard::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(ISDestroy(&reference));
  PetscCall(wrap.Destroy());
  PetscFunctionReturn(0);
}

static PetscErrorCode StallTest(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm, SNESConvergedReason *reason, void *ctx)
{
  auto              *g = static_cast<StallGuard *>(ctx);
  KSP                ksp;
  KSPConvergedReason kspReason;
  KSPNormType        normType;
  PetscReal          kspNorm;
  PetscFunctionBeginUser;
  PetscCall(g->wrap.Inner(snes, it, xnorm, snorm, fnorm, reason));
  if (*reason != SNES_CONVERGED_ITERATING) PetscFunctionReturn(0);
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetConvergedReason(ksp, &kspReason));
  PetscCall(KSPGetNormType(ksp, &normType));
  PetscCall(KSPGetResidualNorm(ksp, &kspNorm));
  const bool candidate = it > 0 && kspReason > 0 && normType == KSP_NORM_UNPRECONDITIONED && fnorm > 0.5 * g->lastNorm;
  if (candidate && kspNorm == 0) {
    // preonly reports no residual of its own: measured here (a direct solve leaves one far below ||F||,
    // a single V-cycle one near it)
    Vec b, work, res, r;
    PetscCall(KSPGetRhs(ksp, &b));
    PetscCall(VecDuplicate(b, &work));
    PetscCall(VecDuplicate(b, &res));
    PetscCall(KSPBuildResidual(ksp, work, res, &r));
    PetscCall(VecNorm(r, NORM_2, &kspNorm));
    PetscCall(VecDestroy(&work));
    PetscCall(VecDestroy(&res));
  }
  // The norms first: in a solve that still converges no step passes them, and no active set is computed.
  const bool flat = candidate && fnorm > StallGuard::kGap * kspNorm;
  g->lastNorm     = fnorm;
  if (!flat) {
    g->stalled = 0;
    PetscCall(ISDestroy(&g->reference));
    PetscFunctionReturn(0);
  }
  Vec       x, F;
  IS        active;
  PetscBool same = PETSC_FALSE;
  PetscCall(SNESGetSolution(snes, &x));
  PetscCall(SNESGetFunction(snes, &F, NULL, NULL));
  PetscCall(SNESVIGetActiveSetIS(snes, x, F, &active)); // the set the next step will use
  if (g->reference) PetscCall(ISEqualUnsorted(active, g->reference, &same));
  if (same) { // this step started from the reference set and ended with it
    PetscCall(ISDestroy(&active));
    g->stalled++;
    g->floor = PetscMin(g->floor, fnorm);
  } else { // the first flat step of a run: its set is the reference of the next ones
    PetscCall(ISDestroy(&g->reference));
    g->reference = active;
    g->stalled   = 0;
    g->floor     = fnorm;
  }
  if (g->stalled >= StallGuard::kStalledSteps) {
    // PETSc 3.18 has no reason for a stall; stopped says which, and -snes_converged_reason the outcome
    *reason    = g->accept ? SNES_CONVERGED_ITS : SNES_DIVERGED_LOCAL_MIN;
    g->stopped = true;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode StallGuardInstall(SNES snes, bool accept, StallGuard &g)
{
  PetscFunctionBeginUser;
  g.accept = accept;
  PetscCall(g.wrap.Wrap(snes, StallTest, &g));
  PetscFunctionReturn(0);
}

} // namespace signorini

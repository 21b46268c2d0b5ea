#include "signorini/kktstop.h"

#include <algorithm>

namespace signorini {

PetscErrorCode KKTStop::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&measure));
  PetscCall(VecDestroy(&residual));
  PetscCall(wrap.Destroy());
  PetscFunctionReturn(0);
}

static PetscErrorCode KKTTest(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm, SNESConvergedReason *reason, void *ctx)
{
  auto *k = static_cast<KKTStop *>(ctx);
  PetscInt maxit;
  PetscFunctionBeginUser;
  PetscCall(k->wrap.Inner(snes, it, xnorm, snorm, fnorm, reason));
  PetscCall(SNESGetTolerances(snes, NULL, NULL, NULL, &maxit, NULL));
  // Only a stop the wrapped test calls convergence is checked; the last allowed step is not refused (its
  // solution is reported with the KKT warning rather than as a failure).
  if (*reason <= 0 || k->steps >= KKTStop::kMaxSteps || it + 1 >= maxit) PetscFunctionReturn(0);
  Vec x, F;
  PetscCall(SNESGetSolution(snes, &x));
  PetscCall(SNESGetFunction(snes, &F, NULL, NULL));
  if (!k->measure) {
    PetscCall(VecDuplicate(x, &k->measure));
    PetscCall(ContactMeasure(*k->space, *k->problem, k->measure));
  }
  if (k->rowScale) {
    if (!k->residual) PetscCall(VecDuplicate(F, &k->residual));
    PetscCall(VecPointwiseDivide(k->residual, F, k->rowScale));
    F = k->residual;
  }
  SolveResult checks;
  PetscCall(MeasureKKTFromResidual(*k->space, *k->sys, x, F, k->loadFactor, k->lower, k->measure, checks));
  const PetscReal worst = std::max(checks.kktRelative, checks.stationarity);
  if (!(worst > k->tolerance)) PetscFunctionReturn(0);
  // On, the next linear solve asked for less (KKTStop::Lowered)
  KSP       ksp;
  PetscReal rtol, atol, dtol;
  PetscInt  kspMaxit;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &kspMaxit));
  PetscCall(KSPSetTolerances(ksp, rtol, std::min(atol, KKTStop::Lowered(fnorm, k->tolerance, worst)), dtol, kspMaxit));
  k->steps++;
  *reason = SNES_CONVERGED_ITERATING;
  PetscFunctionReturn(0);
}

PetscErrorCode KKTStopInstall(SNES snes, const Space &space, const Problem &problem, const System &sys, Vec lower, PetscReal loadFactor, PetscReal tolerance, KKTStop &k)
{
  PetscFunctionBeginUser;
  if (!(tolerance > 0)) PetscFunctionReturn(0);
  k.space      = &space;
  k.problem    = &problem;
  k.sys        = &sys;
  k.lower      = lower;
  k.loadFactor = loadFactor;
  k.tolerance  = tolerance;
  PetscCall(k.wrap.Wrap(snes, KKTTest, &k));
  PetscFunctionReturn(0);
}

} // namespace signorini

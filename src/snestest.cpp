#include "signorini/snestest.h"

#include <petsc/private/snesimpl.h> // the test in place, to wrap it: PETSc 3.18 has no getter for it

namespace signorini {

PetscErrorCode WrappedTest::Wrap(SNES snes, SNESTest test, void *ctx)
{
  PetscFunctionBeginUser;
  if (snes->ops->converged == SNESConvergedSkip) PetscFunctionReturn(0);
  inner                       = snes->ops->converged;
  innerCtx                    = snes->cnvP;
  innerDestroy                = snes->ops->convergeddestroy;
  snes->ops->convergeddestroy = nullptr; // now this wrapper's to destroy
  PetscCall(SNESSetConvergenceTest(snes, test, ctx, NULL));
  PetscFunctionReturn(0);
}

PetscErrorCode WrappedTest::Destroy()
{
  PetscFunctionBeginUser;
  if (innerDestroy) PetscCall(innerDestroy(innerCtx));
  innerDestroy = nullptr;
  PetscFunctionReturn(0);
}

} // namespace signorini

// A SNES convergence test that wraps the one in place (the SNES's own, or another wrapper): the round-off
// floor (stall.h) and the KKT checks (kktstop.h) each judge only what the test they wrap leaves open.
#pragma once

#include <petscsnes.h>

namespace signorini {

using SNESTest = PetscErrorCode (*)(SNES, PetscInt, PetscReal, PetscReal, PetscReal, SNESConvergedReason *, void *);

struct WrappedTest {
  SNESTest inner    = nullptr;
  void    *innerCtx = nullptr;
  PetscErrorCode (*innerDestroy)(void *) = nullptr;
  // Takes over snes's current test and installs test(ctx) in its place; nothing where the current one is
  // -snes_convergence_test skip (the user asked for -snes_max_it steps). Not collective.
  PetscErrorCode Wrap(SNES snes, SNESTest test, void *ctx);
  // The wrapped test's verdict on this step.
  PetscErrorCode Inner(SNES snes, PetscInt it, PetscReal xnorm, PetscReal snorm, PetscReal fnorm, SNESConvergedReason *reason) const { return inner(snes, it, xnorm, snorm, fnorm, reason, innerCtx); }
  // Destroys the wrapped test's context (after SNESDestroy).
  PetscErrorCode Destroy();
};

} // namespace signorini

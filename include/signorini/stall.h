// The round-off floor of the contact solve's residual: a stopping test that sees when Newton steps no
// longer reduce ||F||, so that a tolerance below what double precision gives ends in a few steps with a
// message naming the floor, not after -snes_max_it steps with DIVERGED_MAX_IT.
//
// Why it cannot stop a solve that still converges: the problem is linear on the inactive set, so after a
// reduced-space step that starts and ends with the same active set, the new residual on the inactive set
// is, in exact arithmetic, the final residual of the step's linear solve (the KSP's unpreconditioned
// norm), however loosely that solve stopped. A step whose new ||F|| exceeds that linear residual kGap
// times and is more than half the ||F|| before is flat: the residual computed afresh carries round-off
// that the linear solver's recursive one does not. The first flat step's active set is the reference;
// kStalledSteps further flat steps in a row that end with it (so each started from it too) stop the
// solve (the floor fluctuates, so a target at the floor still gets a few tries). The active set is
// computed only for flat steps; where it moves, or the KSP measures another norm, nothing is judged.
#pragma once

#include "signorini/snestest.h"

namespace signorini {

struct StallGuard {
  static constexpr PetscInt  kStalledSteps = 5;
  static constexpr PetscReal kGap          = 2;
  WrappedTest    wrap; // the test it wraps (the SNES's own, or the KKT or energy test)
  IS             reference = nullptr; // the active set after the first flat step of the current run
  PetscReal      lastNorm  = 0;
  PetscInt       stalled   = 0;     // flat steps in a row on the reference set
  bool           stopped   = false; // the solve ended on the floor
  bool           accept    = false; // as converged (else diverged)
  PetscReal      floor     = 0;     // the least ||F|| of the run
  PetscErrorCode Destroy();
};

// Wraps snes's current convergence test (install it after every other one), unless that is
// -snes_convergence_test skip; accept: a stop at the floor counts as converged (the caller's target is the
// default one, which stiff rows may put below the floor), else as diverged. A SNESVINEWTONRSLS only.
// Collective.
PetscErrorCode StallGuardInstall(SNES snes, bool accept, StallGuard &g);

} // namespace signorini

// Faster moving of the active set in the reduced-space contact solve when the start is far from the
// solution (a single mesh, no nested iteration: the solve starts from u_D with every contact DOF on psi).
//
// Each Newton step of SNESVINEWTONRSLS frees the contact DOFs on psi whose reaction r = A u - b is negative.
// From a start whose active set is too large (paper-5.1: half of Gamma_C from the sign of the load, the
// solution's about 30 %), the reaction of the over-constrained solve is negative only on about the half of
// the surplus nearest to its edge, so the surplus halves per step and the step count grows like
// log2(DOFs across the surplus): CR N = 1024, 512 -> 409 -> 362 -> ... -> 310 active DOFs in 9 steps, each
// with a new BoomerAMG set-up. Beyond the sign change the reaction is still small; so, from the second
// step in a row that only freed DOFs (more than 2 maxChanged each), a step also frees the active DOFs whose
// reaction is below theta times the largest one, each DOF at most once in a solve. A DOF freed too
// early comes back below psi in the next step and is projected back onto it, the reduced-space rule then
// takes over as usual: the discrete solution is the same (the SNES stops at the same residual, with the
// rule's own active set); only the path is shorter (paper-5.1 N = 1024 from one mesh: CR 9 -> 5 Newton
// steps, 8 -> 4 set-ups; P1 10 -> 6, 8 -> 4). Freeing every DOF at most once keeps a too large theta from
// cycling (0.6 without that rule: the same DOFs freed and taken back for ever); theta 0.3 was measured
// best of 0.2 ... 0.5 at N = 512 and 1024.
#pragma once

#include <petscsnes.h>

#include <vector>

namespace signorini {

struct ReleaseOptions {
  PetscReal theta      = 0.3; // -vi_release_theta (0: the plain reduced-space rule)
  PetscInt  maxChanged = 2;   // the active set moves while more DOFs than this change (-amg_reuse_max_changed)
};
PetscErrorCode ReleaseOptionsFromCommandLine(MPI_Comm comm, ReleaseOptions &o);

// The state of one contact solve; lives until SNESSolve has returned.
struct Release {
  ReleaseOptions    opts;
  Mat               A = nullptr;      // F(u) = A u - b
  Vec               b = nullptr, lower = nullptr, r = nullptr;
  PetscReal         zeroTol = 0;       // SNESVI's bound tolerance: a DOF this close to psi is on it
  PetscReal         offset = 0;        // how far above psi a freed DOF is put (beyond the bound tolerance)
  std::vector<char> active, freed;     // per owned DOF: active after the last step; freed by this rule already
  bool              first = true;
  PetscInt          shrinking = 0;     // steps in a row that freed more than 2 maxChanged DOFs and added none
  PetscInt          count = 0;         // DOFs freed by this rule in the solve (global)
  PetscErrorCode    Destroy();
};

// Installs the rule as the post-check of the SNES's line search (SNESVINEWTONRSLS only; lower: psi on the
// contact DOFs, -infinity elsewhere; zeroTolerance: SNESVI's bound tolerance). Does nothing when theta is 0.
PetscErrorCode ReleaseInstall(SNES snes, Mat A, Vec b, Vec lower, PetscReal zeroTolerance, const ReleaseOptions &o, Release &r);

} // namespace signorini

#include "signorini/release.h"
#include "signorini/options.h"

#include <algorithm>

namespace signorini {

PetscErrorCode ReleaseOptionsFromCommandLine(MPI_Comm comm, ReleaseOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Active set of the contact solve", "signorini");
  PetscCall(OptionReal(PetscOptionsObject, "-vi_release_theta", "Contact solve from a start without nested iteration: while the active set moves, a Newton step also frees the active DOFs whose reaction is below this fraction of the largest one, each at most once (0: only those with a negative reaction)", o.theta, 0, 1));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

PetscErrorCode Release::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&r));
  PetscFunctionReturn(0);
}

namespace {
// The active set as SNESVI sees it at u (on the bound, with a positive reaction res = A u - b); the largest
// reaction over it.
PetscReal MarkActive(const Release &s, const PetscScalar *u, const PetscScalar *l, const PetscScalar *res, PetscInt n, std::vector<char> &active)
{
  PetscReal maxR = 0;
  active.resize(n);
  for (PetscInt i = 0; i < n; ++i) {
    active[i] = PetscRealPart(u[i] - l[i]) <= s.zeroTol && PetscRealPart(res[i]) > 0;
    if (active[i]) maxR = std::max(maxR, PetscRealPart(res[i]));
  }
  return maxR;
}

// The post-check of the line search: X the iterate the step started from, W the new one (already
// projected onto the bounds), before the SNES evaluates F there.
PetscErrorCode ReleaseCheck(SNESLineSearch ls, Vec X, Vec, Vec W, PetscBool *, PetscBool *changedW, void *ctx)
{
  auto              &s = *static_cast<Release *>(ctx);
  MPI_Comm           comm = PetscObjectComm((PetscObject)W);
  PetscScalar       *w;
  const PetscScalar *l, *res;
  PetscInt           n;
  std::vector<char>  now;
  PetscFunctionBeginUser;
  PetscCall(VecGetLocalSize(W, &n));
  PetscCall(VecGetArrayRead(s.lower, &l));
  if (s.first) { // the active set the first step worked with, from the residual the SNES holds at X
    const PetscScalar *x;
    Vec                F;
    PetscCall(SNESLineSearchGetVecs(ls, NULL, &F, NULL, NULL, NULL));
    PetscCall(VecGetArrayRead(X, &x));
    PetscCall(VecGetArrayRead(F, &res));
    MarkActive(s, x, l, res, n, s.active);
    PetscCall(VecRestoreArrayRead(F, &res));
    PetscCall(VecRestoreArrayRead(X, &x));
    s.freed.assign(n, 0);
    s.first = false;
  }
  PetscCall(MatMult(s.A, W, s.r));
  PetscCall(VecAXPY(s.r, -1.0, s.b));
  PetscCall(VecGetArray(W, &w));
  PetscCall(VecGetArrayRead(s.r, &res));
  PetscReal maxR = MarkActive(s, w, l, res, n, now);
  PetscInt  moved[2] = {0, 0}; // freed, added by the step
  for (PetscInt i = 0; i < n; ++i) {
    moved[0] += s.active[i] && !now[i];
    moved[1] += !s.active[i] && now[i];
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, moved, 2, MPIU_INT, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &maxR, 1, MPIU_REAL, MPI_MAX, comm));
  // a second step in a row that only freed DOFs, and more than twice maxChanged: the surplus is shrinking
  // by halves and is still wide (a step that frees only a few is near the end anyway; without this on
  // small meshes freeing more only added steps: manufactured-3d with -nested 0, 5 -> 7)
  s.shrinking = moved[0] > 2 * s.opts.maxChanged && moved[1] == 0 ? s.shrinking + 1 : 0;
  PetscInt freed = 0;
  if (s.shrinking >= 2)
    for (PetscInt i = 0; i < n; ++i)
      if (now[i] && !s.freed[i] && PetscRealPart(res[i]) < s.opts.theta * maxR) {
        w[i]       = l[i] + s.offset;
        now[i]     = 0;
        s.freed[i] = 1;
        ++freed;
      }
  PetscCall(VecRestoreArrayRead(s.r, &res));
  PetscCall(VecRestoreArray(W, &w));
  PetscCall(VecRestoreArrayRead(s.lower, &l));
  s.active.swap(now);
  *changedW = freed > 0 ? PETSC_TRUE : PETSC_FALSE;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &freed, 1, MPIU_INT, MPI_SUM, comm));
  s.count += freed;
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode ReleaseInstall(SNES snes, Mat A, Vec b, Vec lower, PetscReal zeroTolerance, const ReleaseOptions &o, Release &r)
{
  SNESLineSearch ls;
  PetscBool      rsls;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)snes, SNESVINEWTONRSLS, &rsls));
  if (!rsls || !(o.theta > 0)) PetscFunctionReturn(0);
  r.opts  = o;
  r.A     = A;
  r.b     = b;
  r.lower = lower;
  r.zeroTol = zeroTolerance;
  // well beyond the bound tolerance, yet far below the data (the solve works near 1, datascale.h): the
  // value of a freed DOF is solved for in the next step anyway
  r.offset = std::max(10 * zeroTolerance, (PetscReal)1e-12);
  PetscCall(VecDuplicate(b, &r.r));
  PetscCall(SNESGetLineSearch(snes, &ls));
  PetscCall(SNESLineSearchSetPostCheck(ls, ReleaseCheck, &r));
  PetscFunctionReturn(0);
}

} // namespace signorini

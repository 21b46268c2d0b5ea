#include "signorini/mark.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace signorini {

namespace {
// Values within this relative distance below the threshold count as equal to it.
constexpr PetscReal kTieSlack = 1e-6;

// Global sum of the values >= t.
PetscErrorCode SumAbove(MPI_Comm comm, const std::vector<PetscReal> &v, PetscReal t, PetscReal *sum)
{
  PetscReal s = 0;
  PetscFunctionBeginUser;
  for (PetscReal x : v)
    if (x >= t) s += x;
  PetscCallMPI(MPI_Allreduce(&s, sum, 1, MPIU_REAL, MPI_SUM, comm));
  PetscFunctionReturn(0);
}

// Global min and max of the values in [lo, hi) (+inf and -inf if none).
PetscErrorCode RangeIn(MPI_Comm comm, const std::vector<PetscReal> &v, PetscReal lo, PetscReal hi, PetscReal *min, PetscReal *max)
{
  PetscReal m[2] = {std::numeric_limits<PetscReal>::infinity(), std::numeric_limits<PetscReal>::infinity()}; // min, -max
  PetscFunctionBeginUser;
  for (PetscReal x : v)
    if (x >= lo && x < hi) m[0] = std::min(m[0], x), m[1] = std::min(m[1], -x);
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, m, 2, MPIU_REAL, MPI_MIN, comm));
  *min = m[0], *max = -m[1];
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode MarkDoerfler(MPI_Comm comm, const std::vector<PetscReal> &eta2, PetscReal theta, std::vector<char> &marked, PetscInt *count)
{
  const PetscReal inf = std::numeric_limits<PetscReal>::infinity();
  PetscReal       total, lo, hi, min, max, target;
  PetscFunctionBeginUser;
  PetscCheck(theta > 0 && theta <= 1, comm, PETSC_ERR_ARG_OUTOFRANGE, "Doerfler parameter %g not in (0, 1]", (double)theta);
  marked.assign(eta2.size(), 0);
  // The positive indicators span [min, max].
  PetscCall(RangeIn(comm, eta2, std::numeric_limits<PetscReal>::min(), inf, &min, &max));
  PetscCall(SumAbove(comm, eta2, min, &total));
  PetscReal t = inf; // the threshold; inf: nothing to mark
  // theta = 1 asks for every cell with a positive indicator. The sums would decide it at round-off: the
  // smallest indicators may lie below the round-off of the total, and differently on other rank counts.
  if (total > 0 && theta == 1) t = min;
  else if (total > 0) {
    target = theta * total;
    // S(x) = sum of the values >= x falls as x grows; S(lo) >= target > S(hi) throughout. t is the
    // smallest value in [lo, hi) once all of them lie within kTieSlack of each other: every value >= t
    // must then be marked, and marking it reaches the target.
    lo = min, hi = inf;
    PetscReal s;
    PetscCall(SumAbove(comm, eta2, max, &s));
    if (s >= target) lo = max;
    for (;;) {
      PetscReal a, b;
      PetscCall(RangeIn(comm, eta2, lo, hi, &a, &b));
      if (b <= a * (1 + kTieSlack)) {
        t = a;
        break;
      }
      // Bisect geometrically between the extreme values still in question: the indicators span many
      // orders of magnitude, and each step at least halves their logarithmic spread.
      const PetscReal mid = std::sqrt(a) * std::sqrt(b);
      PetscCall(SumAbove(comm, eta2, mid, &s));
      if (s >= target) lo = mid;
      else hi = mid;
    }
  }
  PetscInt n = 0;
  for (size_t i = 0; i < eta2.size(); ++i)
    if (eta2[i] > 0 && eta2[i] >= t * (1 - kTieSlack)) marked[i] = 1, ++n;
  if (count) PetscCallMPI(MPI_Allreduce(&n, count, 1, MPIU_INT, MPI_SUM, comm));
  PetscFunctionReturn(0);
}

} // namespace signorini

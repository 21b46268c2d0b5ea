#include "signorini/mark.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace signorini {

namespace {
// Values within this relative distance below the threshold count as equal to it.
constexpr PetscReal kTieSlack = 1e-6;
constexpr PetscReal kInf      = std::numeric_limits<PetscReal>::infinity();

// The global min and max of a set of values ({+inf, -inf} if empty), and the min and -max of this rank's
// values x in [lo, hi) folded into r (r[0] = min, r[1] = -max, so that one MPI_MIN reduces both).
struct Range {
  PetscReal min, max;
};
inline void Fold(PetscReal *r, PetscReal x, bool in)
{
  // Branch-free: the tests of an indicator against a threshold are unpredictable.
  r[0] = std::min(r[0], in ? x : kInf);
  r[1] = std::min(r[1], in ? -x : kInf);
}

// One pass over the values for the search below: the global sum of the values >= mid (added in the
// values' order, as any pass would: the same sum bit for bit) and the global ranges of the values in
// [lo, mid) and in [mid, hi), the two halves the search goes on with.
PetscErrorCode Split(MPI_Comm comm, const std::vector<PetscReal> &v, PetscReal lo, PetscReal mid, PetscReal hi, PetscReal *sum, Range *below, Range *above)
{
  PetscReal s = 0, r[4] = {kInf, kInf, kInf, kInf};
  PetscFunctionBeginUser;
  for (PetscReal x : v) {
    const bool up = x >= mid;
    s += up ? x : 0; // adding +0 leaves s unchanged
    Fold(r, x, x >= lo && !up);
    Fold(r + 2, x, up && x < hi);
  }
  PetscCallMPI(MPI_Allreduce(&s, sum, 1, MPIU_REAL, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, r, 4, MPIU_REAL, MPI_MIN, comm));
  *below = {r[0], -r[1]}, *above = {r[2], -r[3]};
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode MarkDoerfler(MPI_Comm comm, const std::vector<PetscReal> &eta2, PetscReal theta, std::vector<char> &marked, PetscInt *count)
{
  PetscReal total, target;
  Range     all, none;
  PetscFunctionBeginUser;
  PetscCheck(theta > 0 && theta <= 1, comm, PETSC_ERR_ARG_OUTOFRANGE, "Doerfler parameter %g not in (0, 1]", (double)theta);
  marked.assign(eta2.size(), 0);
  // The positive indicators span [min, max] and add up to the total (every positive value is >= min).
  PetscCall(Split(comm, eta2, 0, std::numeric_limits<PetscReal>::min(), kInf, &total, &none, &all));
  PetscReal t = kInf; // the threshold; inf: nothing to mark
  // theta = 1 asks for every cell with a positive indicator. The sums would decide it at round-off: the
  // smallest indicators may lie below the round-off of the total, and differently on other rank counts.
  if (total > 0 && theta == 1) t = all.min;
  else if (total > 0) {
    target = theta * total;
    // S(x) = sum of the values >= x falls as x grows; S(lo) >= target > S(hi) throughout. t is the
    // smallest value in [lo, hi) once all of them lie within kTieSlack of each other: every value >= t
    // must then be marked, and marking it reaches the target. Each step's pass also finds the range of
    // the values in either half, so one pass per step suffices.
    PetscReal lo = all.min, hi = kInf, s;
    Range     in = all, below, above; // in: the values in [lo, hi)
    PetscCall(Split(comm, eta2, lo, all.max, hi, &s, &below, &above));
    if (s >= target) lo = all.max, in = above;
    for (;;) {
      if (in.max <= in.min * (1 + kTieSlack)) {
        t = in.min;
        break;
      }
      // Bisect geometrically between the extreme values still in question: the indicators span many
      // orders of magnitude, and each step at least halves their logarithmic spread.
      const PetscReal mid = std::sqrt(in.min) * std::sqrt(in.max);
      PetscCall(Split(comm, eta2, lo, mid, hi, &s, &below, &above));
      if (s >= target) lo = mid, in = above;
      else hi = mid, in = below;
    }
  }
  PetscInt n = 0;
  for (size_t i = 0; i < eta2.size(); ++i)
    if (eta2[i] > 0 && eta2[i] >= t * (1 - kTieSlack)) marked[i] = 1, ++n;
  if (count) PetscCallMPI(MPI_Allreduce(&n, count, 1, MPIU_INT, MPI_SUM, comm));
  PetscFunctionReturn(0);
}

} // namespace signorini

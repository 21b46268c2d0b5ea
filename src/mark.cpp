#include "signorini/mark.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace signorini {

namespace {
// The width of the bins of the cut (see CutInGap), relative: far above the differences that the solver's
// tolerance leaves between the indicators of runs on other rank counts (about 1e-8 relative), far below
// the spread of the indicators that Doerfler marking tells apart.
constexpr PetscReal kGap = 1e-6;
// Bins below the threshold examined per global reduction (CutInGap).
constexpr int       kBinsPerPass = 1024;
constexpr PetscReal kInf         = std::numeric_limits<PetscReal>::infinity();

// The global min and max of a set of values ({+inf, -inf} if empty), and the min and -max of this rank's
// values folded into r (r[0] = min, r[1] = -max, so that one MPI_MIN reduces both).
struct Range {
  PetscReal min, max;
};
inline void Fold(PetscReal *r, PetscReal x)
{
  r[0] = std::min(r[0], x);
  r[1] = std::min(r[1], -x);
}

// The values still in question, [lo, hi), of this rank, in w[0, n): one step of the search splits them at
// mid into [lo, mid) (moved to the front, n_below of them) and [mid, hi), and returns the global sum of the
// upper part and the global ranges of both. Each step keeps one part, so the passes shrink with the
// search instead of reading every value each time.
PetscErrorCode Split(MPI_Comm comm, PetscReal *w, size_t n, PetscReal mid, size_t *nBelow, PetscReal *sum, Range *below, Range *above)
{
  PetscReal s = 0, r[4] = {kInf, kInf, kInf, kInf};
  PetscFunctionBeginUser;
  PetscReal *split = std::partition(w, w + n, [mid](PetscReal x) { return x < mid; });
  for (PetscReal *x = w; x < split; ++x) Fold(r, *x);
  for (PetscReal *x = split; x < w + n; ++x) Fold(r + 2, *x), s += *x;
  *nBelow = (size_t)(split - w);
  PetscCallMPI(MPI_Allreduce(&s, sum, 1, MPIU_REAL, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, r, 4, MPIU_REAL, MPI_MIN, comm));
  *below = {r[0], -r[1]}, *above = {r[2], -r[3]};
  PetscFunctionReturn(0);
}

// The cut: every value >= it is marked. Not the threshold t itself: indicators that are equal in exact
// arithmetic, or packed closer together than the solver's tolerance (a structured mesh has thousands
// within 1e-9 of each other), differ from run to run on other rank counts, and a cut among them marks other
// cells. So the cut lies in the middle of the first empty bin below t, the bins of relative width kGap
// counted down from t (bin k: t (1 + kGap)^-k <= x < t (1 + kGap)^(1-k), k >= 1): its nearest values lie
// at least kGap / 2 away on either side, and it moves only where a value lies within the solver's
// tolerance of that bin's edges (or t moves by more than that). The bins scale with t, so indicators
// scaled by any factor are cut alike. It marks every value >= t (Doerfler's set) and, where values cluster
// below t, the cluster down to its first gap of 2 kGap or so. Each pass examines kBinsPerPass bins with
// one reduction and leaves the values below them in w[0, n).
PetscErrorCode CutInGap(MPI_Comm comm, PetscReal *w, size_t n, PetscReal t, PetscReal *cut)
{
  const PetscReal       width = std::log1p(kGap);
  const auto            bin   = [t, width](PetscReal x) { return (PetscInt64)std::ceil(std::log(t / x) / width); };
  std::vector<PetscInt> count(kBinsPerPass);
  PetscFunctionBeginUser;
  n = (size_t)(std::partition(w, w + n, [t](PetscReal x) { return x < t; }) - w);
  for (PetscInt64 first = 1;; first += kBinsPerPass) { // this pass: the bins first .. first + kBinsPerPass - 1
    const PetscInt64 last = first + kBinsPerPass - 1;
    std::fill(count.begin(), count.end(), 0);
    // below the pass's bins: the logarithm only near their lower edge, where its round-off matters
    const PetscReal edge  = t * std::exp(-(PetscReal)last * width);
    PetscReal      *below = std::partition(w, w + n, [&](PetscReal x) { return x < edge * (1 - 1e-9) || (x < edge * (1 + 1e-9) && bin(x) > last); });
    for (PetscReal *x = below; x < w + n; ++x) ++count[std::max<PetscInt64>(bin(*x), first) - first]; // bin 0: x rounds to t
    n = (size_t)(below - w);
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, count.data(), kBinsPerPass, MPIU_INT, MPI_SUM, comm));
    for (int k = 0; k < kBinsPerPass; ++k)
      if (count[k] == 0) {
        *cut = t * std::exp(-((PetscReal)(first + k) - 0.5) * width);
        PetscFunctionReturn(0);
      }
  }
}

} // namespace

PetscErrorCode MarkDoerfler(MPI_Comm comm, const std::vector<PetscReal> &eta2, PetscReal theta, std::vector<char> &marked, PetscInt *count)
{
  PetscReal total, s;
  Range     all, below, above;
  size_t    nBelow;
  PetscFunctionBeginUser;
  PetscCheck(theta > 0 && theta <= 1, comm, PETSC_ERR_ARG_OUTOFRANGE, "Doerfler parameter %g not in (0, 1]", (double)theta);
  marked.assign(eta2.size(), 0);
  // The positive indicators, the only candidates: they span [min, max] and add up to the total.
  std::vector<PetscReal> w;
  w.reserve(eta2.size());
  for (PetscReal x : eta2)
    if (x > 0) w.push_back(x);
  PetscCall(Split(comm, w.data(), w.size(), 0, &nBelow, &total, &below, &all));
  PetscReal t = kInf; // the threshold; inf: nothing to mark
  // theta = 1 asks for every cell with a positive indicator. The sums would decide it at round-off: the
  // smallest indicators may lie below the round-off of the total, and differently on other rank counts.
  if (total > 0 && theta == 1) t = all.min;
  else if (total > 0) {
    const PetscReal target = theta * total;
    // S(x) = sum of the values >= x falls as x grows; S(lo) >= target > S(hi) throughout, the values in
    // [lo, hi) are w[first, first + n) and sumHi = S(hi). t is the value in [lo, hi) once they are all
    // equal: the smallest value of the minimal set, every value >= t must be marked, and marking them
    // reaches the target. Each step's pass also finds the range of the values in either half.
    PetscReal sumHi = 0;
    size_t    first = 0, n = w.size();
    Range     in = all; // the values in [lo, hi): lo = min, hi = inf
    // The largest values alone may be enough (lo = max); if not, the search starts from all of them.
    PetscCall(Split(comm, w.data(), n, all.max, &nBelow, &s, &below, &above));
    if (s >= target) first = nBelow, n -= nBelow, in = above;
    while (in.max > in.min) {
      // Bisect geometrically between the extreme values still in question: the indicators span many
      // orders of magnitude, and each step at least halves their logarithmic spread (down to neighbouring
      // doubles, where the split falls at the larger one).
      PetscReal mid = std::sqrt(in.min) * std::sqrt(in.max);
      if (!(mid > in.min && mid <= in.max)) mid = in.max;
      PetscCall(Split(comm, w.data() + first, n, mid, &nBelow, &s, &below, &above));
      if (sumHi + s >= target) first += nBelow, n -= nBelow, in = above; // lo = mid
      else sumHi += s, n = nBelow, in = below;                           // hi = mid
    }
    t = in.min;
    PetscCall(CutInGap(comm, w.data(), w.size(), t, &t));
  }
  PetscInt nMarked = 0;
  for (size_t i = 0; i < eta2.size(); ++i)
    if (eta2[i] > 0 && eta2[i] >= t) marked[i] = 1, ++nMarked;
  if (count) PetscCallMPI(MPI_Allreduce(&nMarked, count, 1, MPIU_INT, MPI_SUM, comm));
  PetscFunctionReturn(0);
}

} // namespace signorini

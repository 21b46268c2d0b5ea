// Unit tests of Doerfler marking (MarkDoerfler) against an independent serial computation: all values on
// every rank, sorted, the shortest prefix of the largest ones that reaches theta times the total (theta = 1:
// every positive value), extended down to the cut that mark.h defines: the middle of the first empty bin
// below the last value t taken, bin k being [t (1 + 1e-6)^-k, t (1 + 1e-6)^(1-k)). The values are spread
// over the ranks in blocks and perturbed by a relative amount that depends on the number of ranks: 1e-13,
// as round-off makes equal indicators differ, and 1e-9 on a cluster of 100 000 values packed 1e-10 apart (as
// a structured mesh packs indicators, and the solver's tolerance perturbs them), so the same cells must be
// marked on 1 and 2 ranks, and the same again when all values are scaled by 3.3e-9, 0.37 or 7.1e3 (as the
// size of the data scales the indicators), and on two neighbouring doubles, where the threshold search ends;
// the check also asserts the Doerfler property. Runs on 1 and 2 ranks (ctest).
#include "signorini/mark.h"
#include "unit_check.h"

#include <algorithm>
#include <functional>
#include <numeric>

using namespace signorini;

// Global value g of a test set: many ties, magnitudes from 1e-12 to 1e3, some zeros.
using Generator = std::function<PetscReal(PetscInt)>;

static std::vector<char> Expected(const std::vector<PetscReal> &v, PetscReal theta)
{
  std::vector<PetscInt> order(v.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](PetscInt a, PetscInt b) { return v[a] > v[b]; });
  const PetscReal total = std::accumulate(v.begin(), v.end(), 0.0);
  std::vector<char> m(v.size(), 0);
  if (total <= 0) return m;
  PetscReal sum = 0, last = 0;
  size_t    taken = 0;
  for (PetscInt i : order) {
    if ((sum >= theta * total && v[i] < last) || v[i] == 0) break;
    sum += v[i], last = v[i], ++taken;
  }
  // The bins of the values below the last one taken, counted down from it: the first bin with no value
  // holds the cut.
  const PetscReal width = std::log1p(1e-6);
  const auto      bin   = [last, width](PetscReal x) { return (PetscInt64)std::ceil(std::log(last / x) / width); };
  PetscInt64      empty = 1;
  for (size_t k = taken; k < order.size() && v[order[k]] > 0; ++k) {
    const PetscInt64 b = bin(v[order[k]]);
    if (b > empty) break;
    if (b == empty) ++empty;
  }
  const PetscReal cut = last * std::exp(-((PetscReal)empty - 0.5) * width);
  for (size_t i = 0; i < v.size(); ++i) m[i] = v[i] > 0 && v[i] >= cut;
  return m;
}

static PetscErrorCode TestSet(unit::Checker &ck, const std::string &name, PetscInt n, const Generator &value, PetscReal noise, PetscReal scale, PetscReal theta)
{
  MPI_Comm    comm = PETSC_COMM_WORLD;
  PetscMPIInt rank, size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // Block distribution; the last rank gets none when there are two or more (a rank without cells).
  const PetscInt parts = size > 1 ? size - 1 : 1, lo = std::min<PetscInt>(n, rank * ((n + parts - 1) / parts)), hi = rank < parts ? std::min<PetscInt>(n, (rank + 1) * ((n + parts - 1) / parts)) : lo;
  std::vector<PetscReal> all(n), mine;
  for (PetscInt g = 0; g < n; ++g) all[g] = value(g);
  for (PetscInt g = lo; g < hi; ++g) mine.push_back(scale * all[g] * (1 + noise * (PetscReal)((g + size) % 3 - 1)));
  std::vector<char> marked;
  PetscInt          count;
  PetscCall(MarkDoerfler(comm, mine, theta, marked, &count));
  // Gather the marks (a test may; the marking itself does not).
  std::vector<int> local(n, 0), global(n, 0);
  for (PetscInt g = lo; g < hi; ++g) local[g] = marked[g - lo];
  PetscCallMPI(MPI_Allreduce(local.data(), global.data(), (int)n, MPI_INT, MPI_SUM, comm));
  const std::vector<char> expected = Expected(all, theta);
  PetscInt wrong = 0, nexp = 0;
  PetscReal total = 0, sum = 0;
  for (PetscInt g = 0; g < n; ++g) {
    wrong += (global[g] != 0) != (expected[g] != 0);
    nexp += expected[g];
    total += all[g];
    if (global[g]) sum += all[g];
  }
  const std::string tag = Format("%s%s theta %g", name.c_str(), scale == 1 ? "" : Format(" x %g", (double)scale).c_str(), (double)theta);
  ck.Check(wrong == 0, tag + ": the marked cells are the serial sort's", "%d cells differ (%d marked, %d expected)", (int)wrong, (int)count, (int)nexp);
  ck.Check(count == nexp, tag + ": count of marked cells", "%d, expected %d", (int)count, (int)nexp);
  ck.Check(total == 0 ? count == 0 : sum >= theta * total * (1 - 1e-12), tag + ": Doerfler property", "marked %g of %g", (double)sum, (double)total);
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  // Few distinct values, each many times: the threshold falls on a tie.
  const Generator ties = [](PetscInt g) { return std::pow(10.0, (PetscReal)((g * 7) % 5) - 3) * (1 + (g % 3)); };
  // All distinct, spanning 15 orders of magnitude, a few zeros.
  const Generator spread = [](PetscInt g) { return g % 17 == 0 ? 0.0 : std::pow(10.0, -12 + 15 * std::fmod(g * 0.6180339887, 1.0)); };
  // One large value: it alone is enough for small theta.
  const Generator peak = [](PetscInt g) { return g == 41 ? 1e6 : 1.0; };
  const Generator zero = [](PetscInt) { return 0.0; };
  const Generator equal = [](PetscInt) { return 0.3; };
  // Half the values in a cluster 1e-10 apart, two parts 5e-6 wide each (five bins) with 1.5e-6 between
  // them, the others spread below it: a cut at the threshold itself would lie among values that the noise
  // of 1e-9 reorders, and whether a bin fits in the gap between the parts depends on where the bins lie.
  const Generator cluster = [](PetscInt g) {
    const PetscInt j = g / 2;
    return g % 2 ? 0.5 * std::pow(10.0, -3 * std::fmod(g * 0.6180339887, 1.0)) : 1 + 1e-10 * (PetscReal)j + (j >= 50000 ? 1.5e-6 : 0);
  };
  // Two neighbouring doubles, unperturbed: the threshold search ends between them.
  const Generator neighbours = [](PetscInt g) { return g % 2 ? 1.0 : std::nextafter(1.0, 2.0); };
  struct Case {
    const char *name;
    PetscInt    n;
    Generator   value;
    PetscReal   noise;
  } cases[] = {{"ties", 1000, ties, 1e-13}, {"spread", 1001, spread, 1e-13}, {"peak", 100, peak, 1e-13}, {"all zero", 50, zero, 1e-13}, {"all equal", 64, equal, 1e-13}, {"cluster", 200000, cluster, 1e-9}, {"neighbouring doubles", 100, neighbours, 0}};
  for (const Case &c : cases)
    for (PetscReal scale : {1.0, 3.3e-9, 0.37, 7.1e3})
      for (PetscReal theta : {0.01, 0.3, 0.5, 0.9, 1.0}) {
        const PetscErrorCode ierr = TestSet(ck, c.name, c.n, c.value, c.noise, scale, theta);
        if (ierr) ck.PetscFailure(ierr, c.name);
      }
  const int status = ck.Finish();
  PetscCall(PetscFinalize());
  return status;
}

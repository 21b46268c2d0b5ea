// Connected components of a distributed graph (components.h): union-find on each rank, then the pieces
// that meet at shared items joined on every rank from the gathered pairs.
#include "signorini/components.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace signorini {

namespace {
// Union-find with path halving; the root of a set is its smallest element, so that the numbering of the
// sets does not depend on the order of the unions.
struct DisjointSets {
  std::vector<PetscInt> parent;
  explicit DisjointSets(PetscInt n) : parent(n)
  {
    for (PetscInt i = 0; i < n; ++i) parent[i] = i;
  }
  PetscInt Find(PetscInt i)
  {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }
  void Join(PetscInt a, PetscInt b)
  {
    a = Find(a), b = Find(b);
    if (a < b) parent[b] = a;
    else if (b < a) parent[a] = b;
  }
};
} // namespace

PetscErrorCode ConnectedComponents(MPI_Comm comm, const ItemGraph &graph, std::vector<PetscInt> &component, PetscInt *count)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // The pieces on this rank: item -> local piece (numbered by first item), -1 for an item in no list.
  DisjointSets      local(graph.numItems);
  std::vector<char> used(graph.numItems, 0);
  for (PetscInt c = 0; c < graph.numCells; ++c) {
    const PetscInt *items = graph.cellItems(c);
    for (PetscInt k = 0; k < graph.per; ++k) {
      used[items[k]] = 1;
      if (k > 0) local.Join(items[0], items[k]);
    }
  }
  std::vector<PetscInt> piece(graph.numItems, -1);
  PetscInt              pieces = 0;
  for (PetscInt i = 0; i < graph.numItems; ++i)
    if (used[i] && local.Find(i) == i) piece[i] = pieces++;
  for (PetscInt i = 0; i < graph.numItems; ++i)
    if (used[i]) piece[i] = piece[local.Find(i)];
  // Global piece numbers: this rank's offset plus the local number.
  PetscInt offset = 0, total = 0;
  PetscCallMPI(MPI_Exscan(&pieces, &offset, 1, MPIU_INT, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(&pieces, &total, 1, MPIU_INT, MPI_SUM, comm));
  std::vector<PetscInt> global(graph.numItems, -1), owner;
  for (PetscInt i = 0; i < graph.numItems; ++i)
    if (used[i]) global[i] = offset + piece[i];
  owner = global;
  PetscCall(graph.shareOwners(owner));
  // The pairs (this copy's piece, the owner's piece) where they differ, once each.
  std::vector<PetscInt> pairs;
  for (PetscInt i = 0; i < graph.numItems; ++i)
    if (used[i] && owner[i] >= 0 && owner[i] != global[i]) pairs.insert(pairs.end(), {global[i], owner[i]});
  {
    std::vector<std::pair<PetscInt, PetscInt>> p(pairs.size() / 2);
    for (size_t k = 0; k < p.size(); ++k) p[k] = {pairs[2 * k], pairs[2 * k + 1]};
    std::sort(p.begin(), p.end());
    p.erase(std::unique(p.begin(), p.end()), p.end());
    pairs.clear();
    for (const auto &q : p) pairs.insert(pairs.end(), {q.first, q.second});
  }
  PetscMPIInt              mine = (PetscMPIInt)pairs.size();
  std::vector<PetscMPIInt> counts(size), displs(size + 1, 0);
  PetscCallMPI(MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (PetscMPIInt r = 0; r < size; ++r) displs[r + 1] = displs[r] + counts[r];
  std::vector<PetscInt> all(displs[size]);
  PetscCallMPI(MPI_Allgatherv(pairs.data(), mine, MPIU_INT, all.data(), counts.data(), displs.data(), MPIU_INT, comm));
  DisjointSets joined(total);
  for (size_t k = 0; k + 1 < all.size(); k += 2) joined.Join(all[k], all[k + 1]);
  std::vector<PetscInt> number(total, -1);
  PetscInt              n = 0;
  for (PetscInt g = 0; g < total; ++g)
    if (joined.Find(g) == g) number[g] = n++;
  component.assign(graph.numItems, -1);
  for (PetscInt i = 0; i < graph.numItems; ++i)
    if (used[i]) component[i] = number[joined.Find(global[i])];
  *count = n;
  PetscFunctionReturn(0);
}

PetscErrorCode LowestPoints(MPI_Comm comm, PetscInt dim, PetscInt n, const std::vector<PetscInt> &component, PetscInt count, const std::function<void(PetscInt, PetscReal *)> &point,
                            std::vector<std::array<PetscReal, 3>> &lowest)
{
  const PetscReal                       inf = std::numeric_limits<PetscReal>::infinity();
  std::vector<std::array<PetscReal, 3>> x(n);
  std::vector<PetscReal>                best(count);
  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < n; ++i) {
    x[i] = {0, 0, 0};
    if (component[i] >= 0) point(i, x[i].data());
  }
  lowest.assign(count, {inf, inf, inf});
  // Coordinate by coordinate: the lowest d-th coordinate among the points that tie in the ones before.
  for (PetscInt d = 0; d < dim; ++d) {
    std::fill(best.begin(), best.end(), inf);
    for (PetscInt i = 0; i < n; ++i) {
      const PetscInt k = component[i];
      if (k < 0) continue;
      bool tie = true;
      for (PetscInt e = 0; e < d; ++e) tie = tie && x[i][e] == lowest[k][e];
      if (tie) best[k] = std::min(best[k], x[i][d]);
    }
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, best.data(), (PetscMPIInt)count, MPIU_REAL, MPI_MIN, comm));
    for (PetscInt k = 0; k < count; ++k) lowest[k][d] = best[k];
  }
  for (auto &l : lowest)
    for (PetscInt d = dim; d < 3; ++d) l[d] = std::isfinite(l[0]) ? 0 : inf;
  PetscFunctionReturn(0);
}

} // namespace signorini

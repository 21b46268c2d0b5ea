#include "signorini/pattern.h"

#include <algorithm>

namespace signorini {

// Global index of every local DOF (ghosts included), through the space's local-to-global mapping.
static PetscErrorCode GlobalIndices(const Space &space, std::vector<PetscInt> &global)
{
  ISLocalToGlobalMapping ltog = space.ltog;
  PetscInt               n;
  PetscFunctionBeginUser;
  PetscCall(ISLocalToGlobalMappingGetSize(ltog, &n));
  PetscCheck(n == space.numLocal, PETSC_COMM_SELF, PETSC_ERR_PLIB, "local-to-global mapping has %" PetscInt_FMT " entries for %" PetscInt_FMT " local DOFs", n, space.numLocal);
  global.resize(space.numLocal);
  for (PetscInt i = 0; i < space.numLocal; ++i) global[i] = i;
  PetscCall(ISLocalToGlobalMappingApply(ltog, space.numLocal, global.data(), global.data()));
  PetscFunctionReturn(0);
}

// The cells holding each local DOF, as compressed rows: cells[offset[i] .. offset[i+1]).
struct DofCells {
  std::vector<PetscInt> offset, cells;
};

static DofCells BuildDofCells(const Space &space)
{
  const PetscInt nb = space.Nb(), nc = space.NumCells();
  DofCells       dc;
  dc.offset.assign(space.numLocal + 1, 0);
  for (PetscInt c = 0; c < nc; ++c)
    for (PetscInt j = 0; j < nb; ++j) ++dc.offset[space.Dofs(c)[j] + 1];
  for (PetscInt i = 0; i < space.numLocal; ++i) dc.offset[i + 1] += dc.offset[i];
  dc.cells.resize(nc * nb);
  std::vector<PetscInt> next(dc.offset.begin(), dc.offset.end() - 1);
  for (PetscInt c = 0; c < nc; ++c)
    for (PetscInt j = 0; j < nb; ++j) dc.cells[next[space.Dofs(c)[j]]++] = c;
  return dc;
}

// Visits the distinct local DOFs coupled to local DOF `row` through this rank's cells. `mark` (one entry
// per local DOF) remembers the last row that visited each DOF, so no sorting is needed; each row may be
// visited only once per `mark` array.
template <class Visit>
static void ForEachColumn(const Space &space, const DofCells &dc, PetscInt row, std::vector<PetscInt> &mark, Visit visit)
{
  for (PetscInt k = dc.offset[row]; k < dc.offset[row + 1]; ++k) {
    const PetscInt *dofs = space.Dofs(dc.cells[k]);
    for (PetscInt j = 0; j < space.Nb(); ++j)
      if (mark[dofs[j]] != row) {
        mark[dofs[j]] = row;
        visit(dofs[j]);
      }
  }
}

// Sends records (row, ncols, cols...), one list per destination rank; returns those this rank received.
static PetscErrorCode ExchangeRecords(MPI_Comm comm, const std::vector<std::vector<PetscInt>> &send, std::vector<PetscInt> &received)
{
  const PetscMPIInt size = (PetscMPIInt)send.size();
  PetscFunctionBeginUser;
  std::vector<PetscMPIInt> scount(size), rcount(size), sdispl(size + 1, 0), rdispl(size + 1, 0);
  for (PetscMPIInt p = 0; p < size; ++p) {
    PetscCall(PetscMPIIntCast((PetscInt)send[p].size(), &scount[p]));
    sdispl[p + 1] = sdispl[p] + scount[p];
  }
  PetscCallMPI(MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm));
  for (PetscMPIInt p = 0; p < size; ++p) rdispl[p + 1] = rdispl[p] + rcount[p];
  std::vector<PetscInt> flat(sdispl[size]);
  for (PetscMPIInt p = 0; p < size; ++p) std::copy(send[p].begin(), send[p].end(), flat.begin() + sdispl[p]);
  received.resize(rdispl[size]);
  PetscCallMPI(MPI_Alltoallv(flat.data(), scount.data(), sdispl.data(), MPIU_INT, received.data(), rcount.data(), rdispl.data(), MPIU_INT, comm));
  PetscFunctionReturn(0);
}

// Sends, for every row this rank does not own, the global columns its cells give to that row to the
// owner, as records (row, ncols, cols...); returns the records received for this rank's own rows.
static PetscErrorCode ExchangeGhostRows(MPI_Comm comm, const Space &space, const DofCells &dc, const std::vector<PetscInt> &global, const std::vector<PetscInt> &ranges, std::vector<PetscInt> &mark, std::vector<PetscInt> &received)
{
  PetscMPIInt size, rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt r = 0; r < space.numLocal; ++r) {
    const PetscInt g = global[r];
    if (g >= ranges[rank] && g < ranges[rank + 1]) continue;
    const PetscMPIInt owner = OwnerOf(ranges, g);
    std::vector<PetscInt> &buf = send[owner];
    buf.push_back(g);
    const size_t head = buf.size();
    buf.push_back(0);
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { buf.push_back(global[d]); });
    buf[head] = (PetscInt)(buf.size() - head - 1);
  }
  PetscCall(ExchangeRecords(comm, send, received));
  PetscFunctionReturn(0);
}

// Crouzeix-Raviart: a face lies in at most two cells, which share no other face, so the columns of a row
// are the row itself and the other faces of its cells, all distinct: count(row) = 1 + d * (its cells,
// on all ranks), read off the cell table in one pass, without the cells-of-each-DOF table and the
// de-duplication the general path needs. A face this rank does not own lies in one of its cells (the
// other one is on the owner), whose faces go to the owner.
static PetscErrorCode ComputeRowCountsCR(MPI_Comm comm, const Space &space, const std::vector<PetscInt> &global, const std::vector<PetscInt> &ranges, PetscMPIInt rank, RowCounts &counts)
{
  const PetscInt rstart = ranges[rank], rend = ranges[rank + 1], nb = space.Nb();
  const auto     owned  = [&](PetscInt g) { return g >= rstart && g < rend; };
  PetscMPIInt    size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  counts.diag.assign(space.numOwned, 1); // the row itself
  counts.offdiag.assign(space.numOwned, 0);
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt g = global[dofs[i]];
      if (!owned(g)) {
        const PetscMPIInt owner = OwnerOf(ranges, g);
        send[owner].push_back(g);
        send[owner].push_back(nb - 1);
        for (PetscInt j = 0; j < nb; ++j)
          if (j != i) send[owner].push_back(global[dofs[j]]);
        continue;
      }
      for (PetscInt j = 0; j < nb; ++j)
        if (j != i) ++(owned(global[dofs[j]]) ? counts.diag[g - rstart] : counts.offdiag[g - rstart]);
    }
  }
  std::vector<PetscInt> received;
  PetscCall(ExchangeRecords(comm, send, received));
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1])
    for (PetscInt j = 0; j < received[k + 1]; ++j) ++(owned(received[k + 2 + j]) ? counts.diag[received[k] - rstart] : counts.offdiag[received[k] - rstart]);
  PetscFunctionReturn(0);
}

PetscErrorCode ComputeRowCounts(const Space &space, RowCounts &counts)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)space.dm);
  PetscMPIInt size, rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  std::vector<PetscInt> ranges, global, received;
  PetscCall(OwnershipRanges(comm, space.numOwned, ranges));
  const PetscInt rstart = ranges[rank], rend = ranges[rank + 1];
  PetscCall(GlobalIndices(space, global));
  if (space.element == Element::CR) {
    PetscCall(ComputeRowCountsCR(comm, space, global, ranges, rank, counts));
    PetscFunctionReturn(0);
  }
  const DofCells        dc = BuildDofCells(space);
  std::vector<PetscInt> mark(space.numLocal, -1);
  PetscCall(ExchangeGhostRows(comm, space, dc, global, ranges, mark, received));

  // The local DOF of each owned row, and the received columns of each owned row (compressed rows).
  std::vector<PetscInt> localOf(space.numOwned, -1), extraOffset(space.numOwned + 1, 0), extra;
  for (PetscInt r = 0; r < space.numLocal; ++r)
    if (global[r] >= rstart && global[r] < rend) localOf[global[r] - rstart] = r;
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1]) extraOffset[received[k] - rstart + 1] += received[k + 1];
  for (PetscInt i = 0; i < space.numOwned; ++i) extraOffset[i + 1] += extraOffset[i];
  extra.resize(extraOffset[space.numOwned]);
  std::vector<PetscInt> next(extraOffset.begin(), extraOffset.end() - 1);
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1])
    for (PetscInt j = 0; j < received[k + 1]; ++j) extra[next[received[k] - rstart]++] = received[k + 2 + j];

  counts.diag.assign(space.numOwned, 0);
  counts.offdiag.assign(space.numOwned, 0);
  std::vector<PetscInt> cols;
  for (PetscInt i = 0; i < space.numOwned; ++i) {
    const PetscInt r = localOf[i];
    PetscCheck(r >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "owned row %" PetscInt_FMT " has no local DOF", rstart + i);
    auto count = [&](PetscInt g) { ++(g >= rstart && g < rend ? counts.diag[i] : counts.offdiag[i]); };
    if (extraOffset[i] == extraOffset[i + 1]) {
      ForEachColumn(space, dc, r, mark, [&](PetscInt d) { count(global[d]); });
      continue;
    }
    // A row shared with other ranks: merge their columns with ours.
    cols.assign(extra.begin() + extraOffset[i], extra.begin() + extraOffset[i + 1]);
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { cols.push_back(global[d]); });
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
    for (PetscInt g : cols) count(g);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode CreateStiffnessMatrix(const Space &space, Mat *A)
{
  MPI_Comm               comm = PetscObjectComm((PetscObject)space.dm);
  RowCounts              counts;
  static PetscLogEvent   event = 0;
  PetscFunctionBeginUser;
  if (!event) PetscCall(PetscLogEventRegister("StiffnessPattern", MAT_CLASSID, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCall(ComputeRowCounts(space, counts));
  PetscCall(MatCreate(comm, A));
  PetscCall(MatSetSizes(*A, space.numOwned, space.numOwned, space.numGlobal, space.numGlobal));
  PetscCall(MatSetType(*A, MATAIJ));
  PetscCall(MatSetFromOptions(*A));
  PetscCall(MatXAIJSetPreallocation(*A, 1, counts.diag.data(), counts.offdiag.data(), NULL, NULL));
  PetscCall(MatSetLocalToGlobalMapping(*A, space.ltog, space.ltog));
  PetscCall(MatSetOption(*A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  // Symmetric by construction, and the symmetric Dirichlet elimination keeps it so.
  PetscCall(MatSetOption(*A, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(*A, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

} // namespace signorini

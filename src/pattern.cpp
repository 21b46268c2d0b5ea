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
  received.clear();
  if (size == 1) PetscFunctionReturn(0); // one rank owns every row
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

// The rows this rank owns as lists of global columns (compressed rows over the owned rows), and the
// global index of every local DOF.
struct Rows {
  std::vector<PetscInt> global, ranges, offset, cols;
  PetscInt              rstart = 0, rend = 0;
  bool                  Owned(PetscInt g) const { return g >= rstart && g < rend; }
};

// Appends the columns of the received records (row, ncols, cols...) to their rows; `next` is the next free
// position of each owned row.
static void AppendReceived(const std::vector<PetscInt> &received, Rows &rows, std::vector<PetscInt> &next)
{
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1])
    for (PetscInt j = 0; j < received[k + 1]; ++j) rows.cols[next[received[k] - rows.rstart]++] = received[k + 2 + j];
}

// Crouzeix-Raviart: a face lies in at most two cells, which share no other face, so the columns of a row
// are the row itself and the other faces of its cells, all distinct: 1 + d * (its cells, on all ranks),
// read off the cell table without the cells-of-each-DOF table and the de-duplication P1 needs. A face
// this rank does not own lies in one of its cells (the other one is on the owner), whose faces go to the
// owner.
static PetscErrorCode BuildRowsCR(MPI_Comm comm, const Space &space, Rows &rows)
{
  const PetscInt nb = space.Nb();
  PetscMPIInt    size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  std::vector<PetscInt>              length(space.numOwned, 1); // the row itself
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt g = rows.global[dofs[i]];
      if (rows.Owned(g)) {
        length[g - rows.rstart] += nb - 1;
        continue;
      }
      std::vector<PetscInt> &buf = send[OwnerOf(rows.ranges, g)];
      buf.push_back(g);
      buf.push_back(nb - 1);
      for (PetscInt j = 0; j < nb; ++j)
        if (j != i) buf.push_back(rows.global[dofs[j]]);
    }
  }
  std::vector<PetscInt> received;
  PetscCall(ExchangeRecords(comm, send, received));
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1]) length[received[k] - rows.rstart] += received[k + 1];
  rows.offset.assign(space.numOwned + 1, 0);
  for (PetscInt i = 0; i < space.numOwned; ++i) rows.offset[i + 1] = rows.offset[i] + length[i];
  rows.cols.resize(rows.offset[space.numOwned]);
  std::vector<PetscInt> next(rows.offset.begin(), rows.offset.end() - 1);
  for (PetscInt i = 0; i < space.numOwned; ++i) rows.cols[next[i]++] = rows.rstart + i;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt g = rows.global[dofs[i]];
      if (!rows.Owned(g)) continue;
      for (PetscInt j = 0; j < nb; ++j)
        if (j != i) rows.cols[next[g - rows.rstart]++] = rows.global[dofs[j]];
    }
  }
  AppendReceived(received, rows, next);
  for (PetscInt i = 0; i < space.numOwned; ++i) std::sort(rows.cols.begin() + rows.offset[i], rows.cols.begin() + rows.offset[i + 1]);
  PetscFunctionReturn(0);
}

// P1: a vertex lies in many cells, so the columns of a row come from the cells-of-each-DOF table with
// duplicates skipped; the columns other ranks' cells give a shared row arrive as records and are merged.
static PetscErrorCode BuildRowsP1(MPI_Comm comm, const Space &space, Rows &rows)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  const DofCells                     dc = BuildDofCells(space);
  std::vector<PetscInt>              mark(space.numLocal, -1), localOf(space.numOwned, -1), received;
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt r = 0; r < space.numLocal; ++r) {
    const PetscInt g = rows.global[r];
    if (rows.Owned(g)) {
      localOf[g - rows.rstart] = r;
      continue;
    }
    std::vector<PetscInt> &buf = send[OwnerOf(rows.ranges, g)];
    buf.push_back(g);
    const size_t head = buf.size();
    buf.push_back(0);
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { buf.push_back(rows.global[d]); });
    buf[head] = (PetscInt)(buf.size() - head - 1);
  }
  PetscCall(ExchangeRecords(comm, send, received));
  // Each row: its own columns, then the received ones; sorted, and duplicates dropped where a row is shared.
  std::vector<PetscInt> extraOffset(space.numOwned + 1, 0), extra;
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1]) extraOffset[received[k] - rows.rstart + 1] += received[k + 1];
  for (PetscInt i = 0; i < space.numOwned; ++i) extraOffset[i + 1] += extraOffset[i];
  extra.resize(extraOffset[space.numOwned]);
  std::vector<PetscInt> next(extraOffset.begin(), extraOffset.end() - 1);
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1])
    for (PetscInt j = 0; j < received[k + 1]; ++j) extra[next[received[k] - rows.rstart]++] = received[k + 2 + j];
  rows.offset.assign(space.numOwned + 1, 0);
  rows.cols.clear();
  rows.cols.reserve(dc.cells.size() * 7 / 10 + space.numOwned); // about a row's distinct columns per cell entry
  for (PetscInt i = 0; i < space.numOwned; ++i) {
    const PetscInt r = localOf[i];
    PetscCheck(r >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "owned row %" PetscInt_FMT " has no local DOF", rows.rstart + i);
    const auto begin = rows.cols.size();
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { rows.cols.push_back(rows.global[d]); });
    rows.cols.insert(rows.cols.end(), extra.begin() + extraOffset[i], extra.begin() + extraOffset[i + 1]);
    std::sort(rows.cols.begin() + begin, rows.cols.end());
    rows.cols.erase(std::unique(rows.cols.begin() + begin, rows.cols.end()), rows.cols.end());
    rows.offset[i + 1] = (PetscInt)rows.cols.size();
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode BuildRows(const Space &space, Rows &rows)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)space.dm);
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(OwnershipRanges(comm, space.numOwned, rows.ranges));
  rows.rstart = rows.ranges[rank], rows.rend = rows.ranges[rank + 1];
  PetscCall(GlobalIndices(space, rows.global));
  if (space.element == Element::CR) PetscCall(BuildRowsCR(comm, space, rows));
  else PetscCall(BuildRowsP1(comm, space, rows));
  PetscFunctionReturn(0);
}

PetscErrorCode CreateStiffnessMatrix(const Space &space, Mat *A)
{
  MPI_Comm             comm = PetscObjectComm((PetscObject)space.dm);
  Rows                 rows;
  PetscMPIInt          size;
  static PetscLogEvent event = 0;
  PetscFunctionBeginUser;
  if (!event) PetscCall(PetscLogEventRegister("StiffnessPattern", MAT_CLASSID, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(BuildRows(space, rows));
  // The columns of the diagonal block (numbered from the first owned one) and of the off-diagonal block
  // (global until the assembly compacts them), each row sorted as the global ones are.
  std::vector<PetscInt> diag(space.numOwned, 0), offdiag(space.numOwned, 0), dcols, ocols;
  dcols.reserve(rows.cols.size());
  for (PetscInt i = 0; i < space.numOwned; ++i)
    for (PetscInt k = rows.offset[i]; k < rows.offset[i + 1]; ++k) {
      const PetscInt g = rows.cols[k];
      if (rows.Owned(g)) ++diag[i], dcols.push_back(g - rows.rstart);
      else ++offdiag[i], ocols.push_back(g);
    }
  std::vector<PetscInt>().swap(rows.cols);
  PetscCall(MatCreate(comm, A));
  PetscCall(MatSetSizes(*A, space.numOwned, space.numOwned, space.numGlobal, space.numGlobal));
  PetscCall(MatSetType(*A, MATAIJ));
  PetscCall(MatSetFromOptions(*A));
  PetscBool aij;
  PetscCall(PetscObjectTypeCompare((PetscObject)*A, size == 1 ? MATSEQAIJ : MATMPIAIJ, &aij));
  PetscCheck(aij, comm, PETSC_ERR_SUP, "the stiffness matrix must be of type aij (-mat_type)");
  PetscCall(MatXAIJSetPreallocation(*A, 1, diag.data(), offdiag.data(), NULL, NULL));
  // The rows complete from the start: StiffnessFill adds into their values, and no insertion searches
  // and shifts a growing row.
  if (size == 1) PetscCall(MatSeqAIJSetColumnIndices(*A, dcols.data()));
  else {
    Mat Ad, Ao;
    PetscCall(MatMPIAIJGetSeqAIJ(*A, &Ad, &Ao, NULL));
    PetscCall(MatSeqAIJSetColumnIndices(Ad, dcols.data()));
    PetscCall(MatSeqAIJSetColumnIndices(Ao, ocols.data()));
  }
  PetscCall(MatSetLocalToGlobalMapping(*A, space.ltog, space.ltog));
  PetscCall(MatSetOption(*A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  // Symmetric by construction, and the symmetric Dirichlet elimination keeps it so.
  PetscCall(MatSetOption(*A, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(*A, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode StiffnessFill::Begin(const Space &space, Mat A)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)A);
  PetscMPIInt size;
  PetscInt    rstart, rend;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  A_  = A;
  nb_ = space.Nb();
  PetscCall(GlobalIndices(space, global_));
  PetscCall(MatGetOwnershipRange(A, &rstart, &rend));
  row_.resize(space.numLocal);
  for (PetscInt d = 0; d < space.numLocal; ++d) row_[d] = global_[d] >= rstart && global_[d] < rend ? global_[d] - rstart : -1;
  blocks_[0] = A, blocks_[1] = nullptr;
  if (size > 1) PetscCall(MatMPIAIJGetSeqAIJ(A, &blocks_[0], &blocks_[1], NULL));
  for (int b = 0; b < 2 && blocks_[b]; ++b) {
    PetscInt  n;
    PetscBool done;
    PetscCall(MatGetRowIJ(blocks_[b], 0, PETSC_FALSE, PETSC_FALSE, &n, &ia_[b], &ja_[b], &done));
    PetscCheck(done, PETSC_COMM_SELF, PETSC_ERR_PLIB, "the stiffness matrix gives no row structure");
    PetscCall(MatSeqAIJGetArray(blocks_[b], &va_[b]));
    PetscCall(PetscArrayzero(va_[b], ia_[b][n])); // the preallocation leaves them unset
  }
  PetscFunctionReturn(0);
}

PetscErrorCode StiffnessFill::Add(const PetscInt *dofs, const PetscReal *Ke)
{
  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < nb_; ++i) {
    const PetscInt r = row_[dofs[i]];
    if (r < 0) { // another rank's row: to its owner at the assembly
      PetscInt gr = global_[dofs[i]], gc[4];
      for (PetscInt j = 0; j < nb_; ++j) gc[j] = global_[dofs[j]];
      PetscCall(MatSetValues(A_, 1, &gr, nb_, gc, &Ke[i * nb_], ADD_VALUES));
      continue;
    }
    for (PetscInt j = 0; j < nb_; ++j) {
      const PetscInt  d = dofs[j], b = row_[d] >= 0 ? 0 : 1, key = b ? global_[d] : row_[d];
      const PetscInt *cols = ja_[b] + ia_[b][r], n = ia_[b][r + 1] - ia_[b][r];
      PetscInt        k    = 0;
      while (k < n && cols[k] != key) ++k;
      PetscCheck(k < n, PETSC_COMM_SELF, PETSC_ERR_PLIB, "column %" PetscInt_FMT " is not in the pattern of row %" PetscInt_FMT, global_[d], global_[dofs[i]]);
      va_[b][ia_[b][r] + k] += Ke[i * nb_ + j];
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode StiffnessFill::End()
{
  PetscFunctionBeginUser;
  for (int b = 0; b < 2 && blocks_[b]; ++b) {
    PetscInt  n;
    PetscBool done;
    PetscCall(MatSeqAIJRestoreArray(blocks_[b], &va_[b]));
    PetscCall(MatRestoreRowIJ(blocks_[b], 0, PETSC_FALSE, PETSC_FALSE, &n, &ia_[b], &ja_[b], &done));
  }
  *this = StiffnessFill();
  PetscFunctionReturn(0);
}

} // namespace signorini

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

// The owned range and the global index of every local DOF.
struct Numbering {
  std::vector<PetscInt> global, ranges;
  PetscInt              rstart = 0, rend = 0;
  bool                  Owned(PetscInt g) const { return g >= rstart && g < rend; }
};

// The columns other ranks' cells give the rows this rank owns: each rank sends the records (row, ncols,
// cols...) of the rows it does not own to their owners. Returned as compressed rows over the owned rows.
struct Extra {
  std::vector<PetscInt> offset, cols;
};

static PetscErrorCode ExchangeExtra(MPI_Comm comm, PetscInt numOwned, const Numbering &num, const std::vector<std::vector<PetscInt>> &send, Extra &extra)
{
  std::vector<PetscInt> received;
  PetscFunctionBeginUser;
  PetscCall(ExchangeRecords(comm, send, received));
  extra.offset.assign(numOwned + 1, 0);
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1]) extra.offset[received[k] - num.rstart + 1] += received[k + 1];
  for (PetscInt i = 0; i < numOwned; ++i) extra.offset[i + 1] += extra.offset[i];
  extra.cols.resize(extra.offset[numOwned]);
  std::vector<PetscInt> next(extra.offset.begin(), extra.offset.end() - 1);
  for (size_t k = 0; k < received.size(); k += 2 + received[k + 1])
    for (PetscInt j = 0; j < received[k + 1]; ++j) extra.cols[next[received[k] - num.rstart]++] = received[k + 2 + j];
  PetscFunctionReturn(0);
}

// Sorts a row's few columns without the branches std::sort mispredicts on random data (they made it the
// largest cost of the pattern): odd-even transposition with min/max on values held in registers.
template <int N>
static void SortFew(PetscInt *a)
{
  PetscInt v[N];
#pragma GCC unroll 8
  for (int k = 0; k < N; ++k) v[k] = a[k];
#pragma GCC unroll 8
  for (int round = 0; round < N; ++round)
#pragma GCC unroll 8
    for (int k = round & 1; k + 1 < N; k += 2) {
      const PetscInt lo = std::min(v[k], v[k + 1]), hi = std::max(v[k], v[k + 1]);
      v[k] = lo, v[k + 1] = hi;
    }
#pragma GCC unroll 8
  for (int k = 0; k < N; ++k) a[k] = v[k];
}

static void SortRow(PetscInt *a, PetscInt n)
{
  switch (n) {
  case 0:
  case 1: return;
  case 2: return SortFew<2>(a);
  case 3: return SortFew<3>(a);
  case 4: return SortFew<4>(a);
  case 5: return SortFew<5>(a);
  case 6: return SortFew<6>(a);
  case 7: return SortFew<7>(a);
  case 8: return SortFew<8>(a);
  default: return std::sort(a, a + n);
  }
}

// The owned rows split into the columns of the diagonal block (numbered from the first owned one) and of
// the off-diagonal block (global until the assembly compacts them), each row sorted: what
// MatXAIJSetPreallocation and MatSeqAIJSetColumnIndices take.
struct Split {
  std::vector<PetscInt> diag, offdiag, dcols, ocols; // per row counts; the rows' columns, row after row
};

// Crouzeix-Raviart: a face lies in at most two cells, which share no other face, so the columns of a row
// are the row itself and the other faces of its cells, all distinct: counted in one pass over the cell
// table and written in a second one straight to their places, without the cells-of-each-DOF table and the
// de-duplication P1 needs. A face this rank does not own lies in one of its cells (the other one is on
// the owner), whose faces go to the owner.
static PetscErrorCode SplitRowsCR(MPI_Comm comm, const Space &space, const Numbering &num, Split &split)
{
  const PetscInt nb = space.Nb(), n = space.numOwned;
  PetscMPIInt    size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  split.diag.assign(n, 1); // the row itself
  split.offdiag.assign(n, 0);
  const auto count = [&](PetscInt i, PetscInt g) { ++(num.Owned(g) ? split.diag[i] : split.offdiag[i]); };
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt g = num.global[dofs[i]];
      if (num.Owned(g)) {
        for (PetscInt j = 0; j < nb; ++j)
          if (j != i) count(g - num.rstart, num.global[dofs[j]]);
        continue;
      }
      std::vector<PetscInt> &buf = send[OwnerOf(num.ranges, g)];
      buf.push_back(g);
      buf.push_back(nb - 1);
      for (PetscInt j = 0; j < nb; ++j)
        if (j != i) buf.push_back(num.global[dofs[j]]);
    }
  }
  Extra extra;
  PetscCall(ExchangeExtra(comm, n, num, send, extra));
  for (PetscInt i = 0; i < n; ++i)
    for (PetscInt k = extra.offset[i]; k < extra.offset[i + 1]; ++k) count(i, extra.cols[k]);
  std::vector<PetscInt> dnext(n + 1, 0), onext(n + 1, 0);
  for (PetscInt i = 0; i < n; ++i) dnext[i + 1] = dnext[i] + split.diag[i], onext[i + 1] = onext[i] + split.offdiag[i];
  split.dcols.resize(dnext[n]);
  split.ocols.resize(onext[n]);
  const auto put = [&](PetscInt i, PetscInt g) {
    if (num.Owned(g)) split.dcols[dnext[i]++] = g - num.rstart;
    else split.ocols[onext[i]++] = g;
  };
  for (PetscInt i = 0; i < n; ++i) {
    put(i, num.rstart + i);
    for (PetscInt k = extra.offset[i]; k < extra.offset[i + 1]; ++k) put(i, extra.cols[k]);
  }
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt g = num.global[dofs[i]];
      if (!num.Owned(g)) continue;
      for (PetscInt j = 0; j < nb; ++j)
        if (j != i) put(g - num.rstart, num.global[dofs[j]]);
    }
  }
  // dnext[i], onext[i] now end row i; each block's row is sorted on its own, the global order split.
  for (PetscInt i = 0; i < n; ++i) {
    SortRow(&split.dcols[dnext[i] - split.diag[i]], split.diag[i]);
    SortRow(&split.ocols[onext[i] - split.offdiag[i]], split.offdiag[i]);
  }
  PetscFunctionReturn(0);
}

// P1: a vertex lies in many cells, so the columns of a row come from the cells-of-each-DOF table with
// duplicates skipped; the columns other ranks' cells give a shared row are merged.
static PetscErrorCode SplitRowsP1(MPI_Comm comm, const Space &space, const Numbering &num, Split &split)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  const DofCells                     dc = BuildDofCells(space);
  std::vector<PetscInt>              mark(space.numLocal, -1);
  std::vector<std::vector<PetscInt>> send(size);
  for (PetscInt r = 0; r < space.numLocal; ++r) {
    const PetscInt g = num.global[r];
    if (num.Owned(g)) continue;
    std::vector<PetscInt> &buf = send[OwnerOf(num.ranges, g)];
    buf.push_back(g);
    const size_t head = buf.size();
    buf.push_back(0);
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { buf.push_back(num.global[d]); });
    buf[head] = (PetscInt)(buf.size() - head - 1);
  }
  Extra extra;
  PetscCall(ExchangeExtra(comm, space.numOwned, num, send, extra));
  std::vector<PetscInt> cols;
  PetscInt              row = 0;
  split.diag.assign(space.numOwned, 0);
  split.offdiag.assign(space.numOwned, 0);
  // About the number of nonzeros: a vertex has as many neighbours as cells in 2D (6 on a regular mesh), and
  // in 3D about 14 against 24 cells.
  split.dcols.reserve(space.dim == 2 ? dc.cells.size() + space.numOwned : dc.cells.size() * 2 / 3);
  for (PetscInt r = 0; r < space.numLocal; ++r) {
    const PetscInt g = num.global[r];
    if (!num.Owned(g)) continue;
    const PetscInt i = g - num.rstart;
    cols.assign(extra.cols.begin() + extra.offset[i], extra.cols.begin() + extra.offset[i + 1]);
    ForEachColumn(space, dc, r, mark, [&](PetscInt d) { cols.push_back(num.global[d]); });
    SortRow(cols.data(), (PetscInt)cols.size());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end()); // a shared row's columns from both sides
    // The columns go row after row: the owned DOFs must be numbered in local order.
    PetscCheck(i == row++, PETSC_COMM_SELF, PETSC_ERR_PLIB, "the owned DOFs are not numbered in local order");
    for (const PetscInt col : cols) {
      if (num.Owned(col)) ++split.diag[i], split.dcols.push_back(col - num.rstart);
      else ++split.offdiag[i], split.ocols.push_back(col);
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode CreateStiffnessMatrix(const Space &space, Mat *A)
{
  MPI_Comm             comm = PetscObjectComm((PetscObject)space.dm);
  Numbering            num;
  PetscMPIInt          size, rank;
  static PetscLogEvent event = 0;
  PetscFunctionBeginUser;
  if (!event) PetscCall(PetscLogEventRegister("StiffnessPattern", MAT_CLASSID, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(OwnershipRanges(comm, space.numOwned, num.ranges));
  num.rstart = num.ranges[rank], num.rend = num.ranges[rank + 1];
  PetscCall(GlobalIndices(space, num.global));
  Split split;
  if (space.element == Element::CR) PetscCall(SplitRowsCR(comm, space, num, split));
  else PetscCall(SplitRowsP1(comm, space, num, split));
  PetscCall(MatCreate(comm, A));
  PetscCall(MatSetSizes(*A, space.numOwned, space.numOwned, space.numGlobal, space.numGlobal));
  PetscCall(MatSetType(*A, MATAIJ));
  PetscCall(MatSetFromOptions(*A));
  PetscBool aij;
  PetscCall(PetscObjectTypeCompare((PetscObject)*A, size == 1 ? MATSEQAIJ : MATMPIAIJ, &aij));
  PetscCheck(aij, comm, PETSC_ERR_SUP, "the stiffness matrix must be of type aij (-mat_type)");
  PetscCall(MatXAIJSetPreallocation(*A, 1, split.diag.data(), split.offdiag.data(), NULL, NULL));
  // The rows complete from the start: StiffnessFill adds into their values, and no insertion searches
  // and shifts a growing row.
  if (size == 1) PetscCall(MatSeqAIJSetColumnIndices(*A, split.dcols.data()));
  else {
    Mat Ad, Ao;
    PetscCall(MatMPIAIJGetSeqAIJ(*A, &Ad, &Ao, NULL));
    PetscCall(MatSeqAIJSetColumnIndices(Ad, split.dcols.data()));
    PetscCall(MatSeqAIJSetColumnIndices(Ao, split.ocols.data()));
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

// The place of key among a row's n sorted columns, if it is there (else a place whose column is not key).
// Short rows (2D, and CR: 5 to 8 columns) are scanned, which measured faster there; longer ones (3D P1:
// about 15) by a binary search whose steps depend on n alone, the comparison choosing the half by a
// conditional move: the scan read half such a row per entry and mispredicted where it stopped, which made
// the element matrices' addition the largest part of the 3D P1 assembly.
static inline PetscInt FindColumn(const PetscInt *cols, PetscInt n, PetscInt key)
{
  if (n <= 8) {
    PetscInt k = 0;
    while (k < n - 1 && cols[k] != key) ++k;
    return k;
  }
  const PetscInt *base = cols;
  while (n > 1) {
    const PetscInt half = n / 2;
    base = base[half] <= key ? base + half : base;
    n -= half;
  }
  return (PetscInt)(base - cols);
}

PetscErrorCode StiffnessFill::Add(const PetscInt *dofs, const PetscReal *Ke)
{
  PetscInt row[4], block[4], key[4]; // each DOF's owned row, and its column: block and index in that block
  PetscFunctionBeginUser;
  for (PetscInt j = 0; j < nb_; ++j) {
    row[j]   = row_[dofs[j]];
    block[j] = row[j] < 0;
    key[j]   = block[j] ? global_[dofs[j]] : row[j];
  }
  for (PetscInt i = 0; i < nb_; ++i) {
    const PetscInt r = row[i];
    if (r < 0) { // another rank's row: to its owner at the assembly
      PetscInt gc[4];
      for (PetscInt j = 0; j < nb_; ++j) gc[j] = global_[dofs[j]];
      PetscCall(MatSetValues(A_, 1, &key[i], nb_, gc, &Ke[i * nb_], ADD_VALUES));
      continue;
    }
    for (PetscInt j = 0; j < nb_; ++j) {
      const PetscInt  b = block[j], start = ia_[b][r], n = ia_[b][r + 1] - start;
      const PetscInt *cols = ja_[b] + start;
      const PetscInt  k    = FindColumn(cols, n, key[j]);
      PetscCheck(n > 0 && cols[k] == key[j], PETSC_COMM_SELF, PETSC_ERR_PLIB, "column %" PetscInt_FMT " is not in the pattern of row %" PetscInt_FMT, global_[dofs[j]], global_[dofs[i]]);
      va_[b][start + k] += Ke[i * nb_ + j];
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

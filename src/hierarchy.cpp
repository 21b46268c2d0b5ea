#include "signorini/hierarchy.h"
#include "signorini/mesh.h"

#include <algorithm>
#include <cmath>

namespace signorini {

namespace {
// -log_view lists the building of the transfers (the adaptive multigrid builds them every step).
enum TransferEvent { kProlongation, kP1ToCR, kRecordP1, kAssembleP1, kTransferEvents };
PetscErrorCode TransferEventGet(TransferEvent e, PetscLogEvent *ev)
{
  static PetscLogEvent events[kTransferEvents] = {0, 0, 0, 0};
  static const char   *names[kTransferEvents]  = {"Prolongation", "P1ToCR", "RecordP1Transfer", "AssembleP1Transfer"};
  PetscFunctionBeginUser;
  if (!events[e]) PetscCall(PetscLogEventRegister(names[e], MAT_CLASSID, &events[e]));
  *ev = events[e];
  PetscFunctionReturn(0);
}

// How many fine cells of all ranks hold each local DOF of the fine space (the divisor of the mean).
PetscErrorCode CellsPerDof(const Space &fine, std::vector<PetscReal> &count)
{
  Vec          loc, glob;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(fine.dm, &loc));
  PetscCall(DMGetGlobalVector(fine.dm, &glob));
  PetscCall(VecSet(loc, 0));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt c = 0; c < fine.NumCells(); ++c)
    for (PetscInt i = 0; i < fine.Nb(); ++i) a[fine.Dofs(c)[i]] += 1;
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(VecSet(glob, 0));
  PetscCall(DMLocalToGlobal(fine.dm, loc, ADD_VALUES, glob));
  PetscCall(DMGlobalToLocal(fine.dm, glob, INSERT_VALUES, loc));
  PetscCall(VecGetArray(loc, &a));
  count.resize(fine.numLocal);
  for (PetscInt i = 0; i < fine.numLocal; ++i) count[i] = PetscRealPart(a[i]);
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMRestoreGlobalVector(fine.dm, &glob));
  PetscCall(DMRestoreLocalVector(fine.dm, &loc));
  PetscFunctionReturn(0);
}

// The bound nz of ProlongationMatrix for CR is reached by few rows: the assembled matrix keeps its
// allocation. A duplicate is allocated to its entries (the same entries in the same order); it is made
// while the matrix is small next to the rest of the level.
PetscErrorCode Compact(Mat *P)
{
  MatInfo info;
  Mat     copy;
  PetscFunctionBeginUser;
  PetscCall(MatGetInfo(*P, MAT_GLOBAL_SUM, &info));
  if (!(info.nz_allocated > info.nz_used)) PetscFunctionReturn(0);
  PetscCall(MatDuplicate(*P, MAT_COPY_VALUES, &copy));
  PetscCall(MatDestroy(P));
  *P = copy;
  PetscFunctionReturn(0);
}

// The global index of this rank's first owned entry of a layout with `owned` entries a rank.
PetscErrorCode FirstOwned(MPI_Comm comm, PetscInt owned, PetscInt *first)
{
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  *first = 0;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Exscan(&owned, first, 1, MPIU_INT, MPI_SUM, comm));
  if (rank == 0) *first = 0; // MPI_Exscan leaves rank 0's result undefined
  PetscFunctionReturn(0);
}

// The rows of a transfer, each owned row set at most once (rows never set stay empty), gathered before
// the matrix exists so that it is allocated to exactly its entries (no spare room to compact away with a
// copy) and filled a whole row at a time.
class TransferRows {
public:
  // owned rows, first the global index of the first of them; at most maxPerRow entries a row
  TransferRows(PetscInt owned, PetscInt first, PetscInt maxPerRow) : first_(first), max_(maxPerRow), count_(owned, -1), cols_(owned * maxPerRow), vals_(owned * maxPerRow) {}
  // the local position of global row `row`, -1 if not owned
  PetscInt Local(PetscInt row) const { return row >= first_ && row - first_ < (PetscInt)count_.size() ? row - first_ : -1; }
  bool     IsSet(PetscInt local) const { return count_[local] >= 0; }
  // Sets row `local` (a local position) to n entries; columns ascending as AIJ stores them.
  void Set(PetscInt local, PetscInt n, const PetscInt *cols, const PetscScalar *vals)
  {
    PetscInt    *c = &cols_[local * max_];
    PetscScalar *v = &vals_[local * max_];
    for (PetscInt k = 0; k < n; ++k) { // insertion: a row has at most four entries
      PetscInt j = k;
      for (; j > 0 && c[j - 1] > cols[k]; --j) c[j] = c[j - 1], v[j] = v[j - 1];
      c[j] = cols[k], v[j] = vals[k];
    }
    count_[local] = n;
  }
  // The matrix of these rows (global size M x N, n local columns). On one rank it is made on the rows'
  // arrays, compacted; on several each row is copied in whole into its exact allocation (MAT_SORTED_FULL),
  // not inserted entry by entry as MatSetValues and PETSc's CSR preallocation do (P1 to CR at 3 M rows,
  // one rank: 0.19 s through the CSR preallocation, 0.14 s row by row, 0.08 s on the arrays). Collective.
  PetscErrorCode Create(MPI_Comm comm, PetscInt n, PetscInt M, PetscInt N, Mat *P)
  {
    const PetscInt        m = (PetscInt)count_.size();
    std::vector<PetscInt> dnz(m), onz(m);
    PetscInt              cStart;
    PetscMPIInt           size;
    PetscFunctionBeginUser;
    PetscCallMPI(MPI_Comm_size(comm, &size));
    if (size == 1) PetscFunctionReturn(CreateSeq(comm, n, P));
    PetscCall(FirstOwned(comm, n, &cStart));
    for (PetscInt r = 0; r < m; ++r) {
      const PetscInt *c = &cols_[r * max_];
      dnz[r]            = 0;
      for (PetscInt k = 0; k < count_[r]; ++k) dnz[r] += c[k] >= cStart && c[k] < cStart + n;
      onz[r] = PetscMax(count_[r], 0) - dnz[r];
    }
    PetscCall(MatCreate(comm, P));
    PetscCall(MatSetSizes(*P, m, n, M, N));
    PetscCall(MatSetType(*P, MATAIJ));
    PetscCall(MatXAIJSetPreallocation(*P, 1, dnz.data(), onz.data(), NULL, NULL));
    PetscCall(MatSetOption(*P, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE));
    PetscCall(MatSetOption(*P, MAT_SORTED_FULL, PETSC_TRUE));
    for (PetscInt r = 0; r < m; ++r) {
      const PetscInt row = first_ + r;
      if (count_[r] > 0) PetscCall(MatSetValues(*P, 1, &row, count_[r], &cols_[r * max_], &vals_[r * max_], INSERT_VALUES));
    }
    PetscCall(MatAssemblyBegin(*P, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(*P, MAT_FINAL_ASSEMBLY));
    PetscCall(MatSetOption(*P, MAT_SORTED_FULL, PETSC_FALSE));
    PetscFunctionReturn(0);
  }

private:
  // The arrays of a sequential matrix made on them (MatCreateSeqAIJWithArrays), owned by the matrix
  // through a composed container: the one copy of the entries is the compacted rows'.
  struct Arrays {
    std::vector<PetscInt>    i, j;
    std::vector<PetscScalar> a;
  };
  static PetscErrorCode DestroyArrays(void *p)
  {
    delete static_cast<Arrays *>(p);
    return 0;
  }
  PetscErrorCode CreateSeq(MPI_Comm comm, PetscInt n, Mat *P)
  {
    const PetscInt m = (PetscInt)count_.size();
    PetscContainer container;
    Arrays        *arrays;
    PetscFunctionBeginUser;
    PetscCall(PetscContainerCreate(PETSC_COMM_SELF, &container));
    arrays = new Arrays;
    PetscCall(PetscContainerSetPointer(container, arrays));
    PetscCall(PetscContainerSetUserDestroy(container, DestroyArrays));
    arrays->i.assign(m + 1, 0);
    for (PetscInt r = 0; r < m; ++r) arrays->i[r + 1] = arrays->i[r] + PetscMax(count_[r], 0);
    const PetscInt nnz = arrays->i[m];
    arrays->j.resize(nnz); // sized to the entries
    arrays->a.resize(nnz);
    for (PetscInt r = 0; r < m; ++r) {
      std::copy(&cols_[r * max_], &cols_[r * max_] + PetscMax(count_[r], 0), &arrays->j[arrays->i[r]]);
      std::copy(&vals_[r * max_], &vals_[r * max_] + PetscMax(count_[r], 0), &arrays->a[arrays->i[r]]);
    }
    cols_ = std::vector<PetscInt>(), vals_ = std::vector<PetscScalar>();
    PetscCall(MatCreateSeqAIJWithArrays(comm, m, n, arrays->i.data(), arrays->j.data(), arrays->a.data(), P));
    PetscCall(PetscObjectCompose((PetscObject)*P, "signorini_transfer_arrays", (PetscObject)container));
    PetscCall(PetscContainerDestroy(&container));
    PetscFunctionReturn(0);
  }

  PetscInt                 first_, max_;
  std::vector<PetscInt>    count_; // entries of each row, -1: not set
  std::vector<PetscInt>    cols_;  // max_ slots a row
  std::vector<PetscScalar> vals_;
};

} // namespace

// (The dimension a template parameter, as in the other cell loops: the loops of the geometry unroll.)
template <PetscInt dim>
static PetscErrorCode ProlongationMatrixD(const Space &coarse, const Space &fine, const std::vector<PetscInt> &parent, Mat *P)
{
  MPI_Comm        comm = PetscObjectComm((PetscObject)fine.dm);
  const PetscInt *gf, *gc;
  PetscFunctionBeginUser;
  PetscLogEvent event;
  PetscCall(TransferEventGet(kProlongation, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCheck((PetscInt)parent.size() == fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)fine.NumCells());
  PetscCheck(coarse.element == fine.element, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "prolongation between different elements");
  // A continuous (P1) coarse function gives every cell holding a fine DOF the same row: each owned DOF is
  // then set once, from the first local cell that holds it (every owned DOF lies in a local cell), with no
  // mean and no communication. Only a CR coarse function needs the mean over the cells of all ranks.
  const bool             once = coarse.element == Element::P1;
  std::vector<PetscReal> count;
  PetscInt               first;
  PetscCall(FirstOwned(comm, fine.numOwned, &first));
  // A row couples the DOFs of at most two parent cells (a CR face on a coarse face); P1 rows hold at most
  // dim + 1 entries, CR rows at most 2 (dim + 1) - 1.
  const PetscInt nz = 2 * coarse.Nb();
  TransferRows   rows(once ? fine.numOwned : 0, first, coarse.Nb());
  if (!once) {
    PetscCall(CellsPerDof(fine, count));
    PetscCall(MatCreateAIJ(comm, fine.numOwned, coarse.numOwned, fine.numGlobal, coarse.numGlobal, nz, NULL, nz, NULL, P));
    PetscCall(MatSetOption(*P, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  }
  PetscCall(ISLocalToGlobalMappingGetIndices(fine.ltog, &gf));
  PetscCall(ISLocalToGlobalMappingGetIndices(coarse.ltog, &gc));
  constexpr PetscInt nb = dim + 1;
  PetscReal      lambda[4], mu[4], x[3];
  Space::Coords  XH, Xh;
  CellGeometry   g{}; // set at the first parent (pc != last); zeroed for the compiler's sake
  PetscInt       last = -1; // the parent whose geometry g is: the children of a cell are consecutive
  for (PetscInt c = 0; c < fine.NumCells(); ++c) {
    const PetscInt pc = parent[c];
    bool           haveCell = false; // Xh, for the first DOF of the cell that needs it
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt dof = fine.Dofs(c)[i], row = once ? rows.Local(gf[dof]) : -1;
      if (fine.kindLocal[dof] == kDirichlet) continue;
      if (once && (row < 0 || rows.IsSet(row))) continue;
      if (pc != last) {
        XH = coarse.XD<dim>(pc);
        ComputeCellGeometryD<dim>(XH, g);
        last = pc;
      }
      if (!haveCell) Xh = fine.XD<dim>(c), haveCell = true;
      DofLambda(fine.element, dim, i, mu);
      SimplexPoint(dim, Xh, mu, x);
      Barycentric(dim, g, XH, x, lambda);
      PetscInt    cols[4], n = 0;
      PetscScalar vals[4];
      for (PetscInt j = 0; j < nb; ++j) {
        const PetscInt  J = coarse.Dofs(pc)[j];
        const PetscReal w = coarse.BasisValue(pc, j, lambda) / (once ? 1 : count[dof]);
        if (coarse.kindLocal[J] == kDirichlet || std::fabs(w) < 1e-12) continue;
        cols[n] = gc[J], vals[n++] = w;
      }
      if (once) rows.Set(row, n, cols, vals);
      else PetscCall(MatSetValues(*P, 1, &gf[dof], n, cols, vals, ADD_VALUES));
    }
  }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(coarse.ltog, &gc));
  PetscCall(ISLocalToGlobalMappingRestoreIndices(fine.ltog, &gf));
  if (once) PetscCall(rows.Create(comm, coarse.numOwned, fine.numGlobal, coarse.numGlobal, P));
  else {
    PetscCall(MatAssemblyBegin(*P, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(*P, MAT_FINAL_ASSEMBLY));
    PetscCall(Compact(P));
  }
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}
PetscErrorCode ProlongationMatrix(const Space &coarse, const Space &fine, const std::vector<PetscInt> &parent, Mat *P)
{
  return WithDim(coarse.dim, [&](auto D) { return ProlongationMatrixD<D>(coarse, fine, parent, P); });
}

PetscErrorCode P1ToCRMatrix(const Space &p1, const Space &cr, Mat *Q)
{
  MPI_Comm        comm = PetscObjectComm((PetscObject)cr.dm);
  const PetscInt *gf, *gc;
  PetscInt        first;
  PetscFunctionBeginUser;
  PetscLogEvent event;
  PetscCall(TransferEventGet(kP1ToCR, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCheck(p1.element == Element::P1 && cr.element == Element::CR && p1.NumCells() == cr.NumCells() && p1.vStart == cr.vStart, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "P1 to CR needs the two spaces of one mesh");
  const PetscInt dim = cr.dim, nb = cr.Nb();
  PetscCall(FirstOwned(comm, cr.numOwned, &first));
  TransferRows rows(cr.numOwned, first, dim);
  PetscCall(ISLocalToGlobalMappingGetIndices(cr.ltog, &gf));
  PetscCall(ISLocalToGlobalMappingGetIndices(p1.ltog, &gc));
  for (PetscInt c = 0; c < cr.NumCells(); ++c)
    for (PetscInt i = 0; i < nb; ++i) { // face i: the vertices of the cell but vertex i (P1 DOF = vertex - vStart)
      const PetscInt dof = cr.Dofs(c)[i], row = rows.Local(gf[dof]);
      if (row < 0 || rows.IsSet(row) || cr.kindLocal[dof] == kDirichlet) continue;
      PetscInt    cols[3], n = 0;
      PetscScalar vals[3];
      for (PetscInt j = 0; j < nb; ++j) {
        const PetscInt v = cr.cellVert[c * nb + j];
        if (j == i || p1.kindLocal[v] == kDirichlet) continue;
        cols[n] = gc[v], vals[n++] = 1.0 / dim;
      }
      rows.Set(row, n, cols, vals);
    }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(p1.ltog, &gc));
  PetscCall(ISLocalToGlobalMappingRestoreIndices(cr.ltog, &gf));
  PetscCall(rows.Create(comm, p1.numOwned, cr.numGlobal, p1.numGlobal, Q));
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}


// RecordP1Transfer's cell loop, the dimension a template parameter (as in the other cell loops).
template <PetscInt dim>
static void RecordCells(const Space &coarse, const MeshCells &cells, const std::vector<PetscInt> &parent, const PetscInt *gc, std::vector<PetscReal> &data)
{
  constexpr PetscInt nb = dim + 1, stride = nb * (nb + 1);
  PetscReal          lambda[4];
  Space::Coords      XH;
  CellGeometry       g{}; // set at the first parent (pc != last); zeroed for the compiler's sake
  PetscInt           last = -1; // the parent whose geometry g is: the children of a cell are consecutive
  for (PetscInt c = 0; c < cells.NumCells(); ++c) {
    const PetscInt      pc  = parent[c];
    PetscReal          *rec = &data[c * stride];
    const Space::Coords Xh  = cells.X(c);
    if (pc != last) {
      XH = coarse.XD<dim>(pc);
      ComputeCellGeometryD<dim>(XH, g);
      last = pc;
    }
    for (PetscInt j = 0; j < nb; ++j) {
      const PetscInt J = coarse.Dofs(pc)[j];
      rec[j]           = coarse.kindLocal[J] == kDirichlet ? -1 : gc[J];
    }
    for (PetscInt k = 0; k < nb; ++k) {
      Barycentric(dim, g, XH, &Xh.x[k * dim], lambda);
      for (PetscInt j = 0; j < nb; ++j) rec[nb + k * nb + j] = std::fabs(lambda[j]) >= 1e-12 ? lambda[j] : 0;
    }
  }
}

PetscErrorCode RecordP1Transfer(const Space &coarse, DM fine, const std::vector<PetscInt> &parent, TransferRecord &r)
{
  MeshCells       cells;
  const PetscInt *gc;
  PetscLogEvent   event;
  PetscFunctionBeginUser;
  PetscCall(TransferEventGet(kRecordP1, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCheck(coarse.element == Element::P1, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "the recorded transfer is between P1 spaces");
  const PetscInt dim = coarse.dim, nb = dim + 1, stride = nb * (nb + 1);
  PetscCall(cells.Init(fine));
  const PetscInt n = cells.NumCells();
  PetscCheck((PetscInt)parent.size() == n, PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)n);
  PetscCall(ISLocalToGlobalMappingGetIndices(coarse.ltog, &gc));
  r.cells.nb = stride / 2;
  r.cells.data.resize(n * stride);
  WithDim(dim, [&](auto D) { RecordCells<D>(coarse, cells, parent, gc, r.cells.data); });
  PetscCall(ISLocalToGlobalMappingRestoreIndices(coarse.ltog, &gc));
  r.coarseOwned  = coarse.numOwned;
  r.coarseGlobal = coarse.numGlobal;
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode AssembleP1Transfer(const TransferRecord &r, const Space &fine, Mat *P)
{
  MPI_Comm        comm = PetscObjectComm((PetscObject)fine.dm);
  const PetscInt *gf;
  PetscInt        first;
  PetscLogEvent   event;
  PetscFunctionBeginUser;
  PetscCall(TransferEventGet(kAssembleP1, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  PetscCheck(fine.element == Element::P1, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "the recorded transfer is between P1 spaces");
  const PetscInt nb = fine.Nb(), stride = nb * (nb + 1);
  PetscCheck(2 * r.cells.nb == stride && (PetscInt)r.cells.data.size() == stride * fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "transfer recorded for %d values on %d cells", (int)r.cells.data.size(), (int)fine.NumCells());
  PetscCall(FirstOwned(comm, fine.numOwned, &first));
  // Every coarse column may lie on any rank once the fine mesh has been redistributed.
  TransferRows rows(fine.numOwned, first, nb);
  PetscCall(ISLocalToGlobalMappingGetIndices(fine.ltog, &gf));
  // Every cell holding a fine vertex gives it the same row (the coarse function is continuous): each owned
  // row is set once, from the first local cell that holds it.
  for (PetscInt c = 0; c < fine.NumCells(); ++c) {
    const PetscReal *rec = &r.cells.data[c * stride];
    for (PetscInt k = 0; k < nb; ++k) {
      const PetscInt dof = fine.Dofs(c)[k], row = rows.Local(gf[dof]);
      if (row < 0 || rows.IsSet(row) || fine.kindLocal[dof] == kDirichlet) continue;
      PetscInt    cols[4], m = 0;
      PetscScalar vals[4];
      for (PetscInt j = 0; j < nb; ++j)
        if (rec[j] >= 0 && rec[nb + k * nb + j] != 0) cols[m] = (PetscInt)rec[j], vals[m++] = rec[nb + k * nb + j];
      rows.Set(row, m, cols, vals);
    }
  }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(fine.ltog, &gf));
  PetscCall(rows.Create(comm, r.coarseOwned, fine.numGlobal, r.coarseGlobal, P));
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode Hierarchy::Destroy()
{
  PetscFunctionBeginUser;
  for (Mat &m : P) PetscCall(MatDestroy(&m));
  P.clear();
  PetscFunctionReturn(0);
}

PetscErrorCode TruncateTransfer(Mat P, IS rows, IS *cols, Mat *Pt)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)P);
  Vec                kept, weight;
  const PetscInt    *idx;
  const PetscScalar *w;
  PetscInt           n, rStart, cStart;
  PetscFunctionBeginUser;
  // A coarse DOF whose column vanishes on the kept rows has a zero truncated basis function: with
  // nonnegative entries, exactly those get weight 0 in P^T 1_rows (one product, no copy of P).
  PetscCall(MatCreateVecs(P, &weight, &kept));
  PetscCall(VecSet(kept, 0));
  PetscCall(MatGetOwnershipRange(P, &rStart, NULL));
  PetscCall(ISGetLocalSize(rows, &n));
  PetscCall(ISGetIndices(rows, &idx));
  PetscScalar *a;
  PetscCall(VecGetArray(kept, &a));
  for (PetscInt k = 0; k < n; ++k) a[idx[k] - rStart] = 1;
  PetscCall(VecRestoreArray(kept, &a));
  PetscCall(ISRestoreIndices(rows, &idx));
  PetscCall(MatMultTranspose(P, kept, weight));
  PetscCall(MatGetOwnershipRangeColumn(P, &cStart, NULL));
  PetscCall(VecGetLocalSize(weight, &n));
  std::vector<PetscInt> keep;
  PetscCall(VecGetArrayRead(weight, &w));
  for (PetscInt j = 0; j < n; ++j)
    if (PetscRealPart(w[j]) > 0) keep.push_back(cStart + j);
  PetscCall(VecRestoreArrayRead(weight, &w));
  PetscCall(VecDestroy(&kept));
  PetscCall(VecDestroy(&weight));
  PetscCall(ISCreateGeneral(comm, (PetscInt)keep.size(), keep.data(), PETSC_COPY_VALUES, cols));
  PetscCall(MatCreateSubMatrix(P, rows, *cols, MAT_INITIAL_MATRIX, Pt));
  PetscFunctionReturn(0);
}

namespace {
// A truncated transfer that stores no entries of its own: Pt = P restricted to the rows `rows` and the
// columns `cols`, applied through P on vectors of P's sizes that are zero outside them. A copy of P's
// entries (MatCreateSubMatrix) on the finest CR level is 40 B per DOF; this one holds a vector of each
// size and the local positions of the kept rows and columns. The results are those of the copy, bit for
// bit: P's rows and columns in the same order, the dropped columns have no entries in the kept rows,
// and the dropped rows enter with zeros (x + 0 = x); MatMultAdd starts each row from the row of y, as
// AIJ's does.
struct Truncated {
  Mat                   P = nullptr;
  Vec                   fine = nullptr, coarse = nullptr; // zero outside the kept rows / columns between uses
  std::vector<PetscInt> rows, cols;                       // local positions of the kept rows / columns
  std::vector<PetscInt> droppedRows, droppedCols;         // and of the others (the active set: few)
};

// The local positions of the owned global indices of `is` (ascending) in a layout starting at `start`
// with n owned entries, and the positions not among them.
PetscErrorCode KeptPositions(IS is, PetscInt start, PetscInt n, std::vector<PetscInt> &kept, std::vector<PetscInt> &dropped)
{
  const PetscInt *idx;
  PetscInt        m;
  PetscFunctionBeginUser;
  PetscCall(ISGetLocalSize(is, &m));
  PetscCall(ISGetIndices(is, &idx));
  kept.resize(m);
  dropped.clear();
  PetscInt next = 0;
  for (PetscInt k = 0; k < m; ++k) {
    kept[k] = idx[k] - start;
    while (next < kept[k]) dropped.push_back(next++);
    ++next;
  }
  while (next < n) dropped.push_back(next++);
  PetscCall(ISRestoreIndices(is, &idx));
  PetscFunctionReturn(0);
}

// short <-> full: into the kept positions of full (intoFull), or gathered from them.
PetscErrorCode MoveKept(const std::vector<PetscInt> &pos, Vec shortVec, Vec full, bool intoFull)
{
  PetscScalar *s, *f;
  PetscFunctionBeginUser;
  PetscCall(VecGetArray(shortVec, &s));
  PetscCall(VecGetArray(full, &f));
  const PetscInt n = (PetscInt)pos.size();
  if (intoFull)
    for (PetscInt k = 0; k < n; ++k) f[pos[k]] = s[k];
  else
    for (PetscInt k = 0; k < n; ++k) s[k] = f[pos[k]];
  PetscCall(VecRestoreArray(full, &f));
  PetscCall(VecRestoreArray(shortVec, &s));
  PetscFunctionReturn(0);
}

PetscErrorCode ZeroAt(const std::vector<PetscInt> &pos, Vec v)
{
  PetscScalar *a;
  PetscFunctionBeginUser;
  if (pos.empty()) PetscFunctionReturn(0);
  PetscCall(VecGetArray(v, &a));
  for (PetscInt k : pos) a[k] = 0;
  PetscCall(VecRestoreArray(v, &a));
  PetscFunctionReturn(0);
}

// z = Pt x or Pt^T x (transpose), + y where y is given: through P (or P^T) on the full vectors, the
// output's full vector holding y on the kept positions for the sum (MatMultAdd adds in place).
PetscErrorCode TruncatedApply(Mat T, Vec x, Vec y, Vec z, bool transpose)
{
  Truncated *t;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(T, &t));
  const std::vector<PetscInt> &in = transpose ? t->rows : t->cols, &out = transpose ? t->cols : t->rows;
  const std::vector<PetscInt> &dropped = transpose ? t->droppedCols : t->droppedRows;
  Vec                          inFull = transpose ? t->fine : t->coarse, outFull = transpose ? t->coarse : t->fine;
  PetscCall(MoveKept(in, x, inFull, true));
  if (y) {
    PetscCall(MoveKept(out, y, outFull, true));
    if (transpose) PetscCall(MatMultTransposeAdd(t->P, inFull, outFull, outFull));
    else PetscCall(MatMultAdd(t->P, inFull, outFull, outFull));
  } else if (transpose) PetscCall(MatMultTranspose(t->P, inFull, outFull));
  else PetscCall(MatMult(t->P, inFull, outFull));
  PetscCall(MoveKept(out, z, outFull, false));
  PetscCall(ZeroAt(dropped, outFull));
  PetscFunctionReturn(0);
}

PetscErrorCode TruncatedMult(Mat T, Vec x, Vec y) { return TruncatedApply(T, x, NULL, y, false); }
PetscErrorCode TruncatedMultAdd(Mat T, Vec x, Vec y, Vec z) { return TruncatedApply(T, x, y, z, false); }
PetscErrorCode TruncatedMultTranspose(Mat T, Vec x, Vec y) { return TruncatedApply(T, x, NULL, y, true); }
PetscErrorCode TruncatedMultTransposeAdd(Mat T, Vec x, Vec y, Vec z) { return TruncatedApply(T, x, y, z, true); }

PetscErrorCode TruncatedDestroy(Mat T)
{
  Truncated *t;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(T, &t));
  PetscCall(MatDestroy(&t->P));
  PetscCall(VecDestroy(&t->fine));
  PetscCall(VecDestroy(&t->coarse));
  delete t;
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode TruncatedTransferShell(Mat P, IS rows, IS cols, Mat *T)
{
  PetscInt m, n, M, N, rStart, cStart, mFull, nFull;
  PetscFunctionBeginUser;
  auto *t = new Truncated;
  t->P    = P;
  PetscCall(PetscObjectReference((PetscObject)P));
  PetscCall(MatCreateVecs(P, &t->coarse, &t->fine));
  PetscCall(VecSet(t->coarse, 0));
  PetscCall(VecSet(t->fine, 0));
  PetscCall(MatGetOwnershipRange(P, &rStart, NULL));
  PetscCall(MatGetOwnershipRangeColumn(P, &cStart, NULL));
  PetscCall(MatGetLocalSize(P, &mFull, &nFull));
  PetscCall(KeptPositions(rows, rStart, mFull, t->rows, t->droppedRows));
  PetscCall(KeptPositions(cols, cStart, nFull, t->cols, t->droppedCols));
  PetscCall(ISGetLocalSize(rows, &m));
  PetscCall(ISGetLocalSize(cols, &n));
  PetscCall(ISGetSize(rows, &M));
  PetscCall(ISGetSize(cols, &N));
  PetscCall(MatCreateShell(PetscObjectComm((PetscObject)P), m, n, M, N, t, T));
  PetscCall(MatShellSetOperation(*T, MATOP_MULT, (void (*)(void))TruncatedMult));
  PetscCall(MatShellSetOperation(*T, MATOP_MULT_ADD, (void (*)(void))TruncatedMultAdd));
  PetscCall(MatShellSetOperation(*T, MATOP_MULT_TRANSPOSE, (void (*)(void))TruncatedMultTranspose));
  PetscCall(MatShellSetOperation(*T, MATOP_MULT_TRANSPOSE_ADD, (void (*)(void))TruncatedMultTransposeAdd));
  PetscCall(MatShellSetOperation(*T, MATOP_DESTROY, (void (*)(void))TruncatedDestroy));
  PetscFunctionReturn(0);
}

namespace {
// Smoothing by one symmetric Gauss-Seidel sweep (SOR, forward then backward, local to each rank) before
// and after the coarse correction: the V-cycle is then a symmetric operator. Measured against a forward
// sweep before and a backward one after (also symmetric, half the smoothing work): paper-5.1 N = 512, CR
// 13 -> 10 CG iterations on the finest level and fewer flops in all, P1 10 -> 8 at the same cost.
PetscErrorCode SetSmoother(PC pc, PetscInt l)
{
  KSP ksp;
  PC  sub;
  PetscFunctionBeginUser;
  PetscCall(PCMGGetSmoother(pc, l, &ksp));
  PetscCall(KSPSetType(ksp, KSPRICHARDSON));
  PetscCall(KSPGetPC(ksp, &sub));
  PetscCall(PCSetType(sub, PCSOR));
  PetscCall(PCSORSetSymmetric(sub, SOR_LOCAL_SYMMETRIC_SWEEP));
  PetscCall(KSPSetTolerances(ksp, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT, 1));
  PetscFunctionReturn(0);
}

// The Galerkin operator Pt^T Afine Pt of the level below. The product's symbolic phase first reserves
// fill x (nnz(A) + nnz(P)) column indices (PETSc's default fill 2), sized for a product as large as its
// factors, where this one has a coarse level's rows: 3D CR N = 48, 107 MB reserved for 7 MB of entries,
// the largest allocation of the solve. The reservation here is 3 times a row of Afine for each coarse
// DOF; the product grows it where that is short (the same product either way).
PetscErrorCode GalerkinOperator(Mat Afine, Mat Pt, Mat *Ac)
{
  MatInfo  a, p;
  PetscInt rows, cols;
  PetscFunctionBeginUser;
  PetscCall(MatGetInfo(Afine, MAT_GLOBAL_SUM, &a));
  PetscCall(MatGetInfo(Pt, MAT_GLOBAL_SUM, &p));
  PetscCall(MatGetSize(Afine, &rows, NULL));
  PetscCall(MatGetSize(Pt, NULL, &cols));
  const PetscReal expected = 3 * a.nz_used / PetscMax(rows, 1) * cols;
  PetscCall(MatProductCreate(Afine, Pt, NULL, Ac));
  PetscCall(MatProductSetType(*Ac, MATPRODUCT_PtAP));
  PetscCall(MatProductSetFill(*Ac, PETSC_DEFAULT));
  PetscCall(MatProductSetFromOptions(*Ac)); // in parallel PETSc picks its algorithm by the fill: the default's choice
  PetscCall(MatProductSetFill(*Ac, PetscMin(2.0, expected / PetscMax(a.nz_used + p.nz_used, 1.0))));
  PetscCall(MatProductSymbolic(*Ac));
  PetscCall(MatProductNumeric(*Ac));
  PetscCall(MatProductClear(*Ac)); // computed once: its references to both factors and its work data go
  PetscCall(MatSetOption(*Ac, MAT_SYMMETRIC, PETSC_TRUE));
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode HierarchyMGSetUp(PC pc, const Hierarchy &h, Mat A, IS inactive)
{
  const PetscInt levels = (PetscInt)h.P.size() + 1;
  KSP            ksp;
  PC             sub;
  IS             rows = inactive, cols;
  Mat            Afine = A;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectReference((PetscObject)rows));
  PetscCall(PetscObjectReference((PetscObject)Afine));
  PetscCall(PCSetType(pc, PCMG));
  PetscCall(PCMGSetLevels(pc, levels, NULL));
  PetscCall(PCMGSetType(pc, PC_MG_MULTIPLICATIVE));
  PetscCall(PCMGSetCycleType(pc, PC_MG_CYCLE_V));
  PetscCall(PCMGSetGalerkin(pc, PC_MG_GALERKIN_NONE)); // the coarse operators are set below
  // PCMG's level l is hierarchy level l: P[l - 1] maps level l - 1 to level l.
  for (PetscInt l = levels - 1; l > 0; --l) {
    Mat Pt, Ac;
    PetscCall(TruncateTransfer(h.P[l - 1], rows, &cols, &Pt));
    PetscCall(GalerkinOperator(Afine, Pt, &Ac));
    PetscCall(MatDestroy(&Pt)); // the copy served the product; the cycle applies the transfer through P
    PetscCall(TruncatedTransferShell(h.P[l - 1], rows, cols, &Pt));
    PetscCall(PCMGSetInterpolation(pc, l, Pt));
    PetscCall(PCMGGetSmoother(pc, l - 1, &ksp));
    PetscCall(KSPSetOperators(ksp, Ac, Ac));
    PetscCall(SetSmoother(pc, l));
    PetscCall(MatDestroy(&Pt));
    PetscCall(MatDestroy(&Afine));
    Afine = Ac;
    PetscCall(ISDestroy(&rows));
    rows = cols;
  }
  PetscCall(MatDestroy(&Afine));
  PetscCall(ISDestroy(&rows));
  PetscCall(PCMGGetCoarseSolve(pc, &ksp));
  PetscCall(KSPSetType(ksp, KSPPREONLY));
  PetscCall(KSPGetPC(ksp, &sub));
  PetscCall(PCSetType(sub, PCHYPRE));
  PetscCall(PCHYPRESetType(sub, "boomeramg"));
  PetscCall(PCSetOperators(pc, A, A));
  PetscCall(PCSetFromOptions(pc));
  PetscCall(PCSetUp(pc));
  ReleaseFreedMemory(); // the copies of the transfers and the products' work data, before the solve needs the memory
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/transfer.h"
#include "signorini/contact.h"
#include "signorini/mesh.h"

#include <cmath>

namespace signorini {

namespace {
// How many fine cells ahead the loops over them start loading the coarse data of their parents.
constexpr PetscInt kAhead = 16;

// Calls f(c, i, pc, lambda) for every DOF i of every fine cell c, with pc its parent and lambda the
// barycentric coordinates of the DOF's point in pc; X(c) gives the vertex coordinates of fine cell c
// (anything SimplexPoint reads: a Space::Coords or a pointer). The dimension D is a constant here, so
// the small loops of the geometry unroll (the same operations in the same order as with dim).
template <int D, class Coords, class F>
void ForEachFineDofD(const Space &coarse, PetscInt numFine, const std::vector<PetscInt> &parent, Coords X, F f)
{
  PetscReal     lambda[4], mu[4][4], x[3];
  CellGeometry  g{}; // set at the first cell (pc != last); zeroed here only for the compiler's sake
  PetscInt      last = -1;
  const bool    p1 = coarse.element == Element::P1;
  Space::Coords XH;
  for (PetscInt i = 0; i <= D; ++i) DofLambda(coarse.element, D, i, mu[i]);
  for (PetscInt c = 0; c < numFine; ++c) {
    const PetscInt pc = parent[c];
    const auto    &Xh = X(c);
    // The vertex coordinates of the parent some cells ahead, whose vertices lie anywhere in vertX.
    if (c + kAhead < numFine)
      for (PetscInt k = 0; k <= D; ++k) __builtin_prefetch(&coarse.vertX[coarse.cellVert[parent[c + kAhead] * (D + 1) + k] * D]);
    // The children of a parent come one after the other: its vertices and geometry once for all of them.
    if (pc != last) XH = coarse.X(pc), ComputeCellGeometryD<D>(XH, g), last = pc;
    for (PetscInt i = 0; i <= D; ++i) {
      // A P1 DOF's point is its vertex: SimplexPoint would give exactly its coordinates (1 x X_i + 0 x ...).
      const PetscReal *xi = p1 ? &Xh[i * D] : x;
      if (!p1) SimplexPoint(D, Xh, mu[i], x);
      Barycentric(D, g, XH, xi, lambda);
      f(c, i, pc, lambda);
    }
  }
}
template <class Coords, class F>
void ForEachFineDof(const Space &coarse, PetscInt numFine, const std::vector<PetscInt> &parent, Coords X, F f)
{
  WithDim(coarse.dim, [&](auto D) { ForEachFineDofD<D>(coarse, numFine, parent, X, f); });
}

// ForEachFineDof where the fine cells come from bisection, whose corners (RefineMarkedBisection) say
// where each fine vertex lies in its parent: the barycentric coordinates of every DOF point follow from
// them, without the fine mesh's cones and coordinates and without solving for them in the parent.
template <int D, class F>
void ForEachFineDofPlacedD(const Space &coarse, const std::vector<PetscInt> &parent, const std::vector<char> &corners, F f)
{
  PetscReal      mu[4][4], corner[4][4], lambda[4];
  const PetscInt numFine = (PetscInt)parent.size();
  for (PetscInt i = 0; i <= D; ++i) DofLambda(coarse.element, D, i, mu[i]);
  for (PetscInt c = 0; c < numFine; ++c) {
    for (PetscInt j = 0; j <= D; ++j) {
      const unsigned char on = corners[c * (D + 1) + j];
      const PetscReal     w  = on == 1 || on == 2 || on == 4 || on == 8 ? 1 : 0.5; // a vertex, or an edge's midpoint
      for (PetscInt k = 0; k <= D; ++k) corner[j][k] = on >> k & 1 ? w : 0;
    }
    for (PetscInt i = 0; i <= D; ++i) {
      for (PetscInt k = 0; k <= D; ++k) {
        lambda[k] = 0;
        for (PetscInt j = 0; j <= D; ++j) lambda[k] += mu[i][j] * corner[j][k];
      }
      f(c, i, parent[c], lambda);
    }
  }
}

// Whether the point of barycentric coordinates lambda in coarse cell pc lies on coarse DOFs (at least
// one) that are all active contact DOFs (aU, aL: local arrays of uH and its lower bound; tol:
// ActiveTolerance). A CR point inside the cell lies on none (a fine contact DOF always lies on one).
bool OnActiveContact(const Space &coarse, PetscInt pc, const PetscReal *lambda, const PetscScalar *aU, const PetscScalar *aL, PetscReal tol)
{
  const PetscReal eps    = 1e-10;
  bool            active = true, onAny = false;
  for (PetscInt j = 0; j < coarse.Nb(); ++j) {
    // P1: vertex j supports the point if lambda_j > 0; CR: face j contains it if lambda_j = 0.
    const bool     on = coarse.element == Element::P1 ? lambda[j] > eps : std::fabs(lambda[j]) < eps;
    const PetscInt J  = coarse.Dofs(pc)[j];
    if (on) active = active && coarse.kindLocal[J] == kContact && PetscRealPart(aU[J] - aL[J]) <= tol;
    onAny = onAny || on;
  }
  return active && onAny;
}

// The coarse vectors as local arrays, for the evaluation at fine DOF points.
struct CoarseArrays {
  const Space       &space;
  Vec                locU = nullptr, locL = nullptr;
  const PetscScalar *u = nullptr, *lower = nullptr;
  PetscReal          tol = 0;
  explicit CoarseArrays(const Space &s) : space(s) {}
  PetscErrorCode Get(Vec uH, Vec lowerH)
  {
    PetscFunctionBeginUser;
    PetscCall(DMGetLocalVector(space.dm, &locU));
    PetscCall(DMGlobalToLocal(space.dm, uH, INSERT_VALUES, locU));
    PetscCall(VecGetArrayRead(locU, &u));
    if (lowerH) {
      PetscCall(ActiveToleranceOf(uH, &tol)); // active as the contact solve counts it
      PetscCall(DMGetLocalVector(space.dm, &locL));
      PetscCall(DMGlobalToLocal(space.dm, lowerH, INSERT_VALUES, locL));
      PetscCall(VecGetArrayRead(locL, &lower));
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode Restore()
  {
    PetscFunctionBeginUser;
    PetscCall(VecRestoreArrayRead(locU, &u));
    PetscCall(DMRestoreLocalVector(space.dm, &locU));
    if (locL) {
      PetscCall(VecRestoreArrayRead(locL, &lower));
      PetscCall(DMRestoreLocalVector(space.dm, &locL));
    }
    PetscFunctionReturn(0);
  }
};

// uh = sum / count, summed over the ranks sharing a DOF (sum, count: local vectors of the fine space).
PetscErrorCode AverageToGlobal(const Space &fine, Vec sum, Vec count, Vec uh)
{
  Vec countGlobal;
  PetscFunctionBeginUser;
  PetscCall(DMGetGlobalVector(fine.dm, &countGlobal));
  PetscCall(VecSet(uh, 0));
  PetscCall(VecSet(countGlobal, 0));
  PetscCall(DMLocalToGlobal(fine.dm, sum, ADD_VALUES, uh));
  PetscCall(DMLocalToGlobal(fine.dm, count, ADD_VALUES, countGlobal));
  PetscCall(VecPointwiseDivide(uh, uh, countGlobal));
  PetscCall(DMRestoreGlobalVector(fine.dm, &countGlobal));
  PetscFunctionReturn(0);
}

// uh = lowerh at the owned DOFs flagged in the local vector flag. Every cell that sees a DOF makes the
// same decision (it depends only on where the point lies in the coarse mesh), so summing the flags over
// ranks only makes the owner see them.
PetscErrorCode SetFlaggedActive(const Space &fine, Vec flag, Vec lowerh, Vec uh)
{
  Vec                flagGlobal;
  const PetscScalar *fl, *lh;
  PetscScalar       *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetGlobalVector(fine.dm, &flagGlobal));
  PetscCall(VecSet(flagGlobal, 0));
  PetscCall(DMLocalToGlobal(fine.dm, flag, ADD_VALUES, flagGlobal));
  PetscCall(VecGetArrayRead(flagGlobal, &fl));
  PetscCall(VecGetArrayRead(lowerh, &lh));
  PetscCall(VecGetArray(uh, &a));
  for (PetscInt i = 0; i < fine.numOwned; ++i)
    if (PetscRealPart(fl[i]) > 0) a[i] = lh[i];
  PetscCall(VecRestoreArray(uh, &a));
  PetscCall(VecRestoreArrayRead(lowerh, &lh));
  PetscCall(VecRestoreArrayRead(flagGlobal, &fl));
  PetscCall(DMRestoreGlobalVector(fine.dm, &flagGlobal));
  PetscFunctionReturn(0);
}

// Local work vectors of the fine space, zeroed, with their arrays.
struct LocalSums {
  const Space &space;
  Vec          vec[3] = {nullptr, nullptr, nullptr};
  PetscScalar *a[3]   = {nullptr, nullptr, nullptr};
  explicit LocalSums(const Space &s) : space(s) {}
  PetscErrorCode Get(int n)
  {
    PetscFunctionBeginUser;
    for (int k = 0; k < n; ++k) {
      PetscCall(DMGetLocalVector(space.dm, &vec[k]));
      PetscCall(VecSet(vec[k], 0));
      PetscCall(VecGetArray(vec[k], &a[k]));
    }
    PetscFunctionReturn(0);
  }
  PetscErrorCode RestoreArrays()
  {
    PetscFunctionBeginUser;
    for (int k = 0; k < 3; ++k)
      if (vec[k]) PetscCall(VecRestoreArray(vec[k], &a[k]));
    PetscFunctionReturn(0);
  }
  PetscErrorCode Restore()
  {
    PetscFunctionBeginUser;
    for (int k = 0; k < 3; ++k)
      if (vec[k]) PetscCall(DMRestoreLocalVector(space.dm, &vec[k]));
    PetscFunctionReturn(0);
  }
};
} // namespace

PetscErrorCode Prolongate(const Space &coarse, Vec uH, const Space &fine, const std::vector<PetscInt> &parent, Vec uh)
{
  CoarseArrays H(coarse);
  LocalSums    s(fine); // sum, count
  PetscFunctionBeginUser;
  PetscCheck((PetscInt)parent.size() == fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)fine.NumCells());
  PetscCheck(coarse.element == fine.element, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "prolongation between different elements");
  PetscCall(H.Get(uH, nullptr));
  PetscCall(s.Get(2));
  ForEachFineDof(coarse, fine.NumCells(), parent, [&](PetscInt c) { return fine.X(c); }, [&](PetscInt c, PetscInt i, PetscInt pc, const PetscReal *lambda) {
    const PetscInt dof = fine.Dofs(c)[i];
    s.a[0][dof] += coarse.Value(pc, H.u, lambda);
    s.a[1][dof] += 1;
  });
  PetscCall(s.RestoreArrays());
  PetscCall(H.Restore());
  PetscCall(AverageToGlobal(fine, s.vec[0], s.vec[1], uh));
  PetscCall(s.Restore());
  PetscFunctionReturn(0);
}

PetscErrorCode TransferActiveSet(const Space &coarse, Vec uH, Vec lowerH, const Space &fine, const std::vector<PetscInt> &parent, Vec lowerh, Vec uh)
{
  CoarseArrays H(coarse);
  LocalSums    s(fine); // flags
  PetscFunctionBeginUser;
  PetscCall(H.Get(uH, lowerH));
  PetscCall(s.Get(1));
  ForEachFineDof(coarse, fine.NumCells(), parent, [&](PetscInt c) { return fine.X(c); }, [&](PetscInt c, PetscInt i, PetscInt pc, const PetscReal *lambda) {
    const PetscInt dof = fine.Dofs(c)[i];
    if (fine.kindLocal[dof] == kContact && OnActiveContact(coarse, pc, lambda, H.u, H.lower, H.tol)) s.a[0][dof] = 1;
  });
  PetscCall(s.RestoreArrays());
  PetscCall(H.Restore());
  PetscCall(SetFlaggedActive(fine, s.vec[0], lowerh, uh));
  PetscCall(s.Restore());
  PetscFunctionReturn(0);
}

PetscErrorCode MeshCells::Init(DM mesh)
{
  PetscFunctionBeginUser;
  PetscCall(reader_.Init(mesh));
  PetscCall(VertexCoordinates(mesh, x_));
  dim_ = reader_.Dim();
  PetscCall(DMPlexGetHeightStratum(mesh, 0, &cStart_, &cEnd_));
  PetscCall(DMPlexGetDepthStratum(mesh, 0, &vStart_, NULL));
  PetscFunctionReturn(0);
}

PetscErrorCode EvaluateOnCells(const Space &coarse, Vec uH, Vec lowerH, DM fine, const std::vector<PetscInt> &parent, CellValues &cv, const std::vector<char> *corners)
{
  CoarseArrays         H(coarse);
  MeshCells            cells;
  static PetscLogEvent event = 0; // -log_view, under the Adapt stage
  PetscFunctionBeginUser;
  if (!event) PetscCall(PetscLogEventRegister("EvaluateOnCells", DM_CLASSID, &event));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  const PetscInt nb     = coarse.dim + 1;
  const bool     placed = corners && !corners->empty();
  PetscInt       cStart, cEnd;
  PetscCall(DMPlexGetHeightStratum(fine, 0, &cStart, &cEnd));
  const PetscInt numFine = cEnd - cStart;
  PetscCheck((PetscInt)parent.size() == numFine, PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)numFine);
  PetscCheck(!placed || (PetscInt)corners->size() == nb * numFine, PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "%d corners for %d fine cells", (int)corners->size(), (int)numFine);
  if (!placed) PetscCall(cells.Init(fine)); // the coordinates, by which the DOF points are placed
  PetscCall(H.Get(uH, lowerH));
  cv.nb = nb;
  cv.data.assign(numFine * 2 * nb, 0);
  PetscInt   checked = -1;    // the last parent looked at for contact DOFs,
  bool       contact = false; // whether it has any (most have none: their children's flags stay 0)
  const auto at      = [&](PetscInt c, PetscInt i, PetscInt pc, const PetscReal *lambda) {
    if (i == 0 && c + kAhead < numFine) // the parent's values some cells ahead (its DOFs lie anywhere in uH)
      for (PetscInt j = 0; j < nb; ++j) __builtin_prefetch(&H.u[coarse.Dofs(parent[c + kAhead])[j]]);
    cv.data[c * 2 * nb + i] = coarse.Value(pc, H.u, lambda);
    if (!lowerH) return;
    if (pc != checked) {
      checked = pc, contact = false;
      for (PetscInt j = 0; j < nb; ++j) contact = contact || coarse.kindLocal[coarse.Dofs(pc)[j]] == kContact;
    }
    if (contact) cv.data[c * 2 * nb + nb + i] = OnActiveContact(coarse, pc, lambda, H.u, H.lower, H.tol);
  };
  if (placed) WithDim(coarse.dim, [&](auto D) { ForEachFineDofPlacedD<D>(coarse, parent, *corners, at); });
  else ForEachFineDof(coarse, numFine, parent, [&](PetscInt c) { return cells.X(c); }, at);
  PetscCall(H.Restore());
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode RedistributeMesh(DM mesh, DM *dist, PetscSF *migration)
{
  PetscPartitioner part;
  PetscFunctionBeginUser;
  *dist = nullptr, *migration = nullptr;
  PetscCall(DMPlexGetPartitioner(mesh, &part));
  PetscCall(PetscPartitionerSetType(part, PETSCPARTITIONERPTSCOTCH));
  PetscCall(DMPlexDistribute(mesh, 0, migration, dist));
  if (*dist) PetscCall(PetscObjectSetName((PetscObject)*dist, "mesh"));
  PetscFunctionReturn(0);
}

PetscErrorCode MigrateCellValues(DM from, PetscSF migration, DM to, CellValues &cv)
{
  PetscSection origin, target;
  PetscInt     cStart, cEnd, pStart, pEnd;
  PetscReal   *data = nullptr;
  PetscFunctionBeginUser;
  // The values as a field on the cells of `from`, sent along the migration's star forest.
  PetscCall(DMPlexGetChart(from, &pStart, &pEnd));
  PetscCall(DMPlexGetHeightStratum(from, 0, &cStart, &cEnd));
  const PetscInt stride = 2 * cv.nb;
  PetscCheck((PetscInt)cv.data.size() == stride * (cEnd - cStart), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "%d cell values for %d cells", (int)cv.data.size(), (int)(cEnd - cStart));
  PetscCall(PetscSectionCreate(PETSC_COMM_SELF, &origin));
  PetscCall(PetscSectionSetChart(origin, pStart, pEnd));
  for (PetscInt c = cStart; c < cEnd; ++c) PetscCall(PetscSectionSetDof(origin, c, stride));
  PetscCall(PetscSectionSetUp(origin));
  PetscCall(PetscSectionCreate(PETSC_COMM_SELF, &target));
  PetscCall(DMPlexDistributeData(from, migration, origin, MPIU_REAL, cv.data.data(), target, (void **)&data));
  PetscCall(DMPlexGetHeightStratum(to, 0, &cStart, &cEnd));
  std::vector<PetscReal> arrived(stride * (cEnd - cStart));
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscInt off, n;
    PetscCall(PetscSectionGetDof(target, c, &n));
    PetscCall(PetscSectionGetOffset(target, c, &off));
    PetscCheck(n == stride, PETSC_COMM_SELF, PETSC_ERR_PLIB, "cell %d arrived with %d values, not %d", (int)c, (int)n, (int)stride);
    for (PetscInt k = 0; k < stride; ++k) arrived[(c - cStart) * stride + k] = data[off + k];
  }
  cv.data.swap(arrived);
  PetscCall(PetscFree(data));
  PetscCall(PetscSectionDestroy(&origin));
  PetscCall(PetscSectionDestroy(&target));
  PetscFunctionReturn(0);
}

PetscErrorCode ApplyCellValues(const Space &fine, const CellValues &cv, Vec lowerh, Vec uh)
{
  LocalSums s(fine); // sum, count and, with lowerh, flags: one pass over the cells
  PetscFunctionBeginUser;
  const PetscInt nb = fine.Nb();
  PetscCheck(cv.nb == nb && (PetscInt)cv.data.size() == 2 * nb * fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "%d cell values for %d cells", (int)cv.data.size(), (int)fine.NumCells());
  PetscCall(s.Get(lowerh ? 3 : 2));
  for (PetscInt c = 0; c < fine.NumCells(); ++c)
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt dof = fine.Dofs(c)[i];
      s.a[0][dof] += cv.data[c * 2 * nb + i];
      s.a[1][dof] += 1;
      if (lowerh && fine.kindLocal[dof] == kContact && cv.data[c * 2 * nb + nb + i] > 0) s.a[2][dof] = 1;
    }
  PetscCall(s.RestoreArrays());
  PetscCall(AverageToGlobal(fine, s.vec[0], s.vec[1], uh));
  if (lowerh) PetscCall(SetFlaggedActive(fine, s.vec[2], lowerh, uh));
  PetscCall(s.Restore());
  PetscFunctionReturn(0);
}

} // namespace signorini

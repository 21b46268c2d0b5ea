#include "signorini/datascale.h"
#include "signorini/common.h"

#include <algorithm>
#include <cmath>

namespace signorini {

namespace {
// Sets the Dirichlet rows of v to 0 (they are rows of the identity in A, u_D in b) and returns max |v_i|.
PetscErrorCode ZeroDirichletRows(const Space &space, Vec v, PetscReal *vmax)
{
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(VecGetArray(v, &a));
  for (PetscInt i : space.dirichletOwned) a[i] = 0;
  PetscCall(VecRestoreArray(v, &a));
  PetscCall(VecNorm(v, NORM_INFINITY, vmax));
  PetscFunctionReturn(0);
}

// log2 of |l|_inf (l.l) / (l.A l) for l = rhs (b, or the load before the elimination) off the Dirichlet rows: the size of A^-1 l if l were an
// eigenvector, and of the right order for a smooth load (a rough one gives less, by at most the condition
// number). l is first scaled by a power of 2 to |l|_inf in [1, 2), so that neither product under- or
// overflows. -infinity when l = 0.
PetscErrorCode LoadScaleLog2(const Space &space, const System &sys, Vec rhs, PetscReal *log2U)
{
  MPI_Comm  comm = PetscObjectComm((PetscObject)sys.b);
  Vec       l, Al;
  PetscReal lmax;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(rhs, &l));
  PetscCall(VecCopy(rhs, l));
  PetscCall(ZeroDirichletRows(space, l, &lmax));
  if (!std::isfinite(lmax)) {
    PetscCall(VecDestroy(&l));
    SIGNORINI_INPUT_ERROR(comm, "the load vector (the integrals of f and g) is not finite: the data overflow double precision; divide f, g, u_D and psi by a power of ten and multiply the solution by it");
  }
  *log2U = -PETSC_INFINITY;
  if (lmax > 0) {
    const int e = std::ilogb(lmax);
    PetscReal ll, lAl;
    PetscCall(VecScale(l, std::ldexp(1.0, -e)));
    PetscCall(VecDuplicate(l, &Al));
    PetscCall(MatMult(sys.A, l, Al));
    PetscCall(VecDotRealPart(l, l, &ll));
    PetscCall(VecDotRealPart(l, Al, &lAl));
    PetscCall(VecDestroy(&Al));
    // A is positive definite where a Dirichlet part exists; without one (a pure contact problem) l may lie
    // in its kernel, and |l|_inf alone sets the scale.
    const PetscReal ratio = lAl > 0 && std::isfinite(lAl) ? ll / lAl : 1;
    *log2U = e + std::log2(std::ldexp(lmax, -e) * ratio);
  }
  PetscCall(VecDestroy(&l));
  PetscFunctionReturn(0);
}

// log2 of max A_ii over the rows that are not Dirichlet rows (the latter are rows of the identity).
PetscErrorCode RowScaleLog2(const Space &space, const System &sys, PetscReal *log2R)
{
  Vec       d;
  PetscReal dmax;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(sys.b, &d));
  PetscCall(MatGetDiagonal(sys.A, d));
  PetscCall(ZeroDirichletRows(space, d, &dmax));
  PetscCall(VecDestroy(&d));
  *log2R = dmax > 0 && std::isfinite(dmax) ? std::log2(dmax) : 0;
  PetscFunctionReturn(0);
}

// Smallest and largest value of v over the given owned indices, over all ranks (+inf, -inf for none).
PetscErrorCode RangeOver(MPI_Comm comm, Vec v, const std::vector<PetscInt> &owned, PetscReal range[2])
{
  const PetscScalar *a;
  PetscFunctionBeginUser;
  PetscReal m[2] = {PETSC_MAX_REAL, PETSC_MAX_REAL}; // min, -max
  PetscCall(VecGetArrayRead(v, &a));
  for (PetscInt i : owned) m[0] = std::min(m[0], PetscRealPart(a[i])), m[1] = std::min(m[1], -PetscRealPart(a[i]));
  PetscCall(VecRestoreArrayRead(v, &a));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, m, 2, MPIU_REAL, MPI_MIN, comm));
  range[0] = m[0], range[1] = -m[1];
  PetscFunctionReturn(0);
}

// d_i = sum over the Dirichlet DOFs j of A_ij (before the elimination) on the other rows, 0 on the
// Dirichlet rows: from the element matrices of the cells with Dirichlet DOFs.
PetscErrorCode DirichletColumnSums(const Space &space, const System &sys, Vec d)
{
  Vec          loc;
  PetscScalar *a;
  PetscReal    Ke[16];
  PetscFunctionBeginUser;
  const PetscInt nb = space.Nb();
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(VecSet(loc, 0));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt *dofs = space.Dofs(c);
    bool            any  = false;
    for (PetscInt i = 0; i < nb; ++i) any = any || space.kindLocal[dofs[i]] == kDirichlet;
    if (!any) continue;
    CellGeometry g;
    ComputeCellGeometry(space.dim, space.X(c), g);
    ElementStiffness(space, c, sys.Kappa(c), g, Ke);
    for (PetscInt i = 0; i < nb; ++i)
      for (PetscInt j = 0; j < nb; ++j)
        if (space.kindLocal[dofs[i]] != kDirichlet && space.kindLocal[dofs[j]] == kDirichlet) a[dofs[i]] += Ke[i * nb + j];
  }
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(VecSet(d, 0));
  PetscCall(DMLocalToGlobal(space.dm, loc, ADD_VALUES, d));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscFunctionReturn(0);
}

// Adds delta to v at the given owned indices.
PetscErrorCode AddAt(Vec v, const std::vector<PetscInt> &owned, PetscReal delta)
{
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(VecGetArray(v, &a));
  for (PetscInt i : owned) a[i] += delta;
  PetscCall(VecRestoreArray(v, &a));
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode DataShiftCompute(const Space &space, const System &sys, Vec lower, PetscReal *shift)
{
  MPI_Comm  comm = PetscObjectComm((PetscObject)sys.b);
  PetscReal d[2], p[2] = {PETSC_MAX_REAL, -PETSC_MAX_REAL}, log2U;
  PetscFunctionBeginUser;
  *shift = 0;
  PetscCall(RangeOver(comm, sys.uD, space.dirichletOwned, d));
  if (lower) PetscCall(RangeOver(comm, lower, space.contactOwned, p));
  const PetscReal lo = std::min(d[0], p[0]), hi = std::max(d[1], p[1]);
  if (!(lo <= hi) || !std::isfinite(lo) || !std::isfinite(hi)) PetscFunctionReturn(0); // no data, or not finite (DataScaleCompute says so)
  const PetscReal mid = lo / 2 + hi / 2, half = hi / 2 - lo / 2;
  if (!(std::fabs(mid) > kShiftRatio * half)) PetscFunctionReturn(0); // (data near 0: no solve of A^-1 l's scale)
  PetscCall(LoadScaleLog2(space, sys, sys.load, &log2U));
  const PetscReal spread = std::max(half, log2U == -PETSC_INFINITY ? 0 : std::exp2(log2U));
  if (std::fabs(mid) > kShiftRatio * spread) *shift = mid;
  PetscFunctionReturn(0);
}

PetscErrorCode ShiftData(const Space &space, const System &sys, Vec lower, Vec u, const DataScale &scale, bool back, Vec *savedB)
{
  const PetscReal s = scale.shift;
  PetscFunctionBeginUser;
  if (s == 0) PetscFunctionReturn(0);
  if (back) {
    PetscCall(VecCopy(*savedB, sys.b));
    PetscCall(VecDestroy(savedB));
  } else {
    Vec d;
    PetscCall(VecDuplicate(sys.b, savedB));
    PetscCall(VecCopy(sys.b, *savedB));
    PetscCall(VecDuplicate(sys.b, &d));
    PetscCall(DirichletColumnSums(space, sys, d));
    PetscCall(VecAXPY(sys.b, s, d)); // b_i - sum_j A_ij (u_D,j - s) = b_i + s d_i
    PetscCall(VecDestroy(&d));
    PetscCall(AddAt(sys.b, space.dirichletOwned, -s)); // the Dirichlet rows: u_D - s
  }
  const PetscReal delta = back ? s : -s;
  PetscCall(AddAt(sys.uD, space.dirichletOwned, delta));
  if (lower) PetscCall(AddAt(lower, space.contactOwned, delta));
  if (u) PetscCall(VecShift(u, delta));
  PetscFunctionReturn(0);
}

PetscErrorCode DataScaleCompute(const Space &space, const System &sys, Vec lower, DataScale *scale)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)sys.b);
  PetscReal          uDmax, psimax = 0, log2U = -PETSC_INFINITY, log2R = 0;
  const PetscScalar *la;
  PetscFunctionBeginUser;
  PetscCall(VecNorm(sys.uD, NORM_INFINITY, &uDmax));
  if (lower) {
    PetscCall(VecGetArrayRead(lower, &la));
    for (PetscInt i : space.contactOwned) psimax = std::max(psimax, std::fabs(PetscRealPart(la[i])));
    PetscCall(VecRestoreArrayRead(lower, &la));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &psimax, 1, MPIU_REAL, MPI_MAX, comm));
  }
  if (!std::isfinite(uDmax) || !std::isfinite(psimax)) SIGNORINI_INPUT_ERROR(comm, "the %s is not finite: the data overflow double precision", std::isfinite(uDmax) ? "obstacle psi" : "Dirichlet value u_D");
  PetscCall(LoadScaleLog2(space, sys, sys.b, &log2U));
  for (PetscReal m : {uDmax, psimax})
    if (m > 0) log2U = std::max(log2U, std::log2(m));
  PetscCall(RowScaleLog2(space, sys, &log2R));
  scale->rows = (PetscInt)std::lround(log2R);
  scale->u    = log2U == -PETSC_INFINITY ? 0 : (PetscInt)std::lround(log2U); // no data: u = 0
  if (std::abs(scale->u) > kMaxScaleExponent) {
    const bool large = scale->u > 0;
    SIGNORINI_INPUT_ERROR(comm, "the data are too %s for double precision: the solution would be about 1e%+.0f, and its energy (about the square) %s; %s f, g, u_D and psi (or %s kappa) by a power of ten and %s the solution by it", large ? "large" : "small", (double)(log2U * std::log10(2.0)), large ? "overflows" : "underflows", large ? "divide" : "multiply", large ? "multiply" : "divide", large ? "multiply" : "divide");
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ScaleData(const System &sys, Vec lower, Vec u, const DataScale &scale, bool back)
{
  const int sign = back ? 1 : -1;
  PetscFunctionBeginUser;
  if (scale.rows != 0) PetscCall(MatScale(sys.A, std::ldexp(1.0, sign * (int)scale.rows)));
  if (scale.u + scale.rows != 0) PetscCall(VecScale(sys.b, std::ldexp(1.0, sign * (int)(scale.u + scale.rows))));
  if (scale.u == 0) PetscFunctionReturn(0);
  for (Vec v : {sys.uD, u})
    if (v) PetscCall(VecScale(v, std::ldexp(1.0, sign * (int)scale.u)));
  if (lower) { // PETSC_NINFINITY (no bound) is a finite number, -PETSC_MAX_REAL / 4, and has to stay what it is:
    // divided, it became a finite bound, which the semismooth function Phi(u - lower, F) squared to infinity
    PetscScalar *a;
    PetscInt     n;
    PetscCall(VecGetLocalSize(lower, &n));
    PetscCall(VecGetArray(lower, &a));
    for (PetscInt i = 0; i < n; ++i)
      if (PetscRealPart(a[i]) > PETSC_NINFINITY) a[i] = std::ldexp(PetscRealPart(a[i]), sign * (int)scale.u);
    PetscCall(VecRestoreArray(lower, &a));
  }
  PetscFunctionReturn(0);
}

} // namespace signorini

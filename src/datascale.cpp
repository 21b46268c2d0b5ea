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

// log2 of |l|_inf (l.l) / (l.A l) for l = b off the Dirichlet rows: the size of A^-1 l if l were an
// eigenvector, and of the right order for a smooth load (a rough one gives less, by at most the condition
// number). l is first scaled by a power of 2 to |l|_inf in [1, 2), so that neither product under- or
// overflows. -infinity when l = 0.
PetscErrorCode LoadScaleLog2(const Space &space, const System &sys, PetscReal *log2U)
{
  MPI_Comm  comm = PetscObjectComm((PetscObject)sys.b);
  Vec       l, Al;
  PetscReal lmax;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(sys.b, &l));
  PetscCall(VecCopy(sys.b, l));
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
} // namespace

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
  PetscCall(LoadScaleLog2(space, sys, &log2U));
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
  for (Vec v : {sys.uD, lower, u})
    if (v) PetscCall(VecScale(v, std::ldexp(1.0, sign * (int)scale.u))); // -infinity (no bound) stays -infinity
  PetscFunctionReturn(0);
}

} // namespace signorini

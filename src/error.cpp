#include "signorini/error.h"
#include "signorini/quadrature.h"
#include "signorini/stages.h"

#include <cmath>

namespace signorini {

PetscErrorCode ErrorOptionsFromCommandLine(MPI_Comm comm, PetscInt &degree)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Error computation", "signorini");
  PetscCall(PetscOptionsInt("-error_quadrature_degree", "Degree of the quadrature for error integrals", "", degree, &degree, NULL));
  PetscOptionsEnd();
  if (degree < 1) SIGNORINI_INPUT_ERROR(comm, "option -error_quadrature_degree: must be >= 1, got %" PetscInt_FMT, degree);
  PetscFunctionReturn(0);
}

PetscErrorCode ErrorAgainstExact(const Space &space, const Problem &problem, Vec u, PetscInt degree, ErrorNorms &e)
{
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  const Quadrature   rule = SimplexQuadrature(space.dim, degree);
  PetscReal          sums[2] = {0, 0};
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Error));
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  const PetscInt nb = space.Nb(), dim = space.dim;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    CellGeometry g;
    ComputeCellGeometry(dim, space.X(c), g);
    // u_h is affine on the cell: its gradient is constant.
    PetscReal gradh[3] = {0, 0, 0}, grad[3];
    for (PetscInt i = 0; i < nb; ++i) {
      space.BasisGrad(c, i, g, grad);
      for (PetscInt d = 0; d < dim; ++d) gradh[d] += PetscRealPart(a[space.Dofs(c)[i]]) * grad[d];
    }
    for (PetscInt q = 0; q < rule.Size(); ++q) {
      const PetscReal *lambda = rule.Point(q);
      PetscReal        x[3], uh = 0, du[3];
      space.Point(c, lambda, x);
      for (PetscInt i = 0; i < nb; ++i) uh += PetscRealPart(a[space.Dofs(c)[i]]) * space.BasisValue(c, i, lambda);
      const PetscReal ue = problem.exact->Scalar(x, dim, error);
      problem.exactGrad->Eval(x, dim, du, error);
      PetscReal d2 = 0;
      for (PetscInt d = 0; d < dim; ++d) d2 += (du[d] - gradh[d]) * (du[d] - gradh[d]);
      sums[0] += rule.weights[q] * g.volume * (ue - uh) * (ue - uh);
      sums[1] += rule.weights[q] * g.volume * d2;
    }
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  MPI_Comm comm = PetscObjectComm((PetscObject)space.dm);
  PetscCall(CheckAll(comm, error.empty(), error));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, 2, MPIU_REAL, MPI_SUM, comm));
  e.l2     = std::sqrt(sums[0]);
  e.h1semi = std::sqrt(sums[1]);
  e.h1     = std::sqrt(sums[0] + sums[1]);
  PetscCall(StagePop(Stage::Error));
  PetscFunctionReturn(0);
}

} // namespace signorini

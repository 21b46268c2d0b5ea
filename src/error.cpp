#include "signorini/error.h"
#include "signorini/options.h"
#include "signorini/quadrature.h"
#include "signorini/stages.h"

#include <cmath>

namespace signorini {

PetscErrorCode ErrorOptionsFromCommandLine(MPI_Comm comm, PetscInt &degree)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Error computation", "signorini");
  PetscCall(OptionInt(PetscOptionsObject, "-error_quadrature_degree", "Degree of the quadrature for error integrals", degree, 1, PETSC_MAX_INT));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

PetscErrorCode ErrorAgainstExact(const Space &space, const Problem &problem, const System &sys, Vec u, PetscInt degree, ErrorNorms &e)
{
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  const Quadrature   rule = SimplexQuadrature(space.dim, degree);
  PetscReal          sums[3] = {0, 0, 0};
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Error));
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  const PetscInt dim = space.dim;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    CellGeometry g;
    ComputeCellGeometry(dim, space.X(c), g);
    // u_h is affine on the cell: its gradient is constant.
    PetscReal gradh[3];
    space.Grad(c, a, g, gradh);
    problem.exact->SetCellSet(space.CellSet(c));
    problem.exactGrad->SetCellSet(space.CellSet(c));
    PetscReal semi2 = 0;
    for (PetscInt q = 0; q < rule.Size(); ++q) {
      const PetscReal *lambda = rule.Point(q);
      PetscReal        x[3], du[3];
      space.Point(c, lambda, x);
      const PetscReal uh = space.Value(c, a, lambda);
      const PetscReal ue = problem.exact->Scalar(x, dim, error);
      problem.exactGrad->Eval(x, dim, du, error);
      PetscReal d2 = 0;
      for (PetscInt d = 0; d < dim; ++d) d2 += (du[d] - gradh[d]) * (du[d] - gradh[d]);
      sums[0] += rule.weights[q] * g.volume * (ue - uh) * (ue - uh);
      semi2 += rule.weights[q] * g.volume * d2;
    }
    sums[1] += semi2;
    sums[2] += sys.Kappa(c) * semi2;
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  MPI_Comm comm = PetscObjectComm((PetscObject)space.dm);
  PetscCall(CheckAll(comm, error.empty(), error));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, 3, MPIU_REAL, MPI_SUM, comm));
  e.l2     = std::sqrt(sums[0]);
  e.h1semi = std::sqrt(sums[1]);
  e.h1     = std::sqrt(sums[0] + sums[1]);
  e.energy = std::sqrt(sums[2]);
  PetscCall(StagePop(Stage::Error));
  PetscFunctionReturn(0);
}

// The discrete function on one cell, evaluated at physical points (of that cell or, for the reference,
// of one of its sub-cells).
namespace {
struct CellFunction {
  const Space       *space;
  const PetscScalar *a;
  PetscInt           c;
  CellGeometry       g;
  PetscReal          grad[3];
  void Init(const Space &s, const PetscScalar *array, PetscInt cell)
  {
    space = &s;
    a     = array;
    c     = cell;
    ComputeCellGeometry(s.dim, s.X(c), g);
    s.Grad(c, a, g, grad);
  }
  PetscReal Value(const PetscReal *x) const
  {
    PetscReal lambda[4];
    Barycentric(space->dim, g, space->X(c), x, lambda);
    return space->Value(c, a, lambda);
  }
};
} // namespace

PetscErrorCode ErrorAgainstReference(const Space &coarse, Vec uH, const Space &fine, const System &fineSys, Vec uh, const std::vector<PetscInt> &parent, ErrorNorms &e)
{
  Vec                locH, loch;
  const PetscScalar *aH, *ah;
  const Quadrature   rule = SimplexQuadrature(fine.dim, 2);
  PetscReal          sums[3] = {0, 0, 0};
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Error));
  PetscCheck((PetscInt)parent.size() == fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)fine.NumCells());
  PetscCall(DMGetLocalVector(coarse.dm, &locH));
  PetscCall(DMGetLocalVector(fine.dm, &loch));
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locH));
  PetscCall(DMGlobalToLocal(fine.dm, uh, INSERT_VALUES, loch));
  PetscCall(VecGetArrayRead(locH, &aH));
  PetscCall(VecGetArrayRead(loch, &ah));
  CellFunction fH, fh;
  for (PetscInt c = 0; c < fine.NumCells(); ++c) {
    fh.Init(fine, ah, c);
    fH.Init(coarse, aH, parent[c]);
    PetscReal d2 = 0;
    for (PetscInt d = 0; d < fine.dim; ++d) d2 += (fH.grad[d] - fh.grad[d]) * (fH.grad[d] - fh.grad[d]);
    sums[1] += d2 * fh.g.volume;
    sums[2] += fineSys.Kappa(c) * d2 * fh.g.volume;
    for (PetscInt q = 0; q < rule.Size(); ++q) {
      PetscReal x[3];
      fine.Point(c, rule.Point(q), x);
      const PetscReal diff = fH.Value(x) - fh.Value(x);
      sums[0] += rule.weights[q] * fh.g.volume * diff * diff;
    }
  }
  PetscCall(VecRestoreArrayRead(locH, &aH));
  PetscCall(VecRestoreArrayRead(loch, &ah));
  PetscCall(DMRestoreLocalVector(coarse.dm, &locH));
  PetscCall(DMRestoreLocalVector(fine.dm, &loch));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, 3, MPIU_REAL, MPI_SUM, PetscObjectComm((PetscObject)fine.dm)));
  e.l2     = std::sqrt(sums[0]);
  e.h1semi = std::sqrt(sums[1]);
  e.h1     = std::sqrt(sums[0] + sums[1]);
  e.energy = std::sqrt(sums[2]);
  PetscCall(StagePop(Stage::Error));
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/error.h"
#include "signorini/options.h"
#include "signorini/quadrature.h"
#include "signorini/stages.h"

#include <algorithm>
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

// The exact solution and its gradient at the rule's points of a block of cells, each expression evaluated
// once for the whole block.
namespace {
struct ExactBlock {
  static constexpr PetscInt kCells = 32;
  std::vector<PetscReal>    x, u, grad; // point q of block cell i: x[(i * nq + q) * dim], u[i * nq + q], grad[(i * nq + q) * dim]
  std::vector<PetscInt>     sets;
  Space::Coords             X[kCells];  // the vertices of block cell i
  template <PetscInt dim>
  void Evaluate(const Space &space, const Problem &problem, const Quadrature &rule, PetscInt c0, PetscInt m, std::string &error)
  {
    const PetscInt nq = rule.Size(), n = m * nq;
    x.resize(kCells * nq * dim);
    u.resize(kCells * nq);
    grad.resize(kCells * nq * dim);
    sets.resize(kCells * nq);
    for (PetscInt i = 0; i < m; ++i) {
      X[i] = space.XD<dim>(c0 + i);
      for (PetscInt q = 0; q < nq; ++q) SimplexPoint(dim, X[i], rule.Point(q), &x[(i * nq + q) * dim]);
      std::fill_n(&sets[i * nq], nq, space.CellSet(c0 + i));
    }
    problem.exact->EvalBatch(n, x.data(), dim, sets.data(), u.data(), error);
    problem.exactGrad->EvalBatch(n, x.data(), dim, sets.data(), grad.data(), error);
  }
};

// The sums of ErrorAgainstExact: int (u - u_h)^2, int |grad(u - u_h)|^2 and with kappa, and int kappa |grad
// u|^2 (the dimension a template parameter, as in the other cell loops).
template <PetscInt dim>
void ExactSums(const Space &space, const Problem &problem, const System &sys, const PetscScalar *a, const Quadrature &rule, PetscReal *sums, std::string &error)
{
  const PetscInt nq = rule.Size();
  ExactBlock     block;
  for (PetscInt c0 = 0; c0 < space.NumCells(); c0 += ExactBlock::kCells) {
    const PetscInt m = std::min(ExactBlock::kCells, space.NumCells() - c0);
    block.Evaluate<dim>(space, problem, rule, c0, m, error);
    for (PetscInt i = 0; i < m; ++i) {
      const PetscInt c = c0 + i;
      CellGeometry   g;
      ComputeCellGeometryD<dim>(block.X[i], g);
      // u_h is affine on the cell: its gradient is constant.
      PetscReal gradh[3];
      space.GradD<dim>(c, a, g, gradh);
      PetscReal semi2 = 0;
      for (PetscInt q = 0; q < nq; ++q) {
        const PetscReal  uh = space.Value(c, a, rule.Point(q)), ue = block.u[i * nq + q];
        const PetscReal *du = &block.grad[(i * nq + q) * dim];
        PetscReal        d2 = 0;
        for (PetscInt d = 0; d < dim; ++d) d2 += (du[d] - gradh[d]) * (du[d] - gradh[d]);
        PetscReal du2 = 0;
        for (PetscInt d = 0; d < dim; ++d) du2 += du[d] * du[d];
        sums[0] += rule.weights[q] * g.volume * (ue - uh) * (ue - uh);
        semi2 += rule.weights[q] * g.volume * d2;
        sums[3] += sys.Kappa(c) * rule.weights[q] * g.volume * du2;
      }
      sums[1] += semi2;
      sums[2] += sys.Kappa(c) * semi2;
    }
  }
}
} // namespace

PetscErrorCode ErrorAgainstExact(const Space &space, const Problem &problem, const System &sys, Vec u, PetscInt degree, ErrorNorms &e)
{
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  const Quadrature   rule = SimplexQuadrature(space.dim, degree);
  PetscReal          sums[4] = {0, 0, 0, 0};
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Error));
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  WithDim(space.dim, [&](auto D) { ExactSums<D>(space, problem, sys, a, rule, sums, error); });
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  MPI_Comm comm = PetscObjectComm((PetscObject)space.dm);
  PetscCall(CheckAll(comm, error.empty(), error));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, 4, MPIU_REAL, MPI_SUM, comm));
  e.l2          = std::sqrt(sums[0]);
  e.h1semi      = std::sqrt(sums[1]);
  e.h1          = std::sqrt(sums[0] + sums[1]);
  e.energy      = std::sqrt(sums[2]);
  e.exactEnergy = std::sqrt(sums[3]);
  PetscCall(StagePop(Stage::Error));
  PetscFunctionReturn(0);
}

// The discrete function on one cell, evaluated at physical points (of that cell or, for the reference,
// of one of its sub-cells). The dimension is a template parameter, as in the other cell loops.
namespace {
template <PetscInt dim>
struct CellFunction {
  const Space       *space = nullptr;
  const PetscScalar *a     = nullptr;
  PetscInt           c     = -1; // none yet
  Space::Coords      X{};
  CellGeometry       g{};
  PetscReal          grad[3] = {0, 0, 0};
  void Init(const Space &s, const PetscScalar *array, PetscInt cell)
  {
    space = &s;
    a     = array;
    c     = cell;
    X     = s.XD<dim>(c);
    ComputeCellGeometryD<dim>(X, g);
    s.GradD<dim>(c, a, g, grad);
  }
  PetscReal Value(const PetscReal *x) const
  {
    PetscReal lambda[4];
    Barycentric(dim, g, X, x, lambda);
    return space->Value(c, a, lambda);
  }
};

// The sums of ErrorAgainstReference: int (uH - uh)^2, int |grad(uH - uh)|^2 and with kappa. The fine cells
// of one coarse cell come one after the other: its function is set up once for all of them.
template <PetscInt dim>
void ReferenceSums(const Space &coarse, const PetscScalar *aH, const Space &fine, const System &fineSys, const PetscScalar *ah, const std::vector<PetscInt> &parent, const Quadrature &rule, PetscReal *sums)
{
  CellFunction<dim> fH, fh;
  for (PetscInt c = 0; c < fine.NumCells(); ++c) {
    fh.Init(fine, ah, c);
    if (parent[c] != fH.c) fH.Init(coarse, aH, parent[c]);
    PetscReal d2 = 0;
    for (PetscInt d = 0; d < dim; ++d) d2 += (fH.grad[d] - fh.grad[d]) * (fH.grad[d] - fh.grad[d]);
    sums[1] += d2 * fh.g.volume;
    sums[2] += fineSys.Kappa(c) * d2 * fh.g.volume;
    for (PetscInt q = 0; q < rule.Size(); ++q) {
      PetscReal x[3];
      SimplexPoint(dim, fh.X, rule.Point(q), x);
      const PetscReal diff = fH.Value(x) - fh.Value(x);
      sums[0] += rule.weights[q] * fh.g.volume * diff * diff;
    }
  }
}
} // namespace

PetscErrorCode ErrorAgainstReference(const Space &coarse, Vec uH, const Space &fine, const System &fineSys, Vec uh, const std::vector<PetscInt> &parent, ErrorNorms &e)
{
  Vec                locH, loch;
  const PetscScalar *aH, *ah;
  const Quadrature   rule = SimplexQuadrature(fine.dim, 2);
  PetscReal          sums[4] = {0, 0, 0, 0};
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Error));
  PetscCheck((PetscInt)parent.size() == fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)fine.NumCells());
  PetscCall(DMGetLocalVector(coarse.dm, &locH));
  PetscCall(DMGetLocalVector(fine.dm, &loch));
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locH));
  PetscCall(DMGlobalToLocal(fine.dm, uh, INSERT_VALUES, loch));
  PetscCall(VecGetArrayRead(locH, &aH));
  PetscCall(VecGetArrayRead(loch, &ah));
  WithDim(fine.dim, [&](auto D) { ReferenceSums<D>(coarse, aH, fine, fineSys, ah, parent, rule, sums); });
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

#include "signorini/assembly.h"
#include "signorini/options.h"
#include "signorini/pattern.h"
#include "signorini/stages.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace signorini {

PetscErrorCode AssemblyOptionsFromCommandLine(MPI_Comm comm, AssemblyOptions &o)
{
  PetscInt rule = o.centroid ? 1 : 0;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Assembly", "signorini");
  PetscCall(OptionEList(PetscOptionsObject, "-load_quadrature", "Load integral rule: accurate (degree -load_quadrature_degree) or centroid (one point)", {"accurate", "centroid"}, rule));
  PetscCall(OptionInt(PetscOptionsObject, "-load_quadrature_degree", "Polynomial degree integrated exactly by the accurate load rule", o.loadDegree, 1, PETSC_MAX_INT));
  PetscOptionsEnd();
  o.centroid = rule == 1;
  PetscFunctionReturn(0);
}

void ElementStiffness(const Space &space, PetscInt c, PetscReal kappa, const CellGeometry &g, PetscReal *Ke)
{
  const PetscInt nb = space.Nb();
  PetscReal      grad[4][3];
  for (PetscInt i = 0; i < nb; ++i) space.BasisGrad(c, i, g, grad[i]);
  for (PetscInt i = 0; i < nb; ++i)
    for (PetscInt j = 0; j < nb; ++j) {
      PetscReal dot = 0;
      for (PetscInt d = 0; d < space.dim; ++d) dot += grad[i][d] * grad[j][d];
      Ke[i * nb + j] = kappa * g.volume * dot;
    }
}

// The load as double precision holds it: f (or g) times a quadrature weight and a cell measure may
// underflow. A fast-decaying load does that far from its peak, which is harmless; a load whose every
// contribution underflows, while f itself is not zero, would give u = 0 without a word.
struct LoadRange {
  PetscReal maxValue = 0, maxIntegrand = 0; // largest |f(x)| and |f(x) w |T|| seen
  std::string example;                      // the first point where a nonzero value underflowed
  void Record(const Expression &e, PetscReal value, PetscReal integrand, const PetscReal *x, PetscInt dim)
  {
    maxValue     = std::max(maxValue, std::fabs(value));
    maxIntegrand = std::max(maxIntegrand, std::fabs(integrand));
    if (value != 0 && !(std::fabs(integrand) >= DBL_MIN) && example.empty()) example = Format("option %s: '%s' is %g at (%g, %g, %g), which times the cell measure underflows double precision, and so does every other value of the load; multiply the data by a power of ten and divide the solution by it", e.Option().c_str(), e.Text().c_str(), (double)value, (double)x[0], (double)x[1], dim == 3 ? (double)x[2] : 0.0);
  }
};

// kappa is taken constant on each cell (its centroid value), so the stiffness integral is exact for
// coefficients that are piecewise constant on the mesh, including jumps between cell sets.
static PetscErrorCode CellCoefficients(const Space &space, const Problem &problem, System &sys)
{
  std::string error;
  PetscFunctionBeginUser;
  // A constant kappa (checked positive by ProblemSetUp's evaluation) is one value, not one per cell.
  const PetscInt n = problem.kappa->IsConstant() ? std::min<PetscInt>(1, space.NumCells()) : space.NumCells();
  sys.kappa.resize(n);
  for (PetscInt c = 0; c < n; ++c) {
    CellGeometry g;
    ComputeCellGeometry(space.dim, space.X(c), g);
    problem.kappa->SetCellSet(space.CellSet(c));
    const PetscReal k = problem.kappa->Scalar(g.centroid, space.dim, error);
    if (!(k > 0) && error.empty()) error = Format("option -kappa: '%s' is %g <= 0 at (%g, %g, %g); kappa must be positive", problem.kappa->Text().c_str(), (double)k, (double)g.centroid[0], (double)g.centroid[1], space.dim == 3 ? (double)g.centroid[2] : 0.0);
    sys.kappa[c] = k;
  }
  PetscCall(CheckAll(PetscObjectComm((PetscObject)space.dm), error.empty(), error));
  PetscFunctionReturn(0);
}

PetscReal SimplexDiameter(PetscInt dim, const PetscReal *X)
{
  PetscReal h2 = 0;
  for (PetscInt i = 0; i <= dim; ++i)
    for (PetscInt j = i + 1; j <= dim; ++j) {
      PetscReal l2 = 0;
      for (PetscInt d = 0; d < dim; ++d) l2 += (X[i * dim + d] - X[j * dim + d]) * (X[i * dim + d] - X[j * dim + d]);
      h2 = std::max(h2, l2);
    }
  return std::sqrt(h2);
}

// The one evaluation of f on a cell (CellLoad), the oscillation only when asked for (else 0); range, where
// given, records the values for the underflow check.
static void ComputeCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, std::vector<PetscReal> &work, CellLoad &load, bool oscillation, LoadRange *range, std::string &error)
{
  const PetscInt    dim  = space.dim;
  const Quadrature &rule = sys.cellRule;
  PetscReal         x[3];
  load.oscillation       = 0;
  if (problem.f->IsConstant()) { // one value, no parser, no oscillation
    const PetscReal f = problem.f->Scalar(g.centroid, dim, error), share = f * g.volume / (dim + 1);
    for (PetscInt k = 0; k <= dim; ++k) load.moment[k] = share;
    if (range) range->Record(*problem.f, f, share, g.centroid, dim);
    return;
  }
  problem.f->SetCellSet(space.CellSet(c));
  work.resize(rule.Size());
  PetscReal total = 0;
  for (PetscInt k = 0; k <= dim; ++k) load.moment[k] = 0;
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    const PetscReal *lambda = rule.Point(q);
    SimplexPoint(dim, X, lambda, x);
    work[q]            = problem.f->Scalar(x, dim, error);
    const PetscReal fq = work[q] * rule.weights[q] * g.volume;
    if (range) range->Record(*problem.f, work[q], fq, x, dim);
    total += fq;
    for (PetscInt k = 0; k <= dim; ++k) load.moment[k] += fq * lambda[k];
  }
  if (!oscillation) return;
  // ||f - mean||^2 / |T| by the oscillation rule: the load's values where it is that rule.
  const Quadrature &orule = sys.oscCellRule;
  PetscReal         mean  = total / g.volume;
  if (orule.Size() != rule.Size()) {
    work.resize(orule.Size());
    mean = 0;
    for (PetscInt q = 0; q < orule.Size(); ++q) {
      SimplexPoint(dim, X, orule.Point(q), x);
      work[q] = problem.f->Scalar(x, dim, error);
      mean += orule.weights[q] * work[q];
    }
  }
  PetscReal dev2 = 0;
  for (PetscInt q = 0; q < orule.Size(); ++q) dev2 += orule.weights[q] * (work[q] - mean) * (work[q] - mean);
  // Poincare on a convex cell: ||w - w_T||_T <= h_T / pi ||grad w||_T.
  load.oscillation = SimplexDiameter(dim, X) / M_PI * std::sqrt(dev2 * g.volume / sys.Kappa(c));
}

void GetCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, std::vector<PetscReal> &work, CellLoad &load, std::string &error)
{
  const PetscInt n = space.dim + 2;
  if (sys.cellLoads.empty()) return ComputeCellLoad(space, problem, sys, c, X, g, work, load, true, nullptr, error);
  const PetscReal *kept = &sys.cellLoads[c * n];
  std::copy(kept, kept + n - 1, load.moment);
  load.oscillation = kept[n - 1];
}

// Cell loop: stiffness into A, f-load into the local load vector, and each cell's load into
// sys.cellLoads when they are kept.
static PetscErrorCode AssembleCells(const Space &space, const Problem &problem, bool keepLoads, System &sys, PetscScalar *load, LoadRange &range, std::string &error)
{
  const PetscInt         nb = space.Nb(), dim = space.dim;
  PetscReal              Ke[16], phi[4][4], vertex[4];
  std::vector<PetscReal> work;
  PetscFunctionBeginUser;
  const bool zeroLoad = problem.f->IsZero();
  for (PetscInt k = 0; k <= dim; ++k) { // phi[i][k] = phi_i(X_k), the same on every cell
    for (PetscInt j = 0; j <= dim; ++j) vertex[j] = j == k;
    for (PetscInt i = 0; i < nb; ++i) phi[i][k] = space.BasisValue(0, i, vertex);
  }
  sys.cellLoads.assign(keepLoads ? space.NumCells() * (dim + 2) : 0, 0.0);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    CellGeometry        g;
    CellLoad            cl;
    const Space::Coords X = space.X(c); // gathered once: every quadrature point needs it
    ComputeCellGeometry(dim, X, g);
    ElementStiffness(space, c, sys.Kappa(c), g, Ke);
    PetscCall(MatSetValuesLocal(sys.A, nb, space.Dofs(c), nb, space.Dofs(c), Ke, ADD_VALUES));
    if (zeroLoad) continue;
    ComputeCellLoad(space, problem, sys, c, X, g, work, cl, keepLoads, &range, error);
    // b_i = int_T f phi_i = sum_k moment_k phi_i(X_k): phi_i is affine.
    for (PetscInt i = 0; i < nb; ++i) {
      PetscReal bi = 0;
      for (PetscInt k = 0; k <= dim; ++k) bi += cl.moment[k] * phi[i][k];
      load[space.Dofs(c)[i]] += bi;
    }
    if (!keepLoads) continue;
    PetscReal *kept = &sys.cellLoads[c * (dim + 2)];
    std::copy(cl.moment, cl.moment + dim + 1, kept);
    kept[dim + 1] = cl.oscillation;
  }
  PetscFunctionReturn(0);
}

// Neumann term: integral of g * phi_i over the faces of Gamma_N, with the face rule mapped into the cell.
static void AssembleNeumann(const Space &space, const Problem &problem, const System &sys, PetscScalar *load, LoadRange &range, std::string &error)
{
  PetscReal lambda[4], x[3];
  for (const BoundaryFace &bf : space.boundary) {
    if (std::find(problem.neumann.begin(), problem.neumann.end(), bf.part) == problem.neumann.end()) continue;
    const PetscReal area = space.FaceMeasure(bf);
    problem.g->SetCellSet(space.CellSet(bf.cell)); // a boundary face has one cell
    for (PetscInt q = 0; q < sys.faceRule.Size(); ++q) {
      space.FaceToCell(bf, sys.faceRule.Point(q), lambda);
      space.Point(bf.cell, lambda, x);
      const PetscReal gx = problem.g->Scalar(x, space.dim, error), gq = gx * sys.faceRule.weights[q] * area;
      range.Record(*problem.g, gx, gq, x, space.dim);
      for (PetscInt i = 0; i < space.Nb(); ++i) load[space.Dofs(bf.cell)[i]] += gq * space.BasisValue(bf.cell, i, lambda);
    }
  }
}

// Dirichlet values: u_D at vertices (P1) or its mean over each face (CR, the canonical CR interpolant).
static void DirichletValues(const Space &space, const Problem &problem, const System &sys, PetscScalar *u, std::string &error)
{
  if (space.element == Element::P1) {
    space.ForEachBoundaryDof([&](PetscInt i, const PetscReal *x) {
      if (space.kindLocal[i] == kDirichlet) u[i] = problem.uD->Scalar(x, space.dim, error);
    });
    return;
  }
  PetscReal lambda[4], x[3];
  for (const BoundaryFace &bf : space.boundary) {
    if (space.kindLocal[bf.dof] != kDirichlet) continue;
    PetscReal mean = 0;
    for (PetscInt q = 0; q < sys.faceRule.Size(); ++q) {
      space.FaceToCell(bf, sys.faceRule.Point(q), lambda);
      space.Point(bf.cell, lambda, x);
      mean += sys.faceRule.weights[q] * problem.uD->Scalar(x, space.dim, error);
    }
    u[bf.dof] = mean;
  }
}

PetscErrorCode AssembleSystem(const Space &space, const Problem &problem, const AssemblyOptions &opts, System &sys)
{
  MPI_Comm             comm = PetscObjectComm((PetscObject)space.dm);
  Vec                  loc;
  PetscScalar         *a;
  std::string          error;
  static PetscLogEvent cellLoop = 0, elimination = 0; // -log_view lists them under the Assemble stage
  PetscFunctionBeginUser;
  if (!cellLoop) PetscCall(PetscLogEventRegister("AssembleCells", MAT_CLASSID, &cellLoop));
  if (!elimination) PetscCall(PetscLogEventRegister("DirichletElim", MAT_CLASSID, &elimination));
  PetscCall(StagePush(Stage::Setup));
  PetscCall(CreateStiffnessMatrix(space, &sys.A));
  PetscCall(DMCreateGlobalVector(space.dm, &sys.b));
  PetscCall(PetscObjectSetName((PetscObject)sys.b, "b"));
  PetscCall(VecDuplicate(sys.b, &sys.load));
  PetscCall(VecDuplicate(sys.b, &sys.uD));
  PetscCall(StagePop(Stage::Setup));

  PetscCall(StagePush(Stage::Assemble));
  sys.cellRule = SimplexQuadrature(space.dim, opts.centroid ? 1 : opts.loadDegree);
  sys.faceRule = SimplexQuadrature(space.dim - 1, opts.centroid ? 1 : opts.loadDegree);
  sys.oscCellRule = sys.cellRule.degree >= System::kOscillationDegree ? sys.cellRule : SimplexQuadrature(space.dim, System::kOscillationDegree);
  sys.oscFaceRule = sys.faceRule.degree >= System::kOscillationDegree ? sys.faceRule : SimplexQuadrature(space.dim - 1, System::kOscillationDegree);
  PetscCall(CellCoefficients(space, problem, sys));
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(VecSet(loc, 0));
  PetscCall(VecGetArray(loc, &a));
  PetscCall(PetscLogEventBegin(cellLoop, 0, 0, 0, 0));
  LoadRange range;
  PetscCall(AssembleCells(space, problem, opts.keepCellLoads, sys, a, range, error));
  if (problem.HasNeumann()) AssembleNeumann(space, problem, sys, a, range, error);
  PetscReal maxes[2] = {range.maxValue, range.maxIntegrand};
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, maxes, 2, MPIU_REAL, MPI_MAX, comm));
  if (maxes[0] > 0 && !(maxes[1] >= DBL_MIN) && error.empty()) error = range.example;
  PetscCall(PetscLogEventEnd(cellLoop, 0, 0, 0, 0));
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(MatAssemblyBegin(sys.A, MAT_FINAL_ASSEMBLY));
  PetscCall(VecSet(sys.load, 0));
  PetscCall(DMLocalToGlobal(space.dm, loc, ADD_VALUES, sys.load));
  PetscCall(MatAssemblyEnd(sys.A, MAT_FINAL_ASSEMBLY));

  // Dirichlet values: every rank evaluates u_D at its own copies of shared DOFs, so the values agree.
  PetscCall(VecSet(loc, 0));
  PetscCall(VecGetArray(loc, &a));
  DirichletValues(space, problem, sys, a, error);
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(space.dm, loc, INSERT_VALUES, sys.uD));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscCall(CheckAll(comm, error.empty(), error));

  // Symmetric elimination keeps A symmetric positive definite for CG: b_i -= A_ij uD_j on free rows.
  PetscInt rstart;
  PetscCall(VecGetOwnershipRange(sys.b, &rstart, NULL));
  std::vector<PetscInt> rows(space.dirichletOwned);
  for (PetscInt &r : rows) r += rstart;
  PetscCall(PetscLogEventBegin(elimination, 0, 0, 0, 0));
  PetscCall(VecCopy(sys.load, sys.b));
  PetscCall(MatZeroRowsColumns(sys.A, (PetscInt)rows.size(), rows.data(), 1.0, sys.uD, sys.b));
  PetscCall(PetscLogEventEnd(elimination, 0, 0, 0, 0));
  PetscCall(StagePop(Stage::Assemble));
  PetscFunctionReturn(0);
}

PetscErrorCode DiscreteEnergy(const Space &space, const System &sys, Vec u, PetscReal *J)
{
  Vec                loc;
  const PetscScalar *a;
  PetscReal          local = 0, Ke[16];
  PetscScalar        chi;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  const PetscInt nb = space.Nb();
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    CellGeometry g;
    ComputeCellGeometry(space.dim, space.X(c), g);
    ElementStiffness(space, c, sys.Kappa(c), g, Ke);
    const PetscInt *dofs = space.Dofs(c);
    for (PetscInt i = 0; i < nb; ++i)
      for (PetscInt j = 0; j < nb; ++j) local += 0.5 * PetscRealPart(a[dofs[i]]) * Ke[i * nb + j] * PetscRealPart(a[dofs[j]]);
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscReal half;
  PetscCallMPI(MPI_Allreduce(&local, &half, 1, MPIU_REAL, MPI_SUM, PetscObjectComm((PetscObject)space.dm)));
  PetscCall(VecDot(sys.load, u, &chi));
  *J = half - PetscRealPart(chi);
  PetscFunctionReturn(0);
}

PetscErrorCode SystemDestroy(System &sys)
{
  PetscFunctionBeginUser;
  PetscCall(MatDestroy(&sys.A));
  PetscCall(VecDestroy(&sys.b));
  PetscCall(VecDestroy(&sys.load));
  PetscCall(VecDestroy(&sys.uD));
  PetscFunctionReturn(0);
}

} // namespace signorini

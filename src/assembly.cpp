#include "signorini/assembly.h"
#include "signorini/components.h"
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

// The dimension a template parameter in the cell loops (see ComputeCellGeometryD), a variable elsewhere.
template <PetscInt dim>
static void ElementStiffnessD(PetscReal b, PetscReal kappa, const CellGeometry &g, PetscReal *Ke) // b: Space::GradScale
{
  constexpr PetscInt nb = dim + 1;
  PetscReal          grad[4][3];
  for (PetscInt i = 0; i < nb; ++i)
    for (PetscInt d = 0; d < dim; ++d) grad[i][d] = b * g.gradLambda[i][d];
  for (PetscInt i = 0; i < nb; ++i)
    for (PetscInt j = 0; j < nb; ++j) {
      PetscReal dot = 0;
      for (PetscInt d = 0; d < dim; ++d) dot += grad[i][d] * grad[j][d];
      Ke[i * nb + j] = kappa * g.volume * dot;
    }
}
void ElementStiffness(const Space &space, PetscInt, PetscReal kappa, const CellGeometry &g, PetscReal *Ke)
{
  WithDim(space.dim, [&](auto D) { ElementStiffnessD<D>(space.GradScale(), kappa, g, Ke); });
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
// coefficients that are piecewise constant on the mesh, including jumps between cell sets. Evaluated at
// all centroids at once (EvalBatch), one per cell.
static PetscErrorCode CellCoefficients(const Space &space, const Problem &problem, System &sys)
{
  std::string error;
  PetscFunctionBeginUser;
  // A constant kappa (checked positive by ProblemSetUp's evaluation) is one value, not one per cell.
  const PetscInt n = problem.kappa->IsConstant() ? std::min<PetscInt>(1, space.NumCells()) : space.NumCells(), dim = space.dim;
  const PetscInt         block = 1024; // centroids a block at a time: no table of n points
  std::vector<PetscReal> x(block * dim);
  std::vector<PetscInt>  sets(block);
  sys.kappa.resize(n);
  for (PetscInt c0 = 0; c0 < n; c0 += block) {
    const PetscInt m = std::min(block, n - c0);
    for (PetscInt i = 0; i < m; ++i) {
      SimplexCentroid(dim, space.X(c0 + i), &x[i * dim]);
      sets[i] = space.CellSet(c0 + i);
    }
    problem.kappa->EvalBatch(m, x.data(), dim, sets.data(), &sys.kappa[c0], error);
    for (PetscInt i = 0; i < m && error.empty(); ++i)
      if (!(sys.kappa[c0 + i] > 0)) error = Format("option -kappa: '%s' is %g <= 0 at (%g, %g, %g); kappa must be positive", problem.kappa->Text().c_str(), (double)sys.kappa[c0 + i], (double)x[i * dim], (double)x[i * dim + 1], dim == 3 ? (double)x[i * dim + 2] : 0.0);
  }
  PetscCall(CheckAll(PetscObjectComm((PetscObject)space.dm), error.empty(), error));
  PetscFunctionReturn(0);
}

// The constant is min(h_T, ||B||_2) / pi for B the matrix of an affine map F(x) = x_0 + B x of the reference
// simplex K onto T: the triangle {0 <= x <= y <= 1} (half a unit square) or Kuhn's tetrahedron
// {0 <= x <= y <= z <= 1} (a sixth of a unit cube). K's mirror images tile the square or cube, so a Neumann
// eigenfunction of K, extended by reflection, is one of the square or cube: K's smallest non-zero Neumann
// eigenvalue is pi^2, its Poincare constant 1 / pi (cos(pi x) + cos(pi y) (+ cos(pi z)) attains it). With
// v = w o F, ||w - w_T||_T^2 = |det B| ||v - v_K||_K^2 <= |det B| / pi^2 ||grad v||_K^2 and
// |grad v| <= ||B|| |grad w o F|, hence ||w - w_T||_T <= ||B|| / pi ||grad w||_T. B's columns are the edges of
// a path through T's vertices (K's vertices in order (0,0), (0,1), (1,1), or (0,0,0), (0,0,1), (0,1,1),
// (1,1,1)), so ||B||^2 is the largest eigenvalue of the Gram matrix of three (two) edges of a path, which
// the squared edge lengths give (u.v = (|u + v|^2 - |u|^2 - |v|^2) / 2). On the right isosceles triangles
// and Kuhn tetrahedra of box meshes this is h_T / sqrt(2) or h_T / sqrt(3) (less gained on bisections); on
// equilateral cells Payne-Weinberger's h_T is smaller and taken.
PetscReal PoincareConstant(PetscInt dim, const PetscReal *X)
{
  if (dim == 2) { // the three paths (by their middle vertex m): a 2 x 2 Gram matrix, its eigenvalue exactly
    PetscReal L[3], norm2 = 0; // L[k]: the squared length of the edge opposite vertex k
    for (PetscInt k = 0; k < 3; ++k) {
      const PetscReal *a = &X[((k + 1) % 3) * 2], *b = &X[((k + 2) % 3) * 2];
      L[k] = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]);
      norm2 = std::max(norm2, L[k]);
    }
    for (PetscInt m = 0; m < 3; ++m) {
      const PetscReal p = L[(m + 1) % 3], q = L[(m + 2) % 3], r = 0.5 * (p + q - L[m]);
      norm2 = std::min(norm2, 0.5 * (p + q) + std::sqrt(0.25 * (p - q) * (p - q) + r * r));
    }
    return std::sqrt(norm2) / M_PI;
  }
  // Tetrahedra: of the twelve paths, those whose edges have the least sum of squares (any path gives a
  // bound; for Kuhn's tetrahedra this is the one of three orthogonal edges, and choosing it costs a few
  // additions where bounding all twelve cost five times the diameter). Its Gram matrix's largest eigenvalue
  // is bounded above by Collatz-Wielandt's max_i (|G| w)_i / w_i with w = |G| (1, 1, 1) (exact where G is
  // diagonal). Edges by vertex pair: 01 02 03 12 13 23; a path a-b-c-d as its edges ab, bc, cd, then ac, bd, ad.
  static constexpr int kPath[12][6] = {{0, 3, 5, 1, 4, 2}, {0, 4, 5, 2, 3, 1}, {1, 3, 4, 0, 5, 2}, {1, 5, 4, 2, 3, 0}, {2, 4, 3, 0, 5, 1}, {2, 5, 3, 1, 4, 0},
                                       {0, 1, 5, 3, 2, 4}, {0, 2, 5, 4, 1, 3}, {3, 1, 2, 0, 5, 4}, {4, 2, 1, 0, 5, 3}, {1, 0, 4, 3, 2, 5}, {3, 0, 2, 1, 4, 5}};
  static constexpr int kPair[6][2]   = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  PetscReal            L[6], h2 = 0;
  for (int e = 0; e < 6; ++e) {
    const PetscReal *a = &X[kPair[e][0] * 3], *b = &X[kPair[e][1] * 3];
    L[e] = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
    h2   = std::max(h2, L[e]);
  }
  PetscReal t[12], least = PETSC_MAX_REAL;
  for (int i = 0; i < 12; ++i) {
    t[i]  = L[kPath[i][0]] + L[kPath[i][1]] + L[kPath[i][2]];
    least = std::min(least, t[i]);
  }
  // Every path whose sum ties with the least (up to round-off), not the first of them: which one comes first
  // depends on the order of T's vertices, which differs between ranks on other partitions, and tied paths
  // can give different bounds (on an adapted mesh of bisected Kuhn tetrahedra the oscillation differed by
  // 1e-4 between 1 and 2 ranks).
  PetscReal lambda = PETSC_MAX_REAL;
  for (int i = 0; i < 12; ++i) {
    if (t[i] > least * (1 + 1e-10)) continue;
    const int      *p   = kPath[i];
    const PetscReal g11 = L[p[0]], g22 = L[p[1]], g33 = L[p[2]];
    const PetscReal g12 = 0.5 * (L[p[3]] - g11 - g22), g23 = 0.5 * (L[p[4]] - g22 - g33), g13 = 0.5 * (L[p[5]] - g11 - g22 - g33) - g12 - g23;
    const PetscReal a12 = std::abs(g12), a13 = std::abs(g13), a23 = std::abs(g23);
    const PetscReal w1 = g11 + a12 + a13, w2 = a12 + g22 + a23, w3 = a13 + a23 + g33;
    lambda = std::min(lambda, std::max(std::max((g11 * w1 + a12 * w2 + a13 * w3) / w1, (a12 * w1 + g22 * w2 + a23 * w3) / w2), (a13 * w1 + a23 * w2 + g33 * w3) / w3));
  }
  return std::sqrt(std::min(h2, lambda)) / M_PI;
}

// The points of `rule` in the simplex with vertices X: x[q * dim ..].
template <PetscInt dim>
static void RulePointsD(const PetscReal *X, const Quadrature &rule, PetscReal *x)
{
  for (PetscInt q = 0; q < rule.Size(); ++q) SimplexPoint(dim, X, rule.Point(q), &x[q * dim]);
}
static void RulePoints(PetscInt dim, const PetscReal *X, const Quadrature &rule, PetscReal *x)
{
  WithDim(dim, [&](auto D) { RulePointsD<D>(X, rule, x); });
}

// The load of a cell (CellLoad) from f's values fx at the points x of the load rule (System::cellRule), the
// oscillation only when asked for (else 0); range, where given, records the values for the underflow check.
// A constant f needs neither fx nor x.
template <PetscInt dim>
static void ComputeCellLoadD(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, const PetscReal *fx, const PetscReal *x, std::vector<PetscReal> &work, CellLoad &load, bool oscillation, LoadRange *range, std::string &error)
{
  const Quadrature &rule = sys.cellRule;
  load.oscillation       = 0;
  if (problem.f->IsConstant()) { // one value, no parser, no oscillation
    const PetscReal f = problem.f->Scalar(g.centroid, dim, error), share = f * g.volume / (dim + 1);
    for (PetscInt k = 0; k <= dim; ++k) load.moment[k] = share;
    if (range) range->Record(*problem.f, f, share, g.centroid, dim);
    return;
  }
  PetscReal total = 0;
  for (PetscInt k = 0; k <= dim; ++k) load.moment[k] = 0;
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    const PetscReal *lambda = rule.Point(q);
    const PetscReal  fq     = fx[q] * rule.weights[q] * g.volume;
    if (range) range->Record(*problem.f, fx[q], fq, &x[q * dim], dim);
    total += fq;
    for (PetscInt k = 0; k <= dim; ++k) load.moment[k] += fq * lambda[k];
  }
  if (!oscillation) return;
  // ||f - mean||^2 / |T| by the oscillation rule: the load's values where it is that rule.
  const Quadrature &orule = sys.oscCellRule;
  PetscReal         mean  = total / g.volume;
  const PetscReal  *fo    = fx;
  if (orule.Size() != rule.Size()) {
    work.resize(orule.Size() * (dim + 1));
    PetscReal *ox = &work[orule.Size()];
    RulePointsD<dim>(X, orule, ox);
    problem.f->SetCellSet(space.CellSet(c));
    problem.f->EvalBatch(orule.Size(), ox, dim, nullptr, work.data(), error);
    mean = 0;
    for (PetscInt q = 0; q < orule.Size(); ++q) mean += orule.weights[q] * work[q];
    fo = work.data();
  }
  PetscReal dev2 = 0;
  for (PetscInt q = 0; q < orule.Size(); ++q) dev2 += orule.weights[q] * (fo[q] - mean) * (fo[q] - mean);
  // Poincare: ||w - w_T||_T <= C_T ||grad w||_T (PoincareConstant; not computed where f is constant on T).
  load.oscillation = dev2 > 0 ? PoincareConstant(dim, X) * std::sqrt(dev2 * g.volume / sys.Kappa(c)) : 0.0;
}
static void ComputeCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, const PetscReal *fx, const PetscReal *x, std::vector<PetscReal> &work, CellLoad &load, bool oscillation, LoadRange *range, std::string &error)
{
  WithDim(space.dim, [&](auto D) { ComputeCellLoadD<D>(space, problem, sys, c, X, g, fx, x, work, load, oscillation, range, error); });
}

void EvaluateCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, std::vector<PetscReal> &work, CellLoad &load, std::string &error)
{
  const PetscInt         nq = sys.cellRule.Size();
  std::vector<PetscReal> fx;
  if (!problem.f->IsConstant()) {
    fx.resize(nq * (space.dim + 1));
    RulePoints(space.dim, X, sys.cellRule, &fx[nq]);
    problem.f->SetCellSet(space.CellSet(c));
    problem.f->EvalBatch(nq, &fx[nq], space.dim, nullptr, fx.data(), error);
  }
  ComputeCellLoad(space, problem, sys, c, X, g, fx.data(), fx.data() + nq, work, load, true, nullptr, error);
}

// f at the load rule's points of a block of cells, one evaluation of the expression for the whole block.
namespace {
struct LoadBlock {
  static constexpr PetscInt kCells = 64;
  std::vector<PetscReal>    x, fx; // point q of block cell i at x[(i * nq + q) * dim], its value at fx[i * nq + q]
  std::vector<PetscInt>     sets;
  template <PetscInt dim>
  void Evaluate(const Space &space, const Problem &problem, const Quadrature &rule, PetscInt c0, PetscInt m, const Space::Coords *X, std::string &error)
  {
    const PetscInt nq = rule.Size();
    x.resize(kCells * nq * dim);
    fx.resize(kCells * nq);
    sets.resize(kCells * nq);
    for (PetscInt i = 0; i < m; ++i) {
      RulePointsD<dim>(X[i], rule, &x[i * nq * dim]);
      std::fill_n(&sets[i * nq], nq, space.CellSet(c0 + i));
    }
    problem.f->EvalBatch(m * nq, x.data(), dim, sets.data(), fx.data(), error);
  }
};
} // namespace

// Cell loop: stiffness into A, f-load into the local load vector, and each cell's load into
// sys.cellLoads when they are kept. Cells go in blocks, f evaluated once per block.
template <PetscInt dim>
static PetscErrorCode AssembleCellsD(const Space &space, const Problem &problem, bool keepLoads, System &sys, StiffnessFill &fill, PetscScalar *load, LoadRange &range, std::string &error)
{
  constexpr PetscInt     nb = dim + 1;
  const PetscInt         nq = sys.cellRule.Size();
  const PetscReal        b  = space.GradScale();
  PetscReal              Ke[16], phi[4][4], vertex[4];
  std::vector<PetscReal> work;
  Space::Coords          X[LoadBlock::kCells];
  CellGeometry           g[LoadBlock::kCells];
  LoadBlock              block;
  PetscFunctionBeginUser;
  const bool zeroLoad = problem.f->IsZero(), evaluate = !zeroLoad && !problem.f->IsConstant();
  for (PetscInt k = 0; k <= dim; ++k) { // phi[i][k] = phi_i(X_k), the same on every cell
    for (PetscInt j = 0; j <= dim; ++j) vertex[j] = j == k;
    for (PetscInt i = 0; i < nb; ++i) phi[i][k] = space.BasisValue(0, i, vertex);
  }
  sys.cellLoads.assign(keepLoads ? space.NumCells() * (dim + 2) : 0, 0.0);
  for (PetscInt c0 = 0; c0 < space.NumCells(); c0 += LoadBlock::kCells) {
    const PetscInt m = std::min(LoadBlock::kCells, space.NumCells() - c0);
    for (PetscInt i = 0; i < m; ++i) {
      X[i] = space.XD<dim>(c0 + i); // gathered once: every quadrature point needs it
      ComputeCellGeometryD<dim>(X[i], g[i]);
      ElementStiffnessD<dim>(b, sys.Kappa(c0 + i), g[i], Ke);
      PetscCall(fill.Add(space.Dofs(c0 + i), Ke));
    }
    if (zeroLoad) continue;
    if (evaluate) block.Evaluate<dim>(space, problem, sys.cellRule, c0, m, X, error);
    for (PetscInt i = 0; i < m; ++i) {
      const PetscInt c = c0 + i;
      CellLoad       cl;
      ComputeCellLoadD<dim>(space, problem, sys, c, X[i], g[i], evaluate ? &block.fx[i * nq] : nullptr, evaluate ? &block.x[i * nq * dim] : nullptr, work, cl, keepLoads, &range, error);
      // b_i = int_T f phi_i = sum_k moment_k phi_i(X_k): phi_i is affine.
      for (PetscInt j = 0; j < nb; ++j) {
        PetscReal bj = 0;
        for (PetscInt k = 0; k <= dim; ++k) bj += cl.moment[k] * phi[j][k];
        load[space.Dofs(c)[j]] += bj;
      }
      if (!keepLoads) continue;
      PetscReal *kept = &sys.cellLoads[c * (dim + 2)];
      std::copy(cl.moment, cl.moment + dim + 1, kept);
      kept[dim + 1] = cl.oscillation;
    }
  }
  PetscFunctionReturn(0);
}
static PetscErrorCode AssembleCells(const Space &space, const Problem &problem, bool keepLoads, System &sys, StiffnessFill &fill, PetscScalar *load, LoadRange &range, std::string &error)
{
  return WithDim(space.dim, [&](auto D) { return AssembleCellsD<D>(space, problem, keepLoads, sys, fill, load, range, error); });
}

// The points of the face rule on boundary face bf (x, rule.Size() * dim values), and their barycentric
// coordinates in its cell (lambda, rule.Size() * (dim + 1) values).
static void FacePoints(const Space &space, const BoundaryFace &bf, const Quadrature &rule, PetscReal *lambda, PetscReal *x)
{
  const Space::Coords X = space.X(bf.cell);
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    space.FaceToCell(bf, rule.Point(q), &lambda[q * (space.dim + 1)]);
    SimplexPoint(space.dim, X, &lambda[q * (space.dim + 1)], &x[q * space.dim]);
  }
}

// Neumann term: integral of g * phi_i over the faces of Gamma_N, with the face rule mapped into the cell.
static void AssembleNeumann(const Space &space, const Problem &problem, const System &sys, PetscScalar *load, LoadRange &range, std::string &error)
{
  const PetscInt         nq = sys.faceRule.Size(), dim = space.dim;
  std::vector<PetscReal> lambda(nq * (dim + 1)), x(nq * dim), gx(nq);
  for (const BoundaryFace &bf : space.boundary) {
    if (std::find(problem.neumann.begin(), problem.neumann.end(), bf.part) == problem.neumann.end()) continue;
    const PetscReal area = space.FaceMeasure(bf);
    FacePoints(space, bf, sys.faceRule, lambda.data(), x.data());
    problem.g->SetCellSet(space.CellSet(bf.cell)); // a boundary face has one cell
    problem.g->EvalBatch(nq, x.data(), dim, nullptr, gx.data(), error);
    for (PetscInt q = 0; q < nq; ++q) {
      const PetscReal gq = gx[q] * sys.faceRule.weights[q] * area;
      range.Record(*problem.g, gx[q], gq, &x[q * dim], dim);
      for (PetscInt i = 0; i < space.Nb(); ++i) load[space.Dofs(bf.cell)[i]] += gq * space.BasisValue(bf.cell, i, &lambda[q * (dim + 1)]);
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
  const PetscInt         nq = sys.faceRule.Size();
  std::vector<PetscReal> lambda(nq * (space.dim + 1)), x(nq * space.dim), ux(nq);
  for (const BoundaryFace &bf : space.boundary) {
    if (space.kindLocal[bf.dof] != kDirichlet) continue;
    FacePoints(space, bf, sys.faceRule, lambda.data(), x.data());
    problem.uD->EvalBatch(nq, x.data(), space.dim, nullptr, ux.data(), error);
    PetscReal mean = 0;
    for (PetscInt q = 0; q < nq; ++q) mean += sys.faceRule.weights[q] * ux[q];
    u[bf.dof] = mean;
  }
}

// Without a Dirichlet part, adding a constant c > 0 keeps u >= psi and changes the energy by -c l(1), where
// l(1) = int f + int_{Gamma_N} g is the sum of the load vector (the basis functions of both elements sum to
// 1). A solution exists only where l(1) < 0, i.e. the load pushes u towards the obstacle: with l(1) = 0
// every u + c solves it too, with l(1) > 0 the energy has no minimum, and the solve would fail with a
// linear solver's message that names neither. Sums within round-off of 0 count as 0. The same holds for
// each piece of a domain in several pieces that has contact but no Dirichlet face (CoarseFindings),
// with the sum over that piece's DOFs: the pieces of the space (DOFs joined through cells) are found only
// then, as the whole domain is one piece otherwise.
static PetscErrorCode CheckLoadTowardsObstacle(const Space &space, const Problem &problem, Vec load)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)load);
  std::vector<PetscInt> piece(space.numLocal, 0);
  PetscInt              count = 1;
  const PetscScalar    *l;
  PetscFunctionBeginUser;
  if (problem.coverage.pieces > 1) {
    ItemGraph graph;
    graph.numItems    = space.numLocal;
    graph.numCells    = space.NumCells();
    graph.per         = space.Nb();
    graph.cellItems   = [&](PetscInt c) { return space.Dofs(c); };
    graph.shareOwners = [&](std::vector<PetscInt> &v) { return SpaceShareOwners(space, v); };
    PetscCall(ConnectedComponents(comm, graph, piece, &count));
  }
  // Per piece: the load's sum and its sum of absolute values over the owned DOFs, whether it has a
  // Dirichlet DOF.
  std::vector<PetscReal> sums(3 * count, 0.0);
  PetscInt               rstart, n;
  const PetscInt        *gidx;
  PetscCall(VecGetOwnershipRange(load, &rstart, NULL));
  PetscCall(VecGetLocalSize(load, &n));
  PetscCall(VecGetArrayRead(load, &l));
  PetscCall(ISLocalToGlobalMappingGetIndices(space.ltog, &gidx));
  for (PetscInt i = 0; i < space.numLocal; ++i) {
    const PetscInt k = piece[i], g = gidx[i];
    if (k < 0) continue;
    if (space.kindLocal[i] == kDirichlet) sums[3 * k + 2] = 1;
    if (g < rstart || g >= rstart + n) continue; // a copy of another rank's DOF
    sums[3 * k] += PetscRealPart(l[g - rstart]);
    sums[3 * k + 1] += PetscAbsScalar(l[g - rstart]);
  }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(space.ltog, &gidx));
  PetscCall(VecRestoreArrayRead(load, &l));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums.data(), (PetscMPIInt)sums.size(), MPIU_REAL, MPI_SUM, comm));
  std::vector<PetscInt> bad;
  for (PetscInt k = 0; k < count; ++k)
    if (sums[3 * k + 2] == 0 && !(sums[3 * k] < -1e-10 * sums[3 * k + 1])) bad.push_back(k);
  if (bad.empty()) PetscFunctionReturn(0);
  const PetscReal total = sums[3 * bad[0]], size = sums[3 * bad[0] + 1];
  const char     *why   = total > 1e-10 * size ? "u + c lowers the energy for every c > 0, so no solution exists" : "u + c solves it for every c > 0, so the solution is not unique";
  if (count == 1)
    SIGNORINI_INPUT_ERROR(comm, "options -f, -g: the scene has no Dirichlet part, so the load must push u towards the obstacle, but its total (int f + int g over Gamma_N) is %.3g (%.3g in absolute value): %s; make the total negative or name a Dirichlet part", (double)total, (double)size, why);
  // Name the piece by a point that does not depend on the ranks (the first bad piece in that order).
  std::vector<PetscInt> cellPiece(space.NumCells());
  for (PetscInt c = 0; c < space.NumCells(); ++c) cellPiece[c] = piece[space.Dofs(c)[0]];
  std::vector<std::array<PetscReal, 3>> lowest;
  PetscCall(LowestPoints(comm, space.dim, space.NumCells(), cellPiece, count, [&](PetscInt c, PetscReal *x) { SimplexCentroid(space.dim, space.X(c), x); }, lowest));
  PetscInt first = bad[0];
  for (PetscInt k : bad)
    if (lowest[k] < lowest[first]) first = k;
  const PetscReal t = sums[3 * first], a = sums[3 * first + 1];
  SIGNORINI_INPUT_ERROR(comm, "options -f, -g: the mesh is in %d pieces, and %d of them (one near (%s)) %s contact but no Dirichlet faces, so the load must push each such piece towards the obstacle, but the total there (int f + int g over Gamma_N) is %.3g (%.3g in absolute value): %s; make it negative or give that piece a Dirichlet face",
                        (int)count, (int)bad.size(), CoordinatesText(space.dim, lowest[first].data()).c_str(), bad.size() == 1 ? "has" : "have", (double)t, (double)a,
                        t > 1e-10 * a ? "u + c lowers the energy there for every c > 0, so no solution exists" : "u + c solves it there for every c > 0, so the solution is not unique");
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
  LoadRange     range;
  StiffnessFill fill;
  PetscCall(fill.Begin(space, sys.A));
  PetscCall(AssembleCells(space, problem, opts.keepCellLoads, sys, fill, a, range, error));
  PetscCall(fill.End());
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
  if (problem.HasContact() && HeldByContactAlone(space, problem)) PetscCall(CheckLoadTowardsObstacle(space, problem, sys.load));

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
    // Relative to the cell's first value: Ke holds constants in its kernel, so the form is the same, and
    // values far from 0 (u_D and psi of 1e8 with a solution that varies by 1) no longer cancel in it (the
    // energy was -252.9 there against -0.4617).
    const PetscInt *dofs = space.Dofs(c);
    const PetscReal a0   = PetscRealPart(a[dofs[0]]);
    for (PetscInt i = 0; i < nb; ++i)
      for (PetscInt j = 0; j < nb; ++j) local += 0.5 * (PetscRealPart(a[dofs[i]]) - a0) * Ke[i * nb + j] * (PetscRealPart(a[dofs[j]]) - a0);
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

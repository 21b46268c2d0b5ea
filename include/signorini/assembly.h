// Assembly of the discrete problem a_h(u, v) = chi(v): the stiffness matrix with kappa constant per cell,
// the load (f over cells, g over Gamma_N), Dirichlet values eliminated symmetrically, and the discrete
// energy J(u_h) = 1/2 a_h(u_h, u_h) - chi(u_h).
#pragma once

#include "signorini/quadrature.h"
#include "signorini/space.h"

namespace signorini {

struct AssemblyOptions {
  // Load quadrature: "accurate" uses a rule exact for f * phi with f a polynomial of degree loadDegree - 1;
  // "centroid" the one-point rule, i.e. f replaced by its value at each cell centroid (the paper's choice).
  bool     centroid   = false;
  PetscInt loadDegree = 4;
  // Keep each cell's load (CellLoad: its moments and oscillation) in System::cellLoads, so that the
  // estimate reads them instead of evaluating f again. Set by the pipeline where the estimate is computed.
  bool keepCellLoads = false;
};
PetscErrorCode AssemblyOptionsFromCommandLine(MPI_Comm comm, AssemblyOptions &o);

// The load of one cell by the assembly's rule (System::cellRule), from one evaluation of f per point:
// moment[k] = int_T f lambda_k (k = 0..dim), so that int_T f phi_i = sum_k moment[k] phi_i(X_k) for the
// (affine) basis functions, int_T f = sum_k moment[k] and Pi_0 f = that / |T|; and the oscillation
// C_T kappa_T^{-1/2} ||f - Pi_0 f||_T (the norm by the same rule; C_T = PoincareConstant), which the
// estimate needs.
struct CellLoad {
  PetscReal moment[4];
  PetscReal oscillation;
  PetscReal Total(PetscInt dim) const
  {
    PetscReal t = 0;
    for (PetscInt k = 0; k <= dim; ++k) t += moment[k];
    return t;
  }
};

struct System {
  Mat                    A = nullptr;    // stiffness, Dirichlet rows and columns replaced by identity
  Vec                    b = nullptr;    // load with Dirichlet values and their column contributions folded in
  Vec                    load = nullptr; // chi as a vector (before elimination): chi(v) = load . v
  Vec                    uD = nullptr;   // Dirichlet values on Dirichlet DOFs, 0 elsewhere
  std::vector<PetscReal> kappa;          // per local cell, or one value when kappa is constant
  Quadrature             cellRule, faceRule;
  // The rules of the estimate's data oscillation ||f - Pi_0 f||, ||g - Pi_0 g||: the load's own where they
  // are exact for degree kOscillationDegree, else rules that are. A one-point rule (-load_quadrature
  // centroid) would see no oscillation at all.
  static constexpr PetscInt kOscillationDegree = 4;
  Quadrature             oscCellRule, oscFaceRule;
  // With AssemblyOptions::keepCellLoads: per local cell, its CellLoad's dim + 1 moments and oscillation
  // (dim + 2 reals per cell); else empty.
  std::vector<PetscReal> cellLoads;
  PetscReal              Kappa(PetscInt c) const { return kappa.size() == 1 ? kappa[0] : kappa[c]; }
};

// Pushes the Setup (matrix creation) and Assemble stages.
PetscErrorCode AssembleSystem(const Space &space, const Problem &problem, const AssemblyOptions &opts, System &sys);
// Whether some piece of the domain has no Dirichlet DOF (the whole domain, or a piece with contact faces
// only, CoarseFindings): its load must push it towards the obstacle, and its solve starts in full contact.
inline bool HeldByContactAlone(const Space &space, const Problem &problem) { return space.numDirichletGlobal == 0 || problem.coverage.contactOnly > 0; }
PetscErrorCode SystemDestroy(System &sys);
// J(u) = 1/2 a_h(u, u) - chi(u), computed cell by cell from the unreduced element matrices.
PetscErrorCode DiscreteEnergy(const Space &space, const System &sys, Vec u, PetscReal *J);
// The load of cell c (vertices X, geometry g) as the assembly computed it: read from sys.cellLoads where the
// assembly kept them (inline: the estimate's cell loops read it for every cell), else evaluated again by
// EvaluateCellLoad (a constant f is not evaluated per point). `work` is scratch space kept across cells; a
// NaN of f is reported in `error` (CheckAll after the loop).
void EvaluateCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, std::vector<PetscReal> &work, CellLoad &load, std::string &error);
inline void GetCellLoad(const Space &space, const Problem &problem, const System &sys, PetscInt c, const PetscReal *X, const CellGeometry &g, std::vector<PetscReal> &work, CellLoad &load, std::string &error)
{
  if (sys.cellLoads.empty()) return EvaluateCellLoad(space, problem, sys, c, X, g, work, load, error);
  const PetscInt   n    = space.dim + 2; // dim + 1 moments, then the oscillation
  const PetscReal *kept = &sys.cellLoads[c * n];
  for (PetscInt k = 0; k < n - 1; ++k) load.moment[k] = kept[k];
  load.oscillation = kept[n - 1];
}
// A constant C_T of Poincare's inequality ||w - w_T||_T <= C_T ||grad w||_T (w_T the mean of w on T) on the
// simplex T with vertices X: h_T / pi (Payne-Weinberger, any convex cell), or smaller where T is an affine
// image of half a square or a sixth of a cube by a map of norm below h_T (see assembly.cpp).
PetscReal PoincareConstant(PetscInt dim, const PetscReal *X);
// Element stiffness of cell c (nb x nb, row-major).
void ElementStiffness(const Space &space, PetscInt c, PetscReal kappa, const CellGeometry &g, PetscReal *Ke);

} // namespace signorini

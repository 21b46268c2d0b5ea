#include "signorini/kkthint.h"
#include "signorini/common.h"
#include "signorini/transfer.h"

#include <algorithm>
#include <cmath>

namespace signorini {

namespace {
PetscReal AspectRatio(PetscInt dim, const PetscReal *X)
{
  CellGeometry g;
  if (!ComputeCellGeometry(dim, X, g)) return PETSC_INFINITY;
  PetscReal edge = 0, grad = 0; // longest edge; largest |grad lambda_k| = 1 / smallest height
  for (PetscInt i = 0; i <= dim; ++i) {
    PetscReal n = 0;
    for (PetscInt d = 0; d < dim; ++d) n += g.gradLambda[i][d] * g.gradLambda[i][d];
    grad = std::max(grad, std::sqrt(n));
    for (PetscInt j = i + 1; j <= dim; ++j) {
      PetscReal e = 0;
      for (PetscInt d = 0; d < dim; ++d) e += (X[i * dim + d] - X[j * dim + d]) * (X[i * dim + d] - X[j * dim + d]);
      edge = std::max(edge, std::sqrt(e));
    }
  }
  return edge * grad;
}
} // namespace

PetscErrorCode MeshAspectRatio(DM mesh, PetscReal *aspect)
{
  MeshCells cells;
  PetscInt  dim;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(mesh, &dim));
  PetscCall(cells.Init(mesh));
  *aspect = 0;
  for (PetscInt c = 0; c < cells.NumCells(); ++c) *aspect = std::max(*aspect, AspectRatio(dim, cells.X(c).x));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, aspect, 1, MPIU_REAL, MPI_MAX, PetscObjectComm((PetscObject)mesh)));
  PetscFunctionReturn(0);
}

PetscErrorCode MeasureStiffness(const Space &space, const System &sys, PetscReal *kappaContrast, PetscReal *aspect)
{
  PetscReal kmin = PETSC_MAX_REAL, maxs[2] = {0, 0}; // max kappa, max aspect ratio
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    kmin    = std::min(kmin, sys.Kappa(c));
    maxs[0] = std::max(maxs[0], sys.Kappa(c));
    maxs[1] = std::max(maxs[1], AspectRatio(space.dim, space.X(c)));
  }
  MPI_Comm comm = PetscObjectComm((PetscObject)space.dm);
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &kmin, 1, MPIU_REAL, MPI_MIN, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, maxs, 2, MPIU_REAL, MPI_MAX, comm));
  *kappaContrast = kmin > 0 ? maxs[0] / kmin : PETSC_INFINITY;
  *aspect        = maxs[1];
  PetscFunctionReturn(0);
}

// The stationarity on the free DOFs (KKTHint checks the conditions on Gamma_C first): where it misses the tolerance,
// the cause the solve shows. At the round-off floor that is the size of the terms of A u against the load
// (u_D or psi far larger than what the load adds to u: psi = 1e9 over paper-5.1, whose load moves u by 0.1,
// leaves 7e-2 of the load), which no option changes.
static PetscErrorCode StationarityHint(MPI_Comm comm, const SolveResult &r, PetscReal tolerance)
{
  PetscFunctionBeginUser;
  const std::string head = Format("signorini: warning: the stationarity on the free DOFs holds only to %.1e of the load (-kkt_tolerance %g)", (double)r.stationarity, (double)tolerance);
  const std::string added = r.vi ? Format("%d Newton steps after SNESVI's residual test passed", (int)r.kktSteps) : Format("%d more linear solves from where the first stopped", (int)r.kktSteps);
  if (r.stoppedBy == "roundoff_floor")
    PetscCall(PetscPrintf(comm, "%s: the solve ended at the round-off floor of its residual (%s), which double precision sets by the terms of A u: the load is small against them (u_D or psi far larger than what the load adds to u, or stiff rows), and that is what it gives here\n", head.c_str(), added.c_str()));
  else if (!r.loosened.empty()) PetscCall(PetscPrintf(comm, "%s: the solver options %s, looser than the defaults, let this through: tighten them\n", head.c_str(), r.loosened.c_str()));
  else PetscCall(PetscPrintf(comm, "%s: the checks did not pass within the %s they add (%s); try -options_file petsc-options/solvers/high-contrast\n", head.c_str(), added.c_str(), r.reason.c_str()));
  PetscFunctionReturn(0);
}

PetscErrorCode KKTHint(const Space &space, const System &sys, const SolveResult &r, PetscReal tolerance)
{
  MPI_Comm comm = PetscObjectComm((PetscObject)space.dm);
  PetscFunctionBeginUser;
  if (!(tolerance > 0)) PetscFunctionReturn(0);
  if (!r.vi || !(r.kktRelative > tolerance)) {
    // (a solve stopped by an energy test, -solve_to, holds the checks only to the error it was asked for)
    if (r.stationarity > tolerance && (r.stoppedBy == "full" || r.stoppedBy == "roundoff_floor")) PetscCall(StationarityHint(comm, r, tolerance));
    PetscFunctionReturn(0);
  }
  const std::string head = Format("signorini: warning: the discrete KKT conditions on Gamma_C hold only to %.1e relative (-kkt_tolerance %g)", (double)r.kktRelative, (double)tolerance);
  // The bounds are exact up to round-off in A u - b; a little room keeps a residual at the bound in (a)/(b).
  const PetscReal reached = r.kktReached * (1 + 1e-6) + 1e-14;
  if (r.kktRelative > reached) {
    PetscCall(PetscPrintf(comm, "%s, more than the residual the solve stopped at (%.1e) permits (%.1e): min pressure %.1e of max %.1e, max |(u - psi) pressure| %.1e, %" PetscInt_FMT " active contact DOFs; look at the solve with -snes_monitor -snes_vi_monitor, and try -snes_vi_zero_tolerance 0, or a direct solve (-options_file petsc-options/solvers/mumps) on a small mesh\n", head.c_str(),
                          (double)r.residual, (double)r.kktReached, (double)r.dual, (double)r.pressureMax, (double)r.complementarity, r.active));
    PetscFunctionReturn(0);
  }
  if (!r.loosened.empty() && r.kktRelative > r.kktDefault) {
    PetscCall(PetscPrintf(comm, "%s: the solver options %s, looser than the defaults, let this through (the solve stopped at a residual of %.1e, which permits %.1e; the defaults permit %.1e): tighten them (defaults: -snes_rtol 1e-9, -ksp_rtol 1e-10, -snes_vi_zero_tolerance 1e-14, no -snes_atol%s)\n", head.c_str(), r.loosened.c_str(), (double)r.residual, (double)r.kktReached, (double)r.kktDefault,
                          r.loosened.find("skip") != std::string::npos ? "; with -snes_convergence_test skip, more -snes_max_it" : ""));
    PetscFunctionReturn(0);
  }
  PetscReal contrast, aspect;
  PetscCall(MeasureStiffness(space, sys, &contrast, &aspect));
  if (contrast >= kStiffContrast || aspect >= kStiffAspect) {
    if (r.stoppedBy == "roundoff_floor") PetscCall(PetscPrintf(comm, "%s: the solve ended at the round-off floor of its residual (%.1e, %d Newton steps after SNESVI's residual test passed), which stiff rows (kappa max/min %.3g, cell aspect ratio up to %.3g) put this high: that is what double precision gives here\n", head.c_str(), (double)r.residual, (int)r.kktSteps, (double)contrast, (double)aspect));
    else PetscCall(PetscPrintf(comm, "%s: stiff rows (kappa max/min %.3g, cell aspect ratio up to %.3g) dominate the residual norm that SNESVI tests, and the solve ended (%s, at %.1e, %d Newton steps after that test passed) before its KKT checks passed; try -options_file petsc-options/solvers/high-contrast\n", head.c_str(), (double)contrast, (double)aspect, r.reason.c_str(), (double)r.residual, (int)r.kktSteps));
  }
  // Otherwise: what the default stopping test permits on this mesh (see kkthint.h).
  PetscFunctionReturn(0);
}

} // namespace signorini

// The warning after a contact solve whose discrete KKT conditions on Gamma_C hold less well than
// -kkt_tolerance asks, with the cause it sees and the remedy for that cause:
//  (a) the user's stopping options (-snes_rtol, -snes_atol, -ksp_rtol, -snes_vi_zero_tolerance, or no
//      residual test at all) are looser than the defaults and let the KKT residual through, where the
//      defaults would not have: tighten them;
//  (b) stiff rows: a large kappa contrast between cells or very stretched cells, so that the residual norm
//      SNESVI tests is dominated by the stiff rows, and the steps the KKT checks add (kktstop.h) ended at
//      their limit (then: the high-contrast preset) or at the residual's round-off floor (then: nothing
//      to do, double precision gives no more);
//  (c) a KKT residual larger than the residual reached permits: what was measured, and what to try.
// Where the conditions on Gamma_C hold (or there is no contact part: the linear solve) and the stationarity
// on the free DOFs does not, the warning names the cause the same way: the round-off floor (the load small
// against the terms of A u), loosened options, or the limit of the steps or solves the checks add.
// Otherwise the KKT residual is what the default stopping test permits on this mesh (the pressure divides
// the reaction by a boundary measure of about h^(d-1), so the permitted residual grows under refinement):
// the solve is as converged as it was asked to be, and nothing is printed.
#pragma once

#include "signorini/contact.h"

namespace signorini {

// Rows count as stiff from a kappa contrast of 100 or cells stretched 10 to 1 (their couplings then differ
// by about 100): well below the contrasts (1e3 and more) and aspect ratios (1e3) where the default stopping
// test has been seen to stop early, and well above what meshes of one material show (aspect ratio about 2
// for box meshes, below 10 for sound Gmsh meshes).
constexpr PetscReal kStiffContrast = 100, kStiffAspect = 10;

// The largest cell aspect ratio of a mesh (as MeasureStiffness), from its coordinates alone. Collective.
PetscErrorCode MeshAspectRatio(DM mesh, PetscReal *aspect);

// The stiffness of the rows of A: max/min kappa over the cells, and the largest cell aspect ratio
// (longest edge over smallest height: 2 for the right triangles of a box mesh). Collective.
PetscErrorCode MeasureStiffness(const Space &space, const System &sys, PetscReal *kappaContrast, PetscReal *aspect);

// Prints the warning (once, on rank 0) when r.kktRelative > tolerance and the cause is one of (a) to (c), or
// when only the stationarity misses it. Collective.
PetscErrorCode KKTHint(const Space &space, const System &sys, const SolveResult &r, PetscReal tolerance);

} // namespace signorini

// An exact solution that does not solve the scene (a typo in -exact_grad, an f or a g derived by hand) makes
// every error figure, and every rate of a convergence study, wrong without a word: the discrete solution
// converges to the scene's solution, not to the one given. So, where the scene has one, -exact_u and
// -exact_grad are checked against the scene at points of the coarse mesh, before the refinement:
//   - -exact_grad against difference quotients of -exact_u, and -div(kappa grad u) = f with the divergence by
//     difference quotients of kappa -exact_grad (kappa pointwise, as the expression gives it), at points
//     inside every cell;
//   - u = u_D on Gamma_D, kappa du/dn = g on Gamma_N, and on Gamma_C u >= psi, kappa du/dn >= 0 and one of
//     them an equality, at points of every boundary face of its part.
// Each condition that fails prints one warning with its worst point (the run goes on: the errors are then
// against the functions as given). The difference quotients are of fourth order with steps of 1e-3 times
// the cell's size, and a condition fails where it misses by more than 1e-3 of its own scale (1e-6 for
// u = u_D and u >= psi), far above their error on any smooth function the coarse mesh can carry.
#pragma once

#include "signorini/problem.h"

#include <vector>

namespace signorini {

// Collective on dm. kind: per mesh point (p - pStart), 1 for a face of Gamma_D, 2 of Gamma_C, 4 of Gamma_N,
// 0 otherwise. *failed: how many conditions failed (a warning printed for each); -1 without an exact solution.
PetscErrorCode CheckExactSolution(DM dm, const Problem &p, const std::vector<char> &kind, PetscInt *failed);

} // namespace signorini

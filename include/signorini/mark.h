// Doerfler (bulk) marking for adaptive refinement: given the squared cell indicators eta_T^2 and theta in
// (0, 1], a set M of cells with
//   sum_{T in M} eta_T^2 >= theta * sum_T eta_T^2,
// the fraction theta of the estimated squared error (the convention of Carstensen, Feischl, Page and
// Praetorius, "Axioms of adaptivity", 2014, for which optimal rates hold for small enough theta; the
// squared indicators are the quantities that add up over cells, so theta is the share of eta^2 refined).
// M consists of the cells with the largest indicators: all cells with eta_T^2 >= t, with t the largest
// threshold that satisfies the inequality, found by bisection on the values with global reductions (no
// gather, no sort). Indicators equal in exact arithmetic, or packed closer than the solver's tolerance,
// differ slightly between runs on other rank counts, so the cut is not t itself but the middle of the
// first empty bin below t, the bins of relative width 1e-6 counted down from t (the cells of a cluster of
// values just below t are marked too): the same cells on any number of ranks, and for indicators scaled
// by any factor.
#pragma once

#include "signorini/common.h"

namespace signorini {

// Collective. eta2: this rank's squared indicators; marked[i] = 1 for the marked cells, else 0. With
// no positive indicator nothing is marked. Returns the number of marked cells (global) in *count.
PetscErrorCode MarkDoerfler(MPI_Comm comm, const std::vector<PetscReal> &eta2, PetscReal theta, std::vector<char> &marked, PetscInt *count = nullptr);

} // namespace signorini

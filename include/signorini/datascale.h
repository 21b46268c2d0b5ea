// The size of the data, so that the solve does not depend on it. PETSc's solvers carry absolute
// thresholds that assume a solution of size about 1: the SNES and KSP absolute tolerances (1e-50), the
// test of SNESVI for "on the bound" (u < psi + 1e-8) and the line search's step cap (1e8). A load of 1e-60
// then stops before the first step with u = 0, loads of 1e-20 take 32 Newton steps instead of 2, and
// loads of 1e20 never converge. The contact solve therefore works on the data divided by a scale U of the
// solution: U is homogeneous of degree 1 in the data (b, u_D, psi), so the solver sees the same problem
// for s f as for f, and it is a power of 2, so that dividing by it and multiplying back are exact.
#pragma once

#include "signorini/assembly.h"

namespace signorini {

// Scales beyond 2^kMaxScaleExponent (about 1e135) or below its inverse are refused: the energy, about U^2,
// would leave the range of double precision (and before it, integrals and products of the data).
constexpr PetscInt kMaxScaleExponent = 450;

// log2 of the scale U of the solution, an integer: the largest of max |u_D|, max psi on Gamma_C (|psi|)
// and the Rayleigh-quotient estimate |l|_inf (l.l) / (l.A l) of |A^-1 l| for l = b off the Dirichlet
// rows (0 when all data are 0). Collective; an input error (one line) when the data are not finite or U
// is out of range. lower: psi on the contact DOFs (null without contact).
PetscErrorCode DataScaleExponent(const Space &space, const System &sys, Vec lower, PetscInt *exponent);

// Multiplies b, u_D, lower and u (each may be null) by 2^exponent: exact, and undone exactly by -exponent.
PetscErrorCode ScaleData(const System &sys, Vec lower, Vec u, PetscInt exponent);

} // namespace signorini

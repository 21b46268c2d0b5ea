// The size of the data, so that the solve does not depend on it. PETSc's solvers carry absolute
// thresholds that assume a solution and a residual of size about 1: the SNES and KSP absolute tolerances
// (1e-50), the test of SNESVI for "on the bound" (u < psi + 1e-8) and the line search's step cap (1e8). A
// load of 1e-60 then stops before the first step with u = 0, loads of 1e-20 take 32 Newton steps instead of
// 2, loads of 1e20 never converge, and kappa = 1e-60 stops at once as well. The solve therefore works on
// u / U and on the equations (A u - b) / R: U is a scale of the solution, homogeneous of degree 1 in the
// data (b, u_D, psi), R the largest diagonal entry of A, so the solver sees the same problem for s f as for
// f (and for s kappa as for kappa); both are powers of 2, so that dividing by them and multiplying back are
// exact, and a scene whose scales are near 1 is solved bit for bit as without them.
#pragma once

#include "signorini/assembly.h"

#include <cmath>

namespace signorini {

// Scales beyond 2^kMaxScaleExponent (about 1e135) or below its inverse are refused: the energy, about U^2,
// would leave the range of double precision (and before it, integrals and products of the data).
constexpr PetscInt kMaxScaleExponent = 450;

struct DataScale {
  PetscInt u = 0;    // U = 2^u
  PetscInt rows = 0; // R = 2^rows
  // A residual of the scaled equations in the units of b.
  PetscReal Residual(PetscReal scaled) const { return std::ldexp(scaled, (int)(u + rows)); }
};

// U: the largest of max |u_D|, max |psi| on Gamma_C and the Rayleigh-quotient estimate |l|_inf (l.l) / (l.A l)
// of |A^-1 l| for l = b off the Dirichlet rows (1 when all data are 0); R: max A_ii off the Dirichlet rows;
// each rounded to a power of 2. Collective; an input error (one line) when the data are not finite or U is
// out of range. lower: psi on the contact DOFs (null without contact).
PetscErrorCode DataScaleCompute(const Space &space, const System &sys, Vec lower, DataScale *scale);

// Into the solver's units (back = false): A / R, b / (U R), u_D, lower and u (each vector may be null) / U;
// back = true multiplies them back. Exact both ways.
PetscErrorCode ScaleData(const System &sys, Vec lower, Vec u, const DataScale &scale, bool back);

} // namespace signorini

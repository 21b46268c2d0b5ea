// The size of the data, so that the solve does not depend on it. PETSc's solvers carry absolute
// thresholds that assume a solution and a residual of size about 1: the SNES and KSP absolute tolerances
// (1e-50), the test of SNESVI for "on the bound" (u < psi + 1e-8) and the line search's step cap (1e8). A
// load of 1e-60 then stops before the first step with u = 0, loads of 1e-20 take 32 Newton steps instead of
// 2, loads of 1e20 never converge, and kappa = 1e-60 stops at once as well. The solve therefore works on
// u / U and on the equations (A u - b) / R: U is a scale of the solution, homogeneous of degree 1 in the
// data (b, u_D, psi), R the largest diagonal entry of A, so the solver sees the same problem for s f as for
// f (and for s kappa as for kappa); both are powers of 2, so that dividing by them and multiplying back are
// exact, and a scene whose scales are near 1 is solved bit for bit as without them.
//
// Before that, data far from 0 against their spread are shifted by a constant: u_D and psi of 1e8 over a
// solution that varies by 1 (a temperature in kelvin, a pressure in pascal) leave A u - b a round-off floor
// of eps |A| |u|, there 1e-3 of the load, so the solve ended at that floor after 10 added Newton steps (4
// times the time), its stationarity and KKT checks missed -kkt_tolerance, and the active count took DOFs 1e-2
// off psi as active. Constants lie in both spaces and in the kernel of the unreduced stiffness, so the
// solve of u - s with u_D - s and psi - s (the Dirichlet columns' share of b moved with them) is the same
// discrete problem; s is their midrange, so near every value that the subtractions are exact (Sterbenz).
#pragma once

#include "signorini/assembly.h"

#include <cmath>

namespace signorini {

// Scales beyond 2^kMaxScaleExponent (about 1e135) or below its inverse are refused: the energy, about U^2,
// would leave the range of double precision (and before it, integrals and products of the data).
constexpr PetscInt kMaxScaleExponent = 450;

// The data are shifted where the midrange of u_D and psi exceeds kShiftRatio times both their half range and
// the load's scale of the solution: scenes of data near 0 are solved as without it.
constexpr PetscReal kShiftRatio = 64;

struct DataScale {
  PetscReal shift = 0; // s, subtracted from u_D, psi and u before the scaling
  PetscInt  u = 0;     // U = 2^u (of the shifted data)
  PetscInt  rows = 0;  // R = 2^rows
  // A residual of the scaled equations in the units of b.
  PetscReal Residual(PetscReal scaled) const { return std::ldexp(scaled, (int)(u + rows)); }
};

// s (DataShiftCompute: the midrange of u_D on the Dirichlet DOFs and psi on the contact DOFs, where it exceeds
// kShiftRatio times their half range and the load's scale of the solution, |A^-1 l| estimated as below for
// l the load before the elimination; else 0). Collective. lower: as below.
PetscErrorCode DataShiftCompute(const Space &space, const System &sys, Vec lower, PetscReal *shift);
// U (DataScaleCompute, of the data as they are, so after ShiftData): the largest of max |u_D - s|, max |psi - s| on Gamma_C and the Rayleigh-quotient
// estimate |l|_inf (l.l) / (l.A l) of |A^-1 l| for l = b off the Dirichlet rows, b with the Dirichlet columns
// of u_D - s (1 when all data are 0); R: max A_ii off the Dirichlet rows;
// each rounded to a power of 2. Collective; an input error (one line) when the data are not finite or U is
// out of range. lower: psi on the contact DOFs (null without contact).
PetscErrorCode DataScaleCompute(const Space &space, const System &sys, Vec lower, DataScale *scale);

// Into the solver's units (back = false): A / R, b / (U R), u_D, lower and u (each vector may be null) / U;
// back = true multiplies them back. Exact both ways.
PetscErrorCode ScaleData(const System &sys, Vec lower, Vec u, const DataScale &scale, bool back);

// The shift s (none where it is 0): u_D - s on the Dirichlet DOFs, psi - s on the contact DOFs (lower), u - s
// (u may be null), and b as the elimination of u_D - s makes it (Dirichlet rows u_D - s, the others
// b_i + s sum_{j Dirichlet} A_ij, those sums from the element matrices); back = true undoes it, b as it was
// (kept in *savedB, which back destroys), u_D and psi exactly, u + s. Collective.
PetscErrorCode ShiftData(const Space &space, const System &sys, Vec lower, Vec u, const DataScale &scale, bool back, Vec *savedB);

} // namespace signorini

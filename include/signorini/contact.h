// The solve: with a contact part, the variational inequality A u >= b-type problem u in K_h is solved by
// SNESVINEWTONRSLS (reduced-space active-set Newton) with lower bounds psi on the contact DOFs; without
// one, a single KSP solve and none of the VI machinery. Default KSP: CG with hypre BoomerAMG. Every
// default can be overridden with the usual -snes_*, -ksp_* and -pc_* options.
//
// After the solve the discrete KKT conditions on Gamma_C are measured. The reaction r = A u - b at a
// contact DOF is divided by the boundary measure that DOF carries (|F| for CR, the lumped sum of |F|/d
// for P1), which approximates the contact pressure kappa du/dn and does not change with the mesh size.
#pragma once

#include "signorini/amgreuse.h"
#include "signorini/assembly.h"
#include "signorini/release.h"

namespace signorini {

struct SolveResult {
  bool        vi = false;
  PetscInt    newtonIts = 0, kspIts = 0;
  std::string reason; // SNES (VI) or KSP converged reason
  // KKT on the contact DOFs (only with a contact part)
  PetscReal primal = 0;          // min (u - psi): >= 0
  PetscReal dual = 0;            // min pressure r/m: >= 0
  PetscReal complementarity = 0; // max |(u - psi) * r/m|: 0
  PetscReal pressureMax = 0, gapMax = 0;
  PetscInt  active = 0; // contact DOFs with u = psi
  // The worst of the three KKT residuals, each relative to its natural scale: max(0, -min gap) / max|u|,
  // -min pressure / max pressure, complementarity / (max pressure * max(max gap, max|u|)); the last two
  // only where some contact DOF is active. Round-off level when the solve converged; a solve that stopped
  // early (stiff rows dominating the SNES residual norm) shows here even when SNES reported convergence.
  PetscReal kktRelative = 0;
  // What the stopping test allows, for the KKT hint (kkthint.h). SNESVI stops on the 2-norm of A u - b over
  // the inactive set, which bounds |r_i| at every contact DOF that is not active, so the dual and
  // complementarity residuals cannot exceed residual / (min contact measure * max pressure) (plus what
  // SNESVI's bound tolerance lets through): kktReached is that bound for the residual where the solve
  // stopped, kktDefault for the default stopping test (-snes_rtol 1e-9 from the start at u_D). Either
  // grows as the mesh is refined (the measure is about h^(d-1)).
  PetscReal   residual = 0, defaultTarget = 0; // the residual reached, and the default test's (units of b)
  PetscReal   kktReached = 0, kktDefault = 0;
  std::string loosened; // the stopping options the user set looser than the defaults ("-snes_rtol 0.001")
  PetscInt    scaleExponent = 0; // the solve worked on u / 2^scaleExponent (DataScale::u, datascale.h)
  PetscInt    kktSteps  = 0; // Newton steps beyond the residual test for the KKT checks (kktstop.h); linear: more solves
  std::string stoppedBy = "full"; // which test ended the solve: full, start_error, energy_error (SolveOptions) or roundoff_floor (stall.h)
  PetscReal stationarity = 0; // max |r| over DOFs that are neither Dirichlet nor contact, relative to max |load|
  PetscReal energy = 0;
  // Nested iteration: one entry per level solved, coarsest first, the finest (this solve) last; empty
  // without nested iteration. newtonIts/kspIts above are the finest level's.
  struct Level {
    PetscInt    dofs = 0, newtonIts = 0, kspIts = 0, amgSetups = 0;
    double      setupSeconds = 0, solveSeconds = 0; // space + assembly, and the solve (prolongation included)
    std::string stoppedBy;                          // as SolveResult::stoppedBy
    PetscReal   energyError = 0;                    // SolveOptions::energyError of the level (0: none)
  };
  std::vector<Level> levels;
  std::string        stopping; // nested iteration: -solve_to (nested.h)
  double             solveSeconds  = 0;  // the whole contact solve (all levels' solves), max over ranks
  double             linearSeconds = -1; // -compare_linear: one CG + BoomerAMG solve of A u = b (-1: not run)
  PetscInt           linearKspIts  = 0;
  AmgReuseStats      amg;                // BoomerAMG set-ups and re-uses in the contact solve (all levels)
};

struct SolveOptions {
  bool      initialGuess  = false; // u holds an initial guess (e.g. prolongated from a coarser level)
  bool      compareLinear = false; // -compare_linear: also time one linear solve of A u = b
  PetscReal kktTolerance  = 1e-6;  // -kkt_tolerance: the full test also asks the KKT checks for this (kktstop.h); above it, a warning
  AmgReuseOptions amgReuse;
  // Where the solve may stop before the full test (nested.h, -solve_to); 0: not at all.
  // Each once the algebraic error |||u - u_h||| is estimated below (contact.cpp, EnergyStop):
  PetscReal startError  = 0; // this fraction of the error of the start (estimated by the first Newton step)
  PetscReal energyError = 0; // this bound
  ReleaseOptions  release; // only for a solve without initialGuess
};
PetscErrorCode SolveOptionsFromCommandLine(MPI_Comm comm, SolveOptions &o);

// The solver options as inputs, before any mesh is built (what the solve would refuse: -ksp_type, -ksp_rtol,
// -snes_type, ...): one line naming the option. contact: the scene has a contact part. Collective.
PetscErrorCode CheckSolverOptions(MPI_Comm comm, bool contact);
// With -help: lists the SNES, KSP and PC options of the default solver without solving anything.
PetscErrorCode SolverOptionsHelp(MPI_Comm comm);
// Writes u_h, psi and the contact pressure at every contact DOF as CSV (x, y[, z], u, psi, pressure),
// sorted by coordinates, gathered on rank 0: the free boundary seen along Gamma_C.
PetscErrorCode WriteContactProfile(const Space &space, const Problem &problem, const System &sys, Vec u, const std::string &file);
// A contact DOF counts as active where u - psi <= ActiveTolerance(min u, max u): the solver puts active DOFs
// exactly on psi, so round-off relative to how much u varies is enough, and a few roundings of values of
// its size (nothing absolute, so that the count does not depend on the size of the data; not relative to
// the size of u alone, which would count DOFs 1e-2 off psi as active where u_D and psi are 1e8).
inline PetscReal ActiveTolerance(PetscReal umin, PetscReal umax)
{
  return 1e-10 * (umax - umin) + 4 * PETSC_MACHINE_EPSILON * PetscMax(PetscAbsReal(umin), PetscAbsReal(umax));
}
// ActiveTolerance of the values of the global vector u. Collective.
PetscErrorCode ActiveToleranceOf(Vec u, PetscReal *tol);
// psi at contact DOFs and -infinity elsewhere (a global vector of the space): the lower bound of K_h.
PetscErrorCode ContactLowerBound(const Space &space, const Problem &problem, Vec lower);
// The boundary measure each contact DOF carries (turns a reaction into a pressure), 0 elsewhere.
PetscErrorCode ContactMeasure(const Space &space, const Problem &problem, Vec measure);
// Makes u admissible: u = u_D (sys.uD) on the Dirichlet DOFs (owned indices), u = max(u, lower) elsewhere
// (lower may be null: no contact part).
PetscErrorCode ProjectOntoConstraints(const System &sys, const std::vector<PetscInt> &dirichletOwned, Vec lower, Vec u);
// u: global vector of the space, overwritten with the solution. Without opts.initialGuess the solve starts
// from u_D (projected onto K_h); with it, from u with its Dirichlet DOFs set to u_D and its contact DOFs
// projected onto u >= psi. Either way the solve stops at the same absolute residual, the one the
// start from u_D would reach (its SNES rtol times its initial residual), so that a good initial guess
// saves work without changing the discrete solution beyond solver tolerance; only opts.startError and
// opts.energyError (nested iteration's -solve_to) let it stop earlier. The solvers work on u and on
// the equations divided by powers of 2 near their sizes (datascale.h), so the iterations do not depend on
// the size of the data, and PETSc's absolute options (-snes_atol, -ksp_atol, -snes_vi_zero_tolerance,
// -snes_linesearch_maxstep) are relative to it. Pushes the Solve stage.
PetscErrorCode Solve(const Space &space, const Problem &problem, const System &sys, Vec u, SolveResult &result, const SolveOptions &opts = SolveOptions());
// The KKT conditions on Gamma_C and the stationarity on the free DOFs of u (SolveResult's primal, dual,
// complementarity, kktRelative, stationarity, ...) from its residual res = A u - b, with u, res, b and
// lower in one scale and the load in it times loadFactor (the solver's units, datascale.h: their ratios
// are the same in any). lower and measure (ContactMeasure) null: the stationarity only. Collective.
PetscErrorCode MeasureKKTFromResidual(const Space &space, const System &sys, Vec u, Vec res, PetscReal loadFactor, Vec lower, Vec measure, SolveResult &r);
// For the output, global vectors of the space that are 0 off Gamma_C: psi, the contact pressure
// (A u - b) / measure (as in the KKT check), and the active set (1 where u - psi is at most ActiveTolerance(min u, max u),
// the rule of SolveResult::active).
PetscErrorCode ContactFields(const Space &space, const Problem &problem, const System &sys, Vec u, Vec psi, Vec pressure, Vec active);

} // namespace signorini

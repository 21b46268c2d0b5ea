// The linear solves inside the Newton steps of the reduced-space VI solver (SNESVINEWTONRSLS): re-use of
// the algebraic multigrid set-up across steps, and inexact steps while the active set still moves.
//
// Every Newton step solves a system with the inactive-set block A_II of the stiffness matrix, and a plain
// BoomerAMG preconditioner is set up again for every new block. Between late steps the inactive set
// usually changes in a few DOFs near the free boundary only, so this shell preconditioner keeps the
// BoomerAMG of a reference block A_RR and applies, on the current set I,
//
//   P^{-1} = [ (A_RR^{-1} restricted to I and R)   0        ]   DOFs in I and R
//            [ 0                                   D^{-1}   ]   DOFs in I, not in R (Jacobi)
//
// which is symmetric positive definite (a principal block of an SPD operator plus a positive diagonal)
// and differs from a preconditioner built for A_II by a perturbation of rank about the number of changed
// DOFs: CG pays roughly one to two iterations per changed DOF instead of a new set-up.
//
// Policy, per Newton step:
//  - the active set still moves (more than maxChanged DOFs changed since the previous step, or this is
//    the first step): the step only has to show where the set goes next, so its solve stops at the
//    relative tolerance inexactRtol; from a good start (nested iteration: the guess carries the coarser
//    level's active set) only the first step counts as moving, since later changes are near the free
//    boundary only (3D paper-5.1 CR N = 48: finest level 3 Newton steps / 37 CG iterations -> 2 / 20,
//    the same energy to 13 digits);
//  - the active set has settled: the solve goes to the KSP's own tolerances;
//  - either way, a new set-up when the reference block differs from the current one in more than
//    maxChanged DOFs (a loose step after a new set-up takes one or two CG iterations; one re-using a
//    set-up for a set that moved by hundreds of DOFs took up to 32), and when a re-used set-up's last
//    solve needed more than twice the iterations per digit of the solve right after its set-up.
// The discrete solution does not depend on any of this: the SNES stops at the same residual.
//
// The preconditioner inside is by default (-vi_pc_type mg) the geometric multigrid over the refinement
// hierarchy (hierarchy.h) where the solve has one (nested iteration: every level, but the coarsest for
// P1), and BoomerAMG where it has none (a single mesh), which reads the usual -pc_hypre_* options;
// -vi_pc_type hypre makes it BoomerAMG everywhere, gamg GAMG (reading -pc_gamg_*: PETSc 3.18's RSLS cannot
// keep a GAMG across blocks of different size, this shell creates one per set-up). The multigrid was
// measured faster than BoomerAMG on every case of paper-5.1 (2D N = 256 to 1024, 3D N = 24, 48, P1 and
// CR: contact solve 0.4 to 0.9 times BoomerAMG's), with the same discrete solution, at about 60 B/DOF
// more memory (2D CR N = 1024: peak 664 against 607 B/DOF): one AIJ copy of the block, made at a set-up
// and used by CG's products too (the blocks RSLS asks for store no entries), and the coarse levels. An explicit -pc_type replaces the shell and
// restores PETSc's behaviour (a new preconditioner for every block, every step to the KSP tolerance).
#pragma once

#include <petscsnes.h>

#include <string>

namespace signorini {

struct Hierarchy; // hierarchy.h

struct AmgReuseOptions {
  bool      enabled     = true; // -amg_reuse (off: a new set-up every step)
  PetscInt  maxChanged  = 2;    // -amg_reuse_max_changed: "changed" means more DOFs than this (global count)
  PetscReal inexactRtol = 1e-1; // -vi_inexact_rtol (0: every step to the KSP tolerances)
  std::string innerType = "mg";    // -vi_pc_type: the preconditioner built for a block (mg: BoomerAMG where there is no hierarchy)
  bool      innerTypeGiven = false; // whether -vi_pc_type was given (else ChoosePreconditioner may change it)
  bool      goodStart   = false; // the initial guess carries its active set (nested iteration): only the
                                 // first step is inexact, later ones go to the KSP tolerance
  const Hierarchy *hierarchy = nullptr; // for -vi_pc_type mg: the transfers up to this solve's level
};
PetscErrorCode AmgReuseOptionsFromCommandLine(MPI_Comm comm, AmgReuseOptions &o);
// The default preconditioner for the run's mesh: the geometric multigrid's pointwise smoother does not
// smooth across very stretched cells (aspect ratio kStiffAspect and more, kkthint.h), where BoomerAMG,
// which coarsens along the strong couplings, does; so there, unless -vi_pc_type was given, BoomerAMG
// alone. Sets *aspect to the mesh's largest cell aspect ratio and *chosen to whether it chose BoomerAMG
// so. Collective.
PetscErrorCode ChoosePreconditioner(DM mesh, AmgReuseOptions &o, PetscReal *aspect, bool *chosen);

struct AmgReuseStats {
  PetscInt setups = 0, reuses = 0; // BoomerAMG set-ups, and Newton steps that re-used one
};

// Makes the PC of the SNES's KSP this shell (before SNESSetFromOptions, so that -pc_type still overrides
// it). The SNES must be of type SNESVINEWTONRSLS. `stats` must outlive the SNES.
PetscErrorCode AmgReuseInstall(SNES snes, const AmgReuseOptions &o, AmgReuseStats *stats);

// The reduced-space solver asks for every Newton step's inactive-set block A_II, as an AIJ copy, which
// BoomerAMG would then copy once more into hypre's format; yet a step that re-uses the BoomerAMG set-up
// only multiplies by the block. With the shell installed and BoomerAMG inside it, this returns in *J a
// matrix that acts as A and hands out blocks that store no entries: they multiply through A (on vectors
// zero outside I), and only a new set-up copies one, straight into hypre's format (the AIJ copy lives
// until it is converted). Otherwise *J = A with a new reference. Either way the caller destroys *J.
PetscErrorCode AmgReuseJacobian(SNES snes, Mat A, Mat *J);

} // namespace signorini

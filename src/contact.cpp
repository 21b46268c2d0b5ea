#include "signorini/contact.h"
#include "signorini/datascale.h"
#include "signorini/energystop.h"
#include "signorini/kktstop.h"
#include "signorini/options.h"
#include "signorini/report.h"
#include "signorini/stages.h"
#include "signorini/stall.h"

#include <petsc/private/kspimpl.h> // the norms a KSP type can report, see CheckKSPNorm

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace signorini {

namespace {
// The default stopping tolerances of the contact solve (and of the linear solves inside it), and the bound
// tolerance of SNESVI (a DOF within it of psi, with a positive residual, is active), in the units of the
// scaled solve (the largest data near 1, see datascale.h). PETSc's own 1e-8 is absolute: once u is scaled
// by the largest data, a scene whose solution on Gamma_C is far smaller than elsewhere (stiff-layers with
// kappa 1e-9 above: u ~ 1e9 at the top, ~0.1 on Gamma_C) had every contact DOF within 1e-8 of psi, so all
// of them counted as active whatever their value, and the solve freed one per Newton step (107 steps, the
// high-contrast preset's 30 not enough). The solver puts active DOFs exactly on psi (it projects onto the
// bounds and does not move active DOFs), so round-off of the largest values is all the tolerance needs.
constexpr PetscReal kSnesRtol = 1e-9, kKspRtol = 1e-10, kZeroTolerance = 1e-14;

// The semismooth solver (SNESVINEWTONSSLS) works on u of size 2^kSslsExponent rather than 1 (datascale.h).
// PETSc 3.18 differentiates its Fischer-Burmeister function Phi(a, b) = a + b - sqrt(a^2 + b^2), a = u - psi,
// b = F, with the derivative 1/2 for both a and b wherever both are below 1e-6 in absolute value: near the
// solution that is every contact DOF with a small gap or a small reaction (close to the free boundary, on
// fine meshes, on stretched cells), whose Newton steps then move it by a fraction of what they should, and
// the solve converges linearly (stiff-stretched-2d -box_faces 3 -refine 3: P1 128 Newton steps, CR
// DIVERGED_MAX_IT after 200, and 110 with the rows scaled by their diagonal). Phi is positively
// homogeneous, Phi(s a, s b) = s Phi(a, b), so scaling u (and with it F) by 2^20 leaves the solution and
// Newton's steps as they are and moves that threshold to 1e-12 relative, below where double precision
// resolves a and b anyway: 5 to 7 Newton steps there.
constexpr int kSslsExponent = 20;

struct ResidualContext {
  Mat  A;
  Vec  b;
  bool refresh  = false;   // J is a copy of A that the solver overwrites (SSLS)
  Vec  rowScale = nullptr; // SSLS: 1 / diag(A), see AdaptToSNESType
};

// F(u) = A u - b (each row divided by its diagonal entry where rowScale is set): the problem is linear,
// only the bounds make it a complementarity problem.
PetscErrorCode Residual(SNES, Vec u, Vec F, void *ctx)
{
  auto *c = static_cast<ResidualContext *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(MatMult(c->A, u, F));
  PetscCall(VecAXPY(F, -1.0, c->b));
  if (c->rowScale) PetscCall(VecPointwiseMult(F, F, c->rowScale));
  PetscFunctionReturn(0);
}

// A is assembled once. The reduced-space solver (RSLS) only extracts the inactive-set block from it, so
// J acts as A (A itself, or the shell of AmgReuseJacobian) and nothing is done here. The semismooth
// solver (SSLS) overwrites J with its own Jacobian D_a + D_b J, so for it J is a copy of A (its rows scaled
// as F's) refreshed before every step (F must keep the original A).
PetscErrorCode ConstantJacobian(SNES, Vec, Mat J, Mat, void *ctx)
{
  auto *c = static_cast<ResidualContext *>(ctx);
  PetscFunctionBeginUser;
  if (c->refresh) PetscCall(MatCopy(c->A, J, SAME_NONZERO_PATTERN));
  if (c->refresh && c->rowScale) PetscCall(MatDiagonalScale(J, c->rowScale, NULL));
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode ContactLowerBound(const Space &space, const Problem &problem, Vec lower)
{
  Vec          loc;
  PetscScalar *a;
  std::string  error;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < space.numLocal; ++i) a[i] = PETSC_NINFINITY;
  space.ForEachBoundaryDof([&](PetscInt i, const PetscReal *x) {
    if (space.kindLocal[i] == kContact) a[i] = problem.psi->Scalar(x, space.dim, error);
  });
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(space.dm, loc, INSERT_VALUES, lower));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscCall(CheckAll(PetscObjectComm((PetscObject)space.dm), error.empty(), error));
  PetscFunctionReturn(0);
}

PetscErrorCode ActiveToleranceOf(Vec u, PetscReal *tol)
{
  PetscReal umin, umax;
  PetscFunctionBeginUser;
  PetscCall(VecMin(u, NULL, &umin));
  PetscCall(VecMax(u, NULL, &umax));
  *tol = ActiveTolerance(umin, umax);
  PetscFunctionReturn(0);
}

PetscErrorCode ContactMeasure(const Space &space, const Problem &problem, Vec measure)
{
  Vec          loc;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(VecSet(loc, 0));
  PetscCall(VecGetArray(loc, &a));
  for (const BoundaryFace &bf : space.boundary) {
    if (std::find(problem.contact.begin(), problem.contact.end(), bf.part) == problem.contact.end()) continue;
    const PetscReal area = space.FaceMeasure(bf);
    if (space.element == Element::CR) a[bf.dof] += area;
    else
      for (PetscInt i = 0; i < space.Nb(); ++i)
        if (i != bf.opposite) a[space.Dofs(bf.cell)[i]] += area / space.dim;
  }
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(VecSet(measure, 0));
  PetscCall(DMLocalToGlobal(space.dm, loc, ADD_VALUES, measure));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscFunctionReturn(0);
}

// BoomerAMG options suited to the Poisson-type operators here (the 2D and 3D recommendations of the hypre
// documentation): HMIS coarsening with extended+i interpolation truncated to 4 entries per row keeps the
// operator complexity low, and in 3D one level of aggressive coarsening makes the set-up, which each
// active set needs, about three times cheaper at the price of more, cheaper CG iterations. They go into
// the options database only where the user gave none, so every -pc_hypre_boomeramg_* option still
// decides; `inserted` lists what was added, for AmgDefaultsRemoveUnused.
static PetscErrorCode AmgDefaultsInsert(PetscInt dim, std::vector<std::string> &inserted)
{
  const std::pair<const char *, const char *> all[] = {{"-pc_hypre_boomeramg_coarsen_type", "HMIS"}, {"-pc_hypre_boomeramg_interp_type", "ext+i"}, {"-pc_hypre_boomeramg_P_max", "4"}, {"-pc_hypre_boomeramg_agg_nl", dim == 3 ? "1" : "0"}};
  PetscFunctionBeginUser;
  for (const auto &o : all) {
    PetscBool set;
    PetscCall(PetscOptionsHasName(NULL, NULL, o.first, &set));
    if (set) continue;
    PetscCall(PetscOptionsSetValue(NULL, o.first, o.second));
    inserted.push_back(o.first);
  }
  PetscFunctionReturn(0);
}

// Defaults that nothing read (the user chose another preconditioner) leave the database again, so that
// they are not reported as unused options.
static PetscErrorCode AmgDefaultsRemoveUnused(const std::vector<std::string> &inserted)
{
  PetscFunctionBeginUser;
  for (const std::string &name : inserted) {
    PetscBool used;
    PetscCall(PetscOptionsUsed(NULL, name.c_str(), &used));
    if (!used) PetscCall(PetscOptionsClearValue(NULL, name.c_str()));
  }
  PetscFunctionReturn(0);
}

static PetscErrorCode ConfigureKSP(KSP ksp)
{
  PC pc;
  PetscFunctionBeginUser;
  PetscCall(KSPSetType(ksp, KSPCG));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCHYPRE));
  PetscCall(PCHYPRESetType(pc, "boomeramg"));
  PetscCall(KSPSetTolerances(ksp, kKspRtol, 1e-50, kCGDivergenceTolerance, 1000));
  PetscCall(KSPSetNormType(ksp, KSP_NORM_UNPRECONDITIONED));
  PetscFunctionReturn(0);
}

// A -ksp_type that cannot report the residual norm the solve stops on (minres: only the preconditioned one)
// failed inside the first solve, as a PETSc error on every rank; it is an input, and named as one. The
// test is PETSc's own choice of norm and side at set-up (KSPSetUpNorms_Private), which is not exported.
static PetscErrorCode CheckKSPNorm(KSP ksp)
{
  const KSPNormType norm = ksp->normtype; // as set; KSPGetNormType would run that test, erring
  const PCSide      side = ksp->pc_side;
  KSPType           type;
  PetscFunctionBeginUser;
  PetscCall(KSPGetType(ksp, &type));
  bool ok = norm == KSP_NORM_DEFAULT;
  for (PetscInt j = 0; j < PC_SIDE_MAX && !ok; ++j) ok = (side == PC_SIDE_DEFAULT || side == j) && ksp->normsupporttable[norm][j] > 0;
  if (!ok) SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)ksp), "option -ksp_type %s: it cannot report the %s residual norm that the solve stops on%s; use cg (the default) or a type that can, such as gmres or fgmres", type, KSPNormTypes[norm], side == PC_SIDE_DEFAULT ? "" : Format(" with -ksp_pc_side %s", PCSides[side]).c_str());
  PetscFunctionReturn(0);
}

// PETSc 3.18 reads -ksp_rtol 1 or -snes_atol -1 without a check, and refuses them only when they are set
// again, inside the solve, as a PETSc error: checked here, as inputs.
static PetscErrorCode CheckTolerances(MPI_Comm comm, const char *prefix, PetscReal rtol, PetscReal atol, PetscInt maxit)
{
  PetscFunctionBeginUser;
  if (!(rtol >= 0 && rtol < 1)) SIGNORINI_INPUT_ERROR(comm, "option -%s_rtol %s: must be at least 0 and below 1", prefix, Format("%g", (double)rtol).c_str());
  if (!(atol >= 0)) SIGNORINI_INPUT_ERROR(comm, "option -%s_atol %s: must be at least 0", prefix, Format("%g", (double)atol).c_str());
  if (maxit < 0) SIGNORINI_INPUT_ERROR(comm, "option -%s_max_it %" PetscInt_FMT ": must be at least 0", prefix, maxit);
  PetscFunctionReturn(0);
}

static PetscErrorCode CheckKSPTolerances(KSP ksp)
{
  PetscReal rtol, atol, dtol;
  PetscInt  maxit;
  PetscFunctionBeginUser;
  PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &maxit));
  PetscCall(CheckTolerances(PetscObjectComm((PetscObject)ksp), "ksp", rtol, atol, maxit));
  PetscFunctionReturn(0);
}

// Where stiff rows dominate ||b|| (kappa jumps, stretched cells), the KSP's relative test passes while the
// soft rows are still off, as in the contact solve (kktstop.h): the solve goes on from where it stopped,
// asked for a residual lowered as far as the stationarity misses -kkt_tolerance, up to KKTStop::kMaxSteps
// times, unless the user set -ksp_rtol looser than the default.
static PetscErrorCode SolveLinear(const Space &space, const System &sys, Vec u, SolveResult &r, PetscReal tolerance, PetscReal loadFactor)
{
  KSP                ksp;
  KSPConvergedReason reason;
  PetscReal          rtol, atol, dtol;
  PetscInt           maxit;
  PetscFunctionBeginUser;
  PetscCall(KSPCreate(PetscObjectComm((PetscObject)u), &ksp));
  PetscCall(KSPSetOperators(ksp, sys.A, sys.A));
  PetscCall(ConfigureKSP(ksp));
  PetscCall(OptionsAsInputError(PetscObjectComm((PetscObject)ksp), KSPSetFromOptions(ksp)));
  PetscCall(CheckKSPNorm(ksp));
  PetscCall(CheckKSPTolerances(ksp));
  PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &maxit));
  if (rtol > kKspRtol) r.loosened = Format("-ksp_rtol %g", (double)rtol);
  PetscCall(KSPSolve(ksp, sys.b, u));
  PetscCall(KSPGetConvergedReason(ksp, &reason));
  PetscCall(KSPGetIterationNumber(ksp, &r.kspIts));
  const bool restarts = reason > 0 && tolerance > 0 && rtol <= kKspRtol;
  Vec        res      = nullptr;
  PetscReal  best     = PETSC_MAX_REAL; // the lowest stationarity so far
  PetscInt   stalled  = 0;              // restarts since it was last halved
  if (restarts) PetscCall(VecDuplicate(u, &res));
  for (; restarts && reason > 0 && r.kktSteps < KKTStop::kMaxSteps; ++r.kktSteps) {
    SolveResult checks;
    PetscReal   norm;
    PetscInt    its;
    PetscCall(MatMult(sys.A, u, res));
    PetscCall(VecAXPY(res, -1.0, sys.b));
    PetscCall(MeasureKKTFromResidual(space, sys, u, res, loadFactor, nullptr, nullptr, checks));
    if (!(checks.stationarity > tolerance)) break;
    // The residual's round-off floor (a load small against the terms of A u, or stiff rows): two restarts
    // that did not halve the stationarity end them, as StallGuard ends the contact solve.
    if (checks.stationarity > 0.5 * best) {
      if (++stalled == 2) {
        r.stoppedBy = "roundoff_floor";
        break;
      }
    } else stalled = 0, best = checks.stationarity;
    PetscCall(VecNorm(res, NORM_2, &norm));
    PetscCall(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE));
    // (from a nonzero guess rtol is relative to ||b||, which the stiff rows dominate: atol alone decides)
    PetscCall(KSPSetTolerances(ksp, 0, KKTStop::Lowered(norm, tolerance, checks.stationarity), dtol, maxit));
    PetscCall(KSPSolve(ksp, sys.b, u));
    PetscCall(KSPGetConvergedReason(ksp, &reason));
    PetscCall(KSPGetIterationNumber(ksp, &its));
    r.kspIts += its;
  }
  PetscCall(VecDestroy(&res));
  r.reason = KSPConvergedReasons[reason];
  PetscCall(KSPDestroy(&ksp));
  if (reason < 0) SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)u), "solver: the linear solve did not converge (%s after %" PetscInt_FMT " iterations); try other -ksp_type/-pc_type options", r.reason.c_str(), r.kspIts);
  PetscFunctionReturn(0);
}

PetscErrorCode SolveOptionsFromCommandLine(MPI_Comm comm, SolveOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Solve", "signorini");
  PetscCall(OptionReal(PetscOptionsObject, "-kkt_tolerance", "The solve goes on beyond its residual test until the relative KKT residuals on Gamma_C and the stationarity off it (without a contact part: the stationarity) are below this (up to 10 Newton steps or linear solves more, or the round-off floor; not with stopping options looser than the defaults); a contact solve that ends above it warns, naming the cause and its remedy (0: neither)", o.kktTolerance, 0));
  PetscCall(OptionBool(PetscOptionsObject, "-compare_linear", "After the solve, time one linear solve of the same operator and right-hand side (same KSP/PC options) for comparison", o.compareLinear));
  PetscOptionsEnd();
  PetscCall(AmgReuseOptionsFromCommandLine(comm, o.amgReuse));
  PetscCall(ReleaseOptionsFromCommandLine(comm, o.release));
  o.release.maxChanged = o.amgReuse.maxChanged; // one notion of an active set that still moves
  PetscFunctionReturn(0);
}

PetscErrorCode ProjectOntoConstraints(const System &sys, const std::vector<PetscInt> &dirichletOwned, Vec lower, Vec u)
{
  PetscScalar       *a;
  const PetscScalar *d;
  PetscFunctionBeginUser;
  PetscCall(VecGetArray(u, &a));
  PetscCall(VecGetArrayRead(sys.uD, &d));
  for (PetscInt i : dirichletOwned) a[i] = d[i];
  PetscCall(VecRestoreArrayRead(sys.uD, &d));
  PetscCall(VecRestoreArray(u, &a));
  if (lower) PetscCall(VecPointwiseMax(u, u, lower));
  PetscFunctionReturn(0);
}

// SNESVI's norm of its function F (Residual) on the inactive set at u.
static PetscErrorCode InactiveSetNorm(SNES snes, ResidualContext &ctx, Vec u, PetscReal *fnorm)
{
  Vec F;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(u, &F));
  PetscCall(Residual(snes, u, F, &ctx));
  PetscCall(SNESVIComputeInactiveSetFnorm(snes, F, u, fnorm));
  PetscCall(VecDestroy(&F));
  PetscFunctionReturn(0);
}

// The residual norm the solve from u_D starts with (InactiveSetNorm at u_D projected onto the bounds). Its
// rtol is relative to this; a solve from a better initial guess stops at the same absolute residual, so the
// guess saves work without changing the discrete solution.
static PetscErrorCode StraightStartNorm(SNES snes, const System &sys, ResidualContext &ctx, Vec lower, PetscReal *fnorm)
{
  Vec u0;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(sys.uD, &u0));
  PetscCall(VecPointwiseMax(u0, sys.uD, lower));
  PetscCall(InactiveSetNorm(snes, ctx, u0, fnorm));
  PetscCall(VecDestroy(&u0));
  PetscFunctionReturn(0);
}

// Whether the user gave the SNES's option `name` (under its prefix).
static PetscErrorCode SNESOptionGiven(SNES snes, const char *name, PetscBool *given)
{
  const char *prefix;
  PetscFunctionBeginUser;
  PetscCall(SNESGetOptionsPrefix(snes, &prefix));
  PetscCall(PetscOptionsHasName(NULL, prefix, name, given));
  PetscFunctionReturn(0);
}

// The Krylov method of the semismooth solver, unless the user chose one. Its Jacobian D_a + D_b A is not
// symmetric, and CG (the reduced-space default) broke down on it (DIVERGED_LINEAR_SOLVE in the first step):
// GMRES. And GMRES's Gram-Schmidt with a second pass where orthogonality is lost: next to a kappa jump the
// Jacobian is ill-conditioned enough that the single classical pass lost it (stiff-checkerboard CR, K = 1e6:
// the recurrence's residual fell to 2e-7 while the true one stayed at 6e-7 of the start, then
// DIVERGED_BREAKDOWN); the pass costs nothing where orthogonality holds (the same iterations on every other
// stiff scene).
static PetscErrorCode KrylovForSemismooth(SNES snes, KSP ksp)
{
  PetscBool typeGiven, gs, mgs, cgs;
  PetscFunctionBeginUser;
  PetscCall(SNESOptionGiven(snes, "-ksp_type", &typeGiven));
  if (!typeGiven) {
    PetscCall(KSPSetType(ksp, KSPGMRES));
    PetscCall(KSPSetFromOptions(ksp)); // GMRES's own options, such as -ksp_gmres_restart
  }
  PetscCall(SNESOptionGiven(snes, "-ksp_gmres_cgs_refinement_type", &gs));
  PetscCall(SNESOptionGiven(snes, "-ksp_gmres_modifiedgramschmidt", &mgs));
  PetscCall(SNESOptionGiven(snes, "-ksp_gmres_classicalgramschmidt", &cgs));
  if (!gs && !mgs && !cgs) PetscCall(KSPGMRESSetCGSRefinementType(ksp, KSP_GMRES_CGS_REFINE_IFNEEDED)); // no-op for non-GMRES types
  PetscFunctionReturn(0);
}

// What the options chose, made to work where it can be. RSLS gets the Jacobian of AmgReuseJacobian
// (blocks in hypre's format when BoomerAMG is inside the re-use shell). Another SNESVI type (-snes_type vinewtonssls)
// needs its own Jacobian matrix (see ConstantJacobian), and it solves the full system, where the AMG
// re-use shell, which works on the reduced-space solver's inactive sets, does not apply: plain BoomerAMG
// takes its place.
static PetscErrorCode AdaptToSNESType(SNES snes, const System &sys, ResidualContext &ctx, Mat *J)
{
  PetscBool rsls, shell;
  KSP       ksp;
  PC        pc;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)snes, SNESVINEWTONRSLS, &rsls));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PetscObjectTypeCompare((PetscObject)pc, PCSHELL, &shell));
  if (rsls) {
    // PETSc 3.18's RSLS hands a GAMG (or MG) preconditioner a block of another size when the active set
    // changes, which GAMG refuses with an error deep inside; the shell builds a fresh one per block.
    PetscBool mg;
    PetscCall(PetscObjectTypeCompareAny((PetscObject)pc, &mg, PCGAMG, PCMG, PCML, ""));
    if (mg) {
      PCType type;
      PetscCall(PCGetType(pc, &type));
      SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)snes), "option -pc_type %s: the reduced-space contact solve cannot keep a multigrid preconditioner across active sets of different size (PETSc 3.18); use -vi_pc_type %s, which builds one for each active set", type, type);
    }
    PetscCall(AmgReuseJacobian(snes, sys.A, J));
    PetscCall(SNESSetJacobian(snes, *J, *J, ConstantJacobian, &ctx));
    // Full steps unless the user chose a line search. The problem is linear on the inactive set, so a full
    // reduced-space step solves it exactly for the current active set (the primal-dual active set method);
    // the default bt line search judges the step by ||F|| on the inactive set, which is no merit function
    // when the active set changes: from a guess whose active set is far off (a coarse level that cannot
    // resolve the load, e.g. stiff-critical k = 64 through box 8x8) it cut every step to 1e-3 and took 39
    // Newton steps where full steps take 2.
    SNESLineSearch ls;
    PetscBool      chosen;
    PetscCall(SNESOptionGiven(snes, "-snes_linesearch_type", &chosen));
    PetscCall(SNESGetLineSearch(snes, &ls));
    if (!chosen) PetscCall(SNESLineSearchSetType(ls, SNESLINESEARCHBASIC));
    PetscFunctionReturn(0);
  }
  PetscCall(MatDuplicate(sys.A, MAT_COPY_VALUES, J));
  ctx.refresh = true;
  // The semismooth function Phi(u - psi, F) weighs u - psi against F (see kSslsExponent for PETSc's
  // threshold in its derivative). Scaled by the largest diagonal entry (datascale.h), the rows of a soft
  // material beside a stiff one carry F of 1/K of their size, and their contact DOFs met that threshold
  // first (stiff-layers-across, K = 1e2 and 1e6: DIVERGED_MAX_IT after 200 Newton steps). Each row divided
  // by its own diagonal entry makes F a displacement, of the size of u - psi in every material (with
  // kSslsExponent too: stiff-checkerboard P1 4 Newton steps instead of 15); the solution does not change
  // (F >= 0 and (u - psi) F = 0 hold row by row).
  PetscCall(MatCreateVecs(sys.A, &ctx.rowScale, NULL));
  PetscCall(MatGetDiagonal(sys.A, ctx.rowScale));
  PetscCall(VecReciprocal(ctx.rowScale));
  PetscCall(SNESSetJacobian(snes, *J, *J, ConstantJacobian, &ctx));
  PetscCall(KrylovForSemismooth(snes, ksp));
  // The solve works on u of size 2^kSslsExponent (Solve): steps of that size are not to be cut.
  SNESLineSearch ls;
  PetscBool      chosen;
  PetscReal      steptol, maxstep, rtol, atol, ltol;
  PetscInt       maxits;
  PetscCall(SNESOptionGiven(snes, "-snes_linesearch_maxstep", &chosen));
  PetscCall(SNESGetLineSearch(snes, &ls));
  PetscCall(SNESLineSearchGetTolerances(ls, &steptol, &maxstep, &rtol, &atol, &ltol, &maxits));
  if (!chosen) PetscCall(SNESLineSearchSetTolerances(ls, steptol, std::ldexp(maxstep, kSslsExponent), rtol, atol, ltol, maxits));
  if (shell) {
    PetscCall(PCSetType(pc, PCHYPRE));
    PetscCall(PCHYPRESetType(pc, "boomeramg"));
    PetscCall(PCSetFromOptions(pc));
  }
  PetscFunctionReturn(0);
}

// The stopping options the user set looser than the defaults, for the KKT hint. A -snes_atol counts only
// where it, not the default rtol, decides when the solve stops; with -snes_convergence_test skip only the
// iteration count does.
static PetscErrorCode LoosenedStoppingTest(SNES snes, PetscReal atol, PetscReal rtol, SolveResult &r)
{
  KSP       ksp;
  PetscReal kspRtol;
  PetscBool set, skip = PETSC_FALSE;
  PetscInt  maxit;
  char      test[32];
  PetscFunctionBeginUser;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetTolerances(ksp, &kspRtol, NULL, NULL, NULL));
  PetscCall(SNESGetTolerances(snes, NULL, NULL, NULL, &maxit, NULL));
  PetscCall(PetscOptionsGetString(NULL, NULL, "-snes_convergence_test", test, sizeof(test), &set));
  if (set) PetscCall(PetscStrcmp(test, "skip", &skip));
  std::string &l = r.loosened;
  if (skip) l += Format(" -snes_convergence_test skip with -snes_max_it %d", (int)maxit);
  if (rtol > kSnesRtol) l += Format(" -snes_rtol %g", (double)rtol);
  if (atol > r.defaultTarget) l += Format(" -snes_atol %g", (double)atol);
  if (kspRtol > kKspRtol) l += Format(" -ksp_rtol %g", (double)kspRtol);
  PetscReal zeroTol = kZeroTolerance;
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-snes_vi_zero_tolerance", &zeroTol, NULL));
  if (zeroTol > kZeroTolerance) l += Format(" -snes_vi_zero_tolerance %g", (double)zeroTol);
  if (!l.empty()) l.erase(0, 1);
  PetscFunctionReturn(0);
}

// The SNES tolerances (see CheckTolerances), and the line searches that work with the contact solve:
// basic (its default here), bt, l2 and cp; nleqerr compares vectors of the full and the inactive-set size,
// and shell needs code of its own.
static PetscErrorCode CheckSNESOptions(SNES snes)
{
  SNESLineSearch     ls;
  SNESLineSearchType type;
  PetscBool          ok = PETSC_FALSE;
  PetscReal          rtol, atol, stol;
  PetscInt         maxit, maxf;
  MPI_Comm         comm = PetscObjectComm((PetscObject)snes);
  PetscFunctionBeginUser;
  PetscCall(SNESGetTolerances(snes, &atol, &rtol, &stol, &maxit, &maxf));
  PetscCall(CheckTolerances(comm, "snes", rtol, atol, maxit));
  if (!(stol >= 0)) SIGNORINI_INPUT_ERROR(comm, "option -snes_stol %s: must be at least 0", Format("%g", (double)stol).c_str());
  PetscCall(SNESGetLineSearch(snes, &ls));
  PetscCall(SNESLineSearchGetType(ls, &type));
  for (const char *t : {SNESLINESEARCHBASIC, SNESLINESEARCHBT, SNESLINESEARCHL2, SNESLINESEARCHCP}) {
    PetscBool same;
    PetscCall(PetscStrcmp(type, t, &same));
    ok = (PetscBool)(ok || same);
  }
  if (!ok) SIGNORINI_INPUT_ERROR(comm, "option -snes_linesearch_type %s: the contact solve cannot use it; use basic (the default), bt, l2 or cp", type);
  PetscFunctionReturn(0);
}

// The KSP types the reduced-space solve has been seen to work with. Its Newton steps solve the block of
// the inactive set, whose size changes from step to step, through the preconditioner shell of amgreuse.h,
// which has no transpose: types that keep vectors from one solve to the next (lgmres, dgmres, fcg,
// pipegcr: vectors of the wrong size, or a crash with pipefcg), that apply the transpose (bicg, ibcgs), or
// that need a PC or matrix of their own (tsirm, fetidp) failed inside the solve, cr and cgls diverged
// where the others converge, and bcgsl's steps left ||F|| where it was though its residual fell to 1e-15.
// Any type not listed is refused up front, with the list.
static PetscErrorCode CheckKSPType(KSP ksp)
{
  static const char *const works[] = {KSPCG, KSPPIPECG, KSPGROPPCG, KSPPIPEPRCG, KSPNASH, KSPSTCG, KSPGLTR, KSPCGNE, KSPLSQR, KSPGMRES, KSPFGMRES, KSPPGMRES, KSPPIPEFGMRES, KSPGCR, KSPBCGS, KSPFBCGS, KSPPIPEBCGS, KSPCGS, KSPTFQMR, KSPTCQMR, KSPQMRCGS, KSPCHEBYSHEV, KSPRICHARDSON, KSPPREONLY};
  KSPType type;
  PetscFunctionBeginUser;
  PetscCall(KSPGetType(ksp, &type));
  std::string list;
  for (const char *t : works) {
    PetscBool same;
    PetscCall(PetscStrcmp(type, t, &same));
    if (same) PetscFunctionReturn(0);
    list += std::string(list.empty() ? "" : ", ") + t;
  }
  SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)ksp), "option -ksp_type %s: the contact solve cannot use it (its Newton steps solve systems whose size changes from step to step, through a preconditioner without a transpose); use cg (the default) or one of %s", type, list.c_str());
  PetscFunctionReturn(0);
}

// The options a contact solve reads, as inputs: the KSP's norm and tolerances, the SNES type (the bounds
// u >= psi need a VI solver; PETSc would refuse another one only inside SNESSolve), its tolerances and line
// search, and the KSP type of the reduced-space solver. Collective.
static PetscErrorCode CheckContactSolver(SNES snes)
{
  KSP       ksp;
  SNESType  type;
  PetscBool vi, rsls;
  PetscFunctionBeginUser;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(CheckKSPNorm(ksp));
  PetscCall(CheckKSPTolerances(ksp));
  PetscCall(SNESGetType(snes, &type));
  PetscCall(PetscObjectTypeCompareAny((PetscObject)snes, &vi, SNESVINEWTONRSLS, SNESVINEWTONSSLS, ""));
  if (!vi) SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)snes), "option -snes_type %s: the contact problem needs a solver for bounds: vinewtonrsls (the default) or vinewtonssls", type);
  PetscCall(CheckSNESOptions(snes));
  PetscCall(PetscObjectTypeCompare((PetscObject)snes, SNESVINEWTONRSLS, &rsls));
  if (rsls) PetscCall(CheckKSPType(ksp));
  PetscFunctionReturn(0);
}

// started: u is a start other than u_D (a guess, or StartInFullContact), whose own residual rtol must not be relative to.
static PetscErrorCode SolveVI(const Space &space, const Problem &problem, const System &sys, Vec lower, Vec u, SolveResult &r, const SolveOptions &opts, const DataScale &scale, bool started)
{
  EnergyStop          energyStop;
  KKTStop             kktStop;
  SNES                snes;
  KSP                 ksp;
  Vec                 upper, F;
  SNESConvergedReason reason;
  ResidualContext     ctx{sys.A, sys.b};
  Mat                 J = nullptr;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(u, &upper));
  PetscCall(VecDuplicate(u, &F));
  PetscCall(VecSet(upper, PETSC_INFINITY));
  PetscCall(SNESCreate(PetscObjectComm((PetscObject)u), &snes));
  PetscCall(SNESSetType(snes, SNESVINEWTONRSLS));
  PetscCall(SNESSetFunction(snes, F, Residual, &ctx));
  PetscCall(SNESSetJacobian(snes, sys.A, sys.A, ConstantJacobian, &ctx));
  PetscCall(SNESVISetVariableBounds(snes, lower, upper));
  PetscCall(SNESSetTolerances(snes, PETSC_DEFAULT, kSnesRtol, 1e-14, 200, PETSC_DEFAULT));
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(ConfigureKSP(ksp));
  AmgReuseOptions reuse = opts.amgReuse;
  reuse.goodStart       = opts.initialGuess;
  PetscCall(AmgReuseInstall(snes, reuse, &r.amg));
  PetscBool zeroTolSet; // PETSc 3.18 sets the bound tolerance only through its option
  PetscCall(PetscOptionsHasName(NULL, NULL, "-snes_vi_zero_tolerance", &zeroTolSet));
  if (!zeroTolSet) PetscCall(PetscOptionsSetValue(NULL, "-snes_vi_zero_tolerance", Format("%g", (double)kZeroTolerance).c_str()));
  const PetscErrorCode fromOptions = SNESSetFromOptions(snes);
  if (!zeroTolSet) PetscCall(PetscOptionsClearValue(NULL, "-snes_vi_zero_tolerance"));
  PetscCall(OptionsAsInputError(PetscObjectComm((PetscObject)snes), fromOptions));
  PetscCall(CheckContactSolver(snes));
  PetscBool rsls;
  PetscCall(PetscObjectTypeCompare((PetscObject)snes, SNESVINEWTONRSLS, &rsls));
  PetscCall(AdaptToSNESType(snes, sys, ctx, &J));
  PetscReal atol, rtol, stol;
  PetscInt  maxit, maxf;
  PetscCall(SNESGetTolerances(snes, &atol, &rtol, &stol, &maxit, &maxf));
  // The residual the solve has to reach: rtol relative to the start from u_D, whatever the start.
  PetscReal f0;
  PetscCall(StraightStartNorm(snes, sys, ctx, lower, &f0));
  const PetscReal target = PetscMax(atol, rtol * f0), rtolAsked = rtol, atolAsked = atol;
  r.defaultTarget        = kSnesRtol * f0;
  PetscCall(LoosenedStoppingTest(snes, atol, rtol, r));
  if (started) {
    // relative to the guess's own residual, which may be larger (a prolongated guess carries the
    // interpolation error) or far smaller (the start in full contact may solve it), rtol would stop earlier
    // than the start from u_D, or never: the target alone decides
    atol = target;
    rtol = 0;
  }
  PetscCall(SNESSetTolerances(snes, atol, rtol, stol, maxit, maxf));
  if (started) {
    // SNES's divergence test is relative to the start's own residual, which a good start (the start in
    // full contact may all but solve it) makes tiny: the first step that changes the active set then
    // "diverged" (DIVERGED_DTOL). Relative to the start from u_D, as the target is, unless the user set it.
    PetscBool set;
    PetscReal divtol, fs;
    PetscCall(PetscOptionsHasName(NULL, NULL, "-snes_divergence_tolerance", &set));
    PetscCall(SNESGetDivergenceTolerance(snes, &divtol));
    PetscCall(InactiveSetNorm(snes, ctx, u, &fs));
    if (!set && divtol > 0 && fs < f0) PetscCall(SNESSetDivergenceTolerance(snes, divtol * f0 / std::max(fs, PETSC_SMALL * f0)));
  }
  // rsls: the energies need F = A u - b and CG on blocks of A, the reduced-space solver's
  const bool energyTest = rsls && (opts.energyError > 0 || opts.startError > 0);
  if (energyTest) PetscCall(EnergyStopInstall(snes, sys, opts, scale, energyStop));
  // The full test, as the defaults or tighter: it ends when the solve's own checks pass (kktstop.h).
  if (!energyTest && r.loosened.empty()) PetscCall(KKTStopInstall(snes, space, problem, sys, lower, std::ldexp(1.0, -(int)(scale.u + scale.rows)), opts.kktTolerance, kktStop));
  kktStop.rowScale = ctx.rowScale;
  // At the floor with the default tolerances (stiff rows: kappa jumps, stretched cells) the active set has
  // settled and every further step would only repeat the last: that is the solution, and the KKT checks
  // after the solve are its test. A tolerance the user tightened below the floor is the user's to loosen.
  const bool tightened = target < r.defaultTarget * (1 - 1e-12);
  StallGuard stall; // last: it wraps the test in place
  if (rsls) PetscCall(StallGuardInstall(snes, !tightened, stall));
  // Inexact Newton: the problem is linear on the inactive set, so once the active set is right, one step
  // whose linear residual is below the target ends the solve; solving further would be wasted. The KSP
  // measures the true (unpreconditioned) residual, which is what the SNES test sees after the step.
  PetscReal kspRtol, kspAtol, kspDtol;
  PetscInt  kspMaxit;
  PetscCall(KSPGetTolerances(ksp, &kspRtol, &kspAtol, &kspDtol, &kspMaxit));
  PetscCall(KSPSetTolerances(ksp, kspRtol, PetscMax(kspAtol, 0.5 * target), kspDtol, kspMaxit));
  // From u_D the active set starts far off (see release.h); a nested-iteration guess carries a good one.
  Release release;
  if (!opts.initialGuess) {
    PetscReal zeroTol = kZeroTolerance;
    PetscCall(PetscOptionsGetReal(NULL, NULL, "-snes_vi_zero_tolerance", &zeroTol, NULL));
    PetscCall(ReleaseInstall(snes, sys.A, sys.b, lower, zeroTol, opts.release, release));
  }
  PetscCall(SNESSolve(snes, NULL, u));
  PetscCall(release.Destroy());
  PetscCall(SNESGetConvergedReason(snes, &reason));
  PetscCall(SNESGetFunctionNorm(snes, &r.residual));
  PetscCall(SNESGetIterationNumber(snes, &r.newtonIts));
  PetscCall(SNESGetLinearSolveIterations(snes, &r.kspIts));
  if (ctx.rowScale) { // the solve saw its rows scaled (AdaptToSNESType); what it reports is of A u - b
    ResidualContext rows{sys.A, sys.b};
    PetscReal       f0Rows;
    PetscCall(InactiveSetNorm(snes, rows, u, &r.residual));
    PetscCall(StraightStartNorm(snes, sys, rows, lower, &f0Rows));
    r.defaultTarget = kSnesRtol * f0Rows;
  }
  r.reason    = energyStop.stopped ? "CONVERGED_ENERGY_ERROR" : SNESConvergedReasons[reason];
  r.stoppedBy = !energyStop.stopped ? "full" : opts.energyError > 0 ? "energy_error" : "start_error";
  PetscCall(energyStop.Destroy());
  r.kktSteps = kktStop.steps;
  // The hint of a failure (read while the KSP exists). The semismooth Jacobian is not symmetric: a Krylov
  // method for symmetric operators given for it is the likely cause, and the hint names it.
  std::string hint = "; for kappa jumps or stretched cells, -options_file petsc-options/solvers/high-contrast";
  PetscBool   symmetricKrylov = PETSC_FALSE;
  if (reason <= 0 && !rsls) PetscCall(PetscObjectTypeCompareAny((PetscObject)ksp, &symmetricKrylov, KSPCG, KSPPIPECG, KSPGROPPCG, KSPPIPEPRCG, KSPNASH, KSPSTCG, KSPGLTR, KSPMINRES, ""));
  if (symmetricKrylov) {
    KSPType kspType;
    PetscCall(KSPGetType(ksp, &kspType));
    hint = Format("; -ksp_type %s needs a symmetric operator, and the Jacobian of -snes_type vinewtonssls is not one: leave -ksp_type out (GMRES) or give gmres", kspType);
  }
  PetscCall(SNESDestroy(&snes));
  PetscCall(stall.Destroy());
  PetscCall(kktStop.Destroy());
  PetscCall(MatDestroy(&J));
  PetscCall(VecDestroy(&ctx.rowScale));
  PetscCall(VecDestroy(&upper));
  PetscCall(VecDestroy(&F));
  if (stall.stopped && stall.accept) {
    r.reason    = "CONVERGED_ROUNDOFF_FLOOR";
    r.stoppedBy = "roundoff_floor";
  }
  if (stall.stopped && !stall.accept) {
    // the least tolerances worth asking for: ten times the floor, up to a power of ten
    const auto      up      = [](PetscReal t) { return std::pow((PetscReal)10, std::ceil(std::log10(t))); };
    const PetscReal atolMin = up(10 * stall.floor), rtolMin = up(10 * stall.floor / f0);
    const std::string asked = atolAsked >= rtolAsked * f0 ? Format("-snes_atol %g", (double)atolAsked) : Format("-snes_rtol %g times the residual %.3e of the start from u_D", (double)rtolAsked, (double)f0);
    SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)u), "solver: the contact solve cannot reach the residual asked for, %.2e (%s): its round-off floor is about %.2e (%" PetscInt_FMT " Newton steps on the same active set did not lower it); ask for -snes_rtol %.0e or -snes_atol %.0e or more", (double)target, asked.c_str(), (double)stall.floor, StallGuard::kStalledSteps, (double)rtolMin, (double)atolMin);
  }
  if (reason <= 0) SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)u), "solver: the contact solve (SNESVI) did not converge (%s after %" PetscInt_FMT " Newton iterations); see -snes_monitor -snes_vi_monitor -ksp_converged_reason%s", r.reason.c_str(), r.newtonIts, hint.c_str());
  PetscFunctionReturn(0);
}

PetscErrorCode MeasureKKTFromResidual(const Space &space, const System &sys, Vec u, Vec res, PetscReal loadFactor, Vec lower, Vec measure, SolveResult &r)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)u);
  const PetscScalar *ua, *ra, *la, *ma, *fa, *ba;
  PetscFunctionBeginUser;
  PetscCall(VecGetArrayRead(u, &ua));
  PetscCall(VecGetArrayRead(res, &ra));
  PetscCall(VecGetArrayRead(sys.load, &fa));
  PetscCall(VecGetArrayRead(sys.b, &ba));
  PetscReal minGap = PETSC_MAX_REAL, minP = PETSC_MAX_REAL, minM = PETSC_MAX_REAL, maxComp = 0, maxP = 0, maxGap = 0, maxFree = 0, maxLoad = 0, maxAu = 0;
  PetscReal lowU = PETSC_MAX_REAL, highU = -PETSC_MAX_REAL;
  std::vector<char> isContact(space.numOwned, 0);
  for (PetscInt i : space.contactOwned) isContact[i] = 1;
  std::vector<char> isDirichlet(space.numOwned, 0);
  for (PetscInt i : space.dirichletOwned) isDirichlet[i] = 1;
  for (PetscInt i = 0; i < space.numOwned; ++i) {
    lowU    = std::min(lowU, PetscRealPart(ua[i])), highU = std::max(highU, PetscRealPart(ua[i]));
    maxLoad = std::max(maxLoad, loadFactor * std::fabs(PetscRealPart(fa[i])));
    if (!isContact[i] && !isDirichlet[i]) maxFree = std::max(maxFree, std::fabs(PetscRealPart(ra[i])));
    if (!isDirichlet[i]) maxAu = std::max(maxAu, std::fabs(PetscRealPart(ra[i] + ba[i]))); // (A u)_i
  }
  std::vector<PetscReal> gaps;
  if (lower) {
    PetscCall(VecGetArrayRead(lower, &la));
    PetscCall(VecGetArrayRead(measure, &ma));
    for (PetscInt i : space.contactOwned) {
      const PetscReal gap = PetscRealPart(ua[i] - la[i]), p = PetscRealPart(ra[i]) / PetscRealPart(ma[i]);
      minGap  = std::min(minGap, gap);
      maxGap  = std::max(maxGap, gap);
      minP    = std::min(minP, p);
      minM    = std::min(minM, PetscRealPart(ma[i]));
      maxP    = std::max(maxP, p);
      maxComp = std::max(maxComp, std::fabs(gap * p));
      gaps.push_back(gap);
    }
    PetscCall(VecRestoreArrayRead(lower, &la));
    PetscCall(VecRestoreArrayRead(measure, &ma));
  }
  PetscCall(VecRestoreArrayRead(u, &ua));
  PetscCall(VecRestoreArrayRead(res, &ra));
  PetscCall(VecRestoreArrayRead(sys.load, &fa));
  PetscCall(VecRestoreArrayRead(sys.b, &ba));
  PetscReal mins[4] = {minGap, minP, minM, lowU}, maxs[7] = {maxComp, maxP, maxGap, highU, maxFree, maxLoad, maxAu};
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, mins, 4, MPIU_REAL, MPI_MIN, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, maxs, 7, MPIU_REAL, MPI_MAX, comm));
  const PetscReal minU = mins[3], maxU = maxs[3], maxAbsU = std::max(-minU, maxU);
  // Relative to the load, or without one (u driven by u_D or psi alone) to the terms A u it balances.
  const PetscReal stationScale = maxs[5] > 0 ? maxs[5] : maxs[6];
  r.stationarity               = stationScale > 0 ? maxs[4] / stationScale : 0;
  if (!lower) PetscFunctionReturn(0);
  r.primal          = mins[0];
  r.dual            = mins[1];
  r.complementarity = maxs[0];
  r.pressureMax     = maxs[1];
  r.gapMax          = maxs[2];
  // Active: u = psi up to round-off (the solver puts active DOFs exactly on psi; ActiveTolerance).
  const PetscReal tol = ActiveTolerance(minU, maxU);
  PetscInt        active = 0;
  for (PetscReal g : gaps) active += g <= tol;
  PetscCallMPI(MPI_Allreduce(&active, &r.active, 1, MPIU_INT, MPI_SUM, comm));
  const PetscReal scaleU = std::max(maxAbsU, r.gapMax);
  r.kktRelative          = scaleU > 0 ? std::max((PetscReal)0, -r.primal) / scaleU : 0;
  if (!(r.active > 0 && r.pressureMax > 0)) PetscFunctionReturn(0);
  r.kktRelative = std::max({r.kktRelative, -r.dual / r.pressureMax, r.complementarity / (r.pressureMax * std::max(r.gapMax, scaleU))});
  // What a residual t permits (see SolveResult): |r_i| <= t at inactive contact DOFs, and a DOF SNESVI
  // counts as active may lie up to its bound tolerance (in the units the solve worked in) above psi.
  PetscReal zeroTol = kZeroTolerance;
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-snes_vi_zero_tolerance", &zeroTol, NULL));
  const auto nearBound = [&](PetscReal tol) { return std::ldexp(tol, (int)r.scaleExponent) / std::max(r.gapMax, scaleU); };
  r.kktReached = r.residual / (mins[2] * r.pressureMax) + nearBound(zeroTol);
  r.kktDefault = r.defaultTarget / (mins[2] * r.pressureMax) + nearBound(kZeroTolerance);
  PetscFunctionReturn(0);
}

// Discrete KKT conditions on Gamma_C and stationarity on the free DOFs of the solution (the data's units).
static PetscErrorCode MeasureKKT(const Space &space, const System &sys, Vec u, Vec lower, Vec measure, SolveResult &r)
{
  Vec res;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(u, &res));
  PetscCall(MatMult(sys.A, u, res));
  PetscCall(VecAXPY(res, -1.0, sys.b));
  PetscCall(MeasureKKTFromResidual(space, sys, u, res, 1, lower, measure, r));
  PetscCall(VecDestroy(&res));
  PetscFunctionReturn(0);
}

PetscErrorCode WriteContactProfile(const Space &space, const Problem &problem, const System &sys, Vec u, const std::string &file)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)u);
  Vec                lower, measure, res, coords[3], loc;
  const PetscScalar *ua, *la, *ma, *ra, *xa[3];
  PetscScalar       *a;
  PetscMPIInt        rank, size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(VecDuplicate(u, &lower));
  PetscCall(VecDuplicate(u, &measure));
  PetscCall(VecDuplicate(u, &res));
  PetscCall(ContactLowerBound(space, problem, lower));
  PetscCall(ContactMeasure(space, problem, measure));
  PetscCall(MatMult(sys.A, u, res));
  PetscCall(VecAXPY(res, -1.0, sys.b));
  // DOF coordinates as global vectors, so they can be read at owned indices
  const std::vector<PetscReal> points = DofPoints(space);
  PetscCall(DMGetLocalVector(space.dm, &loc));
  for (PetscInt d = 0; d < space.dim; ++d) {
    PetscCall(VecDuplicate(u, &coords[d]));
    PetscCall(VecGetArray(loc, &a));
    for (PetscInt i = 0; i < space.numLocal; ++i) a[i] = points[i * space.dim + d];
    PetscCall(VecRestoreArray(loc, &a));
    PetscCall(DMLocalToGlobal(space.dm, loc, INSERT_VALUES, coords[d]));
    PetscCall(VecGetArrayRead(coords[d], &xa[d]));
  }
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscCall(VecGetArrayRead(u, &ua));
  PetscCall(VecGetArrayRead(lower, &la));
  PetscCall(VecGetArrayRead(measure, &ma));
  PetscCall(VecGetArrayRead(res, &ra));
  const int           ncol = (int)space.dim + 3;
  std::vector<double> mine;
  for (PetscInt i : space.contactOwned) {
    for (PetscInt d = 0; d < space.dim; ++d) mine.push_back(PetscRealPart(xa[d][i]));
    mine.push_back(PetscRealPart(ua[i]));
    mine.push_back(PetscRealPart(la[i]));
    mine.push_back(PetscRealPart(ra[i]) / PetscRealPart(ma[i]));
  }
  for (PetscInt d = 0; d < space.dim; ++d) {
    PetscCall(VecRestoreArrayRead(coords[d], &xa[d]));
    PetscCall(VecDestroy(&coords[d]));
  }
  PetscCall(VecRestoreArrayRead(u, &ua));
  PetscCall(VecRestoreArrayRead(lower, &la));
  PetscCall(VecRestoreArrayRead(measure, &ma));
  PetscCall(VecRestoreArrayRead(res, &ra));
  PetscCall(VecDestroy(&lower));
  PetscCall(VecDestroy(&measure));
  PetscCall(VecDestroy(&res));
  // Gather on rank 0: Gamma_C is a lower-dimensional part of the mesh, small enough to write from one rank.
  int              n = (int)mine.size();
  std::vector<int> counts(size), displs(size, 0);
  PetscCallMPI(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm));
  for (int p = 1; p < size; ++p) displs[p] = displs[p - 1] + counts[p - 1];
  std::vector<double> all(rank == 0 ? displs[size - 1] + counts[size - 1] : 0);
  PetscCallMPI(MPI_Gatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, comm));
  std::vector<std::vector<double>> rows;
  for (size_t k = 0; k + ncol <= all.size(); k += ncol) rows.emplace_back(all.begin() + k, all.begin() + k + ncol);
  std::sort(rows.begin(), rows.end());
  static const char *axes[] = {"x", "y", "z"};
  std::string        text;
  for (PetscInt d = 0; d < space.dim; ++d) text += std::string(axes[d]) + ",";
  text += "u,psi,pressure\n";
  for (const auto &r : rows) {
    for (int k = 0; k < ncol; ++k) text += Format(k + 1 < ncol ? "%.17g," : "%.17g\n", r[k]);
  }
  PetscCall(WriteFileAtomically(comm, file, text));
  PetscFunctionReturn(0);
}

// A contact solver read from the options as the solve reads them, without anything to solve.
static PetscErrorCode SolverFromOptions(MPI_Comm comm, SNES *snes)
{
  KSP ksp;
  PetscFunctionBeginUser;
  PetscCall(SNESCreate(comm, snes));
  PetscCall(SNESSetType(*snes, SNESVINEWTONRSLS));
  PetscCall(SNESGetKSP(*snes, &ksp));
  PetscCall(ConfigureKSP(ksp));
  PetscCall(OptionsAsInputError(comm, SNESSetFromOptions(*snes)));
  PetscFunctionReturn(0);
}

PetscErrorCode CheckSolverOptions(MPI_Comm comm, bool contact)
{
  SNES snes;
  KSP  ksp;
  PetscFunctionBeginUser;
  if (contact) {
    PetscCall(SolverFromOptions(comm, &snes));
    const PetscErrorCode checked = CheckContactSolver(snes);
    PetscCall(SNESDestroy(&snes));
    PetscCall(checked);
    PetscFunctionReturn(0);
  }
  PetscCall(KSPCreate(comm, &ksp));
  PetscCall(ConfigureKSP(ksp));
  PetscCall(OptionsAsInputError(comm, KSPSetFromOptions(ksp)));
  PetscErrorCode checked = CheckKSPNorm(ksp);
  if (!checked) checked = CheckKSPTolerances(ksp);
  PetscCall(KSPDestroy(&ksp));
  PetscCall(checked);
  PetscFunctionReturn(0);
}

PetscErrorCode SolverOptionsHelp(MPI_Comm comm)
{
  SNES snes;
  PetscFunctionBeginUser;
  PetscCall(SolverFromOptions(comm, &snes));
  PetscCall(SNESDestroy(&snes));
  PetscFunctionReturn(0);
}

// One CG + BoomerAMG solve of A x = b from x = 0, configured like the VI's inner KSP (ConfigureKSP, then
// the same -ksp_ and -pc_ options): the cost of a linear solve of the same operator to the same
// tolerance, measured in the same run, to compare the contact solve with.
static PetscErrorCode TimeLinearSolve(const System &sys, SolveResult &r)
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)sys.A);
  KSP            ksp;
  Vec            x;
  PetscLogDouble t0;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(sys.b, &x));
  PetscCall(VecSet(x, 0));
  PetscCall(KSPCreate(comm, &ksp));
  PetscCall(KSPSetOperators(ksp, sys.A, sys.A));
  PetscCall(ConfigureKSP(ksp));
  PetscCall(KSPSetFromOptions(ksp));
  ReleaseFreedMemory(); // the memory the contact solve freed is not this solve's to re-use
  PetscCallMPI(MPI_Barrier(comm));
  PetscCall(PetscTime(&t0));
  PetscCall(KSPSolve(ksp, sys.b, x)); // includes the preconditioner set-up
  PetscCall(SecondsSince(comm, t0, &r.linearSeconds));
  PetscCall(KSPGetIterationNumber(ksp, &r.linearKspIts));
  PetscCall(KSPDestroy(&ksp));
  PetscCall(VecDestroy(&x));
  PetscFunctionReturn(0);
}

// A piece of the domain with contact but no Dirichlet face (the whole domain without a Dirichlet part;
// CoarseFindings::contactOnly) has the constants in the kernel of its block of A: the reduced-space
// Newton step is singular there while none of its contact DOFs is active, as from u_D wherever psi lies
// below it, and the solve ended in DIVERGED_LINEAR_SOLVE. This start, the solution with all of Gamma_C
// held at psi, is one from which it is not: on such a piece the reactions on Gamma_C sum to minus the
// piece's load total, which is negative (CheckLoadTowardsObstacle), so one of them at least is positive
// and starts active; every Newton step ends with the reactions on its active set summing the same way,
// so one stays active. It is a start only: with the default linear solver (no options), kept only where
// that converges.
static PetscErrorCode StartInFullContact(const Space &space, const System &sys, Vec lower, Vec u, PetscInt *its)
{
  Mat                A;
  Vec                b, x;
  KSP                ksp;
  KSPConvergedReason reason;
  PetscInt           rstart;
  PetscFunctionBeginUser;
  PetscCall(MatDuplicate(sys.A, MAT_COPY_VALUES, &A));
  PetscCall(VecDuplicate(sys.b, &b));
  PetscCall(VecDuplicate(u, &x));
  PetscCall(VecCopy(sys.b, b));
  PetscCall(VecCopy(u, x)); // the start so far (u_D, or a guess): u_D on Gamma_D, and the KSP's first iterate
  PetscCall(VecGetOwnershipRange(u, &rstart, NULL));
  std::vector<PetscInt> rows(space.contactOwned);
  for (PetscInt &i : rows) i += rstart;
  std::vector<PetscScalar> psi(rows.size());
  PetscCall(VecGetValues(lower, (PetscInt)rows.size(), rows.data(), psi.data()));
  PetscCall(VecSetValues(x, (PetscInt)rows.size(), rows.data(), psi.data(), INSERT_VALUES));
  PetscCall(VecAssemblyBegin(x));
  PetscCall(VecAssemblyEnd(x));
  PetscCall(MatZeroRowsColumns(A, (PetscInt)rows.size(), rows.data(), 1.0, x, b));
  PetscCall(KSPCreate(PetscObjectComm((PetscObject)u), &ksp));
  PetscCall(KSPSetOperators(ksp, A, A));
  PetscCall(ConfigureKSP(ksp));
  PetscCall(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE));
  PetscCall(KSPSolve(ksp, b, x));
  PetscCall(KSPGetConvergedReason(ksp, &reason));
  PetscCall(KSPGetIterationNumber(ksp, its));
  if (reason > 0) PetscCall(VecCopy(x, u));
  PetscCall(KSPDestroy(&ksp));
  PetscCall(MatDestroy(&A));
  PetscCall(VecDestroy(&b));
  PetscCall(VecDestroy(&x));
  PetscFunctionReturn(0);
}

PetscErrorCode Solve(const Space &space, const Problem &problem, const System &sys, Vec u, SolveResult &r, const SolveOptions &opts)
{
  MPI_Comm       comm  = PetscObjectComm((PetscObject)u);
  Vec            lower = nullptr, measure = nullptr;
  PetscLogDouble t0;
  std::vector<std::string> amgDefaults;
  PetscFunctionBeginUser;
  PetscCall(AmgDefaultsInsert(space.dim, amgDefaults));
  // Only where this solve is compared with a linear one timed after it (-compare_linear), both start with
  // no freed memory to re-use (ReleaseFreedMemory). Otherwise the memory earlier stages freed is for this
  // solve to re-use: returning it to the system would make the solve and every stage after it (estimate,
  // refinement, transfer of an adaptive step) fault it in again.
  if (opts.compareLinear) ReleaseFreedMemory();
  PetscCall(StagePush(Stage::Solve));
  PetscCall(PetscTime(&t0));
  r.vi = problem.HasContact();
  if (r.vi) {
    PetscCall(VecDuplicate(u, &lower));
    PetscCall(ContactLowerBound(space, problem, lower));
  }
  PetscCall(SpaceReleaseWorkVectors(space));
  // The solvers see u and the equations shifted by a constant where the data are far from 0 against their
  // spread, and divided by their scales, powers of 2 (datascale.h).
  DataScale scale;
  Vec       savedB = nullptr;
  PetscCall(DataShiftCompute(space, sys, lower, &scale.shift));
  PetscCall(ShiftData(space, sys, lower, opts.initialGuess ? u : nullptr, scale, false, &savedB));
  PetscCall(DataScaleCompute(space, sys, lower, &scale));
  { // the semismooth solver works on u of size 2^kSslsExponent
    char      type[64] = "";
    PetscBool set;
    PetscCall(PetscOptionsGetString(NULL, NULL, "-snes_type", type, sizeof(type), &set));
    if (r.vi && set && std::string(type) == SNESVINEWTONSSLS) scale.u -= kSslsExponent;
  }
  PetscCall(ScaleData(sys, lower, opts.initialGuess ? u : nullptr, scale, false));
  r.scaleExponent = scale.u;
  // Start inside K_h: from u_D, or from the guess with u_D on Gamma_D and u >= psi on Gamma_C.
  if (!opts.initialGuess) PetscCall(VecCopy(sys.uD, u));
  PetscCall(ProjectOntoConstraints(sys, space.dirichletOwned, lower, u));
  PetscInt   startIts = 0;
  // (from a guess too: one carried from a coarser mesh, itself stopped early, may leave no contact DOF of
  // such a body active, with the same singular first step)
  const bool inContact = r.vi && HeldByContactAlone(space, problem);
  if (inContact) PetscCall(StartInFullContact(space, sys, lower, u, &startIts));
  if (r.vi) {
    PetscCall(SolveVI(space, problem, sys, lower, u, r, opts, scale, opts.initialGuess || inContact));
    r.kspIts += startIts; // the start's linear solve counts among the solve's KSP iterations
  } else PetscCall(SolveLinear(space, sys, u, r, opts.kktTolerance, std::ldexp(1.0, -(int)(scale.u + scale.rows))));
  PetscCall(SecondsSince(comm, t0, &r.solveSeconds));
  PetscCall(StagePop(Stage::Solve));
  if (opts.compareLinear) PetscCall(TimeLinearSolve(sys, r));
  PetscCall(ScaleData(sys, lower, u, scale, true));
  r.residual      = scale.Residual(r.residual);
  r.defaultTarget = scale.Residual(r.defaultTarget);
  PetscCall(AmgDefaultsRemoveUnused(amgDefaults));
  if (r.vi) { // only now: the solve's peak memory need not hold it
    PetscCall(VecDuplicate(u, &measure));
    PetscCall(ContactMeasure(space, problem, measure));
  }
  // The checks of the shifted problem, whose A u - b has no round-off floor from the shift; the same
  // conditions (u - psi and the reactions do not change with it). J(u) = J(u - s) - s chi(1).
  PetscCall(MeasureKKT(space, sys, u, lower, measure, r));
  PetscCall(DiscreteEnergy(space, sys, u, &r.energy));
  if (scale.shift != 0) {
    PetscScalar chi1;
    PetscCall(VecSum(sys.load, &chi1));
    r.energy -= scale.shift * PetscRealPart(chi1);
  }
  PetscCall(ShiftData(space, sys, lower, u, scale, true, &savedB));
  PetscCall(VecDestroy(&lower));
  PetscCall(VecDestroy(&measure));
  PetscFunctionReturn(0);
}

} // namespace signorini

namespace signorini {

PetscErrorCode ContactFields(const Space &space, const Problem &problem, const System &sys, Vec u, Vec psi, Vec pressure, Vec active)
{
  Vec                measure;
  const PetscScalar *ua, *ma;
  PetscScalar       *la, *pa, *aa;
  PetscReal          tol;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(u, &measure));
  PetscCall(ContactLowerBound(space, problem, psi));
  PetscCall(ContactMeasure(space, problem, measure));
  PetscCall(MatMult(sys.A, u, pressure));
  PetscCall(VecAXPY(pressure, -1.0, sys.b));
  PetscCall(VecSet(active, 0));
  PetscCall(ActiveToleranceOf(u, &tol)); // the rule of MeasureKKT's active count
  std::vector<char> onContact(space.numOwned, 0);
  for (PetscInt i : space.contactOwned) onContact[i] = 1;
  PetscCall(VecGetArrayRead(u, &ua));
  PetscCall(VecGetArrayRead(measure, &ma));
  PetscCall(VecGetArray(psi, &la));
  PetscCall(VecGetArray(pressure, &pa));
  PetscCall(VecGetArray(active, &aa));
  for (PetscInt i = 0; i < space.numOwned; ++i) {
    if (!onContact[i]) {
      la[i] = pa[i] = 0;
      continue;
    }
    pa[i] /= ma[i];
    aa[i] = PetscRealPart(ua[i] - la[i]) <= tol ? 1 : 0;
  }
  PetscCall(VecRestoreArrayRead(u, &ua));
  PetscCall(VecRestoreArrayRead(measure, &ma));
  PetscCall(VecRestoreArray(psi, &la));
  PetscCall(VecRestoreArray(pressure, &pa));
  PetscCall(VecRestoreArray(active, &aa));
  PetscCall(VecDestroy(&measure));
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/amgreuse.h"
#include "signorini/hierarchy.h"
#include "signorini/kkthint.h"
#include "signorini/options.h"
#include "signorini/common.h"

#include <string>
#include <vector>

namespace signorini {

PetscErrorCode AmgReuseOptionsFromCommandLine(MPI_Comm comm, AmgReuseOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Linear solves of the Newton steps of the contact solve", "signorini");
  PetscCall(OptionBool(PetscOptionsObject, "-amg_reuse", "Keep the BoomerAMG set-up across Newton steps while the inactive set changes little (off: a new set-up every step)", o.enabled));
  PetscCall(OptionReal(PetscOptionsObject, "-vi_inexact_rtol", "Relative tolerance of the linear solves of Newton steps whose active set still moves; from a nested-iteration guess, of the first step only (0: every step to the KSP tolerance)", o.inexactRtol, 0, 1));
  PetscCall(OptionString(PetscOptionsObject, "-vi_pc_type", "Preconditioner built for the inactive-set blocks of the contact solve (hypre, gamg, ..., or mg: geometric multigrid over the nested-iteration levels, -mg_levels_*/-mg_coarse_* options; -pc_type replaces the whole re-using shell; default mg, hypre on meshes of stretched cells)", o.innerType, &o.innerTypeGiven));
  PetscCall(OptionInt(PetscOptionsObject, "-amg_reuse_max_changed", "Set BoomerAMG up anew once more than this many DOFs left or joined the inactive set since its last set-up", o.maxChanged, 0, PETSC_MAX_INT));
  PetscOptionsEnd();
  // A tolerance of 1 would accept any step without a linear solve.
  if (!(o.inexactRtol < 1)) SIGNORINI_INPUT_ERROR(comm, "option -vi_inexact_rtol: must be in [0, 1), got %g", (double)o.inexactRtol);
  PetscFunctionReturn(0);
}

PetscErrorCode ChoosePreconditioner(DM mesh, AmgReuseOptions &o, PetscReal *aspect, bool *chosen)
{
  PetscFunctionBeginUser;
  PetscCall(MeshAspectRatio(mesh, aspect));
  *chosen = !o.innerTypeGiven && o.innerType == PCMG && *aspect >= kStiffAspect;
  if (*chosen) o.innerType = PCHYPRE;
  PetscFunctionReturn(0);
}

namespace {
const char *const kShellName = "BoomerAMG re-used across active sets";

struct Reuse {
  SNES            snes = nullptr;
  std::string     innerType = PCHYPRE;    // the preconditioner built for a block
  AmgReuseOptions opts;
  AmgReuseStats  *stats = nullptr;
  PC              amg   = nullptr;        // BoomerAMG of the reference block
  std::vector<PetscInt> ref;              // the reference inactive set (owned global indices, ascending)
  std::vector<PetscInt> map;              // per local entry of the current set: its position in ref, or -1
  bool            same = true;            // current set == reference set
  std::vector<PetscInt> prev;             // the previous Newton step's inactive set
  bool            havePrev = false;
  PetscReal       tightRtol = -1;         // the KSP's own rtol, for steps whose active set has settled
  bool            fresh = true;           // the current step uses a BoomerAMG set up for it
  PetscReal       rateFresh = 0, rateLast = 0; // residual reduction per CG iteration: after a set-up, and last step
  Vec             rRef = nullptr, zRef = nullptr, diag = nullptr;
};

PetscErrorCode ReuseDestroy(PC pc)
{
  Reuse *r;
  PetscFunctionBeginUser;
  PetscCall(PCShellGetContext(pc, &r));
  PetscCall(PCDestroy(&r->amg));
  PetscCall(VecDestroy(&r->rRef));
  PetscCall(VecDestroy(&r->zRef));
  PetscCall(VecDestroy(&r->diag));
  delete r;
  PetscFunctionReturn(0);
}

// Position of each entry of cur in ref (both ascending), -1 if absent; returns how many entries are in
// one set only.
PetscInt MatchSets(const PetscInt *cur, PetscInt n, const std::vector<PetscInt> &ref, std::vector<PetscInt> &map)
{
  map.assign(n, -1);
  PetscInt i = 0, j = 0, common = 0;
  const PetscInt m = (PetscInt)ref.size();
  while (i < n && j < m) {
    if (cur[i] == ref[j]) map[i++] = j++, ++common;
    else if (cur[i] < ref[j]) ++i;
    else ++j;
  }
  return (n - common) + (m - common);
}

PetscErrorCode BlockToAIJ(Mat B, Mat *aij);
PetscErrorCode BlockAdopt(Mat B, Mat aij);
PetscErrorCode BlockToHypre(Mat B, Mat *H);

// The set cur (n entries) becomes the reference of a fresh set-up.
PetscErrorCode ReuseRecord(Reuse &r, const PetscInt *cur, PetscInt n)
{
  PetscFunctionBeginUser;
  r.ref.assign(cur, cur + n);
  r.map.resize(n);
  for (PetscInt k = 0; k < n; ++k) r.map[k] = k;
  r.same  = true;
  r.fresh = true;
  if (r.stats) r.stats->setups++;
  PetscFunctionReturn(0);
}

PetscErrorCode BuildAmg(PC pc, Reuse &r, Mat P, const PetscInt *cur, PetscInt n)
{
  const char *prefix;
  PetscBool   lazy;
  Mat         H = P;
  PetscFunctionBeginUser;
  PetscCall(PCDestroy(&r.amg));
  PetscCall(VecDestroy(&r.rRef));
  PetscCall(VecDestroy(&r.zRef));
  PetscCall(PCCreate(PetscObjectComm((PetscObject)pc), &r.amg));
  PetscCall(PCGetOptionsPrefix(pc, &prefix));
  PetscCall(PCSetOptionsPrefix(r.amg, prefix));
  // A block of AmgReuseJacobian holds no entries: only a new set-up copies it (AIJ for the multigrid,
  // hypre's format for BoomerAMG), so a solve holds one copy of A_II at most.
  PetscCall(PetscObjectTypeCompare((PetscObject)P, MATSHELL, &lazy));
  if (r.innerType == PCMG && r.opts.hierarchy && !r.opts.hierarchy->P.empty()) {
    IS inactive;
    if (lazy) {
      PetscCall(BlockToAIJ(P, &H));
      PetscCall(BlockAdopt(P, H));
    }
    PetscCall(ISCreateGeneral(PetscObjectComm((PetscObject)pc), n, cur, PETSC_USE_POINTER, &inactive));
    PetscCall(OptionsAsInputError(PetscObjectComm((PetscObject)pc), HierarchyMGSetUp(r.amg, *r.opts.hierarchy, H, inactive)));
    PetscCall(ISDestroy(&inactive));
    if (lazy) PetscCall(MatDestroy(&H)); // the multigrid keeps its reference
    PetscCall(ReuseRecord(r, cur, n));
    PetscFunctionReturn(0);
  }
  if (r.innerType == PCMG) r.innerType = PCHYPRE; // no hierarchy (a single mesh, the coarsest level)
  // an unknown -vi_pc_type or -pc_ option is found here, inside the solve, but on all ranks alike
  PetscCall(OptionsAsInputError(PetscObjectComm((PetscObject)pc), PCSetType(r.amg, r.innerType.c_str())));
  if (r.innerType == PCHYPRE) PetscCall(PCHYPRESetType(r.amg, "boomeramg"));
  PetscCall(OptionsAsInputError(PetscObjectComm((PetscObject)pc), PCSetFromOptions(r.amg)));
  if (lazy) PetscCall(BlockToHypre(P, &H));
  PetscCall(PCSetOperators(r.amg, H, H));
  PetscCall(PCSetUp(r.amg));
  if (lazy) PetscCall(MatDestroy(&H)); // the PC keeps its reference
  PetscCall(ReuseRecord(r, cur, n));
  PetscFunctionReturn(0);
}

PetscErrorCode ReuseSetUp(PC pc)
{
  Reuse          *r;
  Mat             A, P;
  IS              inactive;
  Vec             x;
  const PetscInt *cur;
  PetscInt        n, N;
  PetscBool       sorted;
  PetscFunctionBeginUser;
  PetscCall(PCShellGetContext(pc, &r));
  MPI_Comm comm = PetscObjectComm((PetscObject)pc);
  PetscCall(PCGetOperators(pc, &A, &P));
  PetscCall(SNESVIGetInactiveSet(r->snes, &inactive));
  PetscCheck(inactive, comm, PETSC_ERR_ORDER, "the re-using AMG preconditioner works inside SNESVINEWTONRSLS only");
  PetscCall(SNESGetSolution(r->snes, &x));
  PetscCall(VecGetSize(x, &N));
  PetscCall(ISGetLocalSize(inactive, &n));
  PetscCall(ISSorted(inactive, &sorted));
  PetscCall(ISGetIndices(inactive, &cur));
  std::vector<PetscInt> unused;
  PetscInt changed = r->amg ? MatchSets(cur, n, r->ref, r->map) : N;
  PetscInt moved   = r->havePrev ? MatchSets(cur, n, r->prev, unused) : N;
  PetscInt local[3] = {changed, moved, sorted ? 0 : 1}, global[3];
  PetscCallMPI(MPI_Allreduce(local, global, 3, MPIU_INT, MPI_SUM, comm));
  const bool first = !r->havePrev;
  r->prev.assign(cur, cur + n);
  r->havePrev = true;
  // Inexact steps: while the active set still moves, a step only has to show where it moves next, so
  // its linear solve stops at inexactRtol; once it has settled, the solve goes to the KSP's tolerances.
  // From a good start only the first step is inexact: after it the set moves only near the free
  // boundary, and a second inexact step would only add a third Newton step.
  KSP       ksp;
  PetscReal rtol, atol, dtol;
  PetscInt  maxit;
  PetscCall(SNESGetKSP(r->snes, &ksp));
  PetscCall(KSPGetTolerances(ksp, &rtol, &atol, &dtol, &maxit));
  if (r->tightRtol < 0) r->tightRtol = rtol;
  const bool loose = r->opts.inexactRtol > 0 && (r->opts.goodStart ? first : global[1] > r->opts.maxChanged);
  PetscCall(KSPSetTolerances(ksp, loose ? PetscMax(r->opts.inexactRtol, r->tightRtol) : r->tightRtol, atol, dtol, maxit));
  // A re-used set-up whose last solve needed more than twice the iterations per digit of a fresh one
  // (rate > sqrt(rate after a set-up)) has drifted too far from the current block.
  // (see amgreuse.h for the policy)
  // A set-up is re-used only while few DOFs changed, in loose steps too: each changed DOF costs CG about
  // one to two iterations, and a loose step after a fresh set-up needs one or two in all (paper-5.1 CR
  // N = 1024 from one mesh, 9 Newton steps: loose steps re-using the set-up whatever changed took 32, 16
  // and 8 iterations, ratio to one linear solve 5.9; with a set-up each 1, and the ratio 2.6).
  const bool drifted = !r->fresh && r->rateLast > PetscSqrtReal(r->rateFresh);
  if (!r->amg || !r->opts.enabled || global[2] > 0 || drifted || global[0] > r->opts.maxChanged) PetscCall(BuildAmg(pc, *r, P, cur, n));
  else {
    r->same  = global[0] == 0;
    r->fresh = false;
    if (r->stats) r->stats->reuses++;
    PetscBool lazy, aij;
    Mat       Pref;
    PetscCall(PCGetOperators(r->amg, NULL, &Pref));
    PetscCall(PetscObjectTypeCompare((PetscObject)P, MATSHELL, &lazy));
    PetscCall(PetscObjectTypeCompareAny((PetscObject)Pref, &aij, MATSEQAIJ, MATMPIAIJ, ""));
    if (r->same && lazy && aij) PetscCall(BlockAdopt(P, Pref)); // the multigrid's copy is this block's
  }
  PetscCall(ISRestoreIndices(inactive, &cur));
  // The work vectors of a changed set (in ReuseApply) only when the set has changed: the usual case,
  // the set the AMG was built for, needs none, and at 10^7 DOFs each vector is memory worth saving.
  PetscCall(VecDestroy(&r->diag));
  if (!r->same) {
    Mat Pref;
    PetscCall(PCGetOperators(r->amg, NULL, &Pref));
    if (!r->rRef) PetscCall(MatCreateVecs(Pref, &r->rRef, &r->zRef));
    PetscCall(MatCreateVecs(P, &r->diag, NULL));
    PetscCall(MatGetDiagonal(P, r->diag));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode ReuseApply(PC pc, Vec x, Vec y)
{
  Reuse             *r;
  const PetscScalar *xa, *za, *da;
  PetscScalar       *ya, *ra;
  PetscFunctionBeginUser;
  PetscCall(PCShellGetContext(pc, &r));
  if (r->same) {
    PetscCall(PCApply(r->amg, x, y));
    PetscFunctionReturn(0);
  }
  const PetscInt n = (PetscInt)r->map.size();
  PetscCall(VecSet(r->rRef, 0));
  PetscCall(VecGetArrayRead(x, &xa));
  PetscCall(VecGetArray(r->rRef, &ra));
  for (PetscInt k = 0; k < n; ++k)
    if (r->map[k] >= 0) ra[r->map[k]] = xa[k];
  PetscCall(VecRestoreArray(r->rRef, &ra));
  PetscCall(PCApply(r->amg, r->rRef, r->zRef));
  PetscCall(VecGetArrayRead(r->zRef, &za));
  PetscCall(VecGetArrayRead(r->diag, &da));
  PetscCall(VecGetArray(y, &ya));
  for (PetscInt k = 0; k < n; ++k) ya[k] = r->map[k] >= 0 ? za[r->map[k]] : xa[k] / da[k];
  PetscCall(VecRestoreArray(y, &ya));
  PetscCall(VecRestoreArrayRead(r->diag, &da));
  PetscCall(VecRestoreArrayRead(r->zRef, &za));
  PetscCall(VecRestoreArrayRead(x, &xa));
  PetscFunctionReturn(0);
}

// Records how fast CG converged with the current set-up: (final / initial residual)^(1 / iterations).
PetscErrorCode ReusePostSolve(PC pc, KSP ksp, Vec b, Vec)
{
  Reuse    *r;
  PetscInt  its;
  PetscReal rnorm, bnorm;
  PetscFunctionBeginUser;
  PetscCall(PCShellGetContext(pc, &r));
  PetscCall(KSPGetIterationNumber(ksp, &its));
  PetscCall(KSPGetResidualNorm(ksp, &rnorm));
  PetscCall(VecNorm(b, NORM_2, &bnorm));
  if (its == 0 || !(bnorm > 0)) PetscFunctionReturn(0);
  const PetscReal rate = PetscPowReal(PetscMin(rnorm / bnorm, 1.0), 1.0 / its);
  r->rateLast = rate;
  if (r->fresh) r->rateFresh = rate;
  PetscFunctionReturn(0);
}

PetscErrorCode ReuseView(PC pc, PetscViewer viewer)
{
  Reuse *r;
  PetscFunctionBeginUser;
  PetscCall(PCShellGetContext(pc, &r));
  PetscCall(PetscViewerASCIIPrintf(viewer, "BoomerAMG re-used while at most %" PetscInt_FMT " DOFs changed between inactive sets%s\n", r->opts.maxChanged, r->same ? "" : " (now re-used for a changed set)"));
  if (r->amg) {
    PetscCall(PetscViewerASCIIPushTab(viewer));
    PetscCall(PCView(r->amg, viewer));
    PetscCall(PetscViewerASCIIPopTab(viewer));
  }
  PetscFunctionReturn(0);
}

// The operations of A that SNES and the reduced-space solver use.
template <PetscErrorCode (*Op)(Mat, Vec, Vec)>
PetscErrorCode ForwardToA(Mat J, Vec x, Vec y)
{
  Mat A;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(J, &A));
  PetscCall(Op(A, x, y));
  PetscFunctionReturn(0);
}

PetscErrorCode JacobianGetDiagonal(Mat J, Vec d)
{
  Mat A;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(J, &A));
  PetscCall(MatGetDiagonal(A, d));
  PetscFunctionReturn(0);
}

// An inactive-set block A_II that stores no entries: it acts through A on vectors that are zero outside
// I. Every Newton step gets a new block, but only a step that sets BoomerAMG up anew needs its entries
// (BlockToHypre); a step that re-uses the set-up would otherwise extract and convert a block the size of
// A only to multiply by it.
struct Block {
  Mat      A    = nullptr; // the whole operator (a reference)
  Mat      aij  = nullptr; // the block's entries where a multigrid set-up holds them (a reference), else null
  IS       rows = nullptr; // I: owned global rows, ascending (a reference)
  PetscInt rstart = 0;
  Vec      full = nullptr, fullOut = nullptr; // work vectors of A's size, zero outside I; made when first needed
};

PetscErrorCode BlockContext(Mat B, Block **b)
{
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, b));
  if (!(*b)->full) {
    PetscCall(MatCreateVecs((*b)->A, &(*b)->full, &(*b)->fullOut));
    PetscCall(VecSet((*b)->full, 0));
  }
  PetscFunctionReturn(0);
}

// Copies the entries of a block-sized vector into the rows I of an A-sized one (intoFull), or gathers
// them back. I holds owned rows only, so no communication is needed.
PetscErrorCode MoveEntries(const Block &b, Vec from, Vec to, bool intoFull)
{
  const PetscInt    *idx;
  const PetscScalar *f;
  PetscScalar       *t;
  PetscInt           n;
  PetscFunctionBeginUser;
  PetscCall(ISGetLocalSize(b.rows, &n));
  PetscCall(ISGetIndices(b.rows, &idx));
  PetscCall(VecGetArrayRead(from, &f));
  PetscCall(VecGetArray(to, &t));
  if (intoFull)
    for (PetscInt k = 0; k < n; ++k) t[idx[k] - b.rstart] = f[k];
  else
    for (PetscInt k = 0; k < n; ++k) t[k] = f[idx[k] - b.rstart];
  PetscCall(VecRestoreArray(to, &t));
  PetscCall(VecRestoreArrayRead(from, &f));
  PetscCall(ISRestoreIndices(b.rows, &idx));
  PetscFunctionReturn(0);
}

// The multigrid's copy of the block, where there is one, multiplies without the work vectors of A's size
// (the same products: the zeros outside I add nothing).
PetscErrorCode BlockMult(Mat B, Vec x, Vec y)
{
  Block *b;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, &b));
  if (b->aij) {
    PetscCall(MatMult(b->aij, x, y));
    PetscFunctionReturn(0);
  }
  PetscCall(BlockContext(B, &b));
  PetscCall(MoveEntries(*b, x, b->full, true));
  PetscCall(MatMult(b->A, b->full, b->fullOut));
  PetscCall(MoveEntries(*b, b->fullOut, y, false));
  PetscFunctionReturn(0);
}

PetscErrorCode BlockGetDiagonal(Mat B, Vec d)
{
  Block *b;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, &b));
  if (b->aij) {
    PetscCall(MatGetDiagonal(b->aij, d));
    PetscFunctionReturn(0);
  }
  PetscCall(BlockContext(B, &b));
  PetscCall(MatGetDiagonal(b->A, b->fullOut));
  PetscCall(MoveEntries(*b, b->fullOut, d, false));
  PetscFunctionReturn(0);
}

PetscErrorCode BlockDestroy(Mat B)
{
  Block *b;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, &b));
  PetscCall(VecDestroy(&b->full));
  PetscCall(VecDestroy(&b->fullOut));
  PetscCall(MatDestroy(&b->aij));
  PetscCall(ISDestroy(&b->rows));
  PetscCall(MatDestroy(&b->A));
  delete b;
  PetscFunctionReturn(0);
}

PetscErrorCode BlockView(Mat, PetscViewer viewer)
{
  PetscBool ascii;
  PetscFunctionBeginUser;
  PetscCall(PetscObjectTypeCompare((PetscObject)viewer, PETSCVIEWERASCII, &ascii));
  if (ascii) PetscCall(PetscViewerASCIIPrintf(viewer, "inactive-set block of the stiffness matrix: stores no entries, multiplies through A; copied into hypre's format only for a new BoomerAMG set-up\n"));
  PetscFunctionReturn(0);
}

// The block's entries as an AIJ matrix, for a multigrid set-up.
PetscErrorCode BlockToAIJ(Mat B, Mat *aij)
{
  Block *b;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, &b));
  PetscCall(MatCreateSubMatrix(b->A, b->rows, b->rows, MAT_INITIAL_MATRIX, aij));
  PetscFunctionReturn(0);
}

// B multiplies with aij from now on: the AIJ copy of B's own set that a multigrid holds (A is constant,
// so a copy made for the same set at an earlier step has the same entries).
PetscErrorCode BlockAdopt(Mat B, Mat aij)
{
  Block *b;
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(B, &b));
  PetscCall(PetscObjectReference((PetscObject)aij));
  PetscCall(MatDestroy(&b->aij));
  b->aij = aij;
  PetscCall(VecDestroy(&b->full));
  PetscCall(VecDestroy(&b->fullOut));
  PetscFunctionReturn(0);
}

// The block's entries in hypre's format, for a BoomerAMG set-up (the AIJ copy lives only until converted).
PetscErrorCode BlockToHypre(Mat B, Mat *H)
{
  Mat aij;
  PetscFunctionBeginUser;
  PetscCall(BlockToAIJ(B, &aij));
  PetscCall(MatConvert(aij, MATHYPRE, MAT_INITIAL_MATRIX, H));
  PetscCall(MatDestroy(&aij));
  PetscFunctionReturn(0);
}

PetscErrorCode JacobianCreateSubMatrix(Mat J, IS rows, IS cols, MatReuse reuse, Mat *B)
{
  Mat       A;
  PetscBool same;
  PetscInt  n, N;
  MPI_Comm  comm = PetscObjectComm((PetscObject)J);
  PetscFunctionBeginUser;
  PetscCall(MatShellGetContext(J, &A));
  PetscCheck(reuse == MAT_INITIAL_MATRIX, comm, PETSC_ERR_SUP, "only new blocks of the contact Jacobian");
  same = rows == cols ? PETSC_TRUE : PETSC_FALSE;
  if (!same) PetscCall(ISEqual(rows, cols, &same));
  PetscCheck(same, comm, PETSC_ERR_SUP, "only principal blocks of the contact Jacobian");
  auto *b = new Block;
  b->A    = A;
  PetscCall(PetscObjectReference((PetscObject)A));
  PetscCall(PetscObjectReference((PetscObject)rows));
  b->rows = rows;
  PetscCall(MatGetOwnershipRange(A, &b->rstart, NULL));
  PetscCall(ISGetLocalSize(rows, &n));
  PetscCall(ISGetSize(rows, &N));
  PetscCall(MatCreateShell(comm, n, n, N, N, b, B));
  PetscCall(MatShellSetOperation(*B, MATOP_MULT, (void (*)(void))BlockMult));
  PetscCall(MatShellSetOperation(*B, MATOP_MULT_TRANSPOSE, (void (*)(void))BlockMult)); // A is symmetric
  PetscCall(MatShellSetOperation(*B, MATOP_GET_DIAGONAL, (void (*)(void))BlockGetDiagonal));
  PetscCall(MatShellSetOperation(*B, MATOP_DESTROY, (void (*)(void))BlockDestroy));
  PetscCall(MatShellSetOperation(*B, MATOP_VIEW, (void (*)(void))BlockView));
  PetscCall(MatSetOption(*B, MAT_SYMMETRIC, PETSC_TRUE));
  PetscFunctionReturn(0);
}
} // namespace

PetscErrorCode AmgReuseJacobian(SNES snes, Mat A, Mat *J)
{
  KSP       ksp;
  PC        pc;
  PetscBool shell, rsls;
  PetscFunctionBeginUser;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PetscObjectTypeCompare((PetscObject)pc, PCSHELL, &shell));
  PetscCall(PetscObjectTypeCompare((PetscObject)snes, SNESVINEWTONRSLS, &rsls));
  bool lazy = false; // blocks without entries: BoomerAMG and the multigrid copy a block only to set up
  if (shell && rsls) {
    const char *name;
    PetscCall(PCShellGetName(pc, &name));
    Reuse *r;
    PetscCall(PCShellGetContext(pc, &r));
    lazy = name && std::string(name) == kShellName && (r->innerType == PCHYPRE || r->innerType == PCMG);
  }
  if (!lazy) {
    PetscCall(PetscObjectReference((PetscObject)A));
    *J = A;
    PetscFunctionReturn(0);
  }
  PetscInt m, n, M, N;
  PetscCall(MatGetLocalSize(A, &m, &n));
  PetscCall(MatGetSize(A, &M, &N));
  PetscCall(MatCreateShell(PetscObjectComm((PetscObject)A), m, n, M, N, A, J));
  PetscCall(MatShellSetOperation(*J, MATOP_MULT, (void (*)(void))ForwardToA<MatMult>));
  PetscCall(MatShellSetOperation(*J, MATOP_MULT_TRANSPOSE, (void (*)(void))ForwardToA<MatMultTranspose>));
  PetscCall(MatShellSetOperation(*J, MATOP_GET_DIAGONAL, (void (*)(void))JacobianGetDiagonal));
  PetscCall(MatShellSetOperation(*J, MATOP_CREATE_SUBMATRIX, (void (*)(void))JacobianCreateSubMatrix));
  PetscFunctionReturn(0);
}

PetscErrorCode AmgReuseInstall(SNES snes, const AmgReuseOptions &o, AmgReuseStats *stats)
{
  KSP ksp;
  PC  pc;
  PetscFunctionBeginUser;
  auto *r      = new Reuse;
  r->snes      = snes;
  r->opts      = o;
  r->stats     = stats;
  r->innerType = o.innerType;
  PetscCall(SNESGetKSP(snes, &ksp));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCSHELL));
  PetscCall(PCShellSetContext(pc, r));
  PetscCall(PCShellSetName(pc, kShellName));
  PetscCall(PCShellSetSetUp(pc, ReuseSetUp));
  PetscCall(PCShellSetApply(pc, ReuseApply));
  PetscCall(PCShellSetView(pc, ReuseView));
  PetscCall(PCShellSetPostSolve(pc, ReusePostSolve));
  PetscCall(PCShellSetDestroy(pc, ReuseDestroy));
  PetscFunctionReturn(0);
}

} // namespace signorini

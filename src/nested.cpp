#include "signorini/nested.h"
#include "signorini/options.h"
#include "signorini/stages.h"

#include <cmath>

namespace signorini {

PetscErrorCode NestedOptionsFromCommandLine(MPI_Comm comm, NestedOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Nested iteration", "signorini");
  PetscCall(OptionBool(PetscOptionsObject, "-nested", "Solve on the coarser refinement levels first and start each level from the prolongated coarser solution", o.enabled));
  PetscCall(OptionInt(PetscOptionsObject, "-nested_levels", "Coarse levels solved before the finest one (-1: all refinement levels)", o.levels, -1, PETSC_MAX_INT));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

namespace {
// Calls f(c, i, dof, lambda) for every DOF i of every fine cell c, with lambda the barycentric
// coordinates of the DOF's point in the parent cell.
template <class F>
void ForEachFineDof(const Space &coarse, const Space &fine, const std::vector<PetscInt> &parent, F f)
{
  PetscReal lambda[4], x[3];
  for (PetscInt c = 0; c < fine.NumCells(); ++c) {
    const PetscInt      pc = parent[c];
    const Space::Coords XH = coarse.X(pc);
    CellGeometry        g;
    ComputeCellGeometry(coarse.dim, XH, g);
    for (PetscInt i = 0; i < fine.Nb(); ++i) {
      const PetscInt dof = fine.Dofs(c)[i];
      fine.DofPoint(c, i, x);
      Barycentric(coarse.dim, g, XH, x, lambda);
      f(pc, dof, lambda);
    }
  }
}
} // namespace

PetscErrorCode Prolongate(const Space &coarse, Vec uH, const Space &fine, const std::vector<PetscInt> &parent, Vec uh)
{
  Vec                locH, sum, count, countGlobal;
  const PetscScalar *aH;
  PetscScalar       *s, *n;
  PetscFunctionBeginUser;
  PetscCheck((PetscInt)parent.size() == fine.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "parent map has %d entries for %d fine cells", (int)parent.size(), (int)fine.NumCells());
  PetscCheck(coarse.element == fine.element, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "prolongation between different elements");
  PetscCall(DMGetLocalVector(coarse.dm, &locH));
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locH));
  PetscCall(DMGetLocalVector(fine.dm, &sum));
  PetscCall(DMGetLocalVector(fine.dm, &count));
  PetscCall(DMGetGlobalVector(fine.dm, &countGlobal));
  PetscCall(VecSet(sum, 0));
  PetscCall(VecSet(count, 0));
  PetscCall(VecGetArrayRead(locH, &aH));
  PetscCall(VecGetArray(sum, &s));
  PetscCall(VecGetArray(count, &n));
  // Each fine cell adds the value of its parent's function at each of its DOF points, and a count; the
  // sums over all cells (and ranks) divided by the counts give the value, or, for a CR DOF on a coarse
  // face, the mean of the two sides with equal weights: exactly one fine cell on each side holds that
  // fine face. The mean is the usual choice (it does not prefer either cell and keeps affine functions,
  // which are continuous, exact); the sums make it independent of which rank owns the DOF.
  ForEachFineDof(coarse, fine, parent, [&](PetscInt pc, PetscInt dof, const PetscReal *lambda) {
    s[dof] += coarse.Value(pc, aH, lambda);
    n[dof] += 1;
  });
  PetscCall(VecRestoreArray(count, &n));
  PetscCall(VecRestoreArray(sum, &s));
  PetscCall(VecRestoreArrayRead(locH, &aH));
  PetscCall(VecSet(uh, 0));
  PetscCall(VecSet(countGlobal, 0));
  PetscCall(DMLocalToGlobal(fine.dm, sum, ADD_VALUES, uh));
  PetscCall(DMLocalToGlobal(fine.dm, count, ADD_VALUES, countGlobal));
  PetscCall(VecPointwiseDivide(uh, uh, countGlobal));
  PetscCall(DMRestoreGlobalVector(fine.dm, &countGlobal));
  PetscCall(DMRestoreLocalVector(fine.dm, &count));
  PetscCall(DMRestoreLocalVector(fine.dm, &sum));
  PetscCall(DMRestoreLocalVector(coarse.dm, &locH));
  PetscFunctionReturn(0);
}

PetscErrorCode TransferActiveSet(const Space &coarse, Vec uH, Vec lowerH, const Space &fine, const std::vector<PetscInt> &parent, Vec lowerh, Vec uh)
{
  Vec                locU, locL, flag, flagGlobal;
  const PetscScalar *aU, *aL, *fl, *lh;
  PetscScalar       *f, *a;
  PetscReal          umax;
  PetscFunctionBeginUser;
  // Active as the contact solve counts it (ActiveTolerance), relative to the size of u.
  PetscCall(VecNorm(uH, NORM_INFINITY, &umax));
  const PetscReal tol = ActiveTolerance(umax), eps = 1e-10;
  PetscCall(DMGetLocalVector(coarse.dm, &locU));
  PetscCall(DMGetLocalVector(coarse.dm, &locL));
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locU));
  PetscCall(DMGlobalToLocal(coarse.dm, lowerH, INSERT_VALUES, locL));
  PetscCall(DMGetLocalVector(fine.dm, &flag));
  PetscCall(VecSet(flag, 0));
  PetscCall(VecGetArrayRead(locU, &aU));
  PetscCall(VecGetArrayRead(locL, &aL));
  PetscCall(VecGetArray(flag, &f));
  ForEachFineDof(coarse, fine, parent, [&](PetscInt pc, PetscInt dof, const PetscReal *lambda) {
    if (fine.kindLocal[dof] != kContact) return;
    bool active = true;
    for (PetscInt j = 0; j < coarse.Nb(); ++j) {
      // P1: vertex j supports the point if lambda_j > 0; CR: face j contains it if lambda_{K(j)} = 0.
      const bool on = coarse.element == Element::P1 ? lambda[j] > eps : std::fabs(lambda[j]) < eps;
      const PetscInt J = coarse.Dofs(pc)[j];
      if (on) active = active && coarse.kindLocal[J] == kContact && PetscRealPart(aU[J] - aL[J]) <= tol;
    }
    if (active) f[dof] = 1;
  });
  PetscCall(VecRestoreArray(flag, &f));
  PetscCall(VecRestoreArrayRead(locL, &aL));
  PetscCall(VecRestoreArrayRead(locU, &aU));
  PetscCall(DMRestoreLocalVector(coarse.dm, &locL));
  PetscCall(DMRestoreLocalVector(coarse.dm, &locU));
  // Every cell that sees a DOF makes the same decision (it depends only on where the point lies in the
  // coarse mesh), so summing the flags over ranks only makes the owner see them.
  PetscCall(DMGetGlobalVector(fine.dm, &flagGlobal));
  PetscCall(VecSet(flagGlobal, 0));
  PetscCall(DMLocalToGlobal(fine.dm, flag, ADD_VALUES, flagGlobal));
  PetscCall(DMRestoreLocalVector(fine.dm, &flag));
  PetscCall(VecGetArrayRead(flagGlobal, &fl));
  PetscCall(VecGetArrayRead(lowerh, &lh));
  PetscCall(VecGetArray(uh, &a));
  for (PetscInt i = 0; i < fine.numOwned; ++i)
    if (PetscRealPart(fl[i]) > 0) a[i] = lh[i];
  PetscCall(VecRestoreArray(uh, &a));
  PetscCall(VecRestoreArrayRead(lowerh, &lh));
  PetscCall(VecRestoreArrayRead(flagGlobal, &fl));
  PetscCall(DMRestoreGlobalVector(fine.dm, &flagGlobal));
  PetscFunctionReturn(0);
}

namespace {
// uh = prolongation of the coarse level's solution with its active set (Solve projects it onto the fine
// level's constraints). Part of the Solve stage; `seconds` is its wall time (max over ranks).
PetscErrorCode ProlongateLevel(const MeshSolution &coarse, const Space &fine, const std::vector<PetscInt> &parent, const Problem &problem, Vec uh, double &seconds)
{
  Vec            lowerH, lowerh;
  PetscLogDouble t0;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t0));
  PetscCall(StagePush(Stage::Solve));
  PetscCall(Prolongate(coarse.space, coarse.u, fine, parent, uh));
  PetscCall(VecDuplicate(coarse.u, &lowerH));
  PetscCall(ContactLowerBound(coarse.space, problem, lowerH));
  PetscCall(VecDuplicate(uh, &lowerh));
  PetscCall(ContactLowerBound(fine, problem, lowerh));
  PetscCall(TransferActiveSet(coarse.space, coarse.u, lowerH, fine, parent, lowerh, uh));
  PetscCall(VecDestroy(&lowerh));
  PetscCall(VecDestroy(&lowerH));
  PetscCall(StagePop(Stage::Solve));
  PetscCall(SecondsSince(PetscObjectComm((PetscObject)uh), t0, &seconds));
  PetscFunctionReturn(0);
}

SolveResult::Level LevelSummary(const Space &space, const SolveResult &r, double setupSeconds, double prolongSeconds)
{
  SolveResult::Level info;
  info.dofs         = space.numGlobal;
  info.newtonIts    = r.newtonIts;
  info.kspIts       = r.kspIts;
  info.amgSetups    = r.amg.setups;
  info.setupSeconds = setupSeconds;
  info.solveSeconds = r.solveSeconds + prolongSeconds;
  return info;
}
} // namespace

PetscErrorCode NestedSolve(MeshLevels &levels, const Problem &problem, const PipelineOptions &o, MeshSolution &fine)
{
  const PetscInt                  L = levels.Count();
  MeshSolution                    prev;
  std::vector<SolveResult::Level> summary;
  AmgReuseStats                   amg;
  double                          prolongSeconds = 0;
  PetscFunctionBeginUser;
  PetscCheck(L >= 1, PetscObjectComm((PetscObject)fine.u), PETSC_ERR_ARG_WRONG, "nested iteration needs at least the fine level");
  // The coarse level l is solved from the prolongation of level l - 1 (l > 0), or from u_D.
  const auto fromPrevious = [&](const std::vector<PetscInt> &parent) -> std::function<PetscErrorCode(MeshSolution &)> {
    return [&](MeshSolution &cur) {
      PetscFunctionBeginUser;
      PetscCall(ProlongateLevel(prev, cur.space, parent, problem, cur.u, prolongSeconds));
      PetscCall(prev.Destroy());
      PetscFunctionReturn(0);
    };
  };
  for (PetscInt l = 0; l + 1 < L; ++l) {
    MeshSolution    cur;
    PipelineOptions lo  = o; // the user's solver settings, without the linear comparison (finest level only)
    lo.solve.compareLinear = false;
    lo.kktHint             = false;
    lo.solve.initialGuess  = false;
    lo.keepMesh            = false;
    lo.withMesh            = [&](const Space &) { return DMDestroy(&levels.dm[l]); }; // the space keeps the layout, not the mesh
    prolongSeconds         = 0;
    PetscCall(PipelineRun(levels.dm[l], problem, lo, cur, l > 0 ? fromPrevious(levels.parent[l]) : nullptr));
    std::vector<PetscInt>().swap(levels.parent[l]); // used once
    summary.push_back(LevelSummary(cur.space, cur.result, cur.setupSeconds, prolongSeconds));
    amg.setups += cur.result.amg.setups;
    amg.reuses += cur.result.amg.reuses;
    prev = std::move(cur);
  }
  PipelineOptions fo = o;
  prolongSeconds     = 0;
  if (L > 1) {
    PetscCall(fromPrevious(levels.parent[L - 1])(fine));
    std::vector<PetscInt>().swap(levels.parent[L - 1]);
    fo.solve.initialGuess = true;
  }
  PetscCall(PipelineSolve(problem, fo, fine));
  SolveResult &r = fine.result;
  summary.push_back(LevelSummary(fine.space, r, fine.setupSeconds, prolongSeconds));
  r.solveSeconds = 0;
  for (const SolveResult::Level &s : summary) r.solveSeconds += s.solveSeconds;
  r.levels = std::move(summary);
  r.amg.setups += amg.setups;
  r.amg.reuses += amg.reuses;
  PetscFunctionReturn(0);
}

} // namespace signorini

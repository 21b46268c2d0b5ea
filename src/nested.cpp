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

PetscErrorCode NestedIteration::Next(Step &step, bool &more)
{
  PetscFunctionBeginUser;
  more = ++level_ < levels_.Count();
  if (!more) PetscFunctionReturn(0);
  prolongSeconds_ = 0;
  step.mesh       = levels_.dm[level_];
  step.options    = fine_;
  if (level_ + 1 < levels_.Count()) {
    PipelineOptions &lo = step.options; // the user's solver settings, without the linear comparison (finest level only)
    lo.solve.compareLinear = false;
    lo.kktHint             = false;
    lo.estimate.enabled    = false; // the estimate is of the finest solution
    lo.solve.initialGuess  = false;
    lo.keepMesh            = false;
    lo.withMesh            = [this, l = level_](const Space &) { return DMDestroy(&levels_.dm[l]); }; // the space keeps the layout, not the mesh
  }
  PetscFunctionReturn(0);
}

PetscErrorCode NestedIteration::Carry(MeshSolution &cur, bool &carried)
{
  PetscFunctionBeginUser;
  carried = level_ > 0;
  if (!carried) PetscFunctionReturn(0);
  PetscCall(ProlongateLevel(prev_, cur.space, levels_.parent[level_], problem_, cur.u, prolongSeconds_));
  PetscCall(prev_.Destroy());
  std::vector<PetscInt>().swap(levels_.parent[level_]); // used once
  PetscFunctionReturn(0);
}

PetscErrorCode NestedIteration::Solved(MeshSolution &&m)
{
  PetscFunctionBeginUser;
  summary_.push_back(LevelSummary(m.space, m.result, m.setupSeconds, prolongSeconds_));
  if (level_ + 1 < levels_.Count()) {
    amg_.setups += m.result.amg.setups;
    amg_.reuses += m.result.amg.reuses;
    prev_ = std::move(m);
    PetscCall(SystemDestroy(prev_.sys)); // the prolongation needs the space and u only
    PetscFunctionReturn(0);
  }
  finest         = std::move(m);
  SolveResult &r = finest.result;
  r.solveSeconds = 0;
  for (const SolveResult::Level &s : summary_) r.solveSeconds += s.solveSeconds;
  r.levels = std::move(summary_);
  r.amg.setups += amg_.setups;
  r.amg.reuses += amg_.reuses;
  PetscFunctionReturn(0);
}

} // namespace signorini

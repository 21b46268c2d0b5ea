#include "signorini/nested.h"
#include "signorini/options.h"
#include "signorini/stages.h"
#include "signorini/transfer.h"

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
  step.options.solve.amgReuse.hierarchy = &hierarchy_; // complete for this level once Carry ran
  const auto withMesh = step.options.withMesh;
  step.options.withMesh = [this, l = level_, withMesh](const Space &space) -> PetscErrorCode {
    PetscCall(CoarseSpaceTransfers(l, space));
    return withMesh ? withMesh(space) : 0;
  };
  if (level_ + 1 < levels_.Count()) {
    PipelineOptions &lo = step.options; // the user's solver settings, without the linear comparison (finest level only)
    lo.solve.compareLinear = false;
    lo.kktHint             = false;
    lo.estimate.enabled    = false; // the estimate is of the finest solution
    lo.solve.initialGuess  = false;
    lo.keepMesh            = false;
    lo.withMesh            = [this, l = level_](const Space &space) -> PetscErrorCode {
      PetscCall(CoarseSpaceTransfers(l, space));
      return DMDestroy(&levels_.dm[l]); // the space keeps the layout, not the mesh
    };
  }
  PetscFunctionReturn(0);
}

// CR with -vi_pc_type mg: below each CR level the multigrid continues with P1 on the same mesh (P1 is a
// subspace of CR, so the transfer is exact: a face's value is the mean of its vertices') and then the P1
// hierarchy of the coarser meshes, whose transfers are exact too. The Galerkin operator of the CR level on
// P1 is the P1 stiffness matrix (seven entries a row in 2D) where the Galerkin products of the CR
// prolongation grow denser on every level. Built while the level's mesh exists: the P1 space of the level
// before is kept until then (the finest level's is not kept), the transfer from CR to P1 of the level
// before is replaced.
PetscErrorCode NestedIteration::CoarseSpaceTransfers(PetscInt l, const Space &space)
{
  Space          p1;
  Mat            P;
  PetscLogDouble t0;
  double         seconds;
  PetscFunctionBeginUser;
  if (fine_.solve.amgReuse.innerType != PCMG || space.element != Element::CR) PetscFunctionReturn(0);
  PetscCall(PetscTime(&t0));
  PetscCall(SpaceCreate(levels_.dm[l], Element::P1, problem_, p1));
  PetscCall(SpaceReleaseMesh(p1));
  if (!hierarchy_.P.empty()) { // the transfer of the level before from its CR space to its P1 space
    PetscCall(MatDestroy(&hierarchy_.P.back()));
    hierarchy_.P.pop_back();
  }
  if (l > 0) {
    PetscCall(ProlongationMatrix(p1Prev_, p1, levels_.parent[l], &P));
    hierarchy_.P.push_back(P);
  }
  PetscCall(P1ToCRMatrix(p1, space, &P));
  hierarchy_.P.push_back(P);
  std::swap(p1Prev_, p1);
  PetscCall(SpaceDestroy(p1));
  if (l + 1 == levels_.Count()) PetscCall(SpaceDestroy(p1Prev_)); // no level after the finest needs it
  PetscCall(SecondsSince(PetscObjectComm((PetscObject)P), t0, &seconds));
  prolongSeconds_ += seconds;
  PetscFunctionReturn(0);
}

PetscErrorCode NestedIteration::Carry(MeshSolution &cur, bool &carried)
{
  PetscFunctionBeginUser;
  carried = level_ > 0;
  if (!carried) PetscFunctionReturn(0);
  double seconds;
  PetscCall(ProlongateLevel(prev_, cur.space, levels_.parent[level_], problem_, cur.u, seconds));
  prolongSeconds_ += seconds;
  if (fine_.solve.amgReuse.innerType == PCMG && cur.space.element == Element::P1) {
    Mat            P;
    PetscLogDouble t0;
    PetscCall(PetscTime(&t0));
    PetscCall(StagePush(Stage::Solve));
    PetscCall(ProlongationMatrix(prev_.space, cur.space, levels_.parent[level_], &P));
    PetscCall(StagePop(Stage::Solve));
    hierarchy_.P.push_back(P);
    PetscCall(SecondsSince(PetscObjectComm((PetscObject)cur.u), t0, &seconds));
    prolongSeconds_ += seconds;
  }
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
  PetscCall(hierarchy_.Destroy());
  PetscCall(SpaceDestroy(p1Prev_));
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

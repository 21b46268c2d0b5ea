#include "signorini/nested.h"
#include "signorini/options.h"
#include "signorini/stages.h"
#include "signorini/transfer.h"

namespace signorini {

PetscErrorCode NestedOptionsFromCommandLine(MPI_Comm comm, NestedOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Nested iteration", "signorini");
  PetscCall(OptionBool(PetscOptionsObject, "-nested", "Solve on the coarser refinement levels first and start each level from the prolongated coarser solution (so too the first mesh of -adapt_steps, and the levels and the reference of -study_levels)", o.enabled));
  PetscCall(OptionInt(PetscOptionsObject, "-nested_levels", "Coarse levels solved before the finest one (-1: all refinement levels)", o.levels, -1, PETSC_MAX_INT));
  PetscCall(OptionEList(PetscOptionsObject, "-solve_to", "Where each level of the nested iteration stops: fmg (full multigrid: coarse levels to -solve_to_rtol of the error of their start, the finest to the full test), full (every level to the full test), discretization (every level, the finest included, and every adaptive step after the first, to -solve_to_fraction of its estimated discretization error)", {"fmg", "full", "discretization"}, o.solveTo));
  PetscCall(OptionReal(PetscOptionsObject, "-solve_to_rtol", "-solve_to fmg: a coarse level stops once its estimated algebraic error in the energy norm is this fraction of the error of its start (the prolongated guess)", o.rtol, 0, 1));
  PetscCall(OptionReal(PetscOptionsObject, "-solve_to_fraction", "-solve_to discretization: a level stops once its estimated algebraic error in the energy norm is this fraction of its estimated discretization error", o.fraction, 0, 1));
  PetscOptionsEnd();
  if (!(o.rtol > 0 && o.rtol < 1)) SIGNORINI_INPUT_ERROR(comm, "option -solve_to_rtol: must be in (0, 1), got %g", (double)o.rtol);
  if (!(o.fraction > 0 && o.fraction < 1)) SIGNORINI_INPUT_ERROR(comm, "option -solve_to_fraction: must be in (0, 1), got %g", (double)o.fraction);
  PetscFunctionReturn(0);
}

const char *SolveToName(PetscInt solveTo)
{
  static const char *names[] = {"fmg", "full", "discretization"};
  return names[solveTo];
}

PetscErrorCode ProlongateLevel(const MeshSolution &coarse, const Space &fine, const std::vector<PetscInt> &parent, const Problem &problem, Vec uh, double &seconds)
{
  PetscFunctionBeginUser;
  seconds = 0;
  PetscCall(StageTimed(PetscObjectComm((PetscObject)uh), Stage::Solve, seconds, [&]() -> PetscErrorCode {
    Vec lowerH, lowerh;
    PetscCall(Prolongate(coarse.space, coarse.u, fine, parent, uh));
    PetscCall(VecDuplicate(coarse.u, &lowerH));
    PetscCall(ContactLowerBound(coarse.space, problem, lowerH));
    PetscCall(VecDuplicate(uh, &lowerh));
    PetscCall(ContactLowerBound(fine, problem, lowerh));
    PetscCall(TransferActiveSet(coarse.space, coarse.u, lowerH, fine, parent, lowerh, uh));
    PetscCall(VecDestroy(&lowerh));
    return VecDestroy(&lowerH);
  }));
  PetscFunctionReturn(0);
}

PetscErrorCode AppendLevelTransfers(DM mesh, const Space &space, const Space *coarseP1, const std::vector<PetscInt> &parent, const Problem &problem, Hierarchy &h, Space *p1)
{
  Mat P;
  PetscFunctionBeginUser;
  if (space.element == Element::P1) {
    if (coarseP1) {
      PetscCall(ProlongationMatrix(*coarseP1, space, parent, &P));
      h.P.push_back(P);
    }
    PetscFunctionReturn(0);
  }
  PetscCall(SpaceCreateP1Of(mesh, space, problem, *p1));
  PetscCall(SpaceReleaseMesh(*p1));
  if (!h.P.empty()) { // the transfer of the level before from its CR space to its P1 space
    PetscCall(MatDestroy(&h.P.back()));
    h.P.pop_back();
  }
  if (coarseP1) {
    PetscCall(ProlongationMatrix(*coarseP1, *p1, parent, &P));
    h.P.push_back(P);
  }
  PetscCall(P1ToCRMatrix(*p1, space, &P));
  h.P.push_back(P);
  PetscFunctionReturn(0);
}

namespace {
// The energy error of P1 and CR halves with h: the predicted discretization error of a level from the
// estimate of the level before.
constexpr PetscReal kErrorPerRefinement = 0.5;

SolveResult::Level LevelSummary(const Space &space, const SolveResult &r, double setupSeconds, double prolongSeconds)
{
  SolveResult::Level info;
  info.dofs         = space.numGlobal;
  info.newtonIts    = r.newtonIts;
  info.kspIts       = r.kspIts;
  info.amgSetups    = r.amg.setups;
  info.setupSeconds = setupSeconds;
  info.solveSeconds = r.solveSeconds + prolongSeconds;
  info.stoppedBy    = r.stoppedBy;
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
  step.options.solve.amgReuse.hierarchy = &H(); // complete for this level once Carry ran
  const auto withMesh = step.options.withMesh;
  step.options.withMesh = [this, l = level_, withMesh](const Space &space) -> PetscErrorCode {
    PetscCall(CoarseSpaceTransfers(l, space));
    return withMesh ? withMesh(space) : 0;
  };
  const bool finest = level_ + 1 == levels_.Count();
  if (o_.solveTo == NestedOptions::Fmg && !finest) step.options.solve.startError = o_.rtol;
  energyError_ = o_.solveTo == NestedOptions::Discretization && level_ > 0 ? o_.fraction * kErrorPerRefinement * eta_ : 0;
  step.options.solve.energyError = energyError_;
  // the KKT conditions then hold to the algebraic error asked for (still reported), not to the full test
  if (energyError_ > 0) step.options.kktHint = false;
  if (!finest) {
    PipelineOptions &lo = step.options; // the user's solver settings, without the linear comparison (finest level only)
    lo.solve.compareLinear = false;
    lo.kktHint             = false;
    lo.estimate.enabled    = o_.solveTo == NestedOptions::Discretization; // for the next level's stopping test only
    lo.solve.initialGuess  = false;
    lo.keepMesh            = false;
    lo.withMesh            = [this, l = level_](const Space &space) -> PetscErrorCode {
      PetscCall(CoarseSpaceTransfers(l, space));
      return DMDestroy(&levels_.dm[l]); // the space keeps the layout, not the mesh
    };
  }
  PetscFunctionReturn(0);
}

// CR with -vi_pc_type mg: the transfers of AppendLevelTransfers, built while the level's mesh exists: the
// P1 space of the level before is kept until then (the finest level's is not kept).
PetscErrorCode NestedIteration::CoarseSpaceTransfers(PetscInt l, const Space &space)
{
  Space          p1;
  PetscLogDouble t0;
  double         seconds;
  PetscFunctionBeginUser;
  if (fine_.solve.amgReuse.innerType != PCMG || space.element != Element::CR) PetscFunctionReturn(0);
  PetscCall(PetscTime(&t0));
  PetscCall(AppendLevelTransfers(levels_.dm[l], space, l > 0 ? &p1Prev_ : nullptr, levels_.parent[l], problem_, H(), &p1));
  if (handover_) handover_->p1Dofs.push_back(p1.numGlobal);
  std::swap(p1Prev_, p1);
  PetscCall(SpaceDestroy(p1));
  if (l + 1 == levels_.Count()) { // the finest level's P1 space: the next transfer's coarse space, if any
    if (handover_) handover_->p1 = p1Prev_, p1Prev_ = Space(); // a copied Space still holds the handles
    else PetscCall(SpaceDestroy(p1Prev_));
  }
  PetscCall(SecondsSince(PetscObjectComm((PetscObject)space.dm), t0, &seconds));
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
  if (fine_.solve.amgReuse.innerType == PCMG && cur.space.element == Element::P1)
    PetscCall(StageTimed(PetscObjectComm((PetscObject)cur.u), Stage::Solve, prolongSeconds_, [&] { return AppendLevelTransfers(nullptr, cur.space, &prev_.space, levels_.parent[level_], problem_, H(), nullptr); }));
  PetscCall(prev_.Destroy());
  std::vector<PetscInt>().swap(levels_.parent[level_]); // used once
  PetscFunctionReturn(0);
}

PetscErrorCode NestedIteration::Solved(MeshSolution &&m)
{
  PetscFunctionBeginUser;
  summary_.push_back(LevelSummary(m.space, m.result, m.setupSeconds, prolongSeconds_));
  if (handover_ && m.space.element == Element::P1) handover_->p1Dofs.push_back(m.space.numGlobal);
  summary_.back().energyError = energyError_;
  eta_ = m.estimate.eta;
  if (level_ + 1 < levels_.Count()) {
    amg_.setups += m.result.amg.setups;
    amg_.reuses += m.result.amg.reuses;
    prev_ = std::move(m);
    PetscCall(SystemDestroy(prev_.sys)); // the prolongation needs the space and u only
    PetscFunctionReturn(0);
  }
  PetscCall(hierarchy_.Destroy()); // (empty with a handover)
  PetscCall(SpaceDestroy(p1Prev_));
  finest         = std::move(m);
  SolveResult &r = finest.result;
  r.solveSeconds = 0;
  for (const SolveResult::Level &s : summary_) r.solveSeconds += s.solveSeconds;
  r.levels   = std::move(summary_);
  r.stopping = SolveToName(o_.solveTo);
  r.amg.setups += amg_.setups;
  r.amg.reuses += amg_.reuses;
  PetscFunctionReturn(0);
}

} // namespace signorini

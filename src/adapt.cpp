#include "signorini/adapt.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/localrefine.h"
#include "signorini/mark.h"
#include "signorini/options.h"
#include "signorini/report.h"
#include "signorini/sizes.h"
#include "signorini/stages.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace signorini {

PetscErrorCode AdaptOptionsFromCommandLine(MPI_Comm comm, AdaptOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Adaptive refinement", "signorini");
  PetscCall(OptionInt(PetscOptionsObject, "-adapt_steps", "Adaptive refinements: solve, estimate, mark, refine this many times (0: none)", o.steps, 0, 1000));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_theta", "Doerfler parameter: the marked cells carry this share of the squared estimate", o.theta, 1e-6, 1));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_tol", "Stop refining once the estimate eta is below this", o.tol, 0));
  PetscCall(OptionInt(PetscOptionsObject, "-adapt_max_dofs", "Stop refining once a mesh has this many DOFs (0: no limit)", o.maxDofs, 0, PETSC_MAX_INT));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_imbalance", "Redistribute the refined mesh when max cells per rank / mean exceeds this", o.imbalance, 1));
  PetscInt how = (PetscInt)o.refinement;
  PetscCall(OptionEList(PetscOptionsObject, "-adapt_refinement", "Refinement of the marked cells: bisection of their longest edges or of all their edges (2D and 3D), or PETSc's refine_sbr (2D)", {"bisection", "bisection_all", "sbr"}, how));
  o.refinement = (LocalRefinement)how;
  PetscCall(OptionInt(PetscOptionsObject, "-adapt_reference_steps", "Go on this many steps beyond the adaptive run and measure every earlier step's energy error against the last solution (0: none)", o.referenceSteps, 0, 100));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_reference_dofs", "The reference steps also end at the first mesh with this many times the DOFs of the adaptive run's last step (0: after -adapt_reference_steps only)", o.referenceDofs, 0));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

static std::string ErrorCell(PetscReal e) { return e >= 0 ? Format("%12.4e", (double)e) : Format("%12s", "-"); }

std::string AdaptTable(const std::vector<AdaptRow> &rows)
{
  std::ostringstream o;
  const bool reference = std::any_of(rows.begin(), rows.end(), [](const AdaptRow &r) { return r.reference; });
  o << "  adaptive refinement (run: wall time up to the step's estimate; overhead: from the step's solution to the next mesh; times in s";
  o << (reference ? "; r: a step for the reference only, whose last solution the ref. error is measured against):\n" : "):\n");
  o << Format("  %5s %9s %9s %12s %12s %12s %6s %6s %8s %8s %8s %8s %8s %8s %8s %8s %8s\n", "step", "cells", "DOFs", "eta", "error", "ref. error", "Newton", "KSP", "run", "setup", "solve", "estimate", "mark", "refine", "redist", "transfer", "marked");
  for (size_t k = 0; k < rows.size(); ++k) {
    const AdaptRow &r   = rows[k];
    const bool      last = k + 1 == rows.size();
    o << Format("  %4d%s %9d %9d %12.4e %s %s %6d %6d %8.3f %8.3f %8.3f %8.3f", (int)k, r.reference ? "r" : " ", (int)r.cells, (int)r.dofs, (double)r.eta, ErrorCell(r.error).c_str(), ErrorCell(r.referenceError).c_str(), (int)r.newtonIts, (int)r.kspIts, r.runSeconds, r.setupSeconds, r.solveSeconds, r.estimateSeconds);
    if (last) o << "\n";
    else o << Format(" %8.3f %8.3f %8s %8.3f %8d\n", r.markSeconds, r.refineSeconds, r.redistributed ? Format("%.3f", r.redistributeSeconds).c_str() : "-", r.transferSeconds, (int)r.marked);
  }
  if (rows[0].nestedLevels > 0) o << Format("  step 0 solved by nested iteration over %d refinement levels of its mesh, its setup and solve times those of all of them\n", (int)rows[0].nestedLevels);
  // the steps the reference cannot reach (AdaptiveRefinement::ReferenceErrors)
  for (size_t k = rows.size() - 1; reference && k-- > 0;)
    if (rows[k].redistributed) {
      o << Format("  no ref. error for steps 0 to %d: the mesh after step %d was redistributed, so a cell's parent may be on another rank\n", (int)k, (int)k);
      break;
    }
  return o.str();
}

// The pipeline's estimate of a solution.
static PetscErrorCode PipelineIndicators(const MeshSolution &m, std::vector<PetscReal> &eta2, PetscReal &eta, double &seconds)
{
  PetscFunctionBeginUser;
  if (!m.estimate.computed) SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)m.u), "option -adapt_steps: adaptive refinement marks cells by the error estimate, which this run does not compute (-estimate none?)");
  eta2    = m.estimate.cellEta2;
  eta     = m.estimate.eta;
  seconds = m.estimate.seconds;
  PetscFunctionReturn(0);
}

AdaptiveRefinement::AdaptiveRefinement(DM mesh, const Problem &problem, const PipelineOptions &o, const AdaptOptions &a, PetscInt errorDegree, Indicators indicators) :
  mesh_(mesh), problem_(problem), options_(o), adapt_(a), errorDegree_(errorDegree), indicators_(indicators ? indicators : Indicators(PipelineIndicators))
{
  (void)PetscObjectReference((PetscObject)mesh_);
  multigrid_ = o.solve.amgReuse.innerType == PCMG && problem.HasContact();
}

AdaptiveRefinement::~AdaptiveRefinement()
{
  (void)prev_.Destroy(); // left over only when the run ended with an error
  for (MeshSolution &k : kept_) (void)k.Destroy();
  (void)hierarchy_.Destroy();
  (void)SpaceDestroy(p1_);
  (void)DMDestroy(&mesh_);
}

PetscErrorCode AdaptiveRefinement::Next(Step &step, bool &more)
{
  PetscFunctionBeginUser;
  more = !stop_;
  if (!more) PetscFunctionReturn(0);
  if (start_ == 0) PetscCall(PetscTime(&start_));
  if (nested_) { // a level of the first mesh's hierarchy; its finest level is step 0
    PetscCall(nested_->Next(step, more));
    PetscCheck(more, PetscObjectComm((PetscObject)mesh_), PETSC_ERR_PLIB, "nested iteration ended before the first mesh");
    PetscFunctionReturn(0);
  }
  if (++step_ > 0) PetscCall(Refine());
  step = Step{mesh_, options_};
  if (multigrid_) step.options.solve.amgReuse.hierarchy = &hierarchy_; // complete for this step once Carry ran
  if (adapt_.solveToFraction > 0 && step_ > 0 && !(adaptEnd_ >= 0 && step_ > adaptEnd_)) PetscCall(SolveToDiscretization(step.options));
  PetscFunctionReturn(0);
}

// On meshes adapted to the solution the energy error falls like cells^(-1/d), so the discretization error
// of the new mesh is predicted from the estimate of the one before and the growth of the cell count.
PetscErrorCode AdaptiveRefinement::SolveToDiscretization(PipelineOptions &o) const
{
  MPI_Comm comm = PetscObjectComm((PetscObject)mesh_);
  PetscInt dim, cStart, cEnd, cells;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(mesh_, &dim));
  PetscCall(DMPlexGetHeightStratum(mesh_, 0, &cStart, &cEnd));
  cells = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPIU_INT, MPI_SUM, comm));
  const AdaptRow &before = rows.back();
  o.solve.energyError    = adapt_.solveToFraction * before.eta * std::pow((PetscReal)before.cells / (PetscReal)cells, (PetscReal)1 / dim);
  o.kktHint              = false; // the KKT conditions then hold to the algebraic error asked for (still reported)
  PetscFunctionReturn(0);
}

PetscErrorCode AdaptiveRefinement::Refine()
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)mesh_);
  AdaptRow             &row  = rows.back();
  PetscLogDouble        t0;
  DM                    fine;
  std::vector<PetscInt> parent;
  std::vector<char>     corners; // where the bisection put each child's vertices (EvaluateOnCells)
  Vec                   lowerH = nullptr;
  PetscFunctionBeginUser;
  PetscCall(StagePush(Stage::Adapt));
  PetscCall(PetscTime(&t0));
  PetscCall(RefineMarked(mesh_, marked_, adapt_.refinement, &fine, &parent, &corners));
  PetscCall(SecondsSince(comm, t0, &row.refineSeconds));
  if (adapt_.memoryCheck) { // the next solve's memory, where EndWhereMemoryEnds had no growth to predict it by
    MeshCounts  counts;
    bool        fits;
    std::string need;
    PetscCall(CountMesh(fine, counts));
    const double dofs = Dofs(counts, prev_.space.element);
    PetscCall(MemoryFits(comm, SolveBytes(counts.dim, prev_.space.element, dofs), adapt_.memoryLimit, fits, need));
    if (!fits) SIGNORINI_INPUT_ERROR(comm, "adaptive step %d: the refined mesh has %.3g cells and %.3g DOFs, and %s; stop earlier (-adapt_max_dofs, -adapt_tol) or use more nodes, or -memory_check 0 to run anyway", (int)step_, counts.c, dofs, need.c_str());
  }

  PetscCall(PetscTime(&t0));
  if (problem_.HasContact()) {
    PetscCall(VecDuplicate(prev_.u, &lowerH));
    PetscCall(ContactLowerBound(prev_.space, problem_, lowerH));
  }
  PetscCall(EvaluateOnCells(prev_.space, prev_.u, lowerH, fine, parent, carried_, &corners));
  PetscCall(VecDestroy(&lowerH));
  std::vector<char>().swap(corners);
  PetscCall(SecondsSince(comm, t0, &row.transferSeconds));
  PetscCall(PetscTime(&t0));
  if (adapt_.referenceSteps > 0) { // kept for the errors against the reference
    kept_.push_back(std::move(prev_));
    parents_.resize(step_);
    parents_.push_back(parent);
  } else {
    if (multigrid_ && prev_.space.element == Element::P1) { // the multigrid's coarse P1 space, until Carry
      p1_         = prev_.space;
      prev_.space = Space(); // a copied Space still holds the handles
    }
    PetscCall(prev_.Destroy());
  }
  // the coarse P1 space of the multigrid's next transfer: p1_ (CR; P1 without kept steps) or the kept step's
  coarseP1_ = multigrid_ ? (p1_.dm ? &p1_ : &kept_.back().space) : nullptr;
  if (multigrid_) mgParent_ = std::move(parent);
  prev_ = MeshSolution();
  PetscCall(DMDestroy(&mesh_));
  mesh_ = fine;
  double seconds;
  PetscCall(SecondsSince(comm, t0, &seconds));
  row.transferSeconds += seconds;

  // Refinement leaves every new cell on its parent's rank, so the ranks where the error is refine most.
  PetscInt  cStart, cEnd, n, nmax, ntotal;
  PetscMPIInt size;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(DMPlexGetHeightStratum(mesh_, 0, &cStart, &cEnd));
  n = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(&n, &nmax, 1, MPIU_INT, MPI_MAX, comm));
  PetscCallMPI(MPI_Allreduce(&n, &ntotal, 1, MPIU_INT, MPI_SUM, comm));
  if (size > 1 && nmax > adapt_.imbalance * ntotal / size) {
    DM      dist;
    PetscSF migration;
    PetscCall(PetscTime(&t0));
    PetscCall(RedistributeMesh(mesh_, &dist, &migration));
    if (dist) {
      PetscCall(MigrateCellValues(mesh_, migration, dist, carried_));
      if (multigrid_) { // the cells leave their parents' ranks: the transfer is recorded on them and travels along
        PetscCall(StageTimed(PetscObjectComm((PetscObject)mesh_), Stage::Solve, multigridSeconds_, [&]() -> PetscErrorCode {
          PetscCall(RecordP1Transfer(*coarseP1_, mesh_, mgParent_, record_));
          mgParent_.clear();
          coarseP1_ = nullptr;
          return SpaceDestroy(p1_);
        }));
        PetscCall(MigrateCellValues(mesh_, migration, dist, record_.cells));
      }
      PetscCall(PetscSFDestroy(&migration));
      PetscCall(DMDestroy(&mesh_));
      mesh_ = dist;
      row.redistributed = true;
    }
    PetscCall(SecondsSince(comm, t0, &row.redistributeSeconds));
  }
  PetscCall(StagePop(Stage::Adapt));
  PetscFunctionReturn(0);
}

void AdaptiveRefinement::StartNested(MeshLevels &levels, const NestedOptions &o)
{
  levels_             = &levels;
  handover_.hierarchy = &hierarchy_;
  nested_             = std::make_unique<NestedIteration>(levels, problem_, options_, o, &handover_);
}

PetscErrorCode AdaptiveRefinement::Carry(MeshSolution &cur, bool &carried)
{
  PetscFunctionBeginUser;
  if (nested_) { // nested iteration builds the multigrid's transfers as it goes
    PetscCall(nested_->Carry(cur, carried));
    PetscFunctionReturn(0);
  }
  if (multigrid_) PetscCall(StageTimed(PetscObjectComm((PetscObject)mesh_), Stage::Solve, multigridSeconds_, [&] { return MultigridCarry(cur.space); }));
  carried = step_ > 0;
  if (!carried) PetscFunctionReturn(0);
  PetscCall(StageTimed(PetscObjectComm((PetscObject)mesh_), Stage::Adapt, rows.back().transferSeconds, [&]() -> PetscErrorCode {
    Vec lowerh = nullptr;
    if (problem_.HasContact()) {
      PetscCall(VecDuplicate(cur.u, &lowerh));
      PetscCall(ContactLowerBound(cur.space, problem_, lowerh));
    }
    PetscCall(ApplyCellValues(cur.space, carried_, lowerh, cur.u));
    carried_ = CellValues();
    return VecDestroy(&lowerh);
  }));
  PetscFunctionReturn(0);
}

PetscErrorCode AdaptiveRefinement::Solved(MeshSolution &&m)
{
  MPI_Comm               comm = PetscObjectComm((PetscObject)m.u);
  AdaptRow               row;
  std::vector<PetscReal> eta2;
  PetscInt               n = m.space.NumCells();
  PetscLogDouble         now, t0;
  PetscFunctionBeginUser;
  if (nested_) {
    MeshSolution s0;
    PetscCall(nested_->Solved(std::move(m)));
    if (!nested_->TakeFinest(s0)) PetscFunctionReturn(0);
    step_ = 0;
    nested_.reset();
    // the state MultigridCarry leaves after step 0, with the uniform levels below it
    levelDofs_    = std::move(handover_.p1Dofs);
    p1_           = handover_.p1;
    handover_     = NestedHandover();
    PetscCall(DMDestroy(&levels_->dm.back())); // mesh_ holds the first mesh
    PetscCall(Solved(std::move(s0)));
    PetscFunctionReturn(0);
  }
  PetscCall(PetscTime(&now));
  row.runSeconds = now - start_ - excluded_;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &row.runSeconds, 1, MPI_DOUBLE, MPI_MAX, comm));
  PetscCallMPI(MPI_Allreduce(&n, &row.cells, 1, MPIU_INT, MPI_SUM, comm));
  row.dofs         = m.space.numGlobal;
  row.newtonIts    = m.result.newtonIts;
  row.kspIts       = m.result.kspIts;
  row.nestedLevels = (PetscInt)m.result.levels.size();
  row.setupSeconds = m.result.levels.empty() ? m.setupSeconds : 0; // step 0 by nested iteration: all its levels'
  for (const SolveResult::Level &l : m.result.levels) row.setupSeconds += l.setupSeconds;
  row.solveSeconds = m.result.solveSeconds + multigridSeconds_;
  multigridSeconds_ = 0;
  if (problem_.HasExact()) {
    ErrorNorms e;
    PetscCall(PetscTime(&t0));
    PetscCall(ErrorAgainstExact(m.space, problem_, m.sys, m.u, errorDegree_, e));
    row.error = e.energy;
    PetscCall(PetscTime(&now));
    excluded_ += now - t0;
  }
  PetscCall(indicators_(m, eta2, row.eta, row.estimateSeconds));
  // The adaptive run proper ends after -adapt_steps, below -adapt_tol or at -adapt_max_dofs; the
  // reference steps follow it. An early end is said, so that fewer steps than asked for do not pass unseen.
  if (adaptEnd_ < 0) {
    const std::string at = Format("ended at step %d of -adapt_steps %d: ", (int)step_, (int)adapt_.steps);
    if (step_ >= adapt_.steps) ended = "steps";
    else if (row.eta < adapt_.tol) ended = "tol", endedText = at + Format("eta %.4e is below -adapt_tol %g", (double)row.eta, (double)adapt_.tol);
    else if (adapt_.maxDofs > 0 && row.dofs >= adapt_.maxDofs) ended = "max_dofs", endedText = at + Format("the mesh has %d DOFs, -adapt_max_dofs %d", (int)row.dofs, (int)adapt_.maxDofs);
    if (!ended.empty()) adaptEnd_ = step_;
  }
  row.reference = adaptEnd_ >= 0 && step_ > adaptEnd_;
  stop_         = adaptEnd_ >= 0 && (step_ >= adaptEnd_ + adapt_.referenceSteps || (row.reference && adapt_.referenceDofs > 0 && row.dofs >= adapt_.referenceDofs * rows[adaptEnd_].dofs));
  if (!stop_ && adapt_.memoryCheck && step_ > 0) PetscCall(EndWhereMemoryEnds(m.space, row));
  if (!stop_) {
    PetscCall(StageTimed(PetscObjectComm((PetscObject)mesh_), Stage::Adapt, row.markSeconds, [&] { return MarkDoerfler(comm, eta2, adapt_.theta, marked_, &row.marked); }));
    stop_ = row.marked == 0; // a zero estimate: nothing to refine
    if (stop_ && adaptEnd_ < 0) ended = "zero_estimate", endedText = Format("ended at step %d of -adapt_steps %d: the estimate is zero on every cell, nothing to refine", (int)step_, (int)adapt_.steps);
  }
  rows.push_back(row);
  if (!stop_) {
    prev_ = std::move(m);
    // The transfer needs the space and u only; the last step of the adaptive run stays whole, as the
    // run's result, while the reference steps go on.
    if (step_ != adaptEnd_) PetscCall(SystemDestroy(prev_.sys));
    PetscFunctionReturn(0);
  }
  // The run's result is the last step of the adaptive run; the steps after it only measured its error.
  const bool measured = adaptEnd_ >= 0 && step_ > adaptEnd_ && !kept_.empty();
  finestStep          = measured ? adaptEnd_ : step_;
  if (measured) {
    PetscCall(ReferenceErrors(m));
    PetscCall(m.Destroy());
    finest           = std::move(kept_[adaptEnd_]);
    kept_[adaptEnd_] = MeshSolution(); // a moved MeshSolution still holds the handles
  } else finest = std::move(m);
  for (MeshSolution &k : kept_) PetscCall(k.Destroy());
  kept_.clear();
  parents_.clear();
  PetscCall(hierarchy_.Destroy());
  PetscCall(SpaceDestroy(p1_));
  levelDofs_.clear();
  coarseP1_ = nullptr;
  mgParent_.clear();
  record_   = TransferRecord();
  n    = finest.space.NumCells();
  comm = PetscObjectComm((PetscObject)finest.u); // not m's, which may be gone
  PetscMPIInt size;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  cellsPerRank.assign(size, 0);
  PetscCallMPI(MPI_Allgather(&n, 1, MPIU_INT, cellsPerRank.data(), 1, MPIU_INT, comm));
  PetscFunctionReturn(0);
}

// A step whose next mesh the memory of the nodes would not hold ends the run there, with this step as its
// result (or ends its reference steps there), instead of the kernel's out-of-memory killer inside the next
// refinement or solve (paper-5.1-3d P1 with 6 reference steps: killed at about 30 M DOFs). The next DOFs
// are predicted by the largest growth of a step so far (3D steps grow the mesh 3 to 4 times, 2D ones 1.6
// to 2; the marking changes little from step to step); at step 0 none is known, and Refine checks the mesh
// it made instead. The memory: the larger of sizes.cpp's model for those DOFs and the run's own peak so far
// grown as much, which holds what the model, calibrated on uniform runs, leaves out: the steps a reference
// keeps (2D P1 280, CR 93 bytes per kept DOF), the multigrid's levels, and adapted 3D meshes' share of
// cells per DOF (manufactured-3d P1, 8 steps: 3500 bytes per DOF at 3.4 M DOFs against the model's 2000).
PetscErrorCode AdaptiveRefinement::EndWhereMemoryEnds(const Space &space, const AdaptRow &row)
{
  MPI_Comm    comm   = PetscObjectComm((PetscObject)mesh_);
  double      growth = (double)row.dofs / (double)rows.back().dofs, rssSum, rssMax;
  PetscMPIInt size;
  bool        fits;
  std::string need;
  PetscFunctionBeginUser;
  for (size_t k = 1; k < rows.size(); ++k) growth = std::max(growth, (double)rows[k].dofs / (double)rows[k - 1].dofs);
  const double next = growth * (double)row.dofs;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(PeakRSS(comm, &rssSum, &rssMax));
  const double measured = growth * std::max(0.0, rssSum - size * FixedBytes());
  PetscCall(MemoryFits(comm, std::max(SolveBytes(space.dim, space.element, next), measured), adapt_.memoryLimit, fits, need));
  if (fits) PetscFunctionReturn(0);
  stop_                  = true;
  const std::string text = Format("the next mesh would have about %.3g DOFs (%d times %.3g, the largest growth of a step so far), and %s; -memory_check 0 goes on", next, (int)row.dofs, growth, need.c_str());
  if (adaptEnd_ < 0) {
    adaptEnd_ = step_;
    ended     = "memory";
    endedText = Format("ended at step %d of -adapt_steps %d: ", (int)step_, (int)adapt_.steps) + text;
  } else {
    const std::string what = step_ == adaptEnd_ ? Format("no reference step (-adapt_reference_steps %d)", (int)adapt_.referenceSteps)
                                                : Format("reference steps ended at step %d (%d of -adapt_reference_steps %d)", (int)step_, (int)(step_ - adaptEnd_), (int)adapt_.referenceSteps);
    endedText += (endedText.empty() ? "" : "; ") + what + ": " + text;
  }
  PetscFunctionReturn(0);
}

// The multigrid's transfers up to the space of the step under way (before its solve): the P1 transfer
// from the step before, assembled from its record, and for CR the P1 space of this step's mesh, kept for
// the next step's record, and the transfer from it to CR, which replaces the one of the step before (as
// nested iteration does, nested.h: P1 is a subspace of CR, and the Galerkin operators of the P1 levels
// stay as sparse as P1 stiffness matrices).
PetscErrorCode AdaptiveRefinement::MultigridCarry(const Space &space)
{
  const bool   cr = space.element == Element::CR;
  Space        fineP1;
  const Space *p1 = cr ? &fineP1 : &space;
  Mat          P;
  PetscFunctionBeginUser;
  if (cr) {
    PetscCall(SpaceCreateP1Of(mesh_, space, problem_, fineP1));
    PetscCall(SpaceReleaseMesh(fineP1));
    if (!hierarchy_.P.empty()) { // the transfer from P1 to CR of the step before
      PetscCall(MatDestroy(&hierarchy_.P.back()));
      hierarchy_.P.pop_back();
    }
  }
  if (step_ > 0) {
    // From the coarse P1 space to the fine one directly, as nested iteration builds it, where the fine
    // cells stayed on their parents' ranks; the same matrix as the record's (unit_hierarchy), built per
    // fine vertex instead of per fine cell and vertex, without the mesh.
    if (coarseP1_) PetscCall(ProlongationMatrix(*coarseP1_, *p1, mgParent_, &P));
    else PetscCall(AssembleP1Transfer(record_, *p1, &P));
    record_   = TransferRecord();
    mgParent_ = std::vector<PetscInt>();
    coarseP1_ = nullptr;
    PetscCall(MultigridLevel(P, p1->numGlobal));
  } else levelDofs_.assign(1, p1->numGlobal);
  PetscCall(SpaceDestroy(p1_)); // the coarse one, if it was not a kept step's
  if (cr) {
    p1_ = fineP1; // for the next step's transfer
    PetscCall(P1ToCRMatrix(p1_, space, &P));
    hierarchy_.P.push_back(P);
  }
  PetscFunctionReturn(0);
}

// Adds the P1 level of `dofs` DOFs above the kept ones, P the transfer to it from the level of the step
// before. An adaptive step refines only part of the mesh, so the levels grow slowly (about 1.7 times the
// DOFs per step on stiff-below-h2) and a V-cycle over all of them would cost several times the finest
// level's smoothing. The top kept level is dropped when it has more than half the DOFs of the new one and
// the level below it at least a quarter (the transfers around it are composed, exactly: the P1 spaces are
// nested); the level below then becomes the next to the new one. So the kept levels grow by factors of
// about 2 to 4 (only the top pair may be closer), and a V-cycle costs about twice the finest level's
// smoothing. Without the lower bound every new level would replace the one below it, leaving the
// coarsest level right under the finest (CG iterations per Newton step on stiff-below-h2 P1 rose from 4
// to 38 over 12 steps).
PetscErrorCode AdaptiveRefinement::MultigridLevel(Mat P, PetscInt dofs)
{
  PetscFunctionBeginUser;
  const size_t n = levelDofs_.size();
  if (n >= 2 && 2 * levelDofs_[n - 1] > dofs && 4 * levelDofs_[n - 2] >= dofs) {
    Mat C;
    PetscCall(MatMatMult(P, hierarchy_.P.back(), MAT_INITIAL_MATRIX, PETSC_DEFAULT, &C));
    PetscCall(MatDestroy(&P));
    PetscCall(MatDestroy(&hierarchy_.P.back()));
    hierarchy_.P.back() = C;
    levelDofs_.back()   = dofs;
  } else {
    hierarchy_.P.push_back(P);
    levelDofs_.push_back(dofs);
  }
  PetscFunctionReturn(0);
}

// Every kept step against the last solution, through the parent maps composed step by step down from
// the reference's cells; a redistributed mesh ends the chain (its cells are no longer beside their parents).
PetscErrorCode AdaptiveRefinement::ReferenceErrors(const MeshSolution &ref)
{
  std::vector<PetscInt> map(ref.space.NumCells());
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < (PetscInt)map.size(); ++c) map[c] = c;
  for (PetscInt k = (PetscInt)kept_.size() - 1; k >= 0 && !rows[k].redistributed; --k) {
    ErrorNorms e;
    for (PetscInt &c : map) c = parents_[k + 1][c];
    PetscCall(ErrorAgainstReference(kept_[k].space, kept_[k].u, ref.space, ref.sys, ref.u, map, e));
    rows[k].referenceError = e.energy;
  }
  PetscFunctionReturn(0);
}

} // namespace signorini

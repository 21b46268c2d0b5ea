#include "signorini/adapt.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/localrefine.h"
#include "signorini/mark.h"
#include "signorini/options.h"

#include <algorithm>
#include <sstream>

namespace signorini {

PetscErrorCode AdaptOptionsFromCommandLine(MPI_Comm comm, AdaptOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Adaptive refinement", "signorini");
  PetscCall(OptionInt(PetscOptionsObject, "-adapt_steps", "Adaptive refinements: solve, estimate, mark, refine this many times (0: none)", o.steps, 0, 1000));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_theta", "Doerfler parameter: the marked cells carry this share of the squared estimate", o.theta, 1e-6, 1));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_tol", "Stop refining once the estimate eta is below this", o.tol, 0));
  PetscCall(OptionReal(PetscOptionsObject, "-adapt_imbalance", "Redistribute the refined mesh when max cells per rank / mean exceeds this", o.imbalance, 1));
  PetscInt how = (PetscInt)o.refinement;
  PetscCall(OptionEList(PetscOptionsObject, "-adapt_refinement", "Refinement of the marked cells: bisection of marked edges (2D and 3D) or PETSc's refine_sbr (2D)", {"bisection", "sbr"}, how));
  o.refinement = (LocalRefinement)how;
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

std::string AdaptTable(const std::vector<AdaptRow> &rows)
{
  std::ostringstream o;
  o << "  adaptive refinement (overhead: from the step's solution to the next mesh; times in s):\n";
  o << Format("  %4s %9s %9s %12s %12s %6s %6s %8s %8s %8s %8s %8s %8s %8s\n", "step", "cells", "DOFs", "eta", "error", "Newton", "KSP", "solve", "estimate", "mark", "refine", "redist", "transfer", "marked");
  for (size_t k = 0; k < rows.size(); ++k) {
    const AdaptRow &r   = rows[k];
    const bool      last = k + 1 == rows.size();
    const std::string err = r.error >= 0 ? Format("%12.4e", (double)r.error) : Format("%12s", "-");
    o << Format("  %4d %9d %9d %12.4e %s %6d %6d %8.3f %8.3f", (int)k, (int)r.cells, (int)r.dofs, (double)r.eta, err.c_str(), (int)r.newtonIts, (int)r.kspIts, r.solveSeconds, r.estimateSeconds);
    if (last) o << "\n";
    else o << Format(" %8.3f %8.3f %8s %8.3f %8d\n", r.markSeconds, r.refineSeconds, r.redistributed ? Format("%.3f", r.redistributeSeconds).c_str() : "-", r.transferSeconds, (int)r.marked);
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
}

AdaptiveRefinement::~AdaptiveRefinement()
{
  (void)prev_.Destroy(); // left over only when the run ended with an error
  (void)DMDestroy(&mesh_);
}

PetscErrorCode AdaptiveRefinement::Next(Step &step, bool &more)
{
  PetscFunctionBeginUser;
  more = !stop_;
  if (!more) PetscFunctionReturn(0);
  if (++step_ > 0) PetscCall(Refine());
  step = Step{mesh_, options_};
  PetscFunctionReturn(0);
}

PetscErrorCode AdaptiveRefinement::Refine()
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)mesh_);
  AdaptRow             &row  = rows.back();
  PetscLogDouble        t0;
  DM                    fine;
  std::vector<PetscInt> parent;
  Vec                   lowerH = nullptr;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t0));
  PetscCall(RefineMarked(mesh_, marked_, adapt_.refinement, &fine, &parent));
  PetscCall(SecondsSince(comm, t0, &row.refineSeconds));

  PetscCall(PetscTime(&t0));
  if (problem_.HasContact()) {
    PetscCall(VecDuplicate(prev_.u, &lowerH));
    PetscCall(ContactLowerBound(prev_.space, problem_, lowerH));
  }
  PetscCall(EvaluateOnCells(prev_.space, prev_.u, lowerH, fine, parent, carried_));
  PetscCall(VecDestroy(&lowerH));
  PetscCall(prev_.Destroy());
  prev_ = MeshSolution();
  PetscCall(DMDestroy(&mesh_));
  mesh_ = fine;
  PetscCall(SecondsSince(comm, t0, &row.transferSeconds));

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
      PetscCall(PetscSFDestroy(&migration));
      PetscCall(DMDestroy(&mesh_));
      mesh_ = dist;
      row.redistributed = true;
    }
    PetscCall(SecondsSince(comm, t0, &row.redistributeSeconds));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode AdaptiveRefinement::Carry(MeshSolution &cur, bool &carried)
{
  PetscLogDouble t0;
  Vec            lowerh = nullptr;
  double         seconds;
  PetscFunctionBeginUser;
  carried = step_ > 0;
  if (!carried) PetscFunctionReturn(0);
  PetscCall(PetscTime(&t0));
  if (problem_.HasContact()) {
    PetscCall(VecDuplicate(cur.u, &lowerh));
    PetscCall(ContactLowerBound(cur.space, problem_, lowerh));
  }
  PetscCall(ApplyCellValues(cur.space, carried_, lowerh, cur.u));
  PetscCall(VecDestroy(&lowerh));
  carried_ = CellValues();
  PetscCall(SecondsSince(PetscObjectComm((PetscObject)cur.u), t0, &seconds));
  rows.back().transferSeconds += seconds;
  PetscFunctionReturn(0);
}

PetscErrorCode AdaptiveRefinement::Solved(MeshSolution &&m)
{
  MPI_Comm               comm = PetscObjectComm((PetscObject)m.u);
  AdaptRow               row;
  std::vector<PetscReal> eta2;
  PetscInt               n = m.space.NumCells();
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Allreduce(&n, &row.cells, 1, MPIU_INT, MPI_SUM, comm));
  row.dofs         = m.space.numGlobal;
  row.newtonIts    = m.result.newtonIts;
  row.kspIts       = m.result.kspIts;
  row.solveSeconds = m.result.solveSeconds;
  if (problem_.HasExact()) {
    ErrorNorms e;
    PetscCall(ErrorAgainstExact(m.space, problem_, m.sys, m.u, errorDegree_, e));
    row.error = e.energy;
  }
  PetscCall(indicators_(m, eta2, row.eta, row.estimateSeconds));
  stop_ = step_ >= adapt_.steps || row.eta < adapt_.tol;
  if (!stop_) {
    PetscLogDouble t0;
    PetscCall(PetscTime(&t0));
    PetscCall(MarkDoerfler(comm, eta2, adapt_.theta, marked_, &row.marked));
    PetscCall(SecondsSince(comm, t0, &row.markSeconds));
    stop_ = row.marked == 0; // a zero estimate: nothing to refine
  }
  rows.push_back(row);
  if (stop_) {
    cellsPerRank.resize(0);
    PetscMPIInt size;
    PetscCallMPI(MPI_Comm_size(comm, &size));
    cellsPerRank.resize(size);
    PetscCallMPI(MPI_Allgather(&n, 1, MPIU_INT, cellsPerRank.data(), 1, MPIU_INT, comm));
    finest = std::move(m);
    PetscFunctionReturn(0);
  }
  prev_ = std::move(m);
  PetscCall(SystemDestroy(prev_.sys)); // the transfer needs the space and u only
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/study.h"
#include "signorini/options.h"
#include "signorini/output.h"
#include "signorini/pipeline.h"
#include "signorini/report.h"
#include "signorini/stages.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace signorini {

static std::string   ProfileBase(const std::string &prefix, Element e) { return prefix + "-" + ElementName(e); }
static OutputOptions ProfileOutput(const std::string &prefix, Element e, const Problem &problem) { return OutputOptions{ProfileBase(prefix, e) + ".h5", problem.HasContact(), e == Element::CR}; }

PetscErrorCode StudyOptionsFromCommandLine(MPI_Comm comm, const Problem &problem, StudyOptions &o)
{
  PetscInt    ref      = (PetscInt)o.referenceElement;
  std::string elements = "p1,cr";
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Convergence study", "signorini");
  PetscCall(OptionInt(PetscOptionsObject, "-study_levels", "Solve on this many nested mesh levels (0: a single run)", o.levels, 0, PETSC_MAX_INT));
  PetscCall(OptionInt(PetscOptionsObject, "-reference_refine", "Measure errors against a reference this many refinements beyond the finest level (0: none)", o.referenceRefine, 0, PETSC_MAX_INT));
  PetscCall(OptionEList(PetscOptionsObject, "-reference_space", "Element of the reference solution", {"p1", "cr"}, ref));
  PetscCall(OptionString(PetscOptionsObject, "-study_spaces", "Elements studied, comma separated", elements));
  PetscCall(OptionString(PetscOptionsObject, "-study_output", "Write the study table as JSON to this file", o.file));
  PetscCall(OptionString(PetscOptionsObject, "-study_profiles", "On the finest level write PREFIX-<element>.h5 and PREFIX-<element>-contact.csv", o.profiles));
  PetscOptionsEnd();
  o.referenceElement = (Element)ref;
  o.elements.clear();
  std::stringstream ss(elements);
  for (std::string item; std::getline(ss, item, ',');) {
    item = Trim(item);
    std::transform(item.begin(), item.end(), item.begin(), [](unsigned char ch) { return (char)std::tolower(ch); });
    Element e;
    if (item == "p1") e = Element::P1;
    else if (item == "cr") e = Element::CR;
    else SIGNORINI_INPUT_ERROR(comm, "option -study_spaces: unknown element '%s' (p1 or cr)", item.c_str());
    // each element once: a second study of it would only repeat the first (and write the same files)
    if (std::find(o.elements.begin(), o.elements.end(), e) != o.elements.end()) SIGNORINI_INPUT_ERROR(comm, "option -study_spaces: element %s is named twice", item.c_str());
    o.elements.push_back(e);
  }
  if (o.elements.empty()) SIGNORINI_INPUT_ERROR(comm, "option -study_spaces: no element to study (p1, cr, or p1,cr)");
  if (!o.file.empty()) PetscCall(FileClaim(comm, "-study_output", o.file));
  if (!o.profiles.empty())
    for (Element e : o.elements) { // the files the finest level writes (ConvergenceStudy::Row)
      PetscCall(OutputClaim(comm, "-study_profiles", ProfileOutput(o.profiles, e, problem)));
      if (problem.HasContact()) PetscCall(FileClaim(comm, "-study_profiles", ProfileBase(o.profiles, e) + "-contact.csv"));
    }
  PetscFunctionReturn(0);
}

static PetscReal Rate(PetscReal e0, PetscReal e1, PetscReal h0, PetscReal h1) { return std::log(e0 / e1) / std::log(h0 / h1); }

static PetscErrorCode PrintTable(MPI_Comm comm, const std::vector<StudyRow> &rows)
{
  std::ostringstream o;
  PetscFunctionBeginUser;
  o << Format("%-4s %6s %10s %9s %9s %12s %6s %12s %6s %12s %6s %12s %6s %6s %6s %6s %9s %9s %9s\n", "elem", "N", "h", "cells", "DOFs", "L2", "rate", "H1semi", "rate", "H1", "rate", "eta", "rate", "eta/E", "Newton", "KSP", "solve[s]", "total[s]", "peak[MB]");
  for (size_t i = 0; i < rows.size(); ++i) {
    const StudyRow   &r   = rows[i];
    const ErrorNorms &e   = r.hasReference ? r.reference : r.exact;
    const bool        has = r.hasReference || r.hasExact;
    std::string       rates[4] = {"", "", "", ""};
    const bool        after    = i > 0 && rows[i - 1].element == r.element; // a finer level of the element
    if (after && r.estimate.computed && rows[i - 1].estimate.computed) rates[3] = Format("%.2f", (double)Rate(rows[i - 1].estimate.eta, r.estimate.eta, rows[i - 1].h, r.h));
    if (after && has) {
      const ErrorNorms &p = rows[i - 1].hasReference ? rows[i - 1].reference : rows[i - 1].exact;
      rates[0]            = Format("%.2f", (double)Rate(p.l2, e.l2, rows[i - 1].h, r.h));
      rates[1]            = Format("%.2f", (double)Rate(p.h1semi, e.h1semi, rows[i - 1].h, r.h));
      rates[2]            = Format("%.2f", (double)Rate(p.h1, e.h1, rows[i - 1].h, r.h));
    }
    // the efficiency index eta / energy error, against the exact solution or the reference
    const std::string eta = r.estimate.computed ? Format("%.5e", (double)r.estimate.eta) : "", index = r.estimate.computed && has ? Format("%.2f", (double)(r.estimate.eta / e.energy)) : "";
    const auto  err = [has](PetscReal v) { return has ? Format("%.5e", (double)v) : std::string("-"); };
    o << Format("%-4s %6d %10.4g %9d %9d %12s %6s %12s %6s %12s %6s %12s %6s %6s %6d %6d %9.3f %9.3f %9.1f\n", r.element.c_str(), (int)r.N, (double)r.h, (int)r.cells, (int)r.dofs, err(e.l2).c_str(), rates[0].c_str(), err(e.h1semi).c_str(), rates[1].c_str(),
                err(e.h1).c_str(), rates[2].c_str(), eta.c_str(), rates[3].c_str(), index.c_str(), (int)r.solve.newtonIts, (int)r.solve.kspIts, r.solveSeconds, r.totalSeconds, r.peakRSS / 1048576.0);
  }
  const bool carried = std::any_of(rows.begin(), rows.end(), [](const StudyRow &r) { return r.carried; });
  o << (carried ? "(each level from the one before; total: the run up to the level, mesh, set-up, solve and estimate of its element's levels so far)\n" : "(each level from u_D; total: mesh, set-up, solve and estimate of the level)\n");
  PetscCall(PetscPrintf(comm, "%s", o.str().c_str()));
  PetscFunctionReturn(0);
}

static std::string JsonErrors(const ErrorNorms &e) { return Format("{\"l2\": %.17g, \"h1_semi\": %.17g, \"h1\": %.17g, \"energy\": %.17g}", (double)e.l2, (double)e.h1semi, (double)e.h1, (double)e.energy); }

static PetscErrorCode WriteJSON(MPI_Comm comm, const std::string &file, const std::string &scene, const StudyOptions &o, PetscInt refN, PetscInt refDofs, PetscInt refNestedLevels, const std::vector<StudyRow> &rows)
{
  std::ostringstream j;
  PetscMPIInt        size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  j << "{\n  \"scene\": \"" << scene << "\",\n  \"ranks\": " << size << ",\n";
  if (o.referenceRefine > 0) j << "  \"reference\": {\"element\": \"" << ElementName(o.referenceElement) << "\", \"N\": " << refN << ", \"dofs\": " << refDofs << ", \"nested_levels\": " << refNestedLevels << "},\n";
  j << "  \"rows\": [\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const StudyRow &r = rows[i];
    j << "    {\"element\": \"" << r.element << "\", \"level\": " << r.level << ", \"N\": " << r.N << Format(", \"h\": %.17g", (double)r.h) << ", \"cells\": " << r.cells << ", \"dofs\": " << r.dofs;
    j << ", \"newton_iterations\": " << r.solve.newtonIts << ", \"ksp_iterations\": " << r.solve.kspIts << ", \"converged_reason\": \"" << r.solve.reason << "\"";
    j << ", \"carried\": " << (r.carried ? "true" : "false") << ", \"active\": " << r.solve.active << Format(", \"energy\": %.17g", (double)r.solve.energy);
    if (r.hasExact) j << ", \"error_exact\": " << JsonErrors(r.exact);
    if (r.hasReference) j << ", \"error_reference\": " << JsonErrors(r.reference);
    if (r.estimate.computed) j << ", \"estimate\": " << EstimateJSON(r.estimate, r.hasReference ? &r.reference : r.hasExact ? &r.exact : nullptr);
    j << Format(", \"solve_seconds\": %.6g, \"total_seconds\": %.6g, \"peak_rss_bytes\": %.0f}", r.solveSeconds, r.totalSeconds, r.peakRSS) << (i + 1 < rows.size() ? "," : "") << "\n";
  }
  j << "  ]\n}\n";
  PetscCall(WriteFileAtomically(comm, file, j.str()));
  PetscFunctionReturn(0);
}

PetscErrorCode ConvergenceStudy::Refine()
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)base_);
  PetscLogDouble t0, t1;
  PetscFunctionBeginUser;
  // Without an exact solution or a reference the rows measure the error by the estimate alone.
  if (!problem_.HasExact() && o_.referenceRefine == 0 && !estimate_.enabled)
    SIGNORINI_INPUT_ERROR(comm, "option -estimate none: the scene has no exact solution and the study no reference (-reference_refine m > 0), so nothing would measure its error");
  levels_.assign(Finest() + 1, nullptr);
  parent_.assign(Finest() + 1, {});
  meshSeconds_.assign(Finest() + 1, 0.0);
  PetscCall(PetscObjectReference((PetscObject)base_));
  levels_[0] = base_;
  for (PetscInt l = 1; l <= Finest(); ++l) {
    PetscCall(PetscTime(&t0));
    PetscCall(MeshRefine(levels_[l - 1], &levels_[l], &parent_[l]));
    PetscCall(PetscTime(&t1));
    meshSeconds_[l] = meshSeconds_[l - 1] + (t1 - t0);
  }
  PetscFunctionReturn(0);
}

// Each solve with the user's solver settings and without the KKT warning; the finest level of each
// element keeps its mesh when its profile is written (the HDF5 output needs it).
PetscErrorCode ConvergenceStudy::Next(Step &step, bool &more)
{
  PetscFunctionBeginUser;
  if (!refNested_) {
    if (step_ < 0) PetscCall(Refine());
    ++step_;
    more = step_ < NumRows() || (step_ == NumRows() && o_.referenceRefine > 0);
    if (!more) PetscFunctionReturn(0);
    if (step_ == NumRows() && Carrying()) PetscCall(StartReference());
  }
  if (refNested_) { // a level of the reference's nested iteration
    PetscCall(refNested_->Next(step, more));
    PetscFunctionReturn(0);
  }
  const bool reference = step_ == NumRows();
  const PetscInt level = reference ? Finest() : step_ % o_.levels;
  step                 = Step{levels_[level], SolveOptionsFor(reference ? o_.referenceElement : o_.elements[step_ / o_.levels])};
  if (reference) PetscFunctionReturn(0);
  if (Multigrid()) step.options.solve.amgReuse.hierarchy = &hierarchy_; // complete once Carry ran
  step.options.estimate.enabled = estimate_.enabled;
  step.options.keepMesh         = level == o_.levels - 1 && !o_.profiles.empty();
  PetscCall(PetscTime(&stepStart_));
  PetscFunctionReturn(0);
}

// A solve of the study: the user's solver settings, no KKT warning, no linear comparison, no estimate
// (the rows turn it on).
PipelineOptions ConvergenceStudy::SolveOptionsFor(Element element) const
{
  PipelineOptions o;
  o.element             = element;
  o.assembly            = assembly_;
  o.solve               = solve_;
  o.solve.compareLinear = false;
  o.kktHint             = false;
  o.estimate.enabled    = false;
  return o;
}

// The reference by nested iteration over the study's levels, the coarsest ones left out as -nested_levels
// says (as MeshCreate keeps them for a run). The levels are the study's own, referenced (nested iteration
// frees each once used), and their parent maps copied: the rows' errors need them afterwards.
PetscErrorCode ConvergenceStudy::StartReference()
{
  PetscFunctionBeginUser;
  PetscCall(hierarchy_.Destroy()); // the rows' transfers
  PetscCall(SpaceDestroy(p1Prev_));
  const PetscInt first = o_.nested.levels < 0 ? 0 : PetscMax(0, Finest() - o_.nested.levels);
  for (PetscInt l = first; l <= Finest(); ++l) {
    PetscCall(PetscObjectReference((PetscObject)levels_[l]));
    refLevels_.dm.push_back(levels_[l]);
    refLevels_.parent.push_back(parent_[l]);
  }
  refNested_ = std::make_unique<NestedIteration>(refLevels_, problem_, SolveOptionsFor(o_.referenceElement), o_.nested);
  PetscFunctionReturn(0);
}

// A level after the first of its element starts from the one before (its solution is the last kept);
// every level of a CR element puts its transfers on the multigrid, as nested iteration does.
PetscErrorCode ConvergenceStudy::Carry(MeshSolution &cur, bool &carried)
{
  const PetscInt l = step_ % o_.levels;
  Space          p1;
  PetscFunctionBeginUser;
  if (refNested_) {
    PetscCall(refNested_->Carry(cur, carried));
    PetscFunctionReturn(0);
  }
  carrySeconds_ = 0;
  carried       = step_ < NumRows() && l > 0 && Carrying();
  if (l == 0 || step_ >= NumRows()) { // a new element (its own transfers), or the reference (none)
    PetscCall(hierarchy_.Destroy());
    PetscCall(SpaceDestroy(p1Prev_));
  }
  if (step_ >= NumRows()) PetscFunctionReturn(0);
  const MeshSolution *before = carried ? &solved_.back() : nullptr;
  if (carried) PetscCall(ProlongateLevel(*before, cur.space, parent_[l], problem_, cur.u, carrySeconds_));
  if (!Multigrid()) PetscFunctionReturn(0);
  const Space *coarseP1 = cur.space.element == Element::CR ? (l > 0 ? &p1Prev_ : nullptr) : (before ? &before->space : nullptr);
  PetscCall(StageTimed(PetscObjectComm((PetscObject)cur.u), Stage::Solve, carrySeconds_, [&] { return AppendLevelTransfers(levels_[l], cur.space, coarseP1, parent_[l], problem_, hierarchy_, &p1); }));
  PetscCall(SpaceDestroy(p1Prev_));
  p1Prev_ = p1; // (none for P1)
  PetscFunctionReturn(0);
}

PetscErrorCode ConvergenceStudy::Solved(MeshSolution &&m)
{
  PetscFunctionBeginUser;
  if (refNested_) {
    MeshSolution ref;
    PetscCall(refNested_->Solved(std::move(m)));
    if (!refNested_->TakeFinest(ref)) PetscFunctionReturn(0);
    refNested_.reset();
    PetscCall(MeshLevelsDestroy(refLevels_));
    PetscCall(Reference(ref));
  } else if (step_ < NumRows()) PetscCall(Row(std::move(m)));
  else PetscCall(Reference(m));
  PetscFunctionReturn(0);
}

// The row of the solution just solved, which is kept (its space and u) for the reference. With a
// profile prefix, the finest level also writes PREFIX-<element>.h5/.xmf (the solution) and
// PREFIX-<element>-contact.csv.
PetscErrorCode ConvergenceStudy::Row(MeshSolution &&m)
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)m.u);
  const PetscInt l    = step_ % o_.levels;
  const Element  e    = o_.elements[step_ / o_.levels];
  StudyRow       r;
  PetscLogDouble t1;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t1)); // the row's run time ends with its solve and estimate, not with the profile files
  if (l == o_.levels - 1 && !o_.profiles.empty()) {
    PetscCall(WriteSolution(m.space, problem_, m.sys, m.u, ProfileOutput(o_.profiles, e, problem_)));
    if (problem_.HasContact()) PetscCall(WriteContactProfile(m.space, problem_, m.sys, m.u, ProfileBase(o_.profiles, e) + "-contact.csv"));
  }
  PetscCall(SystemDestroy(m.sys)); // the rows and the reference need the space, u and sys.kappa only (kept)
  r.solve        = m.result;
  r.carried      = l > 0 && Carrying();
  r.estimate     = std::move(m.estimate);
  std::vector<PetscReal>().swap(r.estimate.cellEta2);
  r.solveSeconds = m.result.solveSeconds + carrySeconds_; // the transfers are the preconditioner's data
  r.element      = ElementName(e);
  r.level        = l;
  r.N            = N0_ << l;
  r.h            = h0_ / (1 << l);
  r.cells        = 0;
  PetscInt local = m.space.NumCells();
  PetscCallMPI(MPI_Allreduce(&local, &r.cells, 1, MPIU_INT, MPI_SUM, comm));
  r.dofs         = m.space.numGlobal;
  if (l == 0) elementSeconds_ = 0;
  elementSeconds_ += t1 - stepStart_;
  r.totalSeconds = meshSeconds_[l] + elementSeconds_;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &r.solveSeconds, 1, MPI_DOUBLE, MPI_MAX, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &r.totalSeconds, 1, MPI_DOUBLE, MPI_MAX, comm));
  double rssSum;
  PetscCall(PeakRSS(comm, &rssSum, &r.peakRSS));
  if (problem_.HasExact()) {
    PetscCall(ErrorAgainstExact(m.space, problem_, m.sys, m.u, errorDegree_, r.exact));
    r.hasExact = true;
  }
  rows_.push_back(r);
  solved_.push_back(std::move(m));
  PetscFunctionReturn(0);
}

// Every kept solution against the reference on the reference's mesh, then the reference is freed.
PetscErrorCode ConvergenceStudy::Reference(MeshSolution &r)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)r.u);
  const Space       &ref  = r.space;
  const SolveResult &rr   = r.result;
  const PetscInt     finest = Finest();
  PetscFunctionBeginUser;
  PetscCall(SystemDestroy(r.sys));
  refDofs_ = ref.numGlobal;
  refNestedLevels_ = (PetscInt)rr.levels.size();
  const std::string how = rr.levels.size() < 2 ? "" : Format(" (nested iteration over %d levels; the finest level's iterations)", (int)rr.levels.size());
  PetscCall(PetscPrintf(comm, "reference: %s on level %d (N = %d), %d DOFs, %d Newton / %d KSP iterations, %.2f s%s\n", ElementName(o_.referenceElement), (int)finest, (int)(N0_ << finest), (int)refDofs_, (int)rr.newtonIts, (int)rr.kspIts, rr.solveSeconds, how.c_str()));
  // parent maps from the reference level down to each study level, composed once per level
  std::vector<PetscInt> map(ref.NumCells());
  for (PetscInt c = 0; c < ref.NumCells(); ++c) map[c] = c;
  for (PetscInt l = finest; l >= 0; --l) {
    for (size_t i = 0; i < rows_.size(); ++i)
      if (rows_[i].level == l) {
        PetscCall(ErrorAgainstReference(solved_[i].space, solved_[i].u, ref, r.sys, r.u, map, rows_[i].reference));
        rows_[i].hasReference = true;
      }
    if (l > 0)
      for (PetscInt &c : map) c = parent_[l][c];
  }
  PetscCall(r.Destroy());
  PetscFunctionReturn(0);
}

PetscErrorCode ConvergenceStudy::Finish()
{
  MPI_Comm comm = PetscObjectComm((PetscObject)base_);
  PetscFunctionBeginUser;
  PetscCall(PrintTable(comm, rows_));
  const StudyRow *worst = nullptr; // the smallest index against the exact solution
  for (const StudyRow &r : rows_)
    if (r.hasExact && r.estimate.computed && r.exact.energy > 0 && (!worst || r.estimate.eta / r.exact.energy < worst->estimate.eta / worst->exact.energy)) worst = &r;
  if (worst && o_.nested.solveTo != NestedOptions::Discretization) PetscCall(WarnBoundBelowError(comm, worst->estimate.eta, worst->exact.energy, worst->exact.exactEnergy, Format(" (%s, N = %d)", worst->element.c_str(), (int)worst->N)));
  for (const std::string &file : {o_.file, o_.summary})
    if (!file.empty()) PetscCall(WriteJSON(comm, file, problem_.scene, o_, N0_ << Finest(), refDofs_, refNestedLevels_, rows_));
  for (MeshSolution &m : solved_) PetscCall(m.Destroy());
  for (DM &dm : levels_) PetscCall(DMDestroy(&dm));
  PetscCall(hierarchy_.Destroy());
  PetscCall(SpaceDestroy(p1Prev_));
  PetscCall(MeshLevelsDestroy(refLevels_));
  PetscFunctionReturn(0);
}

} // namespace signorini

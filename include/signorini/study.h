// Convergence study: one scene solved on a sequence of nested meshes with each element, with the error of
// every solution against the exact solution (when the scene has one) and/or against a reference solution
// on a further refined mesh, beside what each solution cost.
//
// All levels come from refining the distributed base mesh in parallel, so the reference is solved once
// and every coarse solution is compared with it on the fine mesh, cell by cell, without gathering.
#pragma once

#include "signorini/assembly.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/estimate.h"
#include "signorini/mesh.h"
#include "signorini/nested.h"
#include "signorini/strategy.h"

#include <memory>

namespace signorini {

struct StudyOptions {
  PetscInt             levels = 0;          // number of mesh levels studied (0: no study, a single run)
  PetscInt             referenceRefine = 0; // refinements of the finest study level for the reference (0: none)
  Element              referenceElement = Element::P1;
  std::vector<Element> elements = {Element::P1, Element::CR};
  std::string          file;     // JSON output (-study_output)
  std::string          summary;  // the same JSON again (-summary: every run's summary file, here the study's)
  std::string          profiles; // prefix of the finest level's solution (HDF5) and contact profile (CSV)
  NestedOptions        nested; // enabled: each level from the one before, the reference by nested iteration (-nested 0: from u_D)
};

// The problem says which profile files are written (contact profiles only with a contact part).
PetscErrorCode StudyOptionsFromCommandLine(MPI_Comm comm, const Problem &problem, StudyOptions &o);

struct StudyRow {
  std::string element;
  PetscInt    level = 0, N = 0, cells = 0, dofs = 0;
  PetscReal   h = 0;
  SolveResult solve;
  bool        carried = false; // started from the level before (else from u_D)
  bool        hasExact = false, hasReference = false;
  ErrorNorms  exact, reference;
  Estimate    estimate; // without the cell indicators
  double      solveSeconds = 0, totalSeconds = 0, peakRSS = 0; // peak resident memory (bytes, max over ranks)
};

// The study as a strategy of the loop over meshes (strategy.h): every element of o.elements on every
// study level (coarse solves first, so that each row's peak memory is not the reference's), each solution
// kept for its row; then, with o.referenceRefine, the reference on the finest level, against which every
// kept solution is measured. The levels of one element go as a run of the finest would (nested.h): each
// level from the prolongation of the one before with its active set, preconditioned by the multigrid over
// the levels so far (-vi_pc_type mg), but each solved to the full test, as its row reports its error; a
// row's total time is the run up to its level (the mesh refinements, and the set-up, solve and estimate
// of every level of its element so far), what a run of that level alone costs up to the coarse levels'
// early stops. The reference is solved as a run of its level is, by nested iteration over all the levels
// (nested.h, with its -solve_to). A scene without a contact part is a linear solve on every level, and
// -nested 0 solves every level and the reference from u_D. `base` is level 0 (the distributed, possibly
// refined, mesh of MeshCreate; the study takes its own reference), `N0` its cells per side (box meshes;
// 0 for files). The levels are refined at the first Next.
class ConvergenceStudy : public MeshStrategy {
public:
  ConvergenceStudy(DM base, PetscInt N0, PetscReal h0, const Problem &problem, const AssemblyOptions &assembly, const SolveOptions &solve, const EstimateOptions &estimate, PetscInt errorDegree, const StudyOptions &o)
    : base_(base), N0_(N0), h0_(h0), problem_(problem), assembly_(assembly), solve_(solve), estimate_(estimate), errorDegree_(errorDegree), o_(o) {}
  PetscErrorCode Next(Step &step, bool &more) override;
  PetscErrorCode Carry(MeshSolution &cur, bool &carried) override;
  PetscErrorCode Solved(MeshSolution &&m) override;
  // After the loop: prints the table, writes the JSON if asked, and frees the solutions and the levels.
  PetscErrorCode Finish();

private:
  PetscErrorCode Refine();
  PetscErrorCode Row(MeshSolution &&m);
  PetscErrorCode Reference(MeshSolution &ref);
  PetscInt       Finest() const { return o_.levels - 1 + o_.referenceRefine; }
  PetscInt       NumRows() const { return (PetscInt)o_.elements.size() * o_.levels; }

  DM                                 base_;
  PetscInt                           N0_;
  PetscReal                          h0_;
  const Problem                     &problem_;
  AssemblyOptions                    assembly_;
  SolveOptions                       solve_;    // the user's, without the linear comparison
  EstimateOptions                    estimate_; // every row's solution; not the reference's
  PetscInt                           errorDegree_;
  StudyOptions                       o_;
  std::vector<DM>                    levels_;
  std::vector<std::vector<PetscInt>> parent_;
  std::vector<double>                meshSeconds_;
  PetscInt                           step_ = -1; // rows first (element-major), then the reference
  PetscLogDouble                     stepStart_ = 0;
  std::vector<StudyRow>              rows_;
  std::vector<MeshSolution>          solved_; // one per row
  PetscInt                           refDofs_ = 0;
  PetscInt                           refNestedLevels_ = 0; // levels of the reference's nested iteration (0: from u_D)
  double                             elementSeconds_ = 0; // the levels of the element under way so far
  double                             carrySeconds_   = 0; // of the row under way: prolongation and transfers
  Hierarchy                          hierarchy_;  // -vi_pc_type mg: the transfers of the element under way
  Space                              p1Prev_;     // CR: the P1 space of the level before (AppendLevelTransfers)
  bool                               Carrying() const { return o_.nested.enabled && problem_.HasContact(); }
  bool                               Multigrid() const { return solve_.amgReuse.innerType == PCMG && Carrying(); }
  // the reference by nested iteration: its levels (references to levels_, copies of parent_)
  MeshLevels                         refLevels_;
  std::unique_ptr<NestedIteration>   refNested_;
  PetscErrorCode                     StartReference();
  PipelineOptions                    SolveOptionsFor(Element element) const;
};

} // namespace signorini

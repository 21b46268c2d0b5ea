// The summary of a run: what was solved, how the solve went, the checks and the errors, and where the
// time went. Printed on rank 0 and, with -summary FILE.json, written as JSON (to a temporary name first,
// then renamed, so a failed run never leaves a half-written file).
#pragma once

#include "signorini/adapt.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/estimate.h"
#include "signorini/files.h"
#include "signorini/mesh.h"
#include "signorini/stages.h"

namespace signorini {

struct Report {
  std::string scene, element, mesh, loadRule;
  PetscInt    dim = 0, refine = 0, coarseCells = 0, cells = 0, dofs = 0, dirichletDofs = 0, contactDofs = 0, ranks = 1, edgeCut = -1;
  std::vector<PetscInt> cellsPerRank;
  CoarseFindings      boundary; // of the coarse mesh
  SolveResult solve;
  std::string preconditioner;    // of the inactive-set blocks (-vi_pc_type, or as ChoosePreconditioner chose)
  PetscReal   aspect = 0;        // the first mesh's largest cell aspect ratio, where it chose the preconditioner
  bool        chosenForAspect = false; // BoomerAMG alone because of stretched cells (no -vi_pc_type given)
  std::vector<AdaptRow> adapt; // adaptive refinement: one row per mesh (empty without)
  std::string           adaptEnded, adaptEndedText; // AdaptiveRefinement::ended, endedText
  bool        hasExact = false;
  ErrorNorms  error;
  Estimate    estimate; // without the cell indicators; estimate.computed = false: none (-estimate none)
  PetscLogDouble stageSeconds[(int)Stage::Count] = {0}; // max over ranks
  PetscLogDouble totalSeconds = 0;
  // Memory in bytes. Peak resident set size of each process so far (getrusage), summed and max over ranks;
  // the stiffness matrix's AIJ arrays (from MatGetInfo); the peak of PETSc's PetscMalloc'ed bytes summed over
  // ranks, known only when PETSc's tracing allocator is on (-malloc_dump, -malloc_debug, -malloc_test),
  // -1 otherwise (hypre and std::vector memory is never in it; the RSS includes everything).
  double peakRSSSum = 0, peakRSSMax = 0, matrixBytes = 0, petscMallocPeak = -1;
  // The expressions of the scene as given (option without '-', text), for the JSON summary, which also
  // records the command line.
  std::vector<std::pair<std::string, std::string>> expressions;
};

// Records the scene's expressions (f, g, u_D, psi, kappa and, if given, the exact solution and gradient).
void ReportRecordExpressions(const Problem &p, Report &r);

PetscErrorCode ReportOptionsFromCommandLine(MPI_Comm comm, std::string &summaryFile);
// Fills the stage times (max over ranks) and the total since `start`.
PetscErrorCode ReportGatherTimes(MPI_Comm comm, PetscLogDouble start, Report &r);
// Collective: peak resident set size of the processes so far (bytes), summed and max over ranks.
PetscErrorCode PeakRSS(MPI_Comm comm, double *sum, double *max);
// Collective: fills the memory figures; A is the stiffness matrix.
PetscErrorCode ReportGatherMemory(MPI_Comm comm, Mat A, Report &r);
PetscErrorCode ReportPrint(MPI_Comm comm, const Report &r);
// eta bounds the error with constant 1 (README, under its assumptions), so an energy error against the
// exact solution above it (index < 1) means that -exact_u/-exact_grad do not solve the scene, or that an
// assumption fails: one warning line, for the smallest index of the run's meshes (`where` names it). Not
// where the error is below 1e-6 of the exact solution's own energy norm `norm`: there it is the solver's
// (u in the discrete space, or nearly), which eta does not bound.
PetscErrorCode WarnBoundBelowError(MPI_Comm comm, PetscReal eta, PetscReal error, PetscReal norm, const std::string &where);
PetscErrorCode ReportWriteJSON(MPI_Comm comm, const Report &r, const std::string &file);
// The estimate as a JSON object: eta, its parts, its seconds and, with the error known (error not null),
// the efficiency index eta / energy error.
std::string EstimateJSON(const Estimate &e, const ErrorNorms *error);

} // namespace signorini

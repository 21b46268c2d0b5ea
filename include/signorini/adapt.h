// Adaptive refinement as a strategy of the loop over meshes (strategy.h): solve, estimate, mark, refine,
// up to -adapt_steps times. After each solve the cells are marked by Doerfler's rule on the estimate's
// cell indicators (mark.h), the marked cells are refined conformingly (localrefine.h), the solution is
// evaluated on the new cells with its active set (transfer.h) and, if the load has become unbalanced, the
// new mesh is redistributed with those values; they are the initial guess of the next solve (nested
// iteration across the adaptive steps). With -vi_pc_type mg (the default) every solve is preconditioned by
// the multigrid over the adapted meshes so far (hierarchy.h; MultigridLevel says which levels are kept),
// as nested iteration's solves are by the multigrid over the uniform levels, instead of a BoomerAMG set up
// on every step: on stiff-below-h2 CR up to 1 M DOFs (17 steps) the Solve stage took 5.3 s instead of
// 12.5 s, the whole run 5.6 instead of 7.4 CPU seconds, for about 250 B/DOF more peak memory.
// The run stops after the last step, once eta < -adapt_tol or the
// DOFs reach -adapt_max_dofs, or when nothing is left to mark. Every step is a row: the mesh, the estimate, the error where the exact
// solution is known, the solve, and the overhead of going on to the next mesh.
//
// Error against an adaptive reference (-adapt_reference_steps m): for scenes without an exact solution the
// run goes on for m more steps, and the solution of the last one is the reference of all earlier steps.
// The adapted meshes are nested (every cell of step k+1 lies in a cell of step k), so each kept solution
// is compared with the reference on the reference's cells through the composed parent maps, exactly
// (ErrorAgainstReference, error.h). A redistribution moves cells away from their parents' rank, so the
// steps before the last redistribution get no reference error (on one rank there is none): the simple,
// correct choice rather than migrating every kept solution. The run's result (summary, -output) is the last
// step of the adaptive run, not the reference.
#pragma once

#include "signorini/hierarchy.h"
#include "signorini/localrefine.h"
#include "signorini/nested.h"
#include "signorini/stages.h"
#include "signorini/strategy.h"
#include "signorini/transfer.h"

#include <memory>

namespace signorini {

struct AdaptOptions {
  PetscInt  steps     = 0;   // -adapt_steps: refinements (0: no adaptive refinement)
  PetscReal theta     = 0.5; // -adapt_theta: Doerfler parameter (mark.h)
  PetscReal tol       = 0;   // -adapt_tol: stop once eta < tol
  PetscInt  maxDofs   = 0;   // -adapt_max_dofs: stop once a mesh has this many DOFs (0: no limit)
  PetscReal imbalance = 1.2; // -adapt_imbalance: redistribute when max cells per rank / mean exceeds it
  // -adapt_refinement: bisection_all (a marked cell cuts all its edges, so its h halves, the default),
  // bisection (only its longest edge: half as many new cells per step, so about twice the steps and run
  // time to the same error on stiff-below-h2), both in 2D and 3D, or sbr (PETSc's refine_sbr transform, 2D,
  // six times the next solve's time at 131 k triangles).
  LocalRefinement refinement = LocalRefinement::BisectionAll;
  PetscInt  referenceSteps = 0; // -adapt_reference_steps: further steps whose last solution is the reference
  // -adapt_reference_dofs: the reference steps end earlier, at the first mesh with this many times the DOFs
  // of the run's last step (0: no such end). A step grows the mesh about 1.6 times in 2D but about 4 times
  // in 3D, so that a number of steps right for one is, for the other, too few or beyond any memory.
  PetscReal referenceDofs = 0;
  // -memory_check, -memory_limit (mesh.h): a step whose next mesh would not fit the memory ends the run (or
  // its reference steps) there (see AdaptiveRefinement::EndWhereMemoryEnds)
  bool   memoryCheck = true;
  double memoryLimit = 0;
  // -solve_to discretization (nested.h): every step after the first stops once its algebraic error is
  // estimated below this fraction of its discretization error, predicted from the estimate of the step
  // before (0: every step to the full test). Not for the reference steps.
  PetscReal solveToFraction = 0;
};
PetscErrorCode AdaptOptionsFromCommandLine(MPI_Comm comm, AdaptOptions &o);

// One mesh of the run. The times are max over ranks, in seconds; the overhead (estimate to transfer) is
// what it took to go from this mesh's solution to the next mesh and its initial guess. The solve includes
// the building of the multigrid's transfers to this mesh (-vi_pc_type mg), its preconditioner's data.
struct AdaptRow {
  PetscInt  cells = 0, dofs = 0, newtonIts = 0, kspIts = 0, marked = 0;
  PetscInt  nestedLevels = 0; // levels of the mesh's hierarchy solved by nested iteration, the mesh's own included (step 0, StartNested)
  PetscReal eta = 0, error = -1; // error: against the exact solution, energy norm (-1: not known)
  PetscReal referenceError = -1; // energy error against the adaptive reference (-1: none)
  double    setupSeconds = 0, solveSeconds = 0, estimateSeconds = 0, markSeconds = 0, refineSeconds = 0, redistributeSeconds = 0, transferSeconds = 0;
  // Wall time of the run from the first mesh up to this step's solution and estimate: the set-up, solve
  // and estimate of every step so far and the overhead of the steps before (not the error computations).
  double    runSeconds = 0;
  bool      redistributed = false; // the next mesh was redistributed
  bool      reference = false;     // a step beyond the adaptive run, solved for the reference only
};
// The rows as a table for the summary printed after the run.
std::string AdaptTable(const std::vector<AdaptRow> &rows);

class AdaptiveRefinement : public MeshStrategy {
public:
  // The squared cell indicators (per local cell) and the estimate eta of a solution, and the seconds
  // they took. By default the pipeline's estimate (MeshSolution::estimate); a test may feed others.
  using Indicators = std::function<PetscErrorCode(const MeshSolution &, std::vector<PetscReal> &eta2, PetscReal &eta, double &seconds)>;
  // Takes a reference to `mesh`, the first mesh, and keeps a reference to the mesh of the step under
  // way until it has refined it (the pipeline drops only its space's reference). errorDegree: the
  // quadrature of the error against the exact solution, when the problem has one.
  AdaptiveRefinement(DM mesh, const Problem &problem, const PipelineOptions &o, const AdaptOptions &a, PetscInt errorDegree, Indicators indicators = nullptr);
  ~AdaptiveRefinement() override;
  PetscErrorCode Next(Step &step, bool &more) override;
  PetscErrorCode Carry(MeshSolution &cur, bool &carried) override;
  PetscErrorCode Solved(MeshSolution &&m) override;
  // Solve the first mesh by nested iteration over the refinement levels it was built by (levels.dm.back()
  // is the first mesh), as a run without -adapt_steps does, instead of from u_D on the mesh alone: with
  // -vi_pc_type mg the multigrid of every later step then goes on down through those levels, where
  // without them its coarsest level, solved by BoomerAMG, would be the first mesh. Before the first Next.
  void StartNested(MeshLevels &levels, const NestedOptions &o);
  // The run's result: the solution of the last step of the adaptive run (rows[finestStep]; reference
  // steps may follow it); the caller destroys it.
  MeshSolution          finest;
  PetscInt              finestStep = 0;
  std::vector<AdaptRow> rows;         // one per mesh solved
  std::vector<PetscInt> cellsPerRank; // of finest's mesh
  // Why the adaptive run ended: "steps" (all -adapt_steps done), "tol", "max_dofs" or "zero_estimate"
  // (nothing to refine), and for an early end the sentence that says so.
  std::string ended, endedText;

private:
  PetscErrorCode Refine(); // the marked cells of mesh_, the solution carried to the new mesh_
  PetscErrorCode ReferenceErrors(const MeshSolution &ref); // of the kept solutions (-adapt_reference_steps)
  PetscErrorCode SolveToDiscretization(PipelineOptions &o) const; // the stopping bound of -solve_to discretization
  PetscErrorCode EndWhereMemoryEnds(const Space &space, const AdaptRow &row); // stop_ where the next mesh would not fit

  DM                mesh_; // the mesh of the step under way
  const Problem    &problem_;
  PipelineOptions   options_;
  AdaptOptions      adapt_;
  PetscInt          errorDegree_;
  Indicators        indicators_;
  PetscInt          step_ = -1;
  PetscInt          adaptEnd_ = -1; // the last step of the adaptive run proper, once known
  bool              stop_ = false;
  PetscLogDouble    start_ = 0;     // the first Next
  // StartNested: the levels of the first mesh, solved by nested_ until it hands over its finest level as
  // step 0 (levels_->dm.back() is dropped then: mesh_ holds the first mesh)
  MeshLevels                      *levels_ = nullptr;
  std::unique_ptr<NestedIteration> nested_;
  NestedHandover                   handover_;
  double            excluded_ = 0;  // seconds of error computations, not run time
  std::vector<MeshSolution>          kept_;    // with reference steps: every step's space and u
  std::vector<std::vector<PetscInt>> parents_; // parents_[k]: cell of step k - 1 containing each cell of step k
  MeshSolution      prev_;    // the solution of mesh_ until it is carried
  std::vector<char> marked_;  // the cells of mesh_ to refine
  CellValues        carried_; // prev_ on the cells of the new mesh
  // -vi_pc_type mg: the multigrid over the adapted meshes (hierarchy.h), as nested iteration builds it
  // over the uniform levels: the P1 transfers from step to step (recorded on the new cells before a
  // redistribution, assembled on the new space), and for CR the transfer from P1 to CR on the mesh of the
  // step under way on top. Levels too close in size to the next are skipped (MultigridLevel).
  bool                  multigrid_ = false;
  Hierarchy             hierarchy_;
  std::vector<PetscInt> levelDofs_; // global P1 DOFs of the kept levels, coarse to fine
  // The P1 transfer from the step before to mesh_ is built once mesh_'s space exists: from the coarse P1
  // space and the parent map (ProlongationMatrix), or, where mesh_ was redistributed, from its record,
  // made on the new cells before they moved (RecordP1Transfer, AssembleP1Transfer).
  Space                 p1_;        // CR: the P1 space of mesh_ (after Refine: of its parent mesh); P1: that
                                    // of the parent mesh, from Refine to Carry, unless a kept step holds it
  const Space          *coarseP1_ = nullptr; // the coarse P1 space (p1_ or a kept step's), until the transfer
  std::vector<PetscInt> mgParent_;  // with it: the parent of every cell of mesh_
  TransferRecord        record_;    // or the record (mesh_ redistributed)
  // its set-up for the next solve, counted as that solve's time and in the Solve stage (the transfers are
  // the preconditioner's data, as BoomerAMG's set-up is, and nested iteration counts their assembly in the
  // solve too)
  double                multigridSeconds_ = 0;
  PetscErrorCode        MultigridCarry(const Space &space);
  PetscErrorCode        MultigridLevel(Mat P, PetscInt dofs);
};

} // namespace signorini

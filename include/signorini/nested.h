// Nested iteration for the contact solve: the problem is solved on the coarsest mesh of the refinement
// hierarchy first, each solution is prolongated to the next finer mesh (values and active set) and
// projected onto its constraints, and serves there as the initial guess, up to the finest mesh. The
// active set is then nearly right before the first Newton step on the finest mesh, so the number of
// Newton steps there stays small as the mesh is refined.
//
// Where each level stops (-solve_to):
//   fmg (default, full multigrid): a coarse level is only the initial guess of the next one, so it need
//     not be solved far below its discretization error: it stops once its algebraic error (estimated from
//     the energy decrease of its Newton steps and CG iterations, contact.cpp) is -solve_to_rtol times the
//     error of its start, the prolongated guess, whose error is about the discretization error of the
//     level before (measured by the energy decrease of the first Newton step); usually two Newton steps
//     with one CG iteration each. The finest level stops at the absolute residual its own solve from u_D
//     would reach (see Solve), so the final discrete solution is the same to solver tolerance as with
//     `full`.
//   full: every level as the finest (the nested iteration before full multigrid).
//   discretization: every level from the first prolongated one on, the finest included, stops once its
//     algebraic error in the energy norm is estimated below -solve_to_fraction times its discretization
//     error, predicted as half the a posteriori estimate eta of the level before (estimate.h; the energy
//     error of P1 and CR halves with h); the coarsest level solves to the full test. The estimate is
//     then computed on every level.
// The early stops need the reduced-space solver (the default); with -snes_type vinewtonssls every level
// stops at the full test (the summary's stopped_by says which test stopped each level).
#pragma once

#include "signorini/hierarchy.h"
#include "signorini/mesh.h"
#include "signorini/strategy.h"
#include "signorini/transfer.h"

namespace signorini {

struct NestedOptions {
  bool     enabled = true; // -nested: used when there is a contact part and a coarser level (-refine > 0)
  PetscInt levels  = -1;   // -nested_levels: coarse levels solved before the finest one (-1: every refinement level)
  enum SolveTo { Fmg, Full, Discretization };
  PetscInt  solveTo  = Fmg;  // -solve_to (above)
  PetscReal rtol     = 0.1;  // -solve_to_rtol: fmg's coarse levels
  PetscReal fraction = 0.1;  // -solve_to_fraction: discretization's algebraic error / discretization error
};
const char *SolveToName(PetscInt solveTo);
PetscErrorCode NestedOptionsFromCommandLine(MPI_Comm comm, NestedOptions &o);

// The prolongation of each level's solution with its active set to the next (transfer.h): uh = that of
// the coarse level's solution (Solve projects it onto the fine level's constraints). Part of the Solve
// stage; `seconds` is its wall time (max over ranks).
PetscErrorCode ProlongateLevel(const MeshSolution &coarse, const Space &fine, const std::vector<PetscInt> &parent, const Problem &problem, Vec uh, double &seconds);

// The multigrid's transfers to a new level (-vi_pc_type mg), appended to h: a P1 level's from coarseP1,
// the space of the level before (none on the first level). Below a CR level the multigrid goes on with
// P1 on the same mesh (P1 is a subspace of CR, so the transfer is exact: a face's value is the mean of
// its vertices') and then the P1 levels of the coarser meshes, whose transfers are exact too; the Galerkin
// operator of the CR level on P1 is the P1 stiffness matrix (seven entries a row in 2D) where the Galerkin
// products of the CR prolongation grow denser on every level. So a CR level builds the P1 space of its
// mesh into *p1 (which the caller keeps as the next level's coarseP1 and frees), replaces the P1-to-CR
// transfer on top of h by the P1 transfer from coarseP1 (the level before's P1 space), and puts its own
// P1-to-CR transfer on top. parent: the parent map of the mesh's cells (transfer.h). Collective.
PetscErrorCode AppendLevelTransfers(DM mesh, const Space &space, const Space *coarseP1, const std::vector<PetscInt> &parent, const Problem &problem, Hierarchy &h, Space *p1);

// Nested iteration as a strategy of the loop over meshes (strategy.h): the levels levels.dm[0 ..
// Count()-1], coarse to fine, each from the prolongation of the one before (the coarsest from u_D). The
// finest level is solved with the options `fine`; the coarse ones without the linear comparison and the
// KKT warning, and each coarse mesh is destroyed (its entry set to NULL) once its level's space is built
// (fine.withMesh frees the finest). Each parent map is dropped once used, and each coarse solution is
// freed once carried (its system already when solved), so that the solves, and above all the finest one,
// the peak of the run's memory, do not hold them. `finest` receives the finest solution, its result with
// one entry per level in result.levels (with where each stopped, -solve_to), the time of all solves together in result.solveSeconds and the
// AMG statistics of all levels. With -vi_pc_type mg, the prolongation matrix between each pair of levels
// is assembled when the finer level is carried to (before the coarse space is freed) and kept, as the only
// data of the coarse levels, until the finest level is solved: the multigrid of every level's solve uses
// all transfers below it (hierarchy.h). For CR the multigrid goes from each CR level to P1 on the same
// mesh and on through the P1 levels (CoarseSpaceTransfers, nested.cpp).
//
// Adaptive refinement (adapt.h) solves its first mesh by nested iteration and goes on with its multigrid:
// with a NestedHandover, the transfers are built into its hierarchy and kept after the finest level, with
// the P1 DOFs of every level and, for CR, the finest level's P1 space (the coarse space of the next
// transfer), instead of being freed.
struct NestedHandover {
  Hierarchy            *hierarchy = nullptr; // filled level by level
  std::vector<PetscInt> p1Dofs;              // global P1 DOFs of each level, coarse to fine
  Space                 p1;                  // CR: the P1 space of the finest level (the receiver frees it)
};
class NestedIteration : public MeshStrategy {
public:
  NestedIteration(MeshLevels &levels, const Problem &problem, const PipelineOptions &fine, const NestedOptions &o, NestedHandover *handover = nullptr) :
    levels_(levels), problem_(problem), fine_(fine), o_(o), handover_(handover)
  {
  }
  PetscErrorCode Next(Step &step, bool &more) override;
  PetscErrorCode Carry(MeshSolution &cur, bool &carried) override;
  PetscErrorCode Solved(MeshSolution &&m) override;
  MeshSolution   finest;
  // For a strategy that runs this one as its first part (the study's reference, an adaptive run's first
  // mesh): once the finest level is solved, moves `finest` into `out` and returns true.
  bool TakeFinest(MeshSolution &out)
  {
    if (!finest.u) return false; // a coarse level
    out    = std::move(finest);
    finest = MeshSolution(); // a moved MeshSolution still holds the handles
    return true;
  }

private:
  MeshLevels                     &levels_;
  const Problem                  &problem_;
  PipelineOptions                 fine_;
  NestedOptions                   o_;
  PetscReal                       eta_ = 0;    // -solve_to discretization: the estimate of the level before,
  PetscReal                       energyError_ = 0; // and the algebraic error this level may keep
  PetscInt                        level_ = -1; // the level of the step under way
  MeshSolution                    prev_;       // the coarser solution until it is carried
  std::vector<SolveResult::Level> summary_;
  AmgReuseStats                   amg_;        // of the coarse levels
  double                          prolongSeconds_ = 0;
  Hierarchy                       hierarchy_;  // -vi_pc_type mg: the transfers so far (unless handed over)
  NestedHandover                 *handover_;
  Hierarchy                      &H() { return handover_ ? *handover_->hierarchy : hierarchy_; }
  Space                           p1Prev_;     // CR with -vi_pc_type mg: the P1 space of the level before
  PetscErrorCode                  CoarseSpaceTransfers(PetscInt level, const Space &space);
};
} // namespace signorini

// How a run goes from mesh to mesh. main solves the scene on a sequence of meshes, each through the
// pipeline (pipeline.h: set-up, Carry, solve, Solved, until Next says stop); a strategy says which mesh comes next and with which options, what is carried
// to it from the mesh before (an initial guess), and what becomes of each solution:
//   SingleRun (below): one mesh; its solution is kept for the report and the output.
//   NestedIteration (nested.h): the refinement levels, coarse to fine; each solution is prolongated with
//     its active set to the next level as its initial guess, and the finest one is kept.
//   ConvergenceStudy (study.h): every element on every study level without carry, each solution kept
//     for its row, then a reference solve on a finer level; the table afterwards.
//   AdaptiveRefinement (adapt.h): each solution's cells marked by the estimate and refined, the solution
//     carried to the new mesh with its active set; the last one is kept. The first mesh is solved by a
//     NestedIteration over its refinement levels, which hands its multigrid transfers over.
#pragma once

#include "signorini/pipeline.h"

namespace signorini {

// One mesh of the sequence and how to solve on it.
struct Step {
  DM              mesh = nullptr; // owned by the strategy (or its caller); options.withMesh may free it
  PipelineOptions options;        // options.solve.initialGuess is set by the loop when Carry carried
};

class MeshStrategy {
public:
  virtual ~MeshStrategy() = default;
  // The next mesh to solve on, or more = false when the sequence is over.
  virtual PetscErrorCode Next(Step &step, bool &more) = 0;
  // Between the set-up and the solve of the step just begun: fills cur.u with what is carried from the
  // previous solution and says so (carried = true), or leaves cur.u alone (default: nothing is carried).
  virtual PetscErrorCode Carry(MeshSolution &cur, bool &carried);
  // The step's solution: the strategy keeps, records or frees it.
  virtual PetscErrorCode Solved(MeshSolution &&m) = 0;
};

// A single run: one mesh with the caller's options.
class SingleRun : public MeshStrategy {
public:
  SingleRun(DM mesh, const PipelineOptions &o) : mesh_(mesh), options_(o) {}
  PetscErrorCode Next(Step &step, bool &more) override;
  PetscErrorCode Solved(MeshSolution &&m) override;
  MeshSolution   finest; // the solution, once solved; the caller destroys it
private:
  DM              mesh_;
  PipelineOptions options_;
  bool            done_ = false;
};

// The loop over meshes: the scene on every mesh the strategy hands out, each through the pipeline, with
// what the strategy carries from one mesh to the next.
PetscErrorCode SolveMeshes(const Problem &problem, MeshStrategy &strategy);

} // namespace signorini

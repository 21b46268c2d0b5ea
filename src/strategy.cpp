#include "signorini/strategy.h"

namespace signorini {

PetscErrorCode MeshStrategy::Carry(MeshSolution &, bool &carried)
{
  PetscFunctionBeginUser;
  carried = false;
  PetscFunctionReturn(0);
}

PetscErrorCode SingleRun::Next(Step &step, bool &more)
{
  PetscFunctionBeginUser;
  more = !done_;
  if (more) step = Step{mesh_, options_};
  done_ = true;
  PetscFunctionReturn(0);
}

PetscErrorCode SingleRun::Solved(MeshSolution &&m)
{
  PetscFunctionBeginUser;
  finest = std::move(m);
  PetscFunctionReturn(0);
}

PetscErrorCode SolveMeshes(const Problem &problem, MeshStrategy &strategy)
{
  Step step;
  bool more;
  PetscFunctionBeginUser;
  PetscCall(strategy.Next(step, more));
  while (more) {
    MeshSolution m;
    bool         carried;
    PetscCall(PipelineSetUp(step.mesh, problem, step.options, m));
    PetscCall(strategy.Carry(m, carried));
    if (carried) step.options.solve.initialGuess = true;
    PetscCall(PipelineSolve(problem, step.options, m));
    PetscCall(strategy.Solved(std::move(m)));
    PetscCall(strategy.Next(step, more));
  }
  PetscFunctionReturn(0);
}

} // namespace signorini

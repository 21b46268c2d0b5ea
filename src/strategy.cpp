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

} // namespace signorini

#include "signorini/pipeline.h"
#include "signorini/kkthint.h"
#include "signorini/stages.h"

namespace signorini {

PetscErrorCode MeshSolution::Destroy()
{
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&u));
  PetscCall(SystemDestroy(sys));
  PetscCall(SpaceDestroy(space));
  PetscFunctionReturn(0);
}

PetscErrorCode PipelineSetUp(DM mesh, const Problem &problem, const PipelineOptions &o, MeshSolution &m)
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)mesh); // withMesh may free the mesh
  PetscLogDouble t0, t1;
  double         hookSeconds = 0;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t0));
  PetscCall(StagePush(Stage::Setup));
  // The CR estimate's companion sums vertex values over the ranks; P1 has its vertices as DOFs.
  PetscCall(SpaceCreate(mesh, o.element, problem, m.space, false, o.element == Element::CR && o.estimate.enabled));
  PetscCall(StagePop(Stage::Setup));
  if (o.withMesh) {
    PetscCall(PetscTime(&t1));
    PetscCall(o.withMesh(m.space));
    PetscCall(SecondsSince(comm, t1, &hookSeconds));
  }
  // Assembly, solve, checks, errors and prolongation need the tables only.
  if (!o.keepMesh) PetscCall(SpaceReleaseMesh(m.space));
  AssemblyOptions assembly = o.assembly;
  assembly.keepCellLoads   = o.estimate.enabled; // read by the estimate instead of evaluating f again
  PetscCall(AssembleSystem(m.space, problem, assembly, m.sys));
  PetscCall(DMCreateGlobalVector(m.space.dm, &m.u));
  PetscCall(PetscObjectSetName((PetscObject)m.u, "u"));
  PetscCall(SecondsSince(comm, t0, &m.setupSeconds));
  m.setupSeconds -= hookSeconds;
  PetscFunctionReturn(0);
}

PetscErrorCode PipelineSolve(const Problem &problem, const PipelineOptions &o, MeshSolution &m)
{
  PetscFunctionBeginUser;
  PetscCall(Solve(m.space, problem, m.sys, m.u, m.result, o.solve));
  // SNES judges convergence by a residual norm that the stiffest rows dominate; the KKT conditions judge
  // the answer itself, so a solve that stopped early does not pass unseen.
  if (o.kktHint) PetscCall(KKTHint(m.space, m.sys, m.result, o.solve.kktTolerance));
  if (o.estimate.enabled) PetscCall(EstimateError(m.space, problem, m.sys, m.u, m.estimate));
  PetscFunctionReturn(0);
}

} // namespace signorini

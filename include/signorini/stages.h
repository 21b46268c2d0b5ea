// The steps of the method as PetscLogStages (so -log_view breaks the run down by step) together with
// their wall-clock times, which the summary reports. Adapt is an adaptive step's own work between two
// meshes (marking, refinement, redistribution, the transfer of the solution). A stage pushed inside
// another (the multigrid's transfers, counted as the solve's, are built during the refinement) pauses
// it, as in -log_view, so the stages' times add up to the run's.
#pragma once

#include <petscsys.h>

#include <functional>

namespace signorini {

enum class Stage { Mesh, Distribute, Refine, Setup, Assemble, Solve, Estimate, Adapt, Error, Output, Count };

const char    *StageName(Stage s);
PetscErrorCode StagesRegister();
PetscErrorCode StagePush(Stage s);
PetscErrorCode StagePop(Stage s);
// Wall-clock seconds spent in the stage on this rank so far.
PetscLogDouble StageSeconds(Stage s);
// Runs f in stage s and adds its wall time (the maximum over comm's ranks) to seconds: for a piece of work
// that a strategy counts in one of its own figures (a step's transfer, the multigrid's set-up).
PetscErrorCode StageTimed(MPI_Comm comm, Stage s, double &seconds, const std::function<PetscErrorCode()> &f);

} // namespace signorini

// The steps of the method as PetscLogStages (so -log_view breaks the run down by step) together with
// their wall-clock times, which the summary reports.
#pragma once

#include <petscsys.h>

namespace signorini {

enum class Stage { Mesh, Distribute, Refine, Setup, Assemble, Solve, Estimate, Error, Output, Count };

const char    *StageName(Stage s);
PetscErrorCode StagesRegister();
PetscErrorCode StagePush(Stage s);
PetscErrorCode StagePop(Stage s);
// Wall-clock seconds spent in the stage on this rank so far.
PetscLogDouble StageSeconds(Stage s);

} // namespace signorini

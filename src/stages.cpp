#include "signorini/stages.h"

namespace signorini {

namespace {
constexpr int  kCount = (int)Stage::Count;
PetscLogStage  gStage[kCount];
PetscLogDouble gStart[kCount], gTotal[kCount];
bool           gRegistered = false;
} // namespace

const char *StageName(Stage s)
{
  static const char *names[kCount] = {"mesh", "distribute", "refine", "setup", "assemble", "solve", "estimate", "error", "output"};
  return names[(int)s];
}

PetscErrorCode StagesRegister()
{
  static const char *logNames[kCount] = {"Mesh", "Distribute", "Refine", "Setup", "Assemble", "Solve", "Estimate", "Error", "Output"};
  PetscFunctionBeginUser;
  if (gRegistered) PetscFunctionReturn(0);
  for (int i = 0; i < kCount; ++i) {
    PetscCall(PetscLogStageRegister(logNames[i], &gStage[i]));
    gTotal[i] = 0;
  }
  gRegistered = true;
  PetscFunctionReturn(0);
}

PetscErrorCode StagePush(Stage s)
{
  PetscFunctionBeginUser;
  PetscCall(StagesRegister());
  PetscCall(PetscLogStagePush(gStage[(int)s]));
  PetscCall(PetscTime(&gStart[(int)s]));
  PetscFunctionReturn(0);
}

PetscErrorCode StagePop(Stage s)
{
  PetscLogDouble now;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&now));
  gTotal[(int)s] += now - gStart[(int)s];
  PetscCall(PetscLogStagePop());
  PetscFunctionReturn(0);
}

PetscLogDouble StageSeconds(Stage s) { return gTotal[(int)s]; }

} // namespace signorini

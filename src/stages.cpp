#include "signorini/stages.h"
#include "signorini/common.h"

#include <vector>

namespace signorini {

namespace {
constexpr int  kCount = (int)Stage::Count;
PetscLogStage  gStage[kCount];
PetscLogDouble gStart[kCount], gTotal[kCount];
bool           gRegistered = false;
std::vector<Stage> gActive; // the stages pushed and not yet popped, innermost last
} // namespace

const char *StageName(Stage s)
{
  static const char *names[kCount] = {"mesh", "distribute", "refine", "setup", "assemble", "solve", "estimate", "adapt", "error", "output"};
  return names[(int)s];
}

PetscErrorCode StagesRegister()
{
  static const char *logNames[kCount] = {"Mesh", "Distribute", "Refine", "Setup", "Assemble", "Solve", "Estimate", "Adapt", "Error", "Output"};
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
  PetscLogDouble now;
  PetscFunctionBeginUser;
  PetscCall(StagesRegister());
  PetscCall(PetscLogStagePush(gStage[(int)s]));
  PetscCall(PetscTime(&now));
  if (!gActive.empty()) gTotal[(int)gActive.back()] += now - gStart[(int)gActive.back()];
  gActive.push_back(s);
  gStart[(int)s] = now;
  PetscFunctionReturn(0);
}

PetscErrorCode StagePop(Stage s)
{
  PetscLogDouble now;
  PetscFunctionBeginUser;
  PetscCheck(!gActive.empty() && gActive.back() == s, PETSC_COMM_SELF, PETSC_ERR_PLIB, "stage %s popped, but it is not the innermost one", StageName(s));
  PetscCall(PetscTime(&now));
  gTotal[(int)s] += now - gStart[(int)s];
  gActive.pop_back();
  if (!gActive.empty()) gStart[(int)gActive.back()] = now;
  PetscCall(PetscLogStagePop());
  PetscFunctionReturn(0);
}

PetscLogDouble StageSeconds(Stage s) { return gTotal[(int)s]; }

PetscErrorCode StageTimed(MPI_Comm comm, Stage s, double &seconds, const std::function<PetscErrorCode()> &f)
{
  PetscLogDouble t0;
  double         dt;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t0));
  PetscCall(StagePush(s));
  PetscCall(f());
  PetscCall(StagePop(s));
  PetscCall(SecondsSince(comm, t0, &dt));
  seconds += dt;
  PetscFunctionReturn(0);
}

} // namespace signorini

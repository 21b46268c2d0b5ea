static const char help[] =
  "signorini-stream: the memory bandwidth that all ranks get together (STREAM triad a = b + s c).\n"
  "CG + BoomerAMG moves far more bytes than it computes with, so the bandwidth of p ranks divided by p times\n"
  "that of one rank bounds the parallel efficiency the contact solve can reach on this machine; run/scaling\n"
  "prints this ceiling next to the measured efficiencies.\n\n"
  "  mpirun -n P signorini-stream [-stream_n doubles per rank and array] [-stream_repeat K]\n\n";

#include "signorini/common.h"
#include "signorini/options.h"

#include <algorithm>
#include <limits>
#include <vector>

using namespace signorini;

struct StreamOptions {
  PetscInt n      = 1 << 23; // 64 MB per array: three of them outgrow the caches of one socket
  PetscInt repeat = 10;
};

static PetscErrorCode StreamOptionsFromCommandLine(MPI_Comm comm, StreamOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, NULL, "Memory bandwidth (STREAM triad)", NULL);
  PetscCall(OptionInt(PetscOptionsObject, "-stream_n", "doubles in each of the three arrays of every rank", o.n, 1, PETSC_MAX_INT));
  PetscCall(OptionInt(PetscOptionsObject, "-stream_repeat", "timed triads; the fastest counts", o.repeat, 1, PETSC_MAX_INT));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

// Bytes per second that all ranks move together in the fastest of `repeat` triads; every rank starts and
// stops each triad together, so the time is that of the slowest rank, as in a solve.
static PetscErrorCode Triad(MPI_Comm comm, const StreamOptions &o, double *rate)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // Each rank writes its own arrays first, so their pages lie next to the core that uses them.
  std::vector<double> a(o.n, 0.0), b(o.n), c(o.n, 2.0);
  for (PetscInt i = 0; i < o.n; ++i) b[i] = (double)(i % 7);
  const double s    = 3.0;
  double       best = std::numeric_limits<double>::max();
  for (PetscInt r = 0; r < o.repeat; ++r) {
    PetscCallMPI(MPI_Barrier(comm));
    const double t0 = MPI_Wtime();
    for (PetscInt i = 0; i < o.n; ++i) a[i] = b[i] + s * c[i];
    PetscCallMPI(MPI_Barrier(comm));
    best = std::min(best, MPI_Wtime() - t0);
  }
  // The result is checked, so that no compiler can drop the loop and no wrong figure goes unnoticed.
  bool ok = true;
  for (PetscInt i = 0; i < o.n && ok; ++i) ok = a[i] == (double)(i % 7) + 6.0;
  PetscCall(CheckAll(comm, ok, "the triad computed wrong values"));
  *rate = 3.0 * sizeof(double) * (double)o.n * size / best;
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(MPI_Comm comm)
{
  StreamOptions o;
  PetscMPIInt   size;
  double        rate = 0;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(OptionsAsInputError(comm, StreamOptionsFromCommandLine(comm, o)));
  PetscCall(CheckUnknownOptions(comm));
  PetscCall(Triad(comm, o, &rate));
  PetscCall(PetscPrintf(comm, "triad bandwidth: %.3f GB/s on %d rank(s), %.3f GB/s per rank (%d doubles per array and rank, fastest of %d)\n", rate / 1e9, size, rate / 1e9 / size, (int)o.n, (int)o.repeat));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, help);
  if (ierr) return ierr;
  PetscPushErrorHandler(PetscReturnErrorHandler, NULL);
  // Input errors and a wrong triad (CheckAll) are raised on every rank.
  const int status = ExitStatus(PETSC_COMM_WORLD, Run(PETSC_COMM_WORLD), "signorini-stream");
  PetscPopErrorHandler();
  PetscFinalize();
  return status;
}

#include "signorini/common.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace signorini {

PetscErrorCode OwnershipRanges(MPI_Comm comm, PetscInt numOwned, std::vector<PetscInt> &ranges)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  ranges.assign(size + 1, 0);
  PetscCallMPI(MPI_Allgather(&numOwned, 1, MPIU_INT, ranges.data() + 1, 1, MPIU_INT, comm));
  for (PetscMPIInt p = 0; p < size; ++p) ranges[p + 1] += ranges[p];
  PetscFunctionReturn(0);
}

PetscMPIInt OwnerOf(const std::vector<PetscInt> &ranges, PetscInt g)
{
  return (PetscMPIInt)(std::upper_bound(ranges.begin(), ranges.end(), g) - ranges.begin() - 1);
}

std::string Format(const char *fmt, ...)
{
  va_list ap;
  va_start(ap, fmt);
  char buf[1024];
  vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  return buf;
}

PetscErrorCode SecondsSince(MPI_Comm comm, PetscLogDouble t0, double *seconds)
{
  PetscLogDouble t1;
  PetscFunctionBeginUser;
  PetscCall(PetscTime(&t1));
  *seconds = t1 - t0;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, seconds, 1, MPI_DOUBLE, MPI_MAX, comm));
  PetscFunctionReturn(0);
}

void ReleaseFreedMemory()
{
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

PetscErrorCode CheckAll(MPI_Comm comm, bool ok, const std::string &message)
{
  PetscMPIInt rank, failing;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscMPIInt mine = ok ? PETSC_MPI_INT_MAX : rank;
  PetscCallMPI(MPI_Allreduce(&mine, &failing, 1, MPI_INT, MPI_MIN, comm));
  if (failing == PETSC_MPI_INT_MAX) PetscFunctionReturn(0);
  char buf[1024] = {0};
  if (rank == failing) snprintf(buf, sizeof buf, "%s", message.c_str());
  PetscCallMPI(MPI_Bcast(buf, sizeof buf, MPI_CHAR, failing, comm));
  SETERRQ(comm, kInputError, "%s", buf);
}

PetscErrorCode ParseIntList(MPI_Comm comm, const std::string &option, const std::string &text, std::vector<PetscInt> &values)
{
  PetscFunctionBeginUser;
  values.clear();
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find(',', pos);
    if (end == std::string::npos) end = text.size();
    std::string item = text.substr(pos, end - pos);
    char       *stop = nullptr;
    long        v    = std::strtol(item.c_str(), &stop, 10);
    if (item.empty() || *stop != '\0') SIGNORINI_INPUT_ERROR(comm, "option %s: '%s' is not a comma-separated list of integers", option.c_str(), text.c_str());
    values.push_back((PetscInt)v);
    pos = end + 1;
  }
  PetscFunctionReturn(0);
}

} // namespace signorini

namespace signorini {
std::string LastPetscError(PetscErrorCode ierr)
{
  const char *text     = nullptr;
  char       *specific = nullptr;
  PetscErrorMessage(ierr, &text, &specific);
  if (specific && specific[0]) return specific;
  return text ? text : "unknown PETSc error";
}

PetscErrorCode OptionsAsInputError(MPI_Comm comm, PetscErrorCode ierr)
{
  PetscFunctionBeginUser;
  if (ierr && ierr != kInputError) {
    std::string message = LastPetscError(ierr);
    message.erase(message.find_last_not_of(" \n") + 1);
    SIGNORINI_INPUT_ERROR(comm, "invalid option: %s", message.c_str());
  }
  PetscCall(ierr);
  PetscFunctionReturn(0);
}

int ExitStatus(MPI_Comm comm, PetscErrorCode ierr, const char *program)
{
  if (!ierr) return 0;
  PetscMPIInt rank;
  MPI_Comm_rank(comm, &rank);
  if (ierr == kInputError) {
    if (rank == 0) std::fprintf(stderr, "%s: error: %s\n", program, LastPetscError(ierr).c_str());
    return 1;
  }
  std::fprintf(stderr, "%s: error on rank %d (PETSc error %d): %s\n", program, rank, (int)ierr, LastPetscError(ierr).c_str());
  MPI_Abort(comm, 2);
  return 2;
}
} // namespace signorini

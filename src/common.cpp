#include "signorini/common.h"

#include <cstdarg>
#include <cstdio>
#include <cstdlib>

namespace signorini {

std::string Format(const char *fmt, ...)
{
  va_list ap;
  va_start(ap, fmt);
  char buf[1024];
  vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  return buf;
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
} // namespace signorini

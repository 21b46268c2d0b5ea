#include "signorini/common.h"

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>

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
  // Any length: messages quote the user's expressions, which have no length limit.
  va_list ap, again;
  va_start(ap, fmt);
  va_copy(again, ap);
  const int n = std::vsnprintf(nullptr, 0, fmt, ap);
  va_end(ap);
  std::string text(n > 0 ? (size_t)n + 1 : 1, '\0');
  if (n > 0) std::vsnprintf(&text[0], text.size(), fmt, again);
  va_end(again);
  text.resize(n > 0 ? (size_t)n : 0);
  return text;
}

std::string CoordinatesText(PetscInt dim, const PetscReal x[])
{
  return dim == 2 ? Format("%g, %g", (double)x[0], (double)x[1]) : Format("%g, %g, %g", (double)x[0], (double)x[1], (double)x[2]);
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

std::string Trim(const std::string &text)
{
  const size_t first = text.find_first_not_of(" \t"), last = text.find_last_not_of(" \t");
  return first == std::string::npos ? "" : text.substr(first, last - first + 1);
}

std::string ReadInt(const std::string &option, const std::string &text, PetscInt min, PetscInt max, PetscInt &value)
{
  const std::string item = Trim(text);
  char             *stop = nullptr;
  errno                  = 0;
  // strtoll, not PETSc's conversion (which wraps modulo 2^32 in 3.18); the range is checked before the
  // value is narrowed to PetscInt.
  const long long v = item.empty() ? 0 : std::strtoll(item.c_str(), &stop, 10);
  if (item.empty() || *stop != '\0') return Format("option %s: '%s' is not an integer", option.c_str(), item.c_str());
  if (errno == ERANGE || v < min || v > max) return Format("option %s: %s is out of range (an integer from %" PetscInt_FMT " to %" PetscInt_FMT ")", option.c_str(), item.c_str(), min, max);
  value = (PetscInt)v;
  return "";
}

std::string ReadList(const std::string &option, const std::string &text, const std::function<std::string(const std::string &)> &item)
{
  if (Trim(text).empty()) return "";
  for (size_t pos = 0;;) {
    const size_t      end  = std::min(text.find(',', pos), text.size());
    const std::string part = text.substr(pos, end - pos);
    if (Trim(part).empty()) return Format("option %s: '%s' is not a comma-separated list (an empty entry)", option.c_str(), text.c_str());
    const std::string error = item(part);
    if (!error.empty() || end == text.size()) return error;
    pos = end + 1;
  }
}

std::string ReadIntList(const std::string &option, const std::string &text, PetscInt min, PetscInt max, std::vector<PetscInt> &values)
{
  values.clear();
  return ReadList(option, text, [&](const std::string &part) {
    PetscInt          v     = 0;
    const std::string error = ReadInt(option, part, min, max, v);
    values.push_back(v);
    return error;
  });
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
  // The other ranks may wait in a collective call that this one never reaches: only an abort ends them.
  // Alone, this rank finalizes and exits like an input error, without Open MPI's abort banner.
  PetscMPIInt size;
  MPI_Comm_size(comm, &size);
  if (size > 1) MPI_Abort(comm, 2);
  return 2;
}
} // namespace signorini

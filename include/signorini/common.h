// Shared helpers of the signorini components: error reporting that is safe on many ranks.
#pragma once

#include <petsc.h>

#include <functional>
#include <string>
#include <type_traits>
#include <vector>

namespace signorini {

// Every error caused by the user's input is raised with this code on *all* ranks at the same point, so
// main() can print one line and exit cleanly. Any other error code may have been raised on a subset of
// ranks and makes main() abort the whole job instead of waiting in a collective that never completes.
constexpr PetscErrorCode kInputError = PETSC_ERR_USER_INPUT;

// The divergence tolerance of every CG solve here: none. CG minimizes the error in the energy norm, while
// its residual norm may rise on the way by up to about sqrt(cond A) (1e6 and more with a kappa contrast of
// 1e9), which PETSc's default (1e5 times the first residual) took for divergence: stiff-checkerboard
// K = 1e9, CR, DIVERGED_DTOL in the first Newton step. A preconditioner that is not SPD shows as
// DIVERGED_INDEFINITE_PC, a stall as the iterations running out; -ksp_divtol still sets one.
constexpr PetscReal kCGDivergenceTolerance = 1e100;

// Collective check: every rank passes its local verdict; if any rank failed, all ranks raise kInputError
// with the message of the lowest failing rank. Use it for conditions found by rank-local work (a bad cell,
// an expression that is NaN somewhere) so that the other ranks do not hang.
PetscErrorCode CheckAll(MPI_Comm comm, bool ok, const std::string &message);

// Raise kInputError on all ranks (the condition must already be known to every rank).
#define SIGNORINI_INPUT_ERROR(comm, ...) SETERRQ((comm), ::signorini::kInputError, __VA_ARGS__)

// `text` without the blanks (spaces, tabs) around it.
std::string Trim(const std::string &text);
// The integer `text` (named by `option` in the message) in [min, max]: returns "" and sets `value`, or
// returns the message of an input error naming the option and the value (not an integer, or out of range,
// also beyond the range of PetscInt). Surrounding blanks are allowed.
std::string ReadInt(const std::string &option, const std::string &text, PetscInt min, PetscInt max, PetscInt &value);
// Calls `item` on each entry of the comma-separated list `text` (blank text: none) until one returns an
// error message, which is returned; an empty entry ("1,,2") is an error too.
std::string ReadList(const std::string &option, const std::string &text, const std::function<std::string(const std::string &)> &item);
// ReadInt for each entry of a comma-separated list ("1,3,4"; blank text gives an empty list).
std::string ReadIntList(const std::string &option, const std::string &text, PetscInt min, PetscInt max, std::vector<PetscInt> &values);

// f(D) with the dimension dim (2 or 3) as a compile-time constant D, a std::integral_constant: the cell
// loops are templates on the dimension, so that their short loops unroll; this is where a variable
// dimension picks one (WithDim(space.dim, [&](auto D) { return LoopD<D>(...); })).
template <class F>
decltype(auto) WithDim(PetscInt dim, F &&f)
{
  if (dim == 2) return f(std::integral_constant<PetscInt, 2>{});
  return f(std::integral_constant<PetscInt, 3>{});
}

// Collective: the ownership ranges of a distributed index set, ranges[p] .. ranges[p + 1] on rank p, from
// each rank's count of owned indices.
PetscErrorCode OwnershipRanges(MPI_Comm comm, PetscInt numOwned, std::vector<PetscInt> &ranges);
// The rank owning global index g, given the ranges of OwnershipRanges.
PetscMPIInt OwnerOf(const std::vector<PetscInt> &ranges, PetscInt g);

// Collective: wall seconds since t0 (from PetscTime), the maximum over the ranks of comm.
PetscErrorCode SecondsSince(MPI_Comm comm, PetscLogDouble t0, double *seconds);

// Gives the memory that earlier stages freed, but the C library kept for re-use, back to the system
// (glibc's malloc_trim; nothing elsewhere). Called before two solves compared in one run (the contact
// solve and the linear one of -compare_linear) so that they start alike: the first to touch new memory
// pays the kernel for zeroing it (about 2.8 s per GB on the 2-core development VM), and a solve run after
// another would otherwise get that memory for free. Elsewhere freed memory is left to be re-used.
void ReleaseFreedMemory();

// printf-style formatting into a std::string.
std::string Format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
// "x, y" or "x, y, z" (dim coordinates of x), for messages that name a place.
std::string CoordinatesText(PetscInt dim, const PetscReal x[]);

} // namespace signorini

namespace signorini {
// The text of the last PETSc error (for errors caught from a call made without PetscCall).
std::string LastPetscError(PetscErrorCode ierr);

// Reading options involves no rank-dependent work (every rank sees the same options database), so an error
// PETSc raises while reading them (a value not in a list, "-refine abc") is raised again as an input error
// on all ranks. Pass the code returned by the component's options function.
PetscErrorCode OptionsAsInputError(MPI_Comm comm, PetscErrorCode ierr);

// The exit status of an executable after its work returned `ierr`, to be called before PetscFinalize:
// an input error (raised on every rank at the same point) is printed once as "PROGRAM: error: ..." and
// gives 1; any other error may have been raised on a subset of ranks, so it is printed with its rank and
// the whole job is aborted instead of leaving the other ranks waiting in a collective.
int ExitStatus(MPI_Comm comm, PetscErrorCode ierr, const char *program);
} // namespace signorini

// Typed readers of the application's options, and the check that every option given is known.
//
// Each component reads its options in one PetscOptionsBegin/PetscOptionsEnd block with these readers
// (they take the PetscOptionsObject those macros declare), so that -help lists them with their help text
// and current value next to PETSc's own. Unlike PETSc 3.18's readers, which convert integers with atoi-like
// calls that wrap modulo 2^32 (-refine 4294967297 reads as 1) and cut strings to a fixed buffer, these
// take the raw text of the value and check all of it: a value that is not what the option takes is an
// input error naming the option and the value. Under -help no value is refused: the option is listed
// with its default, so that -help works whatever else is on the command line.
//
// Every reader registers the option's name. CheckUnknownOptions then refuses, before any work, an option
// that no component read and that no PETSc object would read either (a mistyped application option).
#pragma once

#include "signorini/common.h"

#include <limits>
#include <map>
#include <string>
#include <vector>

namespace signorini {

using OptionItems = PetscOptionItems *;

// `set` (optional) tells whether the option was given.
PetscErrorCode OptionInt(OptionItems items, const char *name, const char *help, PetscInt &value, PetscInt min, PetscInt max, bool *set = nullptr);
PetscErrorCode OptionReal(OptionItems items, const char *name, const char *help, PetscReal &value, PetscReal min = -std::numeric_limits<PetscReal>::infinity(), PetscReal max = std::numeric_limits<PetscReal>::infinity(), bool *set = nullptr);
// "-name" alone means true; otherwise true/false, yes/no, on/off or 1/0.
PetscErrorCode OptionBool(OptionItems items, const char *name, const char *help, bool &value, bool *set = nullptr);
// The whole value, whatever its length ("-name" alone gives "").
PetscErrorCode OptionString(OptionItems items, const char *name, const char *help, std::string &value, bool *set = nullptr);
// One of `choices` (compared without case); `which` is the index of the choice.
PetscErrorCode OptionEList(OptionItems items, const char *name, const char *help, const std::vector<const char *> &choices, PetscInt &which, bool *set = nullptr);
// Comma-separated values ("" gives an empty list); each integer in [min, max]. The caller checks the count.
PetscErrorCode OptionIntList(OptionItems items, const char *name, const char *help, std::vector<PetscInt> &values, PetscInt min, PetscInt max, bool *set = nullptr);
PetscErrorCode OptionRealList(OptionItems items, const char *name, const char *help, std::vector<PetscReal> &values, bool *set = nullptr);
// OptionIntList whose entries may be names too: `names` maps a name to its numbers (all of them join the
// list); `known` lists the names for the message on an unknown one.
PetscErrorCode OptionNamedIntList(OptionItems items, const char *name, const char *help, std::vector<PetscInt> &values, const std::map<std::string, std::vector<PetscInt>> &names, const std::string &known, bool *set = nullptr);

// Collective; call after every component has read its options and before any work. An option in the
// database (command line, options files, PETSC_OPTIONS) that no reader read and that is not of a PETSc
// family (see IsPetscOption) is an input error naming the closest application option.
PetscErrorCode CheckUnknownOptions(MPI_Comm comm);
// Whether an unread option `name` (with or without its leading '-') is left to PETSc: PETSc reads such
// options when it creates its objects, later in the run, and reports unused ones itself (-options_left).
bool IsPetscOption(const std::string &name);
// The registered application option closest to `name` in edit distance ("" if none is registered).
std::string ClosestOption(const std::string &name);

} // namespace signorini

#include "signorini/options.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <set>

namespace signorini {

namespace {

// Every application option a reader was asked for, with its prefix and leading '-'.
std::set<std::string> &Registry()
{
  static std::set<std::string> names;
  return names;
}

std::string Lower(std::string s)
{
  for (char &ch : s) ch = (char)std::tolower((unsigned char)ch);
  return s;
}

// Registers the option and finds its raw value (null when given without one).
PetscErrorCode Find(OptionItems items, const char *name, std::string &full, const char **text, bool &given)
{
  PetscBool set;
  PetscFunctionBeginUser;
  full = std::string("-") + (items->prefix ? items->prefix : "") + (name + 1);
  Registry().insert(full);
  *text = nullptr;
  PetscCall(PetscOptionsFindPair(items->options, items->prefix, name, text, &set));
  given = set;
  PetscFunctionReturn(0);
}

// Under -help the option is listed (once, as PETSc lists its own) with its value and default.
PetscErrorCode ListHelp(OptionItems items, const std::string &full, const std::string &now, const std::string &formerly, const char *help)
{
  PetscFunctionBeginUser;
  if (items->printhelp && items->count == 1 && !items->alreadyprinted) PetscCall((*PetscHelpPrintf)(items->comm, "  %s <now %s : formerly %s>: %s\n", full.c_str(), now.c_str(), formerly.c_str(), help));
  PetscFunctionReturn(0);
}

// A value that `parse` refuses (it returns the message) is an input error, except under -help, where
// the option keeps its default so that -help works whatever else is on the command line.
template <typename T, typename Parse, typename Show>
PetscErrorCode Read(OptionItems items, const char *name, const char *help, T &value, bool *set, Parse parse, Show show)
{
  std::string full;
  const char *text;
  bool        given;
  PetscFunctionBeginUser;
  PetscCall(Find(items, name, full, &text, given));
  const std::string formerly = show(value);
  if (set) *set = given;
  if (given) {
    T                 parsed = value;
    const std::string error  = parse(full, text, parsed);
    if (error.empty()) value = parsed;
    else if (!items->printhelp) SIGNORINI_INPUT_ERROR(items->comm, "%s", error.c_str());
  }
  PetscCall(ListHelp(items, full, show(value), formerly, help));
  PetscFunctionReturn(0);
}

std::string ReadReal(const std::string &option, const std::string &text, PetscReal min, PetscReal max, PetscReal &value)
{
  const std::string item = Trim(text);
  char             *stop = nullptr;
  errno                  = 0;
  const double v = item.empty() ? 0 : std::strtod(item.c_str(), &stop);
  if (item.empty() || *stop != '\0' || std::isnan(v)) return Format("option %s: '%s' is not a number", option.c_str(), item.c_str());
  if ((errno == ERANGE && std::isinf(v)) || v < min || v > max) return Format("option %s: %s is out of range (from %g to %g)", option.c_str(), item.c_str(), (double)min, (double)max);
  value = (PetscReal)v;
  return "";
}

template <typename T>
std::string Join(const std::vector<T> &values, const char *fmt)
{
  std::string s;
  for (size_t i = 0; i < values.size(); ++i) s += (i ? "," : "") + Format(fmt, values[i]);
  return s;
}

// Optimal string alignment distance: edits, deletions, insertions and swaps of neighbours count one each.
size_t EditDistance(const std::string &a, const std::string &b)
{
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i)
    for (size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1])});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// Whether `name` (no '-', lower case) is `root` or starts with root + '_'.
bool HasRoot(const std::string &name, const std::string &root)
{
  return name.compare(0, root.size(), root) == 0 && (name.size() == root.size() || name[root.size()] == '_');
}

// Which options PETSc reads. Options of PETSc's objects are read only when the object is created,
// later in the run (-snes_* only if the scene has a contact part, -dm_view once the mesh exists), so an
// unread one is not a mistake yet; PETSc itself reports the ones left unused at the end (main.cpp). The
// lists are the first words of the option names compiled into PETSc 3.18 (`strings libpetsc_real.so`).
// Options read once by PetscInitialize, never with a prefix:
const char *const kPetscGlobal[] = {"help", "h", "version", "options", "log", "malloc", "info", "on_error", "error_output", "fp_trap", "no_signal_handler", "debugger", "debugger_ranks", "start_in_debugger", "stop_for_debugger", "debug_terminal", "display", "nox", "checkstack", "check_pointer_intensity", "objects_dump", "memory_view", "citations", "history", "skip_petscrc", "use_gpu_aware_mpi", "mpi", "device", "default_device_type", "root_device_context", "cuda", "hip", "sycl", "kokkos", "petsc", "saws", "python", "dll", "library_preload", "get_total_flops", "x_virtual", "viewfromoptions", "mpidump", "random", "build_twosided", "prefix_push", "prefix_pop", "checkfunctionlist", "noshared", "disable_sse", "popen_machine"};
// Families of PETSc's objects. An object may carry a prefix that PETSc composes (sub_ of block Jacobi
// and ASM, mg_levels_ and mg_coarse_ of multigrid, fieldsplit_NAME_, npc_, fas_levels_, ...), so the
// family may start at any word of the name: -mg_levels_ksp_type, -fieldsplit_0_pc_type.
const char *const kPetscObjects[] = {"snes", "ksp", "pc", "mat", "vec", "dm", "da", "is", "sf", "ao", "tao", "ts", "viewer", "draw", "petscpartitioner", "petscsection", "petscsf", "petscspace", "petscdualspace", "petscfe", "petscfv", "petscds", "petsclimiter", "dmplex", "dmsnes", "dmts", "dmnetwork", "dmcomposite", "stag", "matis", "psubcomm", "pf", "lg", "glvis", "adaptor", "convest", "vecscatter", "vecstash", "matstash", "matload", "vecload", "islocaltoglobalmapping"};

} // namespace

bool IsPetscOption(const std::string &option)
{
  const std::string name = Lower(option.substr(option.compare(0, 1, "-") == 0 ? 1 : 0));
  for (const char *root : kPetscGlobal)
    if (HasRoot(name, root)) return true;
  for (const char *root : kPetscObjects)
    if (HasRoot(name, root)) return true;
  // One edit away from an application option (-vi_pc_typo for -vi_pc_type) is a typo of that option,
  // although a PETSc family follows a word of it.
  const std::string closest = ClosestOption(name);
  if (!closest.empty() && EditDistance("-" + name, Lower(closest)) <= 1) return false;
  for (size_t at = name.find('_'); at != std::string::npos; at = name.find('_', at + 1))
    for (const char *root : kPetscObjects)
      if (HasRoot(name.substr(at + 1), root)) return true;
  return false;
}

std::string ClosestOption(const std::string &option)
{
  const std::string name = Lower(option.compare(0, 1, "-") == 0 ? option : "-" + option);
  std::string       best;
  size_t            bestDistance = 0;
  for (const std::string &known : Registry()) {
    const size_t d = EditDistance(name, Lower(known));
    if (best.empty() || d < bestDistance) best = known, bestDistance = d;
  }
  return best;
}

PetscErrorCode CheckUnknownOptions(MPI_Comm comm)
{
  PetscInt                 n;
  char                   **names, **values;
  std::vector<std::string> unknown;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsLeftGet(NULL, &n, &names, &values));
  for (PetscInt i = 0; i < n; ++i)
    if (!IsPetscOption(names[i])) unknown.push_back(std::string("-") + names[i]);
  PetscCall(PetscOptionsLeftRestore(NULL, &n, &names, &values));
  std::string message;
  if (!unknown.empty()) {
    message = Format("unknown option %s (did you mean %s?)", unknown[0].c_str(), ClosestOption(unknown[0]).c_str());
    for (size_t i = 1; i < unknown.size(); ++i) message += (i == 1 ? "; also unknown: " : ", ") + unknown[i];
  }
  // Every rank holds the same options, but a verdict reached on all ranks together cannot deadlock.
  PetscCall(CheckAll(comm, unknown.empty(), message));
  PetscFunctionReturn(0);
}

PetscErrorCode OptionInt(OptionItems items, const char *name, const char *help, PetscInt &value, PetscInt min, PetscInt max, bool *set)
{
  return Read(
    items, name, help, value, set, [&](const std::string &full, const char *text, PetscInt &v) { return ReadInt(full, text ? text : "", min, max, v); }, [](PetscInt v) { return Format("%" PetscInt_FMT, v); });
}

PetscErrorCode OptionReal(OptionItems items, const char *name, const char *help, PetscReal &value, PetscReal min, PetscReal max, bool *set)
{
  return Read(
    items, name, help, value, set, [&](const std::string &full, const char *text, PetscReal &v) { return ReadReal(full, text ? text : "", min, max, v); }, [](PetscReal v) { return Format("%g", (double)v); });
}

PetscErrorCode OptionBool(OptionItems items, const char *name, const char *help, bool &value, bool *set)
{
  auto parse = [](const std::string &full, const char *text, bool &v) {
    const std::string t = Lower(text ? text : "");
    if (t.empty() || t == "true" || t == "yes" || t == "on" || t == "1") v = true;
    else if (t == "false" || t == "no" || t == "off" || t == "0") v = false;
    else return Format("option %s: '%s' is not true or false", full.c_str(), text);
    return std::string();
  };
  return Read(items, name, help, value, set, parse, [](bool v) { return std::string(v ? "true" : "false"); });
}

PetscErrorCode OptionString(OptionItems items, const char *name, const char *help, std::string &value, bool *set)
{
  return Read(
    items, name, help, value, set,
    [](const std::string &, const char *text, std::string &v) {
      v = text ? text : "";
      return std::string();
    },
    [](const std::string &v) { return v; });
}

PetscErrorCode OptionEList(OptionItems items, const char *name, const char *help, const std::vector<const char *> &choices, PetscInt &which, bool *set)
{
  std::string all;
  for (const char *c : choices) all += (all.empty() ? "" : ", ") + std::string(c);
  const std::string text = Format("%s (one of %s)", help, all.c_str());
  auto parse = [&](const std::string &full, const char *value, PetscInt &w) {
    for (size_t k = 0; k < choices.size(); ++k)
      if (value && Lower(value) == Lower(choices[k])) {
        w = (PetscInt)k;
        return std::string();
      }
    return Format("option %s: '%s' is not one of %s", full.c_str(), value ? value : "", all.c_str());
  };
  return Read(items, name, text.c_str(), which, set, parse, [&](PetscInt w) { return std::string(choices[w]); });
}

PetscErrorCode OptionIntList(OptionItems items, const char *name, const char *help, std::vector<PetscInt> &values, PetscInt min, PetscInt max, bool *set)
{
  return Read(
    items, name, help, values, set, [&](const std::string &full, const char *text, std::vector<PetscInt> &v) { return ReadIntList(full, text ? text : "", min, max, v); }, [](const std::vector<PetscInt> &v) { return Join(v, "%" PetscInt_FMT); });
}

PetscErrorCode OptionNamedIntList(OptionItems items, const char *name, const char *help, std::vector<PetscInt> &values, const std::map<std::string, std::vector<PetscInt>> &names, const std::string &known, bool *set)
{
  auto parse = [&](const std::string &full, const char *text, std::vector<PetscInt> &v) {
    v.clear();
    return ReadList(full, text ? text : "", [&](const std::string &part) {
      const std::string item  = Trim(part);
      PetscInt          x     = 0;
      std::string       error = ReadInt(full, part, PETSC_MIN_INT, PETSC_MAX_INT, x); // a number is a number
      if (error.empty()) {
        v.push_back(x);
        return error;
      }
      const auto it = names.find(item);
      if (it != names.end()) {
        v.insert(v.end(), it->second.begin(), it->second.end());
        return std::string();
      }
      if (!std::isdigit((unsigned char)item[0]) && item[0] != '-' && item[0] != '+') error = Format("option %s: '%s' is neither a number nor the name of a part (%s)", full.c_str(), item.c_str(), known.c_str());
      return error;
    });
  };
  return Read(items, name, help, values, set, parse, [](const std::vector<PetscInt> &v) { return Join(v, "%" PetscInt_FMT); });
}

PetscErrorCode OptionRealList(OptionItems items, const char *name, const char *help, std::vector<PetscReal> &values, bool *set)
{
  auto parse = [](const std::string &full, const char *text, std::vector<PetscReal> &v) {
    v.clear();
    return ReadList(full, text ? text : "", [&](const std::string &part) {
      PetscReal         x     = 0;
      const std::string error = ReadReal(full, part, -std::numeric_limits<PetscReal>::max(), std::numeric_limits<PetscReal>::max(), x);
      v.push_back(x);
      return error;
    });
  };
  return Read(items, name, help, values, set, parse, [](const std::vector<PetscReal> &v) { return Join(v, "%g"); });
}

} // namespace signorini

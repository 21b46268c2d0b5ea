// Unit tests of the option readers (options.h): values read whole and checked (integers beyond PetscInt
// refused, not wrapped), and the split between PETSc's options and mistyped application options.
#include "signorini/options.h"
#include "unit_check.h"

#include <string>
#include <vector>

using namespace signorini;

// Reads -t_int, -t_list, -t_real, -t_bool, -t_string, -vi_pc_type with the readers; returns the error code.
struct Values {
  PetscInt              i = 7;
  std::vector<PetscInt> list;
  PetscReal             r = 0.5;
  bool                  b = false;
  std::string           s = "default", viType = "hypre";
};

static PetscErrorCode ReadAll(Values &v)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(PETSC_COMM_WORLD, "", "unit_options", "");
  PetscCall(OptionInt(PetscOptionsObject, "-t_int", "an integer", v.i, 0, PETSC_MAX_INT));
  PetscCall(OptionIntList(PetscOptionsObject, "-t_list", "integers", v.list, 1, 100));
  PetscCall(OptionReal(PetscOptionsObject, "-t_real", "a real", v.r, 0, 1));
  PetscCall(OptionBool(PetscOptionsObject, "-t_bool", "a flag", v.b));
  PetscCall(OptionString(PetscOptionsObject, "-t_string", "text", v.s));
  PetscCall(OptionString(PetscOptionsObject, "-vi_pc_type", "a name with a PETSc word inside", v.viType));
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

// Sets one option, reads all, clears it again.
static PetscErrorCode Try(const char *name, const char *value, Values &v)
{
  PetscCall(PetscOptionsSetValue(NULL, name, value));
  const PetscErrorCode ierr = ReadAll(v);
  PetscCall(PetscOptionsClearValue(NULL, name));
  return ierr;
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  PetscPushErrorHandler(PetscReturnErrorHandler, NULL); // the refused values below raise input errors
  unit::Checker ck;
  {
    Values v;
    ck.Check(Try("-t_int", "4294967297", v) == kInputError && v.i == 7, "2^32 + 1 is refused, not read as 1", "i = %d", (int)v.i);
    ck.Check(Try("-t_int", "99999999999999999999", v) == kInputError, "beyond long long is refused");
    ck.Check(Try("-t_int", "12abc", v) == kInputError, "12abc is not an integer");
    ck.Check(Try("-t_int", "-1", v) == kInputError, "below the minimum is refused");
    ck.Check(Try("-t_int", " 2147483647 ", v) == 0 && v.i == PETSC_MAX_INT, "the largest PetscInt is read", "i = %d", (int)v.i);
    ck.Check(Try("-t_list", "3, 4,5", v) == 0 && v.list == std::vector<PetscInt>{3, 4, 5}, "a list with blanks");
    ck.Check(Try("-t_list", "3,,5", v) == kInputError && Try("-t_list", "3,", v) == kInputError, "empty entries are refused");
    ck.Check(Try("-t_list", "4294967304", v) == kInputError, "a list entry beyond PetscInt is refused");
    ck.Check(Try("-t_real", "0.25", v) == 0 && v.r == 0.25, "a real is read");
    ck.Check(Try("-t_real", "1.5", v) == kInputError && Try("-t_real", "nan", v) == kInputError && Try("-t_real", "0.1x", v) == kInputError, "reals out of range, NaN and trailing text are refused");
    ck.Check(Try("-t_bool", "", v) == 0 && v.b, "a flag alone is true");
    ck.Check(Try("-t_bool", "OFF", v) == 0 && !v.b && Try("-t_bool", "maybe", v) == kInputError, "off is false, maybe is refused");
    const std::string text(100000, 'x');
    ck.Check(Try("-t_string", text.c_str(), v) == 0 && v.s == text, "a string of 100000 characters is read whole", "length %zu", v.s.size());
  }

  // PETSc's families, also behind the prefixes PETSc composes, are left to PETSc.
  for (const char *name : {"snes_monitr", "ksp_type", "pc_hypre_boomeramg_P_max", "mg_levels_ksp_type", "fieldsplit_0_pc_type", "sub_pc_type", "dm_view", "dm_plex_gmsh_spacedim", "log_view", "malloc_dump", "options_left", "help", "h", "version", "error_output_stdout", "petscpartitioner_type", "snes_linesearch_type", "tao_monitor", "ts_type", "vec_type", "mat_view", "on_error_abort", "fp_trap", "no_signal_handler", "info", "viewer_binary_filename", "npc_snes_type"})
    ck.Check(IsPetscOption(name), std::string("-") + name + " is left to PETSc");
  // A word of a PETSc family inside an application option's name does not hide its typo.
  for (const char *name : {"refin", "kapa", "t_itn", "vi_pc_typo", "vi_pc_tpye", "error_quadrature_degre", "box_face"})
    ck.Check(!IsPetscOption(name), std::string("-") + name + " is not PETSc's");
  ck.Check(ClosestOption("-t_lsit") == "-t_list", "-t_lsit is closest to -t_list", "got %s", ClosestOption("-t_lsit").c_str());
  ck.Check(ClosestOption("-vi_pc_typo") == "-vi_pc_type", "-vi_pc_typo is closest to -vi_pc_type", "got %s", ClosestOption("-vi_pc_typo").c_str());
  PetscPopErrorHandler();
  const int status = ck.Finish();
  PetscFinalize();
  return status;
}

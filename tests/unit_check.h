// Tiny check helper shared by the unit test programs (no test framework): every check prints one line
// "PASS name" or "FAIL name: details", and Finish() prints "N passed, M failed" and gives the exit code.
#pragma once

#include <petscsys.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

namespace unit {

class Checker {
public:
  bool Check(bool ok, const std::string &name) { return Check(ok, name, "%s", "check failed"); }
  // Records one check. `details` (printf-style) is printed only when the check fails.
  bool Check(bool ok, const std::string &name, const char *details, ...) __attribute__((format(printf, 4, 5)))
  {
    if (ok) {
      ++passed_;
      std::printf("PASS %s\n", name.c_str());
    } else {
      char    buf[2048];
      va_list ap;
      va_start(ap, details);
      std::vsnprintf(buf, sizeof buf, details, ap);
      va_end(ap);
      ++failed_;
      std::printf("FAIL %s: %s\n", name.c_str(), buf);
    }
    std::fflush(stdout);
    return ok;
  }
  // |actual - expected| <= tol * max(|expected|, floor): relative comparison with an absolute floor.
  bool Close(double actual, double expected, double tol, const std::string &name, double floor = 1.0)
  {
    const double err = std::fabs(actual - expected), scale = std::fmax(std::fabs(expected), floor);
    return Check(err <= tol * scale && std::isfinite(actual), name, "got %.17g, expected %.17g (error %.3g > %.3g)", actual, expected, err, tol * scale);
  }
  // A PETSc call inside a test failed: counts as a failed check so the run cannot pass.
  void PetscFailure(PetscErrorCode ierr, const std::string &where) { Check(false, where, "PETSc error code %d", (int)ierr); }
  int Finish() const
  {
    std::printf("%d passed, %d failed\n", passed_, failed_);
    std::fflush(stdout);
    return failed_ ? 1 : 0;
  }
  int Failed() const { return failed_; }

private:
  int passed_ = 0, failed_ = 0;
};

} // namespace unit

// A scalar or vector function of (x, y, z) given as text, in the convention of deal.II's FunctionParser:
// muparser syntax, variables x, y, z, the constant pi, and comma-separated components for vector values.
#pragma once

#include "signorini/common.h"

#include <array>
#include <memory>
#include <string>
#include <vector>

namespace mu {
class Parser;
}

namespace signorini {

class Expression {
public:
  // Where an expression is evaluated: in a cell, whose "Cell Sets" value is the variable cell_set (every
  // evaluation site calls SetCellSet), or at points of the boundary, which may touch cells of several sets,
  // where the use of cell_set is an input error.
  enum class At { Cell, Point };
  // `option` names the input in error messages (e.g. "-f"); `components` is 1 for a scalar and dim for a gradient.
  static PetscErrorCode Create(MPI_Comm comm, const std::string &option, const std::string &text, int components, std::unique_ptr<Expression> &expr, At at = At::Cell);
  ~Expression();
  Expression(const Expression &)            = delete;
  Expression &operator=(const Expression &) = delete;

  // Values at point x (x has `dim` entries; missing coordinates read as 0). A NaN or infinite result returns
  // false and, if `error` is still empty, describes the first such point there; callers turn a non-empty
  // `error` into a collective input error after their loop (see CheckAll).
  bool      Eval(const PetscReal x[], PetscInt dim, PetscReal values[], std::string &error) const;
  PetscReal Scalar(const PetscReal x[], PetscInt dim, std::string &error) const;
  // Values at n points at once: point i is x[i * dim ..], its cell_set value cellSets[i] (nullptr: the value
  // of SetCellSet), its values values[i * components ..]. The expression's byte code is run once per block
  // of points, one operation over the whole block, instead of once per point: this is what set-up and error
  // integrals over millions of points call. Eval is EvalBatch of one point, so both give the same values
  // bit for bit; they agree with muparser's own evaluation to round-off (see expression.cpp).
  bool EvalBatch(PetscInt n, const PetscReal x[], PetscInt dim, const PetscInt cellSets[], PetscReal values[], std::string &error) const;
  // Value of the variable cell_set (the "Cell Sets" value of the cell being integrated; -1 if none).
  void               SetCellSet(PetscInt v) const { cellSet_ = (double)v; }
  const std::string &Text() const { return text_; }
  const std::string &Option() const { return option_; }
  // True when the expression is the constant 0, so that an integral of it can be skipped.
  bool IsZero() const { return constant_ && components_ == 1 && value_[0] == 0; }
  // True when the expression uses no variable (x, y, z or cell_set): one value everywhere.
  bool IsConstant() const { return constant_; }
  // True when it reads cell_set (then every cell it is evaluated in needs a "Cell Sets" value).
  bool UsesCellSet() const { return usesCellSet_; }

private:
  Expression() = default;
  struct Program; // muparser's byte code, checked and translated once for block evaluation (expression.cpp)
  bool EvalPointwise(PetscInt n, const PetscReal x[], PetscInt dim, const PetscInt cellSets[], PetscReal values[], std::string &error) const;
  bool CheckFinite(PetscInt n, const PetscReal x[], PetscInt dim, const PetscReal values[], std::string &error) const;
  std::unique_ptr<mu::Parser> parser_;
  mutable std::array<double, 3> xyz_{};
  mutable double                cellSet_ = -1;
  std::string                   option_, text_;
  int                           components_ = 1;
  // An expression that uses no variable (kappa = 1, psi = 0) is evaluated once: set-up evaluates kappa
  // in every cell of every level, and the parser costs about as much as the rest of the cell's work.
  bool                          constant_   = false;
  bool                          usesCellSet_ = false;
  std::array<double, 3>         value_{};
  std::unique_ptr<Program>      program_; // null where the byte code has an operation the block evaluation lacks
};

} // namespace signorini

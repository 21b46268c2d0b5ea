#include "signorini/expression.h"

#include <muParser.h>

#include <cmath>

namespace signorini {

Expression::~Expression() = default;

PetscErrorCode Expression::Create(MPI_Comm comm, const std::string &option, const std::string &text, int components, std::unique_ptr<Expression> &expr, At at)
{
  PetscFunctionBeginUser;
  expr.reset(new Expression());
  Expression &e = *expr;
  e.option_     = option;
  e.text_       = text;
  e.components_ = components;
  e.parser_     = std::make_unique<mu::Parser>();
  std::string message;
  try {
    e.parser_->DefineVar("x", &e.xyz_[0]);
    e.parser_->DefineVar("y", &e.xyz_[1]);
    e.parser_->DefineVar("z", &e.xyz_[2]);
    e.parser_->DefineVar("cell_set", &e.cellSet_);
    e.parser_->DefineConst("pi", M_PI);
    e.parser_->DefineConst("Pi", M_PI);
    e.parser_->SetExpr(text);
    int           n = 0;
    const double *v = e.parser_->Eval(n); // muparser parses lazily: evaluate once so syntax errors surface here
    if (n != components) message = Format("option %s: '%s' has %d component(s), expected %d", option.c_str(), text.c_str(), n, components);
    else if (at == At::Point && e.parser_->GetUsedVar().count("cell_set"))
      message = Format("option %s: cell_set is not defined here (%s is a value at boundary points, which may touch cells of several sets; cell_set is defined in -kappa, -f, -g, -exact_u and -exact_grad)", option.c_str(), option.c_str());
    else if (e.parser_->GetUsedVar().empty()) {
      e.constant_ = true;
      for (int c = 0; c < n && c < 3; ++c) e.value_[c] = v[c];
    }
  } catch (mu::Parser::exception_type &err) {
    std::string what = err.GetMsg();
    what.erase(what.find_last_not_of(" .") + 1);
    if (err.GetCode() == mu::ecUNASSIGNABLE_TOKEN) what += " (not a known name: the variables are x, y, z, cell_set and the constant pi)";
    if (err.GetCode() == mu::ecEXPRESSION_TOO_LONG) what += Format(" (muparser takes at most %d characters)", (int)mu::MaxLenExpression);
    message = Format("option %s: cannot parse '%s': %s", option.c_str(), text.c_str(), what.c_str());
  }
  // Every rank parses the same text, so every rank reaches the same verdict.
  if (!message.empty()) SIGNORINI_INPUT_ERROR(comm, "%s", message.c_str());
  PetscFunctionReturn(0);
}

bool Expression::Eval(const PetscReal x[], PetscInt dim, PetscReal values[], std::string &error) const
{
  for (int d = 0; d < 3; ++d) xyz_[d] = d < dim ? x[d] : 0.0;
  int           n = 0;
  const double *v = nullptr;
  double        scalar;
  try {
    // a scalar through muparser's single-result entry point, which skips the result-array bookkeeping
    if (constant_) v = value_.data();
    else if (components_ == 1) v = &(scalar = parser_->Eval());
    else v = parser_->Eval(n);
  } catch (mu::Parser::exception_type &err) {
    if (error.empty()) error = Format("option %s: evaluating '%s' failed: %s", option_.c_str(), text_.c_str(), err.GetMsg().c_str());
    return false;
  }
  for (int c = 0; c < components_; ++c) {
    values[c] = v[c];
    if (!std::isfinite(v[c])) {
      if (error.empty()) error = Format("option %s: '%s' is %g at (%g, %g, %g)", option_.c_str(), text_.c_str(), v[c], xyz_[0], xyz_[1], xyz_[2]);
      return false;
    }
  }
  return true;
}

PetscReal Expression::Scalar(const PetscReal x[], PetscInt dim, std::string &error) const
{
  PetscReal v = 0;
  Eval(x, dim, &v, error);
  return v;
}

} // namespace signorini

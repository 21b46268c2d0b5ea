#include "signorini/expression.h"

#include <muParser.h>

#include <algorithm>
#include <cmath>

namespace signorini {

// muparser's byte code (its reverse Polish program over a value stack) run over a block of points at once:
// each operation is one loop over the block, so the interpretation costs once per block and the loops are
// plain arithmetic. The operations are muparser's own, in its order and on the same functions, so every
// value is the one muparser's Eval gives, bit for bit (unit_expression checks it), but for one operation:
// an integer power 2, 3 or 4 of a value that is not a variable is the product muparser itself uses for a
// variable's (x^3 is x * x * x) where muparser calls std::pow; the two differ by round-off (about 1 ulp),
// and std::pow was half the cost of the error integrals. One difference in how: muparser evaluates only the
// branch of a ? b : c that is taken; a block takes both and selects per point (the branch not taken may
// produce NaN or inf, which is discarded, as muparser never computes it).
struct Expression::Program {
  static constexpr int kBlock = 128;
  // Operations beyond muparser's: that integer power, and its max and min of any number of arguments and
  // its unary minus inline (muparser calls them through a pointer, max and min with the arguments gathered
  // into an array).
  enum Extra { kMax = mu::cmUNKNOWN + 1, kMin, kPowInt, kNegate };
  struct Op {
    int                        cmd;  // an mu::ECmdCode or an Extra
    int                        var;  // cmVAR, cmVARPOW*, cmVARMUL: 0..2 for x, y, z, 3 for cell_set
    double                     a, b; // cmVAL: b; cmVARMUL: var * a + b
    mu::generic_callable_type  fun;  // cmFUNC
    int                        argc; // cmFUNC: number of arguments, negative for a variable number; kPowInt: the power
    bool                       constant = false; // binary operation, kMax, kMin: the last operand is b, not a slot
  };
  std::vector<Op>             ops;
  int                         slots = 0;     // stack slots, slot 0 unused as in muparser
  mutable std::vector<double> stack, vars, args; // slot k at stack[k * kBlock], variable v at vars[v * kBlock]

  // Null for byte code with an operation or a stack layout this evaluator does not know (the point-wise
  // path then serves the expression): string functions, bulk callbacks, assignments, multiple results
  // inside a branch. maxMin: the addresses of muparser's max and min functions.
  static std::unique_ptr<Program> Translate(const mu::ParserByteCode &code, const double *const variables[4], const void *const maxMin[2], int components)
  {
    auto               p  = std::make_unique<Program>();
    const mu::SToken  *t  = code.GetBase();
    int                sp = 0, maxArgs = 0;
    std::vector<int>   branches; // stack depth at each open cmIF (its condition included)
    for (; t->Cmd != mu::cmEND; ++t) {
      Op op{t->Cmd, -1, 0, 0, {}, 0};
      switch (t->Cmd) {
      case mu::cmPOW: // the exponent a constant 2, 3 or 4: replaces the constant's operation
        if (!p->ops.empty() && p->ops.back().cmd == mu::cmVAL && (p->ops.back().b == 2 || p->ops.back().b == 3 || p->ops.back().b == 4)) {
          op.cmd  = kPowInt;
          op.argc = (int)p->ops.back().b;
          p->ops.pop_back();
          if (--sp < 1) return nullptr;
          break;
        }
        [[fallthrough]];
      case mu::cmLE: case mu::cmGE: case mu::cmNEQ: case mu::cmEQ: case mu::cmLT: case mu::cmGT:
      case mu::cmADD: case mu::cmSUB: case mu::cmMUL: case mu::cmDIV: case mu::cmLAND: case mu::cmLOR:
        if (sp < 2) return nullptr;
        --sp;
        Fold(*p, op);
        break;
      case mu::cmIF: // the condition stays in its slot; the branches take the next two
        if (sp < 1) return nullptr;
        branches.push_back(sp);
        break;
      case mu::cmELSE:
        if (branches.empty() || sp != branches.back() + 1) return nullptr;
        break;
      case mu::cmENDIF:
        if (branches.empty() || sp != branches.back() + 2) return nullptr;
        sp -= 2;
        branches.pop_back();
        break;
      case mu::cmVAL:
        op.b = t->Val.data2;
        ++sp;
        break;
      case mu::cmVAR: case mu::cmVARPOW2: case mu::cmVARPOW3: case mu::cmVARPOW4: case mu::cmVARMUL:
        for (int v = 0; v < 4; ++v)
          if (t->Val.ptr == variables[v]) op.var = v;
        if (op.var < 0) return nullptr;
        op.a = t->Val.data, op.b = t->Val.data2;
        ++sp;
        break;
      case mu::cmFUNC: {
        op.fun = t->Fun.cb, op.argc = t->Fun.argc;
        const int n = op.argc < 0 ? -op.argc : op.argc;
        if (op.argc > 3 || sp < n || (op.argc < 0 && n < 1)) return nullptr;
        if (op.argc < 0 && (void *)op.fun._pRawFun == maxMin[0]) op.cmd = kMax;
        if (op.argc < 0 && (void *)op.fun._pRawFun == maxMin[1]) op.cmd = kMin;
        if (op.argc == 1 && (void *)op.fun._pRawFun == UnaryMinus()) op.cmd = kNegate;
        sp += 1 - n;
        if (op.cmd != mu::cmFUNC && n > 1) Fold(*p, op);
        maxArgs = std::max(maxArgs, n);
        break;
      }
      default:
        return nullptr;
      }
      p->slots = std::max(p->slots, sp + 1);
      p->ops.push_back(op);
    }
    if (sp != components || !branches.empty()) return nullptr;
    p->stack.resize((size_t)p->slots * kBlock);
    p->vars.resize(4 * kBlock);
    p->args.resize(maxArgs);
    return p;
  }

  // The address of muparser's unary minus, read from the byte code of "-x" (muparser lists its functions
  // but not its sign operators).
  static const void *UnaryMinus()
  {
    static const void *address = [] {
      mu::Parser p;
      double     x = 0;
      p.DefineVar("x", &x);
      p.SetExpr("-x");
      p.Eval();
      const mu::SToken *t = p.GetByteCode().GetBase();
      return t[0].Cmd == mu::cmVAR && t[1].Cmd == mu::cmFUNC && t[1].Fun.argc == 1 ? (const void *)t[1].Fun.cb._pRawFun : nullptr;
    }();
    return address;
  }

  // An operation whose last operand is a constant (x - 0.4, max(x, 0)) takes the constant from the op
  // instead of a slot the constant's own operation would fill: the constant's op is dropped.
  static void Fold(Program &p, Op &op)
  {
    if (p.ops.empty() || p.ops.back().cmd != mu::cmVAL) return;
    op.constant = true;
    op.b        = p.ops.back().b;
    p.ops.pop_back();
  }

  // a = f(a, b) over the block: b the next slot, or op.b.
  template <class F>
  static void Binary(const Op &op, double *a, int m, F f)
  {
    const double *b = a + kBlock, c = op.b;
    if (op.constant)
      for (int j = 0; j < m; ++j) a[j] = f(a[j], c);
    else
      for (int j = 0; j < m; ++j) a[j] = f(a[j], b[j]);
  }

  // Runs the program on the first m entries of vars; the results are in slots 1..components.
  void Run(int m) const
  {
    int sp = 0;
    for (const Op &op : ops) {
      double       *s = &stack[(size_t)sp * kBlock], *top = s - kBlock; // s: slot sp; top: slot sp - 1
      const double *v = op.var >= 0 ? &vars[op.var * kBlock] : nullptr;
      // a binary operation's result replaces its first operand: slot sp - 1, or sp with a constant second
      double       *a = op.constant ? s : top;
      if (op.cmd < mu::cmASSIGN && !op.constant) --sp;
      switch (op.cmd) {
      case mu::cmLE: Binary(op, a, m, [](double x, double y) -> double { return x <= y; }); break;
      case mu::cmGE: Binary(op, a, m, [](double x, double y) -> double { return x >= y; }); break;
      case mu::cmNEQ: Binary(op, a, m, [](double x, double y) -> double { return x != y; }); break;
      case mu::cmEQ: Binary(op, a, m, [](double x, double y) -> double { return x == y; }); break;
      case mu::cmLT: Binary(op, a, m, [](double x, double y) -> double { return x < y; }); break;
      case mu::cmGT: Binary(op, a, m, [](double x, double y) -> double { return x > y; }); break;
      case mu::cmADD: Binary(op, a, m, [](double x, double y) { return x + y; }); break;
      case mu::cmSUB: Binary(op, a, m, [](double x, double y) { return x - y; }); break;
      case mu::cmMUL: Binary(op, a, m, [](double x, double y) { return x * y; }); break;
      case mu::cmDIV: Binary(op, a, m, [](double x, double y) { return x / y; }); break;
      case mu::cmPOW: Binary(op, a, m, [](double x, double y) { return mu::MathImpl<double>::Pow(x, y); }); break;
      case mu::cmLAND: Binary(op, a, m, [](double x, double y) -> double { return x && y; }); break;
      case mu::cmLOR: Binary(op, a, m, [](double x, double y) -> double { return x || y; }); break;
      case mu::cmIF: case mu::cmELSE: break;
      case mu::cmENDIF: { // slots sp - 2, sp - 1, sp: condition, then, else
        double *c = s - 2 * kBlock;
        for (int j = 0; j < m; ++j) c[j] = c[j] == 0 ? s[j] : top[j];
        sp -= 2;
        break;
      }
      case mu::cmVAL: std::fill(s + kBlock, s + kBlock + m, op.b); ++sp; break;
      case mu::cmVAR: std::copy(v, v + m, s + kBlock); ++sp; break;
      case mu::cmVARPOW2: for (int j = 0; j < m; ++j) s[kBlock + j] = v[j] * v[j]; ++sp; break;
      case mu::cmVARPOW3: for (int j = 0; j < m; ++j) s[kBlock + j] = v[j] * v[j] * v[j]; ++sp; break;
      case mu::cmVARPOW4: for (int j = 0; j < m; ++j) s[kBlock + j] = v[j] * v[j] * v[j] * v[j]; ++sp; break;
      case mu::cmVARMUL: for (int j = 0; j < m; ++j) s[kBlock + j] = v[j] * op.a + op.b; ++sp; break;
      case mu::cmFUNC: Function(op, sp, m); break;
      case kMax: case kMin: MaxMin(op, sp, m); break;
      case kNegate: for (int j = 0; j < m; ++j) s[j] = -s[j]; break;
      case kPowInt: {
        double *b = s;
        if (op.argc == 2) for (int j = 0; j < m; ++j) b[j] = b[j] * b[j];
        else if (op.argc == 3) for (int j = 0; j < m; ++j) b[j] = b[j] * b[j] * b[j];
        else for (int j = 0; j < m; ++j) b[j] = b[j] * b[j] * b[j] * b[j];
        break;
      }
      default: throw mu::ParserError(mu::ecINTERNAL_ERROR); // Translate admits no other operation
      }
    }
  }

  // muparser's max or min of -argc arguments in its order of comparisons: in the top -argc slots, or
  // the last one op.b and the others in the top -argc - 1 slots.
  void MaxMin(const Op &op, int &sp, int m) const
  {
    const int n = -op.argc, inSlots = op.constant ? n - 1 : n;
    sp         += 1 - inSlots;
    double *a   = &stack[(size_t)sp * kBlock];
    if (op.cmd == kMax) MaxMinLoop(a, inSlots, op.constant, op.b, m, [](double x, double y) { return std::max(x, y); });
    else MaxMinLoop(a, inSlots, op.constant, op.b, m, [](double x, double y) { return std::min(x, y); });
  }
  // In place on the first slot (f(r, r) = r), one loop per argument so that each loop is plain arithmetic.
  template <class F>
  static void MaxMinLoop(double *a, int inSlots, bool constant, double c, int m, F f)
  {
    for (int k = 0; k < inSlots; ++k)
      for (int j = 0; j < m; ++j) a[j] = f(a[j], a[k * kBlock + j]);
    if (constant)
      for (int j = 0; j < m; ++j) a[j] = f(a[j], c);
  }

  // A function of argc arguments in slots sp - argc + 1 .. sp; its value replaces the first.
  void Function(const Op &op, int &sp, int m) const
  {
    const int n     = op.argc < 0 ? -op.argc : op.argc;
    sp             += 1 - n;
    double   *a     = &stack[(size_t)sp * kBlock];
    const double *b = a + kBlock, *c = b + kBlock;
    switch (op.argc) {
    case 0: for (int j = 0; j < m; ++j) a[j] = op.fun.call_fun<0>(); break;
    case 1: for (int j = 0; j < m; ++j) a[j] = op.fun.call_fun<1>(a[j]); break;
    case 2: for (int j = 0; j < m; ++j) a[j] = op.fun.call_fun<2>(a[j], b[j]); break;
    case 3: for (int j = 0; j < m; ++j) a[j] = op.fun.call_fun<3>(a[j], b[j], c[j]); break;
    default: // a variable number of arguments, handed over as one array per point
      for (int j = 0; j < m; ++j) {
        for (int k = 0; k < n; ++k) args[k] = a[k * kBlock + j];
        a[j] = op.fun.call_multfun(args.data(), n);
      }
    }
  }
};

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
    e.usesCellSet_ = e.parser_->GetUsedVar().count("cell_set") > 0;
    if (n != components) message = Format("option %s: '%s' has %d component(s), expected %d", option.c_str(), text.c_str(), n, components);
    else if (at == At::Point && e.parser_->GetUsedVar().count("cell_set"))
      message = Format("option %s: cell_set is not defined here (%s is a value at boundary points, which may touch cells of several sets; cell_set is defined in -kappa, -f, -g, -exact_u and -exact_grad)", option.c_str(), option.c_str());
    else if (e.parser_->GetUsedVar().empty()) {
      e.constant_ = true;
      for (int c = 0; c < n && c < 3; ++c) e.value_[c] = v[c];
    } else {
      const double        *variables[4] = {&e.xyz_[0], &e.xyz_[1], &e.xyz_[2], &e.cellSet_};
      const mu::funmap_type &functions  = e.parser_->GetFunDef();
      const void          *maxMin[2]    = {functions.count("max") ? functions.at("max").GetAddr() : nullptr, functions.count("min") ? functions.at("min").GetAddr() : nullptr};
      e.program_                        = Program::Translate(e.parser_->GetByteCode(), variables, maxMin, components);
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

bool Expression::CheckFinite(PetscInt n, const PetscReal x[], PetscInt dim, const PetscReal values[], std::string &error) const
{
  for (PetscInt i = 0; i < n; ++i)
    for (int c = 0; c < components_; ++c) {
      const PetscReal v = values[i * components_ + c];
      if (std::isfinite(v)) continue;
      if (error.empty()) error = Format("option %s: '%s' is %g at (%g, %g, %g)", option_.c_str(), text_.c_str(), v, x[i * dim], dim > 1 ? x[i * dim + 1] : 0.0, dim > 2 ? x[i * dim + 2] : 0.0);
      return false;
    }
  return true;
}

// Point by point through muparser: the path of byte code that Program does not translate.
bool Expression::EvalPointwise(PetscInt n, const PetscReal x[], PetscInt dim, const PetscInt cellSets[], PetscReal values[], std::string &error) const
{
  const double cellSet = cellSet_;
  try {
    for (PetscInt i = 0; i < n; ++i) {
      for (int d = 0; d < 3; ++d) xyz_[d] = d < dim ? x[i * dim + d] : 0.0;
      if (cellSets) cellSet_ = (double)cellSets[i];
      int           k = 0;
      const double *v = components_ == 1 ? &(values[i] = parser_->Eval()) : parser_->Eval(k);
      std::copy(v, v + components_, values + i * components_);
    }
  } catch (mu::Parser::exception_type &err) {
    cellSet_ = cellSet;
    if (error.empty()) error = Format("option %s: evaluating '%s' failed: %s", option_.c_str(), text_.c_str(), err.GetMsg().c_str());
    return false;
  }
  cellSet_ = cellSet;
  return CheckFinite(n, x, dim, values, error);
}

bool Expression::EvalBatch(PetscInt n, const PetscReal x[], PetscInt dim, const PetscInt cellSets[], PetscReal values[], std::string &error) const
{
  if (constant_) {
    for (PetscInt i = 0; i < n; ++i) std::copy(value_.begin(), value_.begin() + components_, values + i * components_);
    return CheckFinite(n, x, dim, values, error);
  }
  if (!program_) return EvalPointwise(n, x, dim, cellSets, values, error);
  const Program &p = *program_;
  constexpr int  B = Program::kBlock;
  for (PetscInt i0 = 0; i0 < n; i0 += B) {
    const int m = (int)std::min<PetscInt>(B, n - i0);
    for (int j = 0; j < m; ++j) {
      for (int d = 0; d < 3; ++d) p.vars[d * B + j] = d < dim ? x[(i0 + j) * dim + d] : 0.0;
      p.vars[3 * B + j] = cellSets ? (double)cellSets[i0 + j] : cellSet_;
    }
    try {
      p.Run(m);
    } catch (mu::Parser::exception_type &err) {
      if (error.empty()) error = Format("option %s: evaluating '%s' failed: %s", option_.c_str(), text_.c_str(), err.GetMsg().c_str());
      return false;
    }
    for (int j = 0; j < m; ++j)
      for (int c = 0; c < components_; ++c) values[(i0 + j) * components_ + c] = p.stack[(size_t)(1 + c) * B + j];
  }
  return CheckFinite(n, x, dim, values, error);
}

bool Expression::Eval(const PetscReal x[], PetscInt dim, PetscReal values[], std::string &error) const
{
  return EvalBatch(1, x, dim, nullptr, values, error);
}

PetscReal Expression::Scalar(const PetscReal x[], PetscInt dim, std::string &error) const
{
  PetscReal v = 0;
  Eval(x, dim, &v, error);
  return v;
}

} // namespace signorini

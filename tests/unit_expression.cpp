// Unit tests of Expression::EvalBatch, the block evaluation of the data expressions: at points that fill
// several blocks and a partial one, with a different cell_set per point, its values must be those of
// Expression::Eval bit for bit, and those of an independent muparser Parser evaluated point by point: bit
// for bit, except that an integer power of a value that is not a variable ((x - y)^3) is a product where
// muparser calls std::pow, which differs by round-off (at most 4 ulp checked); a constant expression gives
// its one value everywhere, and a non-finite value is reported at its point.
#include "signorini/expression.h"
#include "unit_check.h"

#include <muParser.h>

#include <cfloat>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

using signorini::Expression;

// Values of `text` at the points by a fresh muparser Parser, one Eval per point (the reference).
static std::vector<double> Reference(const std::string &text, int dim, const std::vector<double> &x, const std::vector<PetscInt> &sets, int components)
{
  mu::Parser p;
  double     v[4] = {0, 0, 0, 0};
  p.DefineVar("x", &v[0]);
  p.DefineVar("y", &v[1]);
  p.DefineVar("z", &v[2]);
  p.DefineVar("cell_set", &v[3]);
  p.DefineConst("pi", M_PI);
  p.DefineConst("Pi", M_PI);
  p.SetExpr(text);
  std::vector<double> out;
  for (size_t i = 0; i < sets.size(); ++i) {
    for (int d = 0; d < 3; ++d) v[d] = d < dim ? x[i * dim + d] : 0.0;
    v[3]            = (double)sets[i];
    int           n = 0;
    const double *r = p.Eval(n);
    out.insert(out.end(), r, r + components);
  }
  return out;
}

// a == b bit for bit, or within `ulps` units in the last place of b.
static bool Same(const std::vector<double> &a, const std::vector<double> &b, size_t *where, double ulps = 0)
{
  for (size_t i = 0; i < a.size(); ++i) {
    const bool close = std::fabs(a[i] - b[i]) <= ulps * std::ldexp(DBL_EPSILON, std::ilogb(b[i]));
    if (std::memcmp(&a[i], &b[i], sizeof(double)) && !close) return *where = i, false;
  }
  return a.size() == b.size();
}

int main(int argc, char **argv)
{
  unit::Checker check;
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  struct Case {
    const char *text;
    int         components;
    bool        powers = false; // an integer power of a value that is not a variable
  };
  const Case cases[] = {
    {"6.24 * (z * max(0.4 + 0.2 * y - x, 0) - max(x - 0.4 - 0.2 * y, 0))", 1},
    {"max(x - 0.4 - 0.2 * y, 0)^3 - z * max(0.4 + 0.2 * y - x, 0)^3", 1, true},
    {"3 * max(x - 0.4 - 0.2 * y, 0)^2 + 3 * z * max(0.4 + 0.2 * y - x, 0)^2, -0.6 * max(x - 0.4 - 0.2 * y, 0)^2, -max(0.4 + 0.2 * y - x, 0)^3", 3, true},
    {"2*pi*sin(2*pi*x)", 1},
    {"(x < 0.3 ? -1 : (x > 0.7 ? 1 : (y < 0.5 ? 0.2 : -0.2))) * (3 * x^2 + y^3 + z^4)", 1},
    {"cell_set == 2 ? 10 : (cell_set == 1 && x > 0.5 ? 3 : 1)", 1},
    {"exp(-x) * cos(y) + sqrt(z + 1) - abs(x - y) + sign(y - 0.5) + atan2(y, x + 1)", 1},
    {"min(x, y, z, 0.5) + sum(x, 2*y, 3*z) / avg(1, x + 1) - (x || y < 0.2) + (z >= 0.3 && x != y) * 2", 1},
    {"-x^2 + 2 * x * y - y / (1 + z) + x^2 * 3 + 1e-3 * x, y^2 - x, 4 * z - 1", 3},
    {"x > 0.5 ? sin(x) : log(x)", 1},
    {"(x + y)^2.5 - (1 + z)^(-1) + 2^x + (y - x)^4 * (x + 1)^2", 1, true},
    {"y = 2 * x, y + z", 2}, // an assignment: the block evaluation leaves it to muparser, point by point
  };
  // 300 points: two full blocks of 128 and a partial one; coordinates in [0, 1), cell sets 0, 1, 2.
  const int             n = 300;
  std::vector<double>   x(3 * n);
  std::vector<PetscInt> sets(n);
  unsigned              seed = 12345;
  for (int i = 0; i < 3 * n; ++i) x[i] = ((seed = seed * 1103515245u + 12345u) >> 8) / 16777216.0;
  for (int i = 0; i < n; ++i) sets[i] = i % 3;
  for (const Case &c : cases) {
    for (int dim : {2, 3}) {
      std::unique_ptr<Expression> e;
      PetscCall(Expression::Create(PETSC_COMM_SELF, "-test", c.text, c.components, e));
      std::vector<double> batch(n * c.components), single(n * c.components), dx(x.begin(), x.begin() + n * dim);
      std::string         error;
      const bool          ok = e->EvalBatch(n, dx.data(), dim, sets.data(), batch.data(), error);
      for (int i = 0; i < n; ++i) {
        e->SetCellSet(sets[i]);
        e->Eval(&dx[i * dim], dim, &single[i * c.components], error);
      }
      const std::vector<double> ref  = Reference(c.text, dim, dx, sets, c.components);
      size_t                    at   = 0;
      const std::string         name = std::string(c.text).substr(0, 40) + signorini::Format(" (%dD)", dim);
      check.Check(ok && error.empty(), "finite: " + name, "%s", error.c_str());
      check.Check(Same(batch, single, &at), "block = Eval point by point: " + name, "entry %zu: %.17g vs %.17g", at, batch[at], single[at]);
      check.Check(Same(batch, ref, &at, c.powers ? 4 : 0), "block = muparser point by point: " + name, "entry %zu: %.17g vs %.17g", at, batch[at], ref[at]);
    }
  }
  {
    std::unique_ptr<Expression> e;
    PetscCall(Expression::Create(PETSC_COMM_SELF, "-kappa", "2^3 + pi", 1, e));
    std::vector<double> v(n);
    std::string         error;
    e->EvalBatch(n, x.data(), 3, nullptr, v.data(), error);
    bool all = e->IsConstant();
    for (double vi : v) all = all && vi == 8 + M_PI;
    check.Check(all && error.empty(), "a constant expression gives its one value at every point");
  }
  {
    std::unique_ptr<Expression> e;
    PetscCall(Expression::Create(PETSC_COMM_SELF, "-f", "1 / (x - 0.25)", 1, e));
    const double pts[8] = {0.1, 0, 0.2, 0, 0.25, 0.5, 0.3, 0};
    double       v[4];
    std::string  error;
    const bool   ok = e->EvalBatch(4, pts, 2, nullptr, v, error);
    check.Check(!ok && error == "option -f: '1 / (x - 0.25)' is inf at (0.25, 0.5, 0)", "a non-finite value is reported at its point", "got '%s'", error.c_str());
  }
  PetscCall(PetscFinalize());
  return check.Finish();
}

// Unit tests of the quadrature rules: SimplexQuadrature on the reference simplex of dimension 1, 2, 3 and
// GaussLegendre01 on [0, 1], against exact integrals of monomials computed from factorial formulas.
#include "signorini/quadrature.h"
#include "unit_check.h"

#include <cmath>
#include <string>
#include <vector>

using signorini::Quadrature;

static double Factorial(int n)
{
  double f = 1;
  for (int k = 2; k <= n; ++k) f *= k;
  return f;
}

// Exact mean of x^e[0] y^e[1] z^e[2] over the reference dim-simplex (integral divided by its measure
// 1/dim!): dim! * prod e_i! / (sum e_i + dim)!.
static double ExactMonomialMean(int dim, const int *e)
{
  double num = Factorial(dim);
  int    sum = 0;
  for (int d = 0; d < dim; ++d) {
    num *= Factorial(e[d]);
    sum += e[d];
  }
  return num / Factorial(sum + dim);
}

// Rule applied to x^e[0] y^e[1] z^e[2] where (x, y, z) = (bary[1], bary[2], bary[3]).
static double RuleMonomial(const Quadrature &q, int dim, const int *e)
{
  double s = 0;
  for (PetscInt p = 0; p < q.Size(); ++p) {
    double v = q.weights[p];
    for (int d = 0; d < dim; ++d) v *= std::pow(q.Point(p)[d + 1], e[d]);
    s += v;
  }
  return s;
}

// All exponent vectors of length dim with total degree <= maxDeg.
static std::vector<std::vector<int>> Exponents(int dim, int maxDeg)
{
  std::vector<std::vector<int>> out;
  for (int a = 0; a <= maxDeg; ++a)
    for (int b = 0; b <= (dim >= 2 ? maxDeg - a : 0); ++b)
      for (int c = 0; c <= (dim >= 3 ? maxDeg - a - b : 0); ++c) out.push_back({a, b, c});
  return out;
}

static void TestSimplexRule(unit::Checker &ck, int dim, int degree)
{
  const std::string tag = "simplex dim=" + std::to_string(dim) + " degree=" + std::to_string(degree);
  Quadrature        q   = signorini::SimplexQuadrature(dim, degree);
  ck.Check(q.dim == dim && q.degree == degree, tag + " header", "dim %d degree %d", (int)q.dim, (int)q.degree);
  ck.Check(q.Size() >= 1 && (PetscInt)q.bary.size() == q.Size() * (dim + 1), tag + " sizes", "%d points, %zu barycentric entries", (int)q.Size(), q.bary.size());

  // Weights: positive, sum 1.
  double wsum = 0, wmin = 1e300;
  for (double w : q.weights) {
    wsum += w;
    wmin = std::fmin(wmin, w);
  }
  ck.Check(wmin > 0, tag + " weights positive", "min weight %g", wmin);
  ck.Close(wsum, 1.0, 1e-14, tag + " weights sum to 1");

  // Barycentric coordinates in [0, 1], summing to 1.
  double worstRange = 0, worstSum = 0;
  for (PetscInt p = 0; p < q.Size(); ++p) {
    double s = 0;
    for (int k = 0; k <= dim; ++k) {
      const double l = q.Point(p)[k];
      s += l;
      worstRange = std::fmax(worstRange, std::fmax(-l, l - 1));
    }
    worstSum = std::fmax(worstSum, std::fabs(s - 1));
  }
  ck.Check(worstRange <= 0, tag + " barycentric in [0,1]", "a coordinate is outside [0,1] by %g", worstRange);
  ck.Check(worstSum <= 1e-14, tag + " barycentric sum 1", "max |sum - 1| = %g", worstSum);

  // Every monomial of total degree <= degree is integrated exactly.
  double      worst = 0;
  std::string worstName;
  for (const auto &e : Exponents(dim, degree)) {
    const double exact = ExactMonomialMean(dim, e.data()), got = RuleMonomial(q, dim, e.data());
    const double rel   = std::fabs(got - exact) / exact;
    if (rel > worst) {
      worst     = rel;
      worstName = "x^" + std::to_string(e[0]) + " y^" + std::to_string(e[1]) + " z^" + std::to_string(e[2]) + " got " + std::to_string(got) + " exact " + std::to_string(exact);
    }
  }
  ck.Check(worst <= 1e-13, tag + " exact for monomials of degree <= " + std::to_string(degree), "worst relative error %.3g at %s", worst, worstName.c_str());

  // The same in all dim+1 barycentric coordinates (checks lambda_0 too): mean of prod lambda_k^a_k is
  // dim! prod a_k! / (sum a_k + dim)!.
  worst = 0;
  for (const auto &e : Exponents(dim, degree)) {
    const int rest = degree - e[0] - e[1] - e[2]; // remaining degree given to lambda_0
    for (int a0 = 0; a0 <= rest; ++a0) {
      double exact = Factorial(dim) * Factorial(a0), got = 0;
      int    sum   = a0;
      for (int d = 0; d < dim; ++d) {
        exact *= Factorial(e[d]);
        sum += e[d];
      }
      exact /= Factorial(sum + dim);
      for (PetscInt p = 0; p < q.Size(); ++p) {
        double v = q.weights[p] * std::pow(q.Point(p)[0], a0);
        for (int d = 0; d < dim; ++d) v *= std::pow(q.Point(p)[d + 1], e[d]);
        got += v;
      }
      worst = std::fmax(worst, std::fabs(got - exact) / exact);
    }
  }
  ck.Check(worst <= 1e-13, tag + " exact for barycentric monomials incl. lambda_0", "worst relative error %.3g", worst);
}

static void TestGaussLegendre(unit::Checker &ck, int n)
{
  const std::string      tag = "gauss-legendre n=" + std::to_string(n);
  std::vector<PetscReal> t, w;
  signorini::GaussLegendre01(n, t, w);
  ck.Check((int)t.size() == n && (int)w.size() == n, tag + " sizes", "%zu points, %zu weights", t.size(), w.size());
  if ((int)t.size() != n || (int)w.size() != n) return;
  bool inside = true, positive = true, distinct = true;
  for (int i = 0; i < n; ++i) {
    inside   = inside && t[i] > 0 && t[i] < 1;
    positive = positive && w[i] > 0;
    for (int j = 0; j < i; ++j) distinct = distinct && std::fabs(t[i] - t[j]) > 1e-8;
  }
  ck.Check(inside && positive && distinct, tag + " points in (0,1), distinct, weights positive");
  // Exact for t^k, k <= 2n-1: integral 1/(k+1).
  double worst = 0;
  int    worstK = -1;
  for (int k = 0; k <= 2 * n - 1; ++k) {
    double s = 0;
    for (int i = 0; i < n; ++i) s += w[i] * std::pow(t[i], k);
    const double rel = std::fabs(s - 1.0 / (k + 1)) * (k + 1);
    if (rel > worst) worst = rel, worstK = k;
  }
  ck.Check(worst <= 1e-13, tag + " exact for t^k, k <= 2n-1", "worst relative error %.3g at k = %d", worst, worstK);
  // Not exact for t^(2n): the Gauss error on [0, 1] is (n!)^4 / ((2n+1) ((2n)!)^3) g^(2n), i.e.
  // (n!)^4 / ((2n+1) ((2n)!)^2) for g = t^(2n) (n = 1: midpoint rule, 1/3 - 1/4 = 1/12). Checked while the
  // error is well above rounding.
  if (n > 6) return;
  double s = 0;
  for (int i = 0; i < n; ++i) s += w[i] * std::pow(t[i], 2 * n);
  const double errExact = std::pow(Factorial(n), 4) / ((2 * n + 1) * std::pow(Factorial(2 * n), 2));
  ck.Close(1.0 / (2 * n + 1) - s, errExact, 1e-6, tag + " error for t^(2n) matches the Gauss error term", 1e-300);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  for (int dim = 1; dim <= 3; ++dim)
    for (int degree = 1; degree <= 8; ++degree) TestSimplexRule(ck, dim, degree);

  // Degree 1 is the centroid rule and must not integrate x^2 exactly: it gives 1/(dim+1)^2, the exact
  // mean is 2 dim! / (dim+2)! = 2 / ((dim+1)(dim+2)).
  for (int dim = 1; dim <= 3; ++dim) {
    Quadrature   q = signorini::SimplexQuadrature(dim, 1);
    const int    e[3] = {2, 0, 0};
    const double got = RuleMonomial(q, dim, e), exact = ExactMonomialMean(dim, e);
    ck.Check(q.Size() == 1, "centroid rule dim=" + std::to_string(dim) + " has one point", "%d points", (int)q.Size());
    ck.Close(got, 1.0 / ((dim + 1) * (dim + 1)), 1e-15, "centroid rule dim=" + std::to_string(dim) + " gives 1/(dim+1)^2 for x^2");
    ck.Check(std::fabs(got - exact) > 1e-3 * exact, "centroid rule dim=" + std::to_string(dim) + " is not exact for x^2", "got %.17g, exact %.17g", got, exact);
  }
  for (int n = 1; n <= 12; ++n) TestGaussLegendre(ck, n);

  // The symmetric rules' point counts, which set the cost of a load integral (exactness is checked above).
  const int points2[] = {1, 3, 6, 6, 7}, points3[] = {1, 4, 14, 14, 14};
  for (int degree = 1; degree <= 5; ++degree) {
    const PetscInt n2 = signorini::SimplexQuadrature(2, degree).Size(), n3 = signorini::SimplexQuadrature(3, degree).Size();
    ck.Check(n2 == points2[degree - 1] && n3 == points3[degree - 1], "degree " + std::to_string(degree) + " rules have " + std::to_string(points2[degree - 1]) + " (triangle) and " + std::to_string(points3[degree - 1]) + " (tetrahedron) points", "%d and %d", (int)n2, (int)n3);
  }

  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

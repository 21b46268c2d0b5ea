#include "signorini/quadrature.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>

namespace signorini {

void GaussLegendre01(PetscInt n, std::vector<PetscReal> &points, std::vector<PetscReal> &weights)
{
  points.assign(n, 0.0);
  weights.assign(n, 0.0);
  // Newton's method on the Legendre polynomial P_n from Chebyshev-like initial guesses.
  for (PetscInt i = 0; i < n; ++i) {
    double t = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1, p1 = t;
      for (PetscInt k = 2; k <= n; ++k) {
        double pk = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0        = p1;
        p1        = pk;
      }
      double pn = n == 0 ? 1 : (n == 1 ? t : p1);
      double pm = n == 1 ? 1 : p0;
      dp        = n * (t * pn - pm) / (t * t - 1);
      double dt = pn / dp;
      t -= dt;
      if (std::fabs(dt) < 1e-16) break;
    }
    // recompute the derivative at the converged root for the weight
    double p0 = 1, p1 = t;
    for (PetscInt k = 2; k <= n; ++k) {
      double pk = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
      p0        = p1;
      p1        = pk;
    }
    double pn = n == 1 ? t : p1, pm = n == 1 ? 1 : p0;
    dp         = n * (t * pn - pm) / (t * t - 1);
    points[i]  = 0.5 * (1 - t);
    weights[i] = 1.0 / ((1 - t * t) * dp * dp); // 2/((1-t^2) P'^2) scaled by 1/2 for [0, 1]
  }
}

namespace {
// One orbit of a fully symmetric rule: every distinct permutation of the barycentric point
//   'c' (1/(d+1), ..., 1/(d+1)),   'v' (a, ..., a, 1 - d a),   'e' (a, a, 1/2 - a, 1/2 - a) (3D only),
//   'g' (a, b, 1 - a - b) on a triangle, (a, a, b, 1 - 2 a - b) on a tetrahedron,
// each with the same weight.
struct Orbit {
  char      kind;
  PetscReal a, weight, b = 0;
};

void AddOrbit(Quadrature &q, const Orbit &o)
{
  const PetscInt         d = q.dim;
  std::vector<PetscReal> p(d + 1, o.kind == 'c' ? 1.0 / (d + 1) : o.a);
  if (o.kind == 'v') p[d] = 1 - d * o.a;
  if (o.kind == 'e') p[2] = p[3] = 0.5 - o.a;
  if (o.kind == 'g') p[d - 1] = o.b, p[d] = 1 - (d - 1) * o.a - o.b;
  std::sort(p.begin(), p.end());
  do {
    q.bary.insert(q.bary.end(), p.begin(), p.end());
    q.weights.push_back(o.weight);
  } while (std::next_permutation(p.begin(), p.end()));
}

// Symmetric rules with positive weights (Strang and Fix, Dunavant, Keast) where they need far fewer points
// than the conical product rule of the same degree: a load integral evaluates f at every point of every
// cell, and the default degree 4 takes 6 instead of 9 points per triangle, 14 instead of 36 per
// tetrahedron; the error integrals' default degree 6 takes 12 instead of 16 per triangle and 24 instead of
// 80 per tetrahedron. The constants are the published ones, polished to double precision on the moment
// equations; unit_quadrature checks that each rule integrates every monomial of its degree exactly.
bool SymmetricRule(Quadrature &q)
{
  const auto add = [&q](std::initializer_list<Orbit> orbits) {
    for (const Orbit &o : orbits) AddOrbit(q, o);
    return true;
  };
  const PetscReal r15 = std::sqrt(15.0);
  if (q.dim == 2 && q.degree == 2) return add({{'v', 1.0 / 6, 1.0 / 3}});
  if (q.dim == 2 && q.degree <= 4) return add({{'v', 0.44594849091596489, 0.22338158967801125}, {'v', 0.091576213509770896, 0.10995174365532205}});
  if (q.dim == 2 && q.degree == 5) return add({{'c', 0, 9.0 / 40}, {'v', (6 + r15) / 21, (155 + r15) / 1200}, {'v', (6 - r15) / 21, (155 - r15) / 1200}});
  if (q.dim == 2 && q.degree == 6) return add({{'v', 0.063089014491502228, 0.050844906370206817}, {'v', 0.24928674517091042, 0.11678627572637937}, {'g', 0.053145049844816947, 0.082851075618373575, 0.31035245103378441}});
  if (q.dim == 3 && q.degree == 2) return add({{'v', (5 - std::sqrt(5.0)) / 20, 0.25}});
  if (q.dim == 3 && q.degree <= 5) return add({{'v', 0.3108859192633005, 0.11268792571801556}, {'v', 0.092735250310891235, 0.073493043116361984}, {'e', 0.45449629587435025, 0.042546020777081597}});
  if (q.dim == 3 && q.degree == 6) return add({{'v', 0.21460287125915203, 0.039922750258167492}, {'v', 0.040673958534611353, 0.010077211055320643}, {'v', 0.32233789014227551, 0.055357181543654722}, {'g', 0.063661001875017525, 27.0 / 560, 0.26967233145831581}});
  return false;
}
} // namespace

Quadrature SimplexQuadrature(PetscInt dim, PetscInt degree)
{
  Quadrature q;
  q.dim    = dim;
  q.degree = degree < 1 ? 1 : degree;
  if (q.degree == 1) {
    q.bary.assign(dim + 1, 1.0 / (dim + 1));
    q.weights.assign(1, 1.0);
    return q;
  }
  if (SymmetricRule(q)) return q;
  // The collapse multiplies the integrand by (1-s_d)^(dim-1-d) in direction d: n_d Gauss points integrate
  // degree + dim - 1 - d exactly when 2 n_d - 1 >= degree + dim - 1 - d.
  PetscInt                            n[3] = {1, 1, 1}, total = 1;
  std::vector<PetscReal>              s[3], w[3];
  for (PetscInt d = 0; d < dim; ++d) {
    n[d] = (q.degree + dim - 1 - d) / 2 + 1;
    GaussLegendre01(n[d], s[d], w[d]);
    total *= n[d];
  }
  for (PetscInt idx = 0; idx < total; ++idx) {
    PetscInt  rest = idx, ii[3] = {0, 0, 0};
    PetscReal xi[3] = {0, 0, 0}, weight = 1;
    for (PetscInt d = 0; d < dim; ++d) {
      ii[d] = rest % n[d];
      rest /= n[d];
      xi[d] = s[d][ii[d]];
      weight *= w[d][ii[d]];
    }
    // Duffy map from the cube onto {x_i >= 0, sum x_i <= 1}; the Jacobian is prod_d (1 - xi_d)^(dim-1-d).
    PetscReal x[3] = {0, 0, 0}, scale = 1;
    for (PetscInt d = 0; d < dim; ++d) {
      x[d] = xi[d] * scale;
      for (PetscInt k = 0; k < dim - 1 - d; ++k) weight *= (1 - xi[d]);
      scale *= (1 - xi[d]);
    }
    PetscReal factorial = 1;
    for (PetscInt d = 2; d <= dim; ++d) factorial *= d;
    weight *= factorial; // divide by the reference simplex measure 1/dim!
    PetscReal l0 = 1;
    for (PetscInt d = 0; d < dim; ++d) l0 -= x[d];
    q.bary.push_back(l0);
    for (PetscInt d = 0; d < dim; ++d) q.bary.push_back(x[d]);
    q.weights.push_back(weight);
  }
  return q;
}

} // namespace signorini

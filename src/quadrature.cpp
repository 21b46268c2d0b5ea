#include "signorini/quadrature.h"

#include <cmath>

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

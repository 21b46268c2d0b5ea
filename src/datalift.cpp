// The affine parts of the data lifted into the flux, cell by cell (datalift.h).
#include "signorini/datalift.h"

#include <algorithm>
#include <cmath>

namespace signorini {

namespace {

// The homogeneous quadratics in the barycentric coordinates of a dim-simplex: monomial p is
// lambda_{i[p]} lambda_{j[p]} (i <= j), at[i][j] its number, and M[p][q] = int_T (monomial p)(monomial q) / |T|.
template <PetscInt dim>
struct Quadratics {
  static constexpr PetscInt nb = dim + 1, nq = nb * (nb + 1) / 2;
  PetscInt                  i[nq], j[nq], at[nb][nb];
  PetscReal                 M[nq][nq];
  Quadratics()
  {
    PetscInt p = 0;
    for (PetscInt a = 0; a < nb; ++a)
      for (PetscInt b = a; b < nb; ++b) i[p] = a, j[p] = b, at[a][b] = at[b][a] = p++;
    // int_T lambda^alpha / |T| = d! prod alpha_k! / (d + 4)! for |alpha| = 4
    PetscReal dfact = 1, d4fact = 1;
    for (PetscInt k = 2; k <= dim; ++k) dfact *= k;
    for (PetscInt k = 2; k <= dim + 4; ++k) d4fact *= k;
    for (PetscInt p = 0; p < nq; ++p)
      for (PetscInt q = 0; q < nq; ++q) {
        PetscInt alpha[nb] = {};
        ++alpha[i[p]], ++alpha[j[p]], ++alpha[i[q]], ++alpha[j[q]];
        PetscReal prod = 1;
        for (PetscInt k = 0; k < nb; ++k)
          for (PetscInt m = 2; m <= alpha[k]; ++m) prod *= m;
        M[p][q] = dfact * prod / d4fact;
      }
  }
};

template <PetscInt dim>
const Quadratics<dim> &Monomials()
{
  static const Quadratics<dim> q;
  return q;
}

template <PetscInt dim>
struct Field {
  static constexpr PetscInt nq = Quadratics<dim>::nq;
  PetscReal                 c[nq][dim] = {};
  // + s times the affine field of vertex values a (row per vertex): a_k lambda_k sum_m lambda_m.
  void AddAffine(const PetscReal *a, PetscReal s)
  {
    const Quadratics<dim> &Q = Monomials<dim>();
    for (PetscInt k = 0; k <= dim; ++k)
      for (PetscInt m = k; m <= dim; ++m)
        for (PetscInt d = 0; d < dim; ++d) c[Q.at[k][m]][d] += s * (m == k ? a[k * dim + d] : a[k * dim + d] + a[m * dim + d]);
  }
  // + s B_ab = s lambda_a lambda_b (X_b - X_a)
  void AddBubble(const PetscReal *X, PetscInt a, PetscInt b, PetscReal s)
  {
    const PetscInt p = Monomials<dim>().at[a][b];
    for (PetscInt d = 0; d < dim; ++d) c[p][d] += s * (X[b * dim + d] - X[a * dim + d]);
  }
  void Add(const Field &o, PetscReal s)
  {
    for (PetscInt p = 0; p < nq; ++p)
      for (PetscInt d = 0; d < dim; ++d) c[p][d] += s * o.c[p][d];
  }
};

// M v (M: Quadratics::M), so that (u, v)_T / |T| = Dot(u, Mv): each field is multiplied once. The
// monomials v does not have are skipped (a cycle's field has 3 of 10).
template <PetscInt dim>
Field<dim> MassTimes(const Field<dim> &v)
{
  const Quadratics<dim> &Q = Monomials<dim>();
  Field<dim>             mv;
  for (PetscInt q = 0; q < Q.nq; ++q) {
    bool zero = true;
    for (PetscInt d = 0; d < dim; ++d) zero = zero && v.c[q][d] == 0;
    if (zero) continue;
    for (PetscInt p = 0; p < Q.nq; ++p)
      for (PetscInt d = 0; d < dim; ++d) mv.c[p][d] += Q.M[p][q] * v.c[q][d];
  }
  return mv;
}

template <PetscInt dim>
PetscReal Dot(const Field<dim> &u, const Field<dim> &mv)
{
  PetscReal s = 0;
  for (PetscInt p = 0; p < Field<dim>::nq; ++p)
    for (PetscInt d = 0; d < dim; ++d) s += u.c[p][d] * mv.c[p][d];
  return s;
}

// Solves G z = b in place (z in b) for the small symmetric positive definite G (n <= 3) by Cholesky;
// leaves z = 0 where a pivot is not positive (the free part then unused: tau stays admissible).
void SolveSmall(PetscInt n, PetscReal G[3][3], PetscReal *b)
{
  PetscReal L[3][3] = {};
  for (PetscInt k = 0; k < n; ++k) {
    PetscReal s = G[k][k];
    for (PetscInt m = 0; m < k; ++m) s -= L[k][m] * L[k][m];
    if (!(s > 0)) {
      std::fill(b, b + n, 0.0);
      return;
    }
    L[k][k] = std::sqrt(s);
    for (PetscInt r = k + 1; r < n; ++r) {
      PetscReal t = G[r][k];
      for (PetscInt m = 0; m < k; ++m) t -= L[r][m] * L[k][m];
      L[r][k] = t / L[k][k];
    }
  }
  for (PetscInt k = 0; k < n; ++k) {
    for (PetscInt m = 0; m < k; ++m) b[k] -= L[k][m] * b[m];
    b[k] /= L[k][k];
  }
  for (PetscInt k = n - 1; k >= 0; --k) {
    for (PetscInt m = k + 1; m < n; ++m) b[k] -= L[m][k] * b[m];
    b[k] /= L[k][k];
  }
}

template <PetscInt dim>
void LiftCellD(const PetscReal *X, const CellGeometry &g, const PetscReal *lf, PetscInt numFaces, const FaceLift *faces, const PetscReal *D, const PetscReal *Dh, PetscReal *r2, PetscReal *rh2, PetscReal *tauOut)
{
  constexpr PetscInt nb = dim + 1, nc = dim == 2 ? 1 : 3; // divergence-free cycles
  Field<dim>         tau;
  // The load's affine part: tau_f = -sum_{i<j} (l_i - l_j) / (d + 1) B_ij.
  for (PetscInt a = 0; a < nb; ++a)
    for (PetscInt b = a + 1; b < nb; ++b) tau.AddBubble(X, a, b, -(lf[a] - lf[b]) / nb);
  // The Neumann faces' affine parts: tau_F = sum_j l_j lambda_j (X_j - X_o) |grad lambda_o|.
  for (PetscInt f = 0; f < numFaces; ++f) {
    const PetscInt o = faces[f].opposite;
    PetscReal      gl2 = 0, a[nb * dim] = {};
    for (PetscInt d = 0; d < dim; ++d) gl2 += g.gradLambda[o][d] * g.gradLambda[o][d];
    const PetscReal invh = std::sqrt(gl2);
    for (PetscInt k = 0; k < nb; ++k)
      if (k != o)
        for (PetscInt d = 0; d < dim; ++d) a[k * dim + d] = faces[f].l[k] * (X[k * dim + d] - X[o * dim + d]) * invh;
    tau.AddAffine(a, 1);
  }
  Field<dim> R, Rh;
  R.AddAffine(D, 1), R.Add(tau, -1);
  Rh.AddAffine(Dh, 1), Rh.Add(tau, -1);
  // The cycles through vertex 0: (0, 1, 2), and in 3D (0, 1, 3), (0, 2, 3); B_ca = -B_ac.
  static const PetscInt cycles[3][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}};
  Field<dim>            C[nc];
  for (PetscInt t = 0; t < nc; ++t) {
    const PetscInt *v = cycles[t];
    C[t].AddBubble(X, v[0], v[1], 1), C[t].AddBubble(X, v[1], v[2], 1), C[t].AddBubble(X, v[0], v[2], -1);
  }
  Field<dim> MC[nc];
  PetscReal  G[3][3], z[3];
  for (PetscInt s = 0; s < nc; ++s) {
    MC[s] = MassTimes(C[s]);
    for (PetscInt t = 0; t <= s; ++t) G[s][t] = G[t][s] = Dot(C[t], MC[s]);
    z[s] = 0.5 * (Dot(R, MC[s]) + Dot(Rh, MC[s]));
  }
  SolveSmall(nc, G, z);
  for (PetscInt t = 0; t < nc; ++t) R.Add(C[t], -z[t]), Rh.Add(C[t], -z[t]), tau.Add(C[t], z[t]);
  *r2  = std::max(Dot(R, MassTimes(R)), (PetscReal)0) * g.volume;
  *rh2 = std::max(Dot(Rh, MassTimes(Rh)), (PetscReal)0) * g.volume;
  if (tauOut)
    for (PetscInt p = 0; p < Field<dim>::nq; ++p)
      for (PetscInt d = 0; d < dim; ++d) tauOut[p * dim + d] = tau.c[p][d];
}

} // namespace

void LiftCell(PetscInt dim, const PetscReal *X, const CellGeometry &g, const PetscReal *lf, PetscInt numFaces, const FaceLift *faces, const PetscReal *D, const PetscReal *Dh, PetscReal *r2, PetscReal *rh2, PetscReal *tauOut)
{
  WithDim(dim, [&](auto Dim) { LiftCellD<Dim>(X, g, lf, numFaces, faces, D, Dh, r2, rh2, tauOut); });
}

void LiftValue(PetscInt dim, const PetscReal *tau, const PetscReal *lambda, PetscReal *value)
{
  PetscInt p = 0;
  for (PetscInt d = 0; d < dim; ++d) value[d] = 0;
  for (PetscInt a = 0; a <= dim; ++a)
    for (PetscInt b = a; b <= dim; ++b, ++p)
      for (PetscInt d = 0; d < dim; ++d) value[d] += tau[p * dim + d] * lambda[a] * lambda[b];
}

} // namespace signorini

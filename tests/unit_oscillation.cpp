// Unit tests of the constants the data oscillation of the estimate is weighted with; each must bound for
// every function (else the estimate is no longer guaranteed), so the tests compare with quantities computed
// independently.
// 1. PoincareConstant (assembly.h), C_T of ||w - w_T||_T <= C_T ||grad w||_T, against Rayleigh quotients
// ||w - w_T||^2 / ||grad w||^2:
//  - exact values: half a square and a sixth of a cube (Kuhn's tetrahedron), scaled, turned and with their
//    vertices in every order, have C_T = (leg) / pi, attained by cos(pi x) + cos(pi y) (+ cos(pi z)) (its
//    quotient by quadrature equals C_T^2); equilateral cells get Payne-Weinberger's h_T / pi;
//  - invariants: C_T <= h_T / pi, scaling with the cell, unchanged by rotation and translation and by the
//    order of the vertices (bisections of the reference cell, where paths through the vertices tie);
//  - the bound on random, flat and stretched cells and on near-Kuhn ones (where it is below h_T / pi):
//    C_T^2 >= the largest quotient of affine w (the covariance of the cell's points, exactly) and of the
//    reference eigenfunction carried to the cell by each of its vertex orders (by quadrature).
// 2. NeumannLiftNorm (estimate.h), ||tau||_T of the affine divergence-free lifting of an affine l of mean zero
// on a face: Green's identity int_F l e = int_T tau . grad e for random quadratic e (which holds for every e
// only if tau's normal trace is l on F and 0 on the other faces and div tau = 0), and the norm against
// the quadrature of |tau|^2, on random and flat triangles and tetrahedra, every face.
#include "signorini/assembly.h"
#include "signorini/datalift.h"
#include "signorini/estimate.h"
#include "signorini/quadrature.h"
#include "unit_check.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

using signorini::PoincareConstant;

namespace {

using Cell = std::vector<double>; // (dim + 1) x dim vertex coordinates

double Diameter(int dim, const Cell &X)
{
  double h2 = 0;
  for (int i = 0; i <= dim; ++i)
    for (int j = i + 1; j <= dim; ++j) {
      double l2 = 0;
      for (int d = 0; d < dim; ++d) l2 += (X[i * dim + d] - X[j * dim + d]) * (X[i * dim + d] - X[j * dim + d]);
      h2 = std::max(h2, l2);
    }
  return std::sqrt(h2);
}

// The reference simplex K: half the unit square, Kuhn's sixth of the unit cube.
Cell Reference(int dim)
{
  if (dim == 2) return {0, 0, 0, 1, 1, 1};
  return {0, 0, 0, 0, 0, 1, 0, 1, 1, 1, 1, 1};
}

// x -> s Q x + t with Q a rotation (about the z axis, then the x axis in 3D).
Cell Move(int dim, const Cell &X, double s, double a, double b, const double *t)
{
  Cell Y(X.size());
  for (int i = 0; i <= dim; ++i) {
    double p[3] = {X[i * dim], X[i * dim + 1], dim == 3 ? X[i * dim + 2] : 0};
    double q[3] = {std::cos(a) * p[0] - std::sin(a) * p[1], std::sin(a) * p[0] + std::cos(a) * p[1], p[2]};
    if (dim == 3) p[0] = q[0], p[1] = std::cos(b) * q[1] - std::sin(b) * q[2], p[2] = std::sin(b) * q[1] + std::cos(b) * q[2];
    else p[0] = q[0], p[1] = q[1];
    for (int d = 0; d < dim; ++d) Y[i * dim + d] = s * p[d] + t[d];
  }
  return Y;
}

Cell Permuted(int dim, const Cell &X, const int *perm)
{
  Cell Y(X.size());
  for (int i = 0; i <= dim; ++i)
    for (int d = 0; d < dim; ++d) Y[i * dim + d] = X[perm[i] * dim + d];
  return Y;
}

// The largest of f (>= 0) over the cell with its vertices in every order.
template <class F>
double MaxOverVertexOrders(int dim, const Cell &X, const F &f)
{
  int    perm[4] = {0, 1, 2, 3};
  double worst   = 0;
  do worst = std::max(worst, f(Permuted(dim, X, perm)));
  while (std::next_permutation(perm, perm + dim + 1));
  return worst;
}

// The largest eigenvalue of a symmetric dim x dim matrix (Jacobi rotations until the off-diagonal vanishes).
double LargestEigenvalue(int dim, double A[3][3])
{
  for (int sweep = 0; sweep < 50; ++sweep)
    for (int p = 0; p < dim; ++p)
      for (int q = p + 1; q < dim; ++q) {
        if (std::abs(A[p][q]) < 1e-300) continue;
        const double theta = 0.5 * std::atan2(2 * A[p][q], A[q][q] - A[p][p]), c = std::cos(theta), s = std::sin(theta);
        for (int k = 0; k < dim; ++k) {
          const double akp = A[k][p], akq = A[k][q];
          A[k][p] = c * akp - s * akq, A[k][q] = s * akp + c * akq;
        }
        for (int k = 0; k < dim; ++k) {
          const double apk = A[p][k], aqk = A[q][k];
          A[p][k] = c * apk - s * aqk, A[q][k] = s * apk + c * aqk;
        }
      }
  double m = A[0][0];
  for (int d = 1; d < dim; ++d) m = std::max(m, A[d][d]);
  return m;
}

// The largest quotient of affine w = a.x: a^T Cov a / |a|^2 with Cov the covariance of the cell's points,
// E[x x^T] = (sum_i X_i X_i^T + (sum_i X_i)(sum_i X_i)^T) / ((d+1)(d+2)).
double AffineQuotient(int dim, const Cell &X)
{
  double S[3] = {0, 0, 0}, A[3][3] = {{0}};
  for (int i = 0; i <= dim; ++i)
    for (int d = 0; d < dim; ++d) S[d] += X[i * dim + d];
  for (int d = 0; d < dim; ++d)
    for (int e = 0; e < dim; ++e) {
      double m = S[d] * S[e];
      for (int i = 0; i <= dim; ++i) m += X[i * dim + d] * X[i * dim + e];
      A[d][e] = m / ((dim + 1) * (dim + 2)) - S[d] * S[e] / ((dim + 1) * (dim + 1));
    }
  return LargestEigenvalue(dim, A);
}

// The quotient of w = phi o F^{-1} on the cell, phi = sum_d cos(pi xhat_d) the eigenfunction of K and F the
// affine map with F(K's vertex i) = X_i: int_K (phi - mean)^2 / int_K |B^{-T} grad phi|^2 (|det B| cancels).
double EigenfunctionQuotient(int dim, const Cell &X, const signorini::Quadrature &rule)
{
  const Cell K = Reference(dim);
  // B = M V^{-1}, M and V the edge matrices from vertex 0 (columns); B^{-T} = M^{-T} V^T.
  double M[3][3] = {{0}}, V[3][3] = {{0}}, Minv[3][3] = {{0}};
  for (int j = 0; j < dim; ++j)
    for (int d = 0; d < dim; ++d) M[d][j] = X[(j + 1) * dim + d] - X[d], V[d][j] = K[(j + 1) * dim + d] - K[d];
  if (dim == 2) {
    const double det = M[0][0] * M[1][1] - M[0][1] * M[1][0];
    Minv[0][0] = M[1][1] / det, Minv[0][1] = -M[0][1] / det, Minv[1][0] = -M[1][0] / det, Minv[1][1] = M[0][0] / det;
  } else {
    const double det = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) - M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) + M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
        Minv[i][j] = (M[i1][j1] * M[i2][j2] - M[i1][j2] * M[i2][j1]) / det;
      }
  }
  double BinvT[3][3] = {{0}}; // (M^{-1})^T V^T
  for (int i = 0; i < dim; ++i)
    for (int j = 0; j < dim; ++j)
      for (int k = 0; k < dim; ++k) BinvT[i][j] += Minv[k][i] * V[j][k];
  double wsum = 0, mean = 0, m2 = 0, g2 = 0;
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    double xh[3] = {0, 0, 0};
    for (int i = 0; i <= dim; ++i)
      for (int d = 0; d < dim; ++d) xh[d] += rule.Point(q)[i] * K[i * dim + d];
    double phi = 0, grad[3], g[3] = {0, 0, 0};
    for (int d = 0; d < dim; ++d) phi += std::cos(M_PI * xh[d]), grad[d] = -M_PI * std::sin(M_PI * xh[d]);
    for (int i = 0; i < dim; ++i)
      for (int j = 0; j < dim; ++j) g[i] += BinvT[i][j] * grad[j];
    const double w = rule.weights[q];
    wsum += w, mean += w * phi, m2 += w * phi * phi;
    for (int d = 0; d < dim; ++d) g2 += w * g[d] * g[d];
  }
  mean /= wsum;
  return (m2 / wsum - mean * mean) / (g2 / wsum);
}

// Every vertex order of the cell: each carries phi differently, and each quotient must stay below C^2.
double WorstEigenfunctionQuotient(int dim, const Cell &X, const signorini::Quadrature &rule)
{
  return MaxOverVertexOrders(dim, X, [&](const Cell &Y) { return EigenfunctionQuotient(dim, Y, rule); });
}

void TestExact(unit::Checker &ck, int dim, const signorini::Quadrature &rule)
{
  const std::string tag = std::to_string(dim) + "D";
  const double      t[3] = {0.3, -1.2, 2.5}, leg = 0.37;
  const Cell        K = Move(dim, Reference(dim), leg, 0.7, 1.1, t);
  const double      worst = MaxOverVertexOrders(dim, K, [&](const Cell &Y) { return std::abs(PoincareConstant(dim, Y.data()) * M_PI / leg - 1); });
  ck.Check(worst < 1e-13, tag + " reference cell (leg 0.37, turned, every vertex order): C = leg / pi", "largest relative deviation %.3g", worst);
  // The bound is attained: the eigenfunction's quotient is C^2 (to the quadrature's error).
  const double C = PoincareConstant(dim, K.data());
  ck.Close(EigenfunctionQuotient(dim, K, rule), C * C, 1e-9, tag + " reference cell: cos(pi x) + ... attains C^2 (sharp)", 0.0);
  // Equilateral cells: Payne-Weinberger's h_T / pi is the smaller.
  const Cell E = dim == 2 ? Cell{0, 0, 1, 0, 0.5, std::sqrt(3.0) / 2} : Cell{1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
  ck.Close(PoincareConstant(dim, E.data()), Diameter(dim, E) / M_PI, 1e-14, tag + " equilateral cell: C = h / pi", 0.0);
}

void TestRandom(unit::Checker &ck, int dim, const signorini::Quadrature &rule)
{
  const std::string                      tag = std::to_string(dim) + "D";
  std::mt19937                           gen(17 + dim);
  std::uniform_real_distribution<double> u(0, 1), angle(0, 2 * M_PI);
  int    above = 0, notInvariant = 0, belowAffine = 0, belowEigen = 0, gained = 0, n = 0;
  double worstAffine = 0, worstEigen = 0;
  const Cell K = Reference(dim);
  for (int kind = 0; kind < 4; ++kind)
    for (int trial = 0; trial < 60; ++trial, ++n) {
      Cell X(K.size());
      for (int i = 0; i < (int)X.size(); ++i) {
        if (kind == 0) X[i] = u(gen);                            // any cell
        if (kind == 1) X[i] = K[i] + 0.15 * (u(gen) - 0.5);      // near the reference: C below h / pi
        if (kind == 2) X[i] = K[i] * (i % dim == 0 ? 30.0 : 1.0); // stretched along x
        if (kind == 3) X[i] = (i % dim == dim - 1 ? 0.01 : 1.0) * u(gen); // flat
        if (kind == 2) X[i] += 0.05 * (u(gen) - 0.5);
      }
      const double C = PoincareConstant(dim, X.data()), h = Diameter(dim, X);
      if (!(C <= h / M_PI * (1 + 1e-14))) ++above;
      const double t[3] = {u(gen), u(gen), u(gen)}, s = 0.5 + u(gen);
      const Cell   Y    = Move(dim, X, s, angle(gen), angle(gen), t);
      if (std::abs(PoincareConstant(dim, Y.data()) / (s * C) - 1) > 1e-10) ++notInvariant;
      const double qa = AffineQuotient(dim, X), qe = WorstEigenfunctionQuotient(dim, X, rule);
      worstAffine = std::max(worstAffine, qa / (C * C)), worstEigen = std::max(worstEigen, qe / (C * C));
      belowAffine += !(qa <= C * C * (1 + 1e-12));
      belowEigen += !(qe <= C * C * (1 + 1e-9));
      gained += C < 0.99 * h / M_PI;
    }
  ck.Check(above == 0, tag + " C <= h / pi on " + std::to_string(n) + " random, near-reference, stretched and flat cells", "%d above", above);
  ck.Check(notInvariant == 0, tag + " C scales with the cell and ignores rotation and translation", "%d cells changed", notInvariant);
  ck.Check(belowAffine == 0, tag + " C^2 >= the largest quotient of affine functions (covariance)", "%d cells below; largest quotient / C^2 %.6f", belowAffine, worstAffine);
  ck.Check(belowEigen == 0, tag + " C^2 >= the quotient of the reference eigenfunction in every vertex order", "%d cells below; largest quotient / C^2 %.6f", belowEigen, worstEigen);
  ck.Check(gained >= 40, tag + " C below h / pi on the near-reference cells", "%d of %d cells", gained, n);
  std::printf("  %s: largest quotient / C^2: affine %.4f, eigenfunction %.4f; C < 0.99 h / pi on %d of %d cells\n", tag.c_str(), worstAffine, worstEigen, gained, n);
}

// C_T must not depend on the order of T's vertices: each rank numbers a cell's vertices its own way, and the
// estimate must be the same on any number of ranks. Checked on every vertex order of the cells that
// bisection makes from Kuhn's tetrahedron (half a square in 2D), where several paths through the vertices
// tie (taking the first of them made C_T differ by up to 16 % between vertex orders, and the estimate of an
// adapted 3D mesh by 1e-4 between 1 and 2 ranks), and of 20 random cells.
void TestVertexOrder(unit::Checker &ck, int dim)
{
  const std::string tag = std::to_string(dim) + "D";
  // Descendants by bisection of any edge, three generations (the refinements cut any marked edge, not only
  // the longest): 1 + 2 E + (2 E)^2 + (2 E)^3 cells, E the edges of a cell.
  std::vector<Cell> cells = {Reference(dim)}, generation = cells;
  for (int g = 0; g < 3; ++g) {
    std::vector<Cell> next;
    for (const Cell &X : generation)
      for (int a = 0; a <= dim; ++a)
        for (int b = a + 1; b <= dim; ++b)
          for (int moved : {a, b}) { // the child whose vertex `moved` goes to the edge's midpoint
            Cell Y = X;
            for (int d = 0; d < dim; ++d) Y[moved * dim + d] = 0.5 * (X[a * dim + d] + X[b * dim + d]);
            next.push_back(Y);
          }
    cells.insert(cells.end(), next.begin(), next.end());
    generation.swap(next);
  }
  std::mt19937                           gen(5 + dim);
  std::uniform_real_distribution<double> u(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    Cell X(dim * (dim + 1));
    for (double &x : X) x = u(gen);
    cells.push_back(X);
  }
  double worst = 0;
  for (const Cell &X : cells) {
    const double C = PoincareConstant(dim, X.data());
    worst          = std::max(worst, MaxOverVertexOrders(dim, X, [&](const Cell &Y) { return std::abs(PoincareConstant(dim, Y.data()) / C - 1); }));
  }
  ck.Check(worst < 1e-13, tag + " C the same in every vertex order (" + std::to_string(cells.size()) + " cells: bisections of the reference cell, random)", "largest relative deviation %.3g", worst);
}

double Volume(int dim, const Cell &X)
{
  double e[3][3];
  for (int k = 0; k < dim; ++k)
    for (int d = 0; d < dim; ++d) e[k][d] = X[(k + 1) * dim + d] - X[d];
  if (dim == 2) return std::abs(e[0][0] * e[1][1] - e[0][1] * e[1][0]) / 2;
  return std::abs(e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0])) / 6;
}

// The measure of the face opposite vertex o.
double FaceArea(int dim, const Cell &X, int o)
{
  int v[3], n = 0;
  for (int k = 0; k <= dim; ++k)
    if (k != o) v[n++] = k;
  double a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
  for (int d = 0; d < dim; ++d) a[d] = X[v[1] * dim + d] - X[v[0] * dim + d];
  if (dim == 2) return std::sqrt(a[0] * a[0] + a[1] * a[1]);
  for (int d = 0; d < dim; ++d) b[d] = X[v[2] * dim + d] - X[v[0] * dim + d];
  const double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  return std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) / 2;
}

// A random quadratic e(x) = e0 + beta . x + x^T G x and its gradient.
struct Quadratic {
  int    dim;
  double e0, beta[3], G[3][3];
  Quadratic(int dim_, std::mt19937 &gen, std::uniform_real_distribution<double> &u) : dim(dim_), e0(u(gen)), beta{u(gen), u(gen), u(gen)}
  {
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b <= a; ++b) G[a][b] = G[b][a] = u(gen);
  }
  double operator()(const double *x) const
  {
    double v = e0;
    for (int a = 0; a < dim; ++a) {
      v += beta[a] * x[a];
      for (int b = 0; b < dim; ++b) v += x[a] * G[a][b] * x[b];
    }
    return v;
  }
  void Grad(const double *x, double *grad) const
  {
    for (int a = 0; a < dim; ++a) {
      grad[a] = beta[a];
      for (int b = 0; b < dim; ++b) grad[a] += 2 * G[a][b] * x[b];
    }
  }
};

void TestLift(unit::Checker &ck, int dim)
{
  const std::string                      tag = std::to_string(dim) + "D";
  const signorini::Quadrature            cellRule = signorini::SimplexQuadrature(dim, 4), faceRule = signorini::SimplexQuadrature(dim - 1, 4);
  std::mt19937                           gen(29 + dim);
  std::uniform_real_distribution<double> u(-1, 1);
  double                                 worstGreen = 0, worstNorm = 0;
  int                                    n = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Cell X((dim + 1) * dim);
    for (int i = 0; i < (int)X.size(); ++i) X[i] = u(gen) * (trial % 4 == 3 && i % dim == dim - 1 ? 0.02 : 1.0); // every fourth flat
    const double vol = Volume(dim, X);
    for (int o = 0; o <= dim; ++o, ++n) {
      double l[4] = {0, 0, 0, 0}, sum = 0;
      for (int j = 0; j <= dim; ++j)
        if (j != o) l[j] = u(gen), sum += l[j];
      for (int j = 0; j <= dim; ++j)
        if (j != o) l[j] -= sum / dim; // mean zero on the face
      const Quadratic e(dim, gen, u);
      const double area = FaceArea(dim, X, o), h = dim * vol / area;
      // int_F l e by the face rule, l = sum_j l_j lambda_j
      double lhs = 0;
      for (PetscInt q = 0; q < faceRule.Size(); ++q) {
        double lambda[4] = {0, 0, 0, 0}, x[3] = {0, 0, 0}, lq = 0;
        for (int j = 0, m = 0; j <= dim; ++j)
          if (j != o) lambda[j] = faceRule.Point(q)[m++];
        for (int j = 0; j <= dim; ++j) {
          lq += l[j] * lambda[j];
          for (int d = 0; d < dim; ++d) x[d] += lambda[j] * X[j * dim + d];
        }
        lhs += faceRule.weights[q] * area * lq * e(x);
      }
      // int_T tau . grad e and int_T |tau|^2 by the cell rule
      double rhs = 0, tau2 = 0;
      for (PetscInt q = 0; q < cellRule.Size(); ++q) {
        const double *lambda = cellRule.Point(q);
        double        x[3] = {0, 0, 0}, tau[3] = {0, 0, 0}, grad[3] = {0, 0, 0};
        for (int j = 0; j <= dim; ++j)
          for (int d = 0; d < dim; ++d) {
            x[d] += lambda[j] * X[j * dim + d];
            if (j != o) tau[d] += l[j] * lambda[j] * (X[j * dim + d] - X[o * dim + d]) / h;
          }
        e.Grad(x, grad);
        for (int d = 0; d < dim; ++d) rhs += cellRule.weights[q] * vol * tau[d] * grad[d], tau2 += cellRule.weights[q] * vol * tau[d] * tau[d];
      }
      signorini::CellGeometry g;
      signorini::ComputeCellGeometry(dim, X.data(), g);
      const double norm = signorini::NeumannLiftNorm(dim, X.data(), g, o, l);
      worstGreen = std::max(worstGreen, std::abs(lhs - rhs) / std::max(std::abs(lhs), 1e-3 * area));
      worstNorm  = std::max(worstNorm, std::abs(norm * norm - tau2) / tau2);
    }
  }
  ck.Check(worstGreen < 1e-12, tag + " lifting: int_F l e = int_T tau . grad e (" + std::to_string(n) + " faces, random quadratic e)", "largest relative difference %.3g", worstGreen);
  ck.Check(worstNorm < 1e-12, tag + " lifting: NeumannLiftNorm^2 = the quadrature of |tau|^2", "largest relative difference %.3g", worstNorm);
}

// 3. LiftCell (datalift.h): the field tau added to the flux of one cell, for random affine parts of f and of g
// on a random set of the cell's faces and random affine D, Dh, on random and flat cells:
//  - Green's identity int_T tau . grad e = int_T l_f e + sum_F int_F l_F e for random quadratic e, which holds
//    for every such e only if div tau = -l_f and tau.n = l_F on the chosen faces and 0 on the others;
//  - the returned ||D - tau||^2 and ||Dh - tau||^2 against their quadrature;
//  - its free part is the minimiser: (D - tau, C) + (Dh - tau, C) = 0 for the divergence-free fields C =
//    B_ab + B_bc + B_ca (B_ij = lambda_i lambda_j (X_j - X_i)) of every triangle (a, b, c) of the cell's vertices.
void TestLiftCell(unit::Checker &ck, int dim)
{
  const std::string                      tag = std::to_string(dim) + "D";
  const int                              nb = dim + 1;
  const signorini::Quadrature            cellRule = signorini::SimplexQuadrature(dim, 4), faceRule = signorini::SimplexQuadrature(dim - 1, 4);
  std::mt19937                           gen(41 + dim);
  std::uniform_real_distribution<double> u(-1, 1);
  double                                 worstGreen = 0, worstNorm = 0, worstStationary = 0;
  int                                    faces = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Cell X(nb * dim);
    for (int i = 0; i < (int)X.size(); ++i) X[i] = u(gen) * (trial % 4 == 3 && i % dim == dim - 1 ? 0.02 : 1.0); // every fourth flat
    const double vol = Volume(dim, X);
    signorini::CellGeometry g;
    signorini::ComputeCellGeometry(dim, X.data(), g);
    double lf[4] = {0, 0, 0, 0}, sum = 0, D[12], Dh[12];
    for (int k = 0; k < nb; ++k) lf[k] = u(gen), sum += lf[k];
    for (int k = 0; k < nb; ++k) lf[k] -= sum / nb;
    for (int i = 0; i < nb * dim; ++i) D[i] = u(gen), Dh[i] = D[i] + 0.3 * u(gen);
    std::vector<signorini::FaceLift> lifts;
    for (int o = 0; o <= dim; ++o) {
      if ((trial + o) % 3 == 0) continue; // about two faces in three
      signorini::FaceLift f{o, {0, 0, 0, 0}};
      double              fs = 0;
      for (int j = 0; j <= dim; ++j)
        if (j != o) f.l[j] = u(gen), fs += f.l[j];
      for (int j = 0; j <= dim; ++j)
        if (j != o) f.l[j] -= fs / dim;
      lifts.push_back(f);
    }
    faces += (int)lifts.size();
    double tau[30], r2, rh2;
    signorini::LiftCell(dim, X.data(), g, lf, (PetscInt)lifts.size(), lifts.data(), D, Dh, &r2, &rh2, tau);
    const Quadratic e(dim, gen, u);
    const auto      point = [&](const double *lambda, double *x) {
      for (int d = 0; d < dim; ++d) x[d] = 0;
      for (int j = 0; j <= dim; ++j)
        for (int d = 0; d < dim; ++d) x[d] += lambda[j] * X[j * dim + d];
    };
    // The right-hand side: int_T l_f e and int_F l_F e by the rules.
    double rhs = 0, scale = 0;
    for (const signorini::FaceLift &f : lifts) {
      const double area = FaceArea(dim, X, (int)f.opposite);
      for (PetscInt q = 0; q < faceRule.Size(); ++q) {
        double lambda[4] = {0, 0, 0, 0}, x[3], lq = 0;
        for (int j = 0, m = 0; j <= dim; ++j)
          if (j != f.opposite) lambda[j] = faceRule.Point(q)[m++];
        for (int j = 0; j <= dim; ++j) lq += f.l[j] * lambda[j];
        point(lambda, x);
        rhs += faceRule.weights[q] * area * lq * e(x), scale += faceRule.weights[q] * area * std::abs(lq * e(x));
      }
    }
    // The cycles' fields at a point.
    const int  cycles[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
    const int  numCycles    = dim == 2 ? 1 : 4;
    const auto cycle        = [&](int t, const double *lambda, double *c) {
      for (int d = 0; d < dim; ++d) c[d] = 0;
      for (int s = 0; s < 3; ++s) {
        const int a = cycles[t][s], b = cycles[t][(s + 1) % 3];
        for (int d = 0; d < dim; ++d) c[d] += lambda[a] * lambda[b] * (X[b * dim + d] - X[a * dim + d]);
      }
    };
    double lhs = 0, q2 = 0, qh2 = 0, dC[4] = {0, 0, 0, 0}, dScale[4] = {0, 0, 0, 0};
    for (PetscInt q = 0; q < cellRule.Size(); ++q) {
      const double *lambda = cellRule.Point(q);
      const double  w      = cellRule.weights[q] * vol;
      double        x[3], t[3], grad[3], lq = 0, Rq[3], Rhq[3];
      point(lambda, x);
      signorini::LiftValue(dim, tau, lambda, t);
      for (int j = 0; j <= dim; ++j) lq += lf[j] * lambda[j];
      e.Grad(x, grad);
      for (int a = 0; a < dim; ++a) {
        Rq[a] = -t[a], Rhq[a] = -t[a];
        for (int j = 0; j <= dim; ++j) Rq[a] += D[j * dim + a] * lambda[j], Rhq[a] += Dh[j * dim + a] * lambda[j];
      }
      rhs += w * lq * e(x), scale += w * std::abs(lq * e(x));
      for (int a = 0; a < dim; ++a) lhs += w * t[a] * grad[a], q2 += w * Rq[a] * Rq[a], qh2 += w * Rhq[a] * Rhq[a];
      for (int c = 0; c < numCycles; ++c) {
        double C[3];
        cycle(c, lambda, C);
        for (int a = 0; a < dim; ++a) dC[c] += w * (Rq[a] + Rhq[a]) * C[a], dScale[c] += w * (std::abs(Rq[a]) + std::abs(Rhq[a])) * std::abs(C[a]);
      }
    }
    worstGreen = std::max(worstGreen, std::abs(lhs - rhs) / scale);
    worstNorm  = std::max({worstNorm, std::abs(r2 - q2) / q2, std::abs(rh2 - qh2) / qh2});
    for (int c = 0; c < numCycles; ++c) worstStationary = std::max(worstStationary, std::abs(dC[c]) / dScale[c]);
  }
  ck.Check(worstGreen < 1e-12, tag + " LiftCell: int_T tau . grad e = int_T l_f e + sum_F int_F l_F e (40 cells, " + std::to_string(faces) + " Neumann faces, random quadratic e)", "largest relative difference %.3g", worstGreen);
  ck.Check(worstNorm < 1e-12, tag + " LiftCell: ||D - tau||^2 and ||Dh - tau||^2 equal their quadrature", "largest relative difference %.3g", worstNorm);
  ck.Check(worstStationary < 1e-12, tag + " LiftCell: the free part minimises ||D - tau||^2 + ||Dh - tau||^2 (stationary in every cycle field)", "largest relative derivative %.3g", worstStationary);
}

} // namespace

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  for (int dim = 2; dim <= 3; ++dim) {
    const signorini::Quadrature rule = signorini::SimplexQuadrature(dim, 20);
    TestExact(ck, dim, rule);
    TestRandom(ck, dim, rule);
    TestVertexOrder(ck, dim);
    TestLift(ck, dim);
    TestLiftCell(ck, dim);
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : (int)ierr;
}

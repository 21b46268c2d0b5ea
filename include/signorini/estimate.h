// A posteriori estimate of the error in the energy norm |||v|||^2 = sum_T ||kappa^{1/2} grad v||_T^2 (the
// broken seminorm for CR), by an equilibrated flux and a conforming companion of u_h, for both elements
// through one path:
//
//   sigma in RT0, div sigma = -Pi_0 f on every cell, sigma.n = Pi_0 g on Gamma_N, sigma.n >= 0 on Gamma_C;
//   v conforming P1 with v = u_D on Gamma_D and v >= psi on Gamma_C (P1: v = u_h).
//
// From the variational inequality, for E = |||u - v|||:
//   E^2 <= (F + osc) E + gamma,  F = ||kappa^{-1/2}(kappa grad v - sigma)||,  gamma = int_{Gamma_C} sigma.n (v - psi),
// with osc = (sum_T C_T^2 / kappa_T ||f - Pi_0 f||_T^2)^{1/2} (C_T Poincare's constant, PoincareConstant) and the
// same for g on Gamma_N, so E <= (b + sqrt(b^2 + 4 gamma)) / 2 with b = F + osc, and
//   |||u - u_h||| <= N + E,  N = |||u_h - v|||   (nonconformity; zero for P1).
// eta is the smallest of this bound and two more from the same inequality (see estimate.cpp, Bound): one
// with kappa grad_h u_h in place of kappa grad v, and a primal-dual split that bounds |||u - v||| and the
// flux's own error S = ||kappa^{-1/2}(kappa grad u - sigma)|| together, E^2 + S^2 <= F^2 + 2 gamma + 2 osc E,
// with |||u - u_h||| <= min(E + N, S + ||kappa^{-1/2}(kappa grad_h u_h - sigma)||): both avoid counting the
// distance of v from u_h twice (for CR on the manufactured 3D scene, index 3.09 -> 2.11 at 4x4x4).
// Where the oscillation weighs in eta, the same bounds are taken a second time with sigma + tau, tau a
// cell-local field that carries the affine parts of f and g (datalift.h), so that the oscillation is that
// of f - Pi_1 f and g - Pi_1 g; eta is the smaller.
// The bound is guaranteed for kappa constant per cell, u_D and psi affine on each boundary face, and an
// exact discrete solution (the flux is equilibrated up to the solver's residual).
//
// CR (Marini): the face fluxes of cell T are Phi_{T,F} = int_T kappa grad u_h . grad phi_F - int_T f phi_F
// (the load by the assembly's rule), the cell's share of the residual of DOF F: they sum to -int_T f, are
// opposite on the two sides of a free face, equal int_F g phi_F on Gamma_N and the (non-negative) residual
// on Gamma_C. v: the vertex average of u_h, set to u_D on Gamma_D and raised to psi on Gamma_C, moved by
// conjugate gradients towards the conforming function closest to u_h where the average is far from it
// (cells of large aspect ratio), and solved for with BoomerAMG where the gradients show it was very far
// (cells of large kappa that touch at a vertex only); where the contact term weighs in eta, the bound is
// also taken with v held at psi at the vertices of the active contact faces, and eta is the smaller.
// P1 (Braess-Schoeberl, Ern-Vohralik): sigma = sum over vertices a of sigma_a, sigma_a in RT0 on the patch
// of a, with int_T div sigma_a = int_T (kappa grad u_h . grad psi_a - f psi_a) on each cell, zero normal
// flux on the faces of the patch without a, closest to the cellwise RT0 interpolant of psi_a kappa grad u_h
// in the diagonal of the RT0 mass matrix, or in the full matrix on patches with stretched cells (see
// equilibrate.cpp, also for the Neumann, Dirichlet and contact faces).
#pragma once

#include "signorini/assembly.h"

namespace signorini {

struct EstimateOptions {
  bool enabled = true; // -estimate none leaves the estimate out
};
PetscErrorCode EstimateOptionsFromCommandLine(MPI_Comm comm, EstimateOptions &o);

// The flux and the companion the estimate is computed from.
struct Reconstruction {
  // sigma in RT0: flux[(c - cStart) * (dim + 1) + k] = integral over cone face k of cell c (the face opposite
  // the cell's vertex k, as in Space::cellVert) of sigma . n, n pointing out of the cell.
  std::vector<PetscReal> flux;
  // v at every local vertex (index v - vStart); empty for P1, where v = u_h. CR: per local vertex, the
  // lower bound of v (psi on Gamma_C, the lowest real elsewhere), whether v may move (not on Gamma_D), and
  // whether this rank owns the vertex (ImproveCompanion).
  std::vector<PetscReal> companion, lower;
  std::vector<char>      movable, owned;
  // CR, per local vertex: 1 where an active contact face (u_h = psi at its midpoint, over all ranks)
  // touches it, where v may be held at psi (EstimateFromReconstruction); anyPinned: whether any vertex
  // of any rank is (the same on every rank, as the pass it decides is collective).
  std::vector<char>      pinned;
  bool                   anyPinned = false;
  // Per local cell, C_T kappa_T^{-1/2} ||f - Pi_0 f||_T (see CellLoad in assembly.h), from the loads
  // that the flux needed; empty: the estimate gets them itself.
  std::vector<PetscReal> oscillation;
  // P1: per local cell F_T^2 = ||kappa^{-1/2}(kappa grad u_h - sigma)||_T^2, computed with the flux from
  // the cell data it had (no second geometry and gradient); empty: the estimate computes it.
  std::vector<PetscReal> fluxTerm;
};

struct Estimate {
  bool      computed = false;
  PetscReal eta = 0;           // the bound of |||u - u_h|||
  PetscReal flux = 0;          // F (of sigma + tau where the lifted bound is eta)
  PetscReal nonconformity = 0; // N
  PetscReal contact = 0;       // gamma
  PetscReal oscillation = 0;   // osc (f and g; of f - Pi_1 f and g - Pi_1 g where the lifted bound is eta)
  std::vector<PetscReal> cellEta2; // per local cell: its indicator squared (flux, nonconformity, oscillation and contact parts of the cell)
  double    seconds = 0;       // max over ranks
};

// sigma = sum_k Phi_k (x - X_k) / (d |T|) = s0 + c (x - x_T) with s0 = sigma(x_T), c = sum_k Phi_k / (d |T|)
// (= -Pi_0 f / d), so for a constant w (kappa grad v, or kappa grad_h u_h)
//   ||w - sigma||_T^2 = |T| |w - s0|^2 + c^2 int_T |x - x_T|^2,  int_T |x - x_T|^2 = |T| / ((d+1)(d+2)) sum_k |X_k - x_T|^2
// exactly (the cross term vanishes: x - x_T has mean zero on T). The w-free parts are computed once a cell.
struct CellFlux {
  PetscReal s0[3] = {0, 0, 0}, spread = 0, volume, kappa; // spread = c^2 int_T |x - x_T|^2
  CellFlux(PetscInt dim, const PetscReal *X, const CellGeometry &g, const PetscReal *phi, PetscReal kappa_) : volume(g.volume), kappa(kappa_)
  {
    PetscReal c = 0, m2 = 0;
    for (PetscInt k = 0; k <= dim; ++k) {
      c += phi[k];
      for (PetscInt d = 0; d < dim; ++d) {
        const PetscReal r = g.centroid[d] - X[k * dim + d];
        s0[d] += phi[k] * r;
        m2 += r * r;
      }
    }
    const PetscReal scale = 1 / (dim * g.volume);
    for (PetscInt d = 0; d < dim; ++d) s0[d] *= scale;
    c *= scale;
    spread = c * c * g.volume / ((dim + 1) * (dim + 2)) * m2;
  }
  // ||kappa^{-1/2}(w - sigma)||_T^2
  PetscReal Term(PetscInt dim, const PetscReal *w) const
  {
    PetscReal d2 = 0;
    for (PetscInt d = 0; d < dim; ++d) d2 += (w[d] - s0[d]) * (w[d] - s0[d]);
    return (volume * d2 + spread) / kappa;
  }
};

// Per element, from the solution u (global vector) of the assembled system.
PetscErrorCode ReconstructCR(const Space &space, const Problem &problem, const System &sys, Vec u, Reconstruction &r);
// generic: every vertex patch by the general solve (sparse elimination of the cell graph Laplacian), not the
// 2D one along the cells' cycle or path around the vertex, with its faces matched by a hash of their vertex
// numbers, not through small numbers of the patch's vertices; the two agree to round-off (unit_equilibrate).
PetscErrorCode ReconstructP1(const Space &space, const Problem &problem, const System &sys, Vec u, Reconstruction &r, bool generic = false);
// CR: moves the companion towards the conforming function closest to u_h where the vertex average is far
// from it (see estimate_cr.cpp). vertexSums holds, per local vertex z, this rank's sums over its cells at z
// of kappa_T |T| grad(u_h - v)_T . grad lambda_z and of kappa_T |T| |grad lambda_z|^2 (2 values a vertex;
// summed over ranks here), and n2 = N^2 over all ranks; `improved` says whether v changed.
PetscErrorCode ImproveCompanion(const Space &space, const System &sys, std::vector<PetscReal> &vertexSums, PetscReal n2, Reconstruction &r, bool &improved);
// Pushes the Estimate stage: the reconstruction of the space's element, then the estimate from it.
PetscErrorCode EstimateError(const Space &space, const Problem &problem, const System &sys, Vec u, Estimate &e);
// ||tau||_T for the divergence-free affine field tau = sum_j l_j lambda_j (X_j - X_o) / h_F on the simplex T
// (vertices X, dim x (dim + 1), geometry g) whose normal trace is the affine l (values l_j at the vertices j != o, summing
// to 0) on the face F opposite vertex o and 0 on the other faces (h_F the height over F): then
// int_F l e = int_T tau . grad e for every e in H^1(T), which bounds Neumann data oscillation (estimate.cpp).
PetscReal NeumannLiftNorm(PetscInt dim, const PetscReal *X, const CellGeometry &g, PetscInt opposite, const PetscReal *l);

} // namespace signorini

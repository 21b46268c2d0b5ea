// The affine parts of the data lifted into the equilibrated flux of the estimate (estimate.cpp).
//
// The flux sigma0 of the reconstructions is in RT0 with div sigma0 = -Pi_0 f and sigma0.n = Pi_0 g on
// Gamma_N, so the data enter the bound as an oscillation ||f - Pi_0 f||, ||g - Pi_0 g|| that counts
// linearly (E^2 <= F^2 + 2 osc E + ...). On a cell T a field tau with
//   div tau = -(Pi_1 f - Pi_0 f),  tau.n = Pi_1 g - Pi_0 g on T's Neumann faces,  tau.n = 0 on its other faces
// keeps sigma = sigma0 + tau in H(div) with the same contact and interface fluxes, and makes the
// oscillation that of f - Pi_1 f and g - Pi_1 g; what was linear now enters F^2 = ||kappa^{-1/2}(w - sigma)||^2
// quadratically. Such fields (with l_f = Pi_1 f - Pi_0 f = sum_k l_k lambda_k, sum_k l_k = 0):
//   - B_ij = lambda_i lambda_j (X_j - X_i) has zero normal trace on every face (X_j - X_i is tangent to the
//     faces with both vertices, lambda_i lambda_j = 0 on the others) and div B_ij = lambda_i - lambda_j, so
//     tau_f = -sum_{i<j} (l_i - l_j) / (d + 1) B_ij has div tau_f = -l_f;
//   - the combinations of B around a cycle of vertices (B_ab + B_bc + B_ca) are divergence-free: one in
//     2D, three in 3D, chosen to bring sigma closest to w;
//   - tau_F = sum_j l_j lambda_j (X_j - X_o) / h_F for the face F opposite vertex o (NeumannLiftNorm).
// Every field here is a homogeneous quadratic in the barycentric coordinates (an affine field a times
// sum_k lambda_k = 1), and their inner products are exact from int_T lambda^alpha = |T| d! alpha! / (d + |alpha|)!.
#pragma once

#include "signorini/space.h"

namespace signorini {

// The affine Neumann data of one face of a cell: the face opposite vertex `opposite`, l[k] the value of
// Pi_1 g - Pi_0 g at vertex k (k != opposite; l[opposite] unused).
struct FaceLift {
  PetscInt  opposite;
  PetscReal l[4];
};

// On the simplex T (vertices X, geometry g), with w - sigma0 and wh - sigma0 affine fields given by their
// values D, Dh at the vertices ((dim + 1) x dim, row per vertex): the field tau above for the affine part
// lf of the load (dim + 1 values, summing to 0) and the Neumann faces `faces`, its free part minimising
// ||D - tau||^2 + ||Dh - tau||^2. Returns ||D - tau||_T^2 and ||Dh - tau||_T^2 (unweighted); tauOut, where
// given, gets tau as (dim + 1)(dim + 2) / 2 vectors of dim, the coefficients of lambda_i lambda_j (i <= j,
// in the order (0,0), (0,1), ..., (0,d), (1,1), ...), for LiftValue.
void LiftCell(PetscInt dim, const PetscReal *X, const CellGeometry &g, const PetscReal *lf, PetscInt numFaces, const FaceLift *faces, const PetscReal *D, const PetscReal *Dh, PetscReal *r2, PetscReal *rh2, PetscReal *tauOut = nullptr);
// The value at barycentric coordinates lambda of a field given as LiftCell's tauOut.
void LiftValue(PetscInt dim, const PetscReal *tau, const PetscReal *lambda, PetscReal *value);

} // namespace signorini

// Quadrature rules on the reference simplex of dimension 1, 2 or 3, in barycentric coordinates.
//
// The rule of degree 1 is the one-point centroid rule. Degrees 2 to 6 on triangles and tetrahedra use
// fully symmetric rules (3, 6, 6, 7, 12 points on a triangle; 4, 14, 14, 14, 24 on a tetrahedron). Other degrees,
// and segments, use Stroud's conical product rule: Gauss-Legendre points on the unit cube collapsed onto the
// simplex (Duffy map), with enough points in each direction that the Jacobian of the collapse is integrated
// too (on a segment, the Gauss-Legendre rule). All weights are positive and sum to 1, so
// integral over T of g = |T| * sum_q w_q g(x_q). One rule serves triangles, tetrahedra and their faces.
#pragma once

#include <petscsys.h>

#include <vector>

namespace signorini {

struct Quadrature {
  PetscInt               dim    = 0;  // simplex dimension
  PetscInt               degree = 0;  // polynomials of total degree <= degree are integrated exactly
  std::vector<PetscReal> bary;        // size npoints * (dim + 1)
  std::vector<PetscReal> weights;     // size npoints, sum 1
  PetscInt               Size() const { return (PetscInt)weights.size(); }
  const PetscReal       *Point(PetscInt q) const { return &bary[q * (dim + 1)]; }
};

// Gauss-Legendre rule with n points on [0, 1].
void GaussLegendre01(PetscInt n, std::vector<PetscReal> &points, std::vector<PetscReal> &weights);

// Rule on the dim-simplex exact for total degree `degree` (>= 1).
Quadrature SimplexQuadrature(PetscInt dim, PetscInt degree);

} // namespace signorini

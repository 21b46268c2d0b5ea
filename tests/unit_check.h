// Tiny check helper shared by the unit test programs (no test framework): every check prints one line
// "PASS name" or "FAIL name: details", and Finish() prints "N passed, M failed" and gives the exit code.
#pragma once

#include "signorini/problem.h"

#include <petscdmplex.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <algorithm>
#include <array>
#include <string>
#include <vector>

namespace unit {

// The scene data of a unit test: the boundary parts and the expressions (the defaults of a plain Poisson
// problem with f = 1 and zero boundary data).
struct SceneData {
  std::vector<PetscInt> dirichlet, contact;
  const char           *f = "1", *g = "0", *uD = "0", *psi = "0", *kappa = "1";
};
inline PetscErrorCode MakeProblem(MPI_Comm comm, PetscInt dim, const SceneData &d, signorini::Problem &p)
{
  using signorini::Expression;
  PetscFunctionBeginUser;
  p.dirichlet = d.dirichlet;
  p.contact   = d.contact;
  PetscCall(Expression::Create(comm, "-f", d.f, 1, p.f));
  PetscCall(Expression::Create(comm, "-g", d.g, 1, p.g));
  PetscCall(Expression::Create(comm, "-u_D", d.uD, 1, p.uD));
  PetscCall(Expression::Create(comm, "-psi", d.psi, 1, p.psi));
  PetscCall(Expression::Create(comm, "-kappa", d.kappa, 1, p.kappa));
  PetscCall(signorini::ProblemSetUp(comm, dim, p));
  PetscFunctionReturn(0);
}

class Checker {
public:
  bool Check(bool ok, const std::string &name) { return Check(ok, name, "%s", "check failed"); }
  // Records one check. `details` (printf-style) is printed only when the check fails.
  bool Check(bool ok, const std::string &name, const char *details, ...) __attribute__((format(printf, 4, 5)))
  {
    if (ok) {
      ++passed_;
      std::printf("PASS %s\n", name.c_str());
    } else {
      char    buf[2048];
      va_list ap;
      va_start(ap, details);
      std::vsnprintf(buf, sizeof buf, details, ap);
      va_end(ap);
      ++failed_;
      std::printf("FAIL %s: %s\n", name.c_str(), buf);
    }
    std::fflush(stdout);
    return ok;
  }
  // |actual - expected| <= tol * max(|expected|, floor): relative comparison with an absolute floor.
  bool Close(double actual, double expected, double tol, const std::string &name, double floor = 1.0)
  {
    const double err = std::fabs(actual - expected), scale = std::fmax(std::fabs(expected), floor);
    return Check(err <= tol * scale && std::isfinite(actual), name, "got %.17g, expected %.17g (error %.3g > %.3g)", actual, expected, err, tol * scale);
  }
  // A PETSc call inside a test failed: counts as a failed check so the run cannot pass.
  void PetscFailure(PetscErrorCode ierr, const std::string &where) { Check(false, where, "PETSc error code %d", (int)ierr); }
  int Finish() const
  {
    std::printf("%d passed, %d failed\n", passed_, failed_);
    std::fflush(stdout);
    return failed_ ? 1 : 0;
  }
  int Failed() const { return failed_; }

private:
  int passed_ = 0, failed_ = 0;
};

// Coordinates of the vertices in the closure of point p (closure order).
inline PetscErrorCode PointVertices(DM dm, PetscInt p, std::vector<std::array<double, 3>> &out)
{
  PetscInt           vStart, vEnd, n, *closure = nullptr;
  Vec                coords;
  DM                 cdm;
  PetscSection       csec;
  const PetscScalar *xa;
  PetscInt           dim;
  PetscFunctionBeginUser;
  out.clear();
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vStart, &vEnd));
  PetscCall(DMGetCoordinatesLocal(dm, &coords));
  PetscCall(DMGetCoordinateDM(dm, &cdm));
  PetscCall(DMGetLocalSection(cdm, &csec));
  PetscCall(VecGetArrayRead(coords, &xa));
  PetscCall(DMPlexGetTransitiveClosure(dm, p, PETSC_TRUE, &n, &closure));
  for (PetscInt i = 0; i < n; ++i) {
    const PetscInt q = closure[2 * i];
    if (q < vStart || q >= vEnd) continue;
    PetscInt off;
    PetscCall(PetscSectionGetOffset(csec, q, &off));
    std::array<double, 3> x{0, 0, 0};
    for (PetscInt d = 0; d < dim; ++d) x[d] = PetscRealPart(xa[off + d]);
    out.push_back(x);
  }
  PetscCall(DMPlexRestoreTransitiveClosure(dm, p, PETSC_TRUE, &n, &closure));
  PetscCall(VecRestoreArrayRead(coords, &xa));
  PetscFunctionReturn(0);
}

// Largest negative barycentric coordinate of a fine cell's centroid in its parent (0 when inside).
inline PetscErrorCode ParentOutside(DM coarse, DM fine, const std::vector<PetscInt> &parent, double *outside)
{
  PetscInt cS, cE, ccS;
  PetscFunctionBeginUser;
  *outside = 0;
  PetscCall(DMPlexGetHeightStratum(fine, 0, &cS, &cE));
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &ccS, NULL));
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal vol, x[3], v0[3], J[9], invJ[9], detJ;
    PetscInt  dim;
    PetscCall(DMGetDimension(fine, &dim));
    PetscCall(DMPlexComputeCellGeometryFVM(fine, c, &vol, x, NULL));
    PetscCall(DMPlexComputeCellGeometryAffineFEM(coarse, ccS + parent[c - cS], v0, J, invJ, &detJ));
    // reference coordinates xi = invJ (x - v0) - 1 on PETSc's reference simplex in [-1, 1]^dim
    PetscReal xi[3] = {0, 0, 0}, lambda0 = 1;
    for (PetscInt i = 0; i < dim; ++i) {
      for (PetscInt j = 0; j < dim; ++j) xi[i] += invJ[i * dim + j] * (x[j] - v0[j]);
      xi[i] -= 1.0;
      *outside = std::max(*outside, -(double)(xi[i] + 1) / 2);
      lambda0 -= (xi[i] + 1) / 2;
    }
    *outside = std::max(*outside, -(double)lambda0);
  }
  PetscFunctionReturn(0);
}

// PETSc's consistency checks of a mesh (symmetry, skeleton, faces, geometry with positive Jacobians, point
// star forest, interface cones): each raises an error when it fails.
inline PetscErrorCode CheckPlex(DM dm)
{
  PetscFunctionBeginUser;
  PetscCall(DMPlexCheckSymmetry(dm));
  PetscCall(DMPlexCheckSkeleton(dm, 0));
  PetscCall(DMPlexCheckFaces(dm, 0));
  PetscCall(DMPlexCheckGeometry(dm));
  PetscCall(DMPlexCheckPointSF(dm, NULL, PETSC_FALSE));
  PetscCall(DMPlexCheckInterfaceCones(dm));
  PetscFunctionReturn(0);
}

} // namespace unit

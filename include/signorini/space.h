// The discrete space: conforming P1 (one DOF per vertex) or Crouzeix-Raviart (one DOF per face, i.e. per
// height-1 point), laid out by a PetscSection on the mesh's DOF points, with the DOFs on Gamma_D and on
// Gamma_C classified. Its vectors and their exchange go through a layout DM that needs no mesh (layout.h),
// so the mesh can be freed once the tables are built (SpaceReleaseMesh).
//
// Both elements are described through barycentric coordinates lambda_0..lambda_d of a cell, so one code
// path serves triangles and tetrahedra. The cell tables list a cell's vertices so that vertex k is the one
// not on face k of its cone, and then
//   P1: phi_i = lambda_i                (DOF i = vertex i of the cell)
//   CR: phi_i = 1 - d * lambda_i        (DOF i = face i of the cone, the face opposite vertex i)
// i.e. phi_i = a + b * lambda_i with (a, b) = (0, 1) or (1, -d).
#pragma once

#include "signorini/problem.h"

#include <petscdmplex.h>

#include <algorithm>
#include <cmath>

namespace signorini {

enum class Element { P1, CR };
const char *ElementName(Element e);

// Affine geometry of one simplex.
struct CellGeometry {
  PetscReal volume;
  PetscReal gradLambda[4][3]; // gradients of the barycentric coordinates
  PetscReal centroid[3];
};
// The centroid of the simplex with vertices X (the mean of the vertices).
inline void SimplexCentroid(PetscInt dim, const PetscReal *X, PetscReal *x)
{
  for (PetscInt d = 0; d < dim; ++d) {
    x[d] = 0;
    for (PetscInt k = 0; k <= dim; ++k) x[d] += X[k * dim + d];
    x[d] *= 1.0 / (dim + 1);
  }
}
// J = [X_1 - X_0, ..., X_d - X_0] and its determinant; false for a degenerate simplex: |det| tiny relative
// to the cell's size (round-off leaves collinear vertices a det ~ 1e-17).
template <PetscInt dim>
inline bool SimplexJacobian(const PetscReal *X, PetscReal J[3][3], PetscReal &det)
{
  for (PetscInt r = 0; r < dim; ++r)
    for (PetscInt k = 0; k < dim; ++k) J[r][k] = X[(k + 1) * dim + r] - X[r];
  if (dim == 2) det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
  else det = J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
  PetscReal h2 = 0;
  for (PetscInt k = 0; k < dim; ++k) {
    PetscReal len2 = 0;
    for (PetscInt r = 0; r < dim; ++r) len2 += J[r][k] * J[r][k];
    h2 = std::max(h2, len2);
  }
  const PetscReal h = std::sqrt(h2);
  return std::isfinite(det) && std::fabs(det) > 1e-12 * (dim == 2 ? h * h : h * h * h);
}
// Returns false for a degenerate cell (g then all zero). Inline, with the dimension a template
// parameter inside: the cell loops call it for millions of cells, and with its loops unrolled it takes a
// fraction of the time (the same operations in the same order, so the same results).
template <PetscInt dim>
inline bool ComputeCellGeometryD(const PetscReal *X, CellGeometry &g)
{
  // grad lambda_k = row k-1 of J^{-1}, grad lambda_0 = -sum of the others.
  PetscReal J[3][3], inv[3][3], det;
  if (!SimplexJacobian<dim>(X, J, det)) {
    g = CellGeometry{}; // set even so: the compiler then sees no member of g unset where it is read
    return false;
  }
  const PetscReal invDet = 1 / det; // one division a cell, not one an entry
  if (dim == 2) {
    inv[0][0] = J[1][1] * invDet, inv[0][1] = -J[0][1] * invDet;
    inv[1][0] = -J[1][0] * invDet, inv[1][1] = J[0][0] * invDet;
  } else {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        // cofactor of J[j][i], divided by det
        const int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
        inv[i][j]    = (J[r0][c0] * J[r1][c1] - J[r0][c1] * J[r1][c0]) * invDet;
      }
  }
  g.volume = std::fabs(det) / (dim == 2 ? 2.0 : 6.0);
  SimplexCentroid(dim, X, g.centroid);
  for (PetscInt d = 0; d < dim; ++d) g.gradLambda[0][d] = 0;
  for (PetscInt k = 1; k <= dim; ++k)
    for (PetscInt d = 0; d < dim; ++d) {
      g.gradLambda[k][d] = inv[k - 1][d];
      g.gradLambda[0][d] -= inv[k - 1][d];
    }
  return true;
}
// The same for a dimension known at run time (out of line: the loops that know theirs call the template).
bool ComputeCellGeometry(PetscInt dim, const PetscReal *X, CellGeometry &g);
// Whether the simplex with vertices X is not degenerate: ComputeCellGeometry's verdict without the geometry.
bool SimplexIsValid(PetscInt dim, const PetscReal *X);
// x = sum_k lambda_k X_k: the point of barycentric coordinates lambda in the simplex with vertices X.
inline void SimplexPoint(PetscInt dim, const PetscReal *X, const PetscReal *lambda, PetscReal *x)
{
  for (PetscInt d = 0; d < dim; ++d) {
    x[d] = 0;
    for (PetscInt k = 0; k <= dim; ++k) x[d] += lambda[k] * X[k * dim + d];
  }
}

// The barycentric coordinates of the point of DOF i of a cell (where basis function i is 1): vertex i
// (P1), or the centroid of the face opposite vertex i (CR).
inline void DofLambda(Element e, PetscInt dim, PetscInt i, PetscReal *lambda)
{
  for (PetscInt k = 0; k <= dim; ++k) lambda[k] = e == Element::P1 ? (k == i) : (k == i ? 0.0 : 1.0 / dim);
}

// lambda: the barycentric coordinates of x in the simplex of geometry g whose first vertex is X0
// (lambda_k = grad lambda_k . (x - X0) for k >= 1). Outside the simplex some lambda_k are negative.
inline void Barycentric(PetscInt dim, const CellGeometry &g, const PetscReal *X0, const PetscReal *x, PetscReal *lambda)
{
  PetscReal sum = 0;
  for (PetscInt k = 1; k <= dim; ++k) {
    lambda[k] = 0;
    for (PetscInt d = 0; d < dim; ++d) lambda[k] += g.gradLambda[k][d] * (x[d] - X0[d]);
    sum += lambda[k];
  }
  lambda[0] = 1 - sum;
}

// A face on a named boundary part, seen from its only cell.
struct BoundaryFace {
  PetscInt cell;     // local cell index (c - cStart)
  PetscInt opposite; // index (0..dim) of the cell vertex not on the face
  PetscInt part;     // "Face Sets" value
  PetscInt dof;      // CR: local DOF of the face; P1: -1
  PetscInt face;     // the face's mesh point
};

// A face between two cells, for face-based post-processing (jumps, fluxes) after the mesh is freed. The
// tables are built only when SpaceCreate is asked for them (interiorFaces): most runs need none of it.
// Interior faces with both cells on this rank are listed once, with both sides. A face on the boundary
// between two ranks' cells (the mesh has no overlap: each rank holds one of its cells) is listed on both
// ranks as a SharedFace with its local side only, and sharedFaceSF joins the two entries: its roots are
// the SharedFace entries (index into sharedFaces) of the rank that owns the face in the point SF, its
// leaves those of the other rank, each pointing at the owner's entry. PetscSFBcast over it hands each
// shared face's per-face data (e.g. the owner's side of a jump) to the other rank, PetscSFReduce the
// other way; counting faces, the owned entries count each shared face once.
struct InteriorFace {
  PetscInt cell[2];  // the two local cells (c - cStart)
  PetscInt local[2]; // index (0..dim) of the face in each cell's cone: the cell vertex opposite it (CR: its DOF)
};
struct SharedFace {
  PetscInt cell;  // the local cell (c - cStart)
  PetscInt local; // index of the face in that cell's cone
  bool     owned; // this rank owns the face (a root of sharedFaceSF)
};

enum DofKind : char { kFree = 0, kDirichlet = 1, kContact = 2 };

struct Space {
  DM       mesh = nullptr; // the mesh (a reference, its topology only: the DOF layout is in dm); null once released
  DM       dm   = nullptr; // the DOF layout: creates the local and global vectors, exchanges between them
  Element  element = Element::CR;
  PetscInt dim = 2, cStart = 0, cEnd = 0, vStart = 0;
  PetscInt numLocal = 0, numOwned = 0, numGlobal = 0, numContactGlobal = 0, numDirichletGlobal = 0;
  // Per cell only what cannot be looked up cheaply: at 10^7 cells every entry is 40 MB of memory and
  // of page faults in the set-up.
  std::vector<PetscInt>     cellDof;   // (dim+1) local DOF indices per cell (CR; P1 DOFs are the cellVert entries)
  std::vector<PetscInt>     cellVert;  // (dim+1) vertices per cell (as v - vStart), vertex k opposite cone face k
  std::vector<PetscReal>    vertX;     // dim coordinates per local vertex (v - vStart)
  std::vector<PetscInt>     cellSet;   // "Cell Sets" value per cell (-1: none); empty if the mesh has no such label
  std::vector<char>         kindLocal; // DofKind per local DOF (consistent across ranks)
  std::vector<PetscInt>     dirichletOwned, contactOwned; // indices into the owned part of a global Vec
  std::vector<BoundaryFace> boundary;  // faces of all named parts on this rank
  ISLocalToGlobalMapping    ltog = nullptr; // global index of every local DOF (ghosts included)
  // Only with SpaceCreate(..., interiorFaces = true); see InteriorFace above.
  std::vector<InteriorFace> interiorFaces;
  std::vector<SharedFace>   sharedFaces;
  PetscSF                   sharedFaceSF = nullptr;
  // Only with SpaceCreate(..., vertexExchange = true), for a space without vertex DOFs (CR) that needs
  // vertex values summed over ranks (the estimate's conforming companion): roots are the local vertices
  // (v - vStart), leaves the local copies of vertices another rank owns, each pointing at the owner's
  // vertex. PetscSFReduce sums the copies onto the owner, PetscSFBcast hands the owner's value back.
  PetscSF                   vertexSF = nullptr;

  // The vertex coordinates of a cell, (dim+1)*dim values; converts to a pointer for the functions that
  // take one (keep the object, not the pointer, beyond one expression).
  struct Coords {
    PetscReal x[12];
    operator const PetscReal *() const { return x; }
  };

  PetscInt        NumCells() const { return cEnd - cStart; }
  PetscInt        CellSet(PetscInt c) const { return cellSet.empty() ? -1 : cellSet[c]; }
  PetscInt        Nb() const { return dim + 1; }
  // P1 DOF i is vertex vStart + i, so a cell's DOFs are its vertex entries: a tetrahedral mesh has about six
  // cells per vertex, and a second table would cost 96 bytes per DOF.
  const PetscInt *Dofs(PetscInt c) const { return &(element == Element::P1 ? cellVert : cellDof)[c * (dim + 1)]; }
  PetscInt        Vertex(PetscInt c, PetscInt k) const { return vStart + cellVert[c * (dim + 1) + k]; } // mesh point
  Coords          X(PetscInt c) const { return WithDim(dim, [&](auto D) { return XD<D>(c); }); }
  // X(c) and Grad with the dimension a constant: in the cell loops that know it, their loops unroll.
  template <PetscInt D>
  Coords XD(PetscInt c) const
  {
    Coords X;
    for (PetscInt k = 0; k <= D; ++k)
      for (PetscInt d = 0; d < D; ++d) X.x[k * D + d] = vertX[cellVert[c * (D + 1) + k] * D + d];
    return X;
  }
  template <PetscInt D>
  void GradD(PetscInt c, const PetscScalar *a, const CellGeometry &g, PetscReal *grad) const
  {
    const PetscReal b = GradScale(); // grad phi_i = b grad lambda_i
    for (PetscInt d = 0; d < D; ++d) grad[d] = 0;
    for (PetscInt i = 0; i <= D; ++i)
      for (PetscInt d = 0; d < D; ++d) grad[d] += PetscRealPart(a[Dofs(c)[i]]) * (b * g.gradLambda[i][d]);
  }
  PetscReal BasisValue(PetscInt, PetscInt i, const PetscReal *lambda) const
  {
    return element == Element::P1 ? lambda[i] : 1.0 - dim * lambda[i];
  }
  // b of phi_i = a + b lambda_i (see the top of the file): grad phi_i = b grad lambda_i.
  PetscReal GradScale() const { return element == Element::P1 ? 1.0 : -(PetscReal)dim; }
  void      BasisGrad(PetscInt, PetscInt i, const CellGeometry &g, PetscReal *grad) const
  {
    const PetscReal b = GradScale();
    for (PetscInt d = 0; d < dim; ++d) grad[d] = b * g.gradLambda[i][d];
  }
  // The discrete function u_h = sum_i a_i phi_i on cell c, a a local vector's array: its value at barycentric
  // coordinates lambda, and its gradient (constant on the cell; g the cell's geometry).
  PetscReal Value(PetscInt c, const PetscScalar *a, const PetscReal *lambda) const
  {
    PetscReal v = 0;
    for (PetscInt i = 0; i < Nb(); ++i) v += PetscRealPart(a[Dofs(c)[i]]) * BasisValue(c, i, lambda);
    return v;
  }
  void Grad(PetscInt c, const PetscScalar *a, const CellGeometry &g, PetscReal *grad) const { WithDim(dim, [&](auto D) { GradD<D>(c, a, g, grad); }); }
  // Physical point of barycentric coordinates lambda in cell c.
  void Point(PetscInt c, const PetscReal *lambda, PetscReal *x) const;
  // Where basis function i of cell c is 1: vertex i (P1) or the centroid of the face opposite it (CR).
  void DofPoint(PetscInt c, PetscInt i, PetscReal *x) const;
  // Calls f(dof, x) once for every local DOF on Gamma_D or Gamma_C, x its point (vertex or face centroid).
  template <class F>
  void ForEachBoundaryDof(F f) const
  {
    PetscReal x[3];
    if (element == Element::P1) { // DOF i is vertex vStart + i (checked by SpaceCreate)
      for (PetscInt i = 0; i < numLocal; ++i)
        if (kindLocal[i] != kFree) f(i, &vertX[i * dim]);
      return;
    }
    for (const BoundaryFace &bf : boundary) // a CR DOF on a part is a face of it, on the rank of its cell
      if (kindLocal[bf.dof] != kFree) {
        DofPoint(bf.cell, bf.opposite, x);
        f(bf.dof, x);
      }
  }
  // Measure of boundary face bf (length in 2D, area in 3D) and its barycentric coordinates in the cell
  // of a point with face-barycentric coordinates mu (dim entries).
  PetscReal FaceMeasure(const BoundaryFace &bf) const;
  void      FaceToCell(const BoundaryFace &bf, const PetscReal *mu, PetscReal *lambda) const;
};

// The point of every local DOF (dim values each): for output and tests; the solver itself does not keep
// this table.
std::vector<PetscReal> DofPoints(const Space &space);

PetscErrorCode ElementFromCommandLine(MPI_Comm comm, Element &e);
// Builds the section, cell tables and DOF classification. Checks that every named part exists on the mesh
// and consists of boundary faces, that no face is in two named parts, that the cells are not degenerate,
// and that psi <= u_D where Gamma_D and Gamma_C meet (otherwise no u in H^1 satisfies both). With
// interiorFaces, also the face tables (interiorFaces, sharedFaces, sharedFaceSF); with vertexExchange, vertexSF.
PetscErrorCode SpaceCreate(DM mesh, Element element, const Problem &problem, Space &space, bool interiorFaces = false, bool vertexExchange = false);
// The P1 space of `mesh`, whose CR space (or any space of it) is `of`: as SpaceCreate(mesh, P1, problem, ...)
// builds it (no face tables, no vertex exchange), with the cell tables and boundary faces copied from `of`
// instead of looked up in the mesh again (the multigrid over adaptive CR levels needs one every step,
// adapt.h), and without SpaceCreate's checks of the mesh and the data, which `of` passed.
PetscErrorCode SpaceCreateP1Of(DM mesh, const Space &of, const Problem &problem, Space &space);
PetscErrorCode SpaceDestroy(Space &space);
// Drops the space's reference to the mesh, so that once the caller drops its own the DMPlex is freed.
// Everything but the HDF5 output works on the tables and the layout (assembly, solve, KKT, energy, errors,
// prolongation), so it may be called right after SpaceCreate.
PetscErrorCode SpaceReleaseMesh(Space &space);
// A clone of the space's mesh carrying the space's local section (DOF of point p at p - start) and mat
// type aij, for comparisons with PETSc's own DMPlex machinery (DMCreateMatrix, DMGlobalToLocal): the space
// itself needs no such DM. Needs the mesh (before SpaceReleaseMesh).
PetscErrorCode SpaceSectionDM(const Space &space, DM *dm);
// The DM keeps the work vectors of DMGetLocalVector/DMGetGlobalVector after they are restored, for the
// next caller; at 10^7 DOFs each is 80 MB that should not stay through a solve. Frees them.
PetscErrorCode SpaceReleaseWorkVectors(const Space &space);
// Collective: every local copy of a DOF another rank owns takes the owner's entry of `values` (one per
// local DOF; integers up to 2^53, carried in the space's vectors).
PetscErrorCode SpaceShareOwners(const Space &space, std::vector<PetscInt> &values);

} // namespace signorini

// Unit tests of the element layer: ComputeCellGeometry on hand-made simplices, then the P1 and CR spaces
// built by SpaceCreate on small box meshes (basis functions against the mesh's own faces and vertices,
// element stiffness against the |F_i||F_j| n_i.n_j / |T| formula, DOF counts against counting formulas).
#include "signorini/assembly.h"
#include "signorini/mesh.h"
#include "signorini/space.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <vector>

using namespace signorini;

// ---------------------------------------------------------------------------------------------------
// Part 1: ComputeCellGeometry on hand-made cells.

struct HandCell {
  std::string            name;
  PetscInt               dim;
  std::vector<PetscReal> X;      // (dim+1) * dim
  double                 volume; // exact, by hand
};

static void CheckGeometry(unit::Checker &ck, const HandCell &hc)
{
  const PetscInt dim = hc.dim;
  CellGeometry   g;
  const bool     ok = ComputeCellGeometry(dim, hc.X.data(), g);
  if (!ck.Check(ok && signorini::SimplexIsValid(dim, hc.X.data()), hc.name + " is accepted", "returned false for a non-degenerate cell")) return;
  ck.Close(g.volume, hc.volume, 1e-13, hc.name + " volume", 0.0);

  // grad lambda_k . (X_j - X_0) = delta_kj - delta_k0 for j = 1..dim, and sum_k grad lambda_k = 0.
  double worst = 0, worstSum = 0;
  for (PetscInt k = 0; k <= dim; ++k)
    for (PetscInt j = 1; j <= dim; ++j) {
      double dot = 0, gn = 0, en = 0;
      for (PetscInt d = 0; d < dim; ++d) {
        const double e = hc.X[j * dim + d] - hc.X[d];
        dot += g.gradLambda[k][d] * e;
        gn += g.gradLambda[k][d] * g.gradLambda[k][d];
        en += e * e;
      }
      const double expected = (k == j ? 1.0 : 0.0) - (k == 0 ? 1.0 : 0.0);
      worst                 = std::fmax(worst, std::fabs(dot - expected) / std::fmax(1.0, std::sqrt(gn * en)));
    }
  double gmax = 0;
  for (PetscInt k = 0; k <= dim; ++k)
    for (PetscInt d = 0; d < dim; ++d) gmax = std::fmax(gmax, std::fabs(g.gradLambda[k][d]));
  for (PetscInt d = 0; d < dim; ++d) {
    double s = 0;
    for (PetscInt k = 0; k <= dim; ++k) s += g.gradLambda[k][d];
    worstSum = std::fmax(worstSum, std::fabs(s) / gmax);
  }
  ck.Check(worst <= 1e-12, hc.name + " grad lambda_k . (X_j - X_0) = delta_kj - delta_k0", "worst relative error %.3g", worst);
  ck.Check(worstSum <= 1e-14, hc.name + " sum_k grad lambda_k = 0", "worst |sum| / max|grad| = %.3g", worstSum);

  double cerr = 0;
  for (PetscInt d = 0; d < dim; ++d) {
    double c = 0;
    for (PetscInt k = 0; k <= dim; ++k) c += hc.X[k * dim + d];
    cerr = std::fmax(cerr, std::fabs(g.centroid[d] - c / (dim + 1)));
  }
  ck.Check(cerr <= 1e-14, hc.name + " centroid", "error %.3g", cerr);
}

static void TestHandCells(unit::Checker &ck)
{
  const std::vector<HandCell> cells = {
    {"triangle reference", 2, {0, 0, 1, 0, 0, 1}, 0.5},
    {"triangle general", 2, {1, 2, 4, 3, 2, 5}, 4.0},            // edges (3,1), (1,3): det 8
    {"triangle clockwise", 2, {0, 0, 0, 1, 1, 0}, 0.5},
    {"triangle flat aspect 1e3", 2, {0, 0, 1, 0, 0.5, 1e-3}, 0.5e-3},
    {"triangle needle aspect 1e3", 2, {0, 0, 1e-3, 0, 0, 1}, 0.5e-3},
    {"tet reference", 3, {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, 1.0 / 6},
    {"tet PETSc orientation (det<0)", 3, {0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1}, 1.0 / 6},
    {"tet general", 3, {1, 0, 0, 3, 1, 0, 1, 4, 1, 0, 1, 5}, 37.0 / 6}, // edges (2,1,0), (0,4,1), (-1,1,5): det 37
    {"tet flat aspect 1e3", 3, {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.3, 0.3, 1e-3}, 1e-3 / 6},
    {"tet needle aspect 1e3", 3, {0, 0, 0, 1e-3, 0, 0, 0, 1e-3, 0, 0, 0, 1}, 1e-6 / 6},
  };
  for (const HandCell &hc : cells) CheckGeometry(ck, hc);

  // Exact gradients of the reference cells: lambda_k = x_k (k >= 1), lambda_0 = 1 - sum x.
  for (PetscInt dim = 2; dim <= 3; ++dim) {
    const HandCell &hc = cells[dim == 2 ? 0 : 5];
    CellGeometry    g;
    ComputeCellGeometry(dim, hc.X.data(), g);
    double err = 0;
    for (PetscInt k = 0; k <= dim; ++k)
      for (PetscInt d = 0; d < dim; ++d) err = std::fmax(err, std::fabs(g.gradLambda[k][d] - (k == 0 ? -1.0 : (k == d + 1 ? 1.0 : 0.0))));
    ck.Check(err == 0, hc.name + " gradients are exactly e_k and -(1,..,1)", "max error %g", err);
  }

  // Degenerate cells: exactly representable collinear / coplanar vertices, a repeated vertex, and
  // collinear / coplanar vertices whose determinant is not exactly 0 in floating point.
  const std::vector<HandCell> degenerate = {
    {"degenerate triangle collinear (0,0),(1,1),(2,2)", 2, {0, 0, 1, 1, 2, 2}, 0},
    {"degenerate triangle repeated vertex", 2, {0, 0, 1, 0, 1, 0}, 0},
    {"degenerate tet coplanar z=0", 3, {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, 0},
    {"degenerate tet repeated vertex", 3, {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0}, 0},
    {"degenerate triangle collinear with rounding (0.1,0.2),(0.4,0.5),(0.7,0.8)", 2, {0.1, 0.2, 0.4, 0.5, 0.7, 0.8}, 0},
    {"degenerate tet coplanar x+y+z=1 with rounding", 3, {0.1, 0.2, 0.7, 0.3, 0.3, 0.4, 0.6, 0.1, 0.3, 0.2, 0.5, 0.3}, 0},
  };
  for (const HandCell &hc : degenerate) {
    CellGeometry g;
    const bool   ok = ComputeCellGeometry(hc.dim, hc.X.data(), g);
    ck.Check(!ok, hc.name + " is rejected", "returned true (volume %.3g)", ok ? (double)g.volume : 0.0);
    ck.Check(!signorini::SimplexIsValid(hc.dim, hc.X.data()), hc.name + " is rejected by SimplexIsValid");
  }
}

// ---------------------------------------------------------------------------------------------------
// Part 2: spaces on box meshes.

static double Det3(const double a[3], const double b[3], const double c[3])
{
  return a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
}

// Barycentric coordinates of x in the simplex with vertex rows X (dim+1 rows of dim), by Cramer's rule.
static void Barycentric(PetscInt dim, const PetscReal *X, const double *x, double *lambda)
{
  if (dim == 2) {
    const double a[2] = {X[2] - X[0], X[3] - X[1]}, b[2] = {X[4] - X[0], X[5] - X[1]}, r[2] = {x[0] - X[0], x[1] - X[1]};
    const double det = a[0] * b[1] - a[1] * b[0];
    lambda[1]        = (r[0] * b[1] - r[1] * b[0]) / det;
    lambda[2]        = (a[0] * r[1] - a[1] * r[0]) / det;
    lambda[0]        = 1 - lambda[1] - lambda[2];
    return;
  }
  double e[3][3], r[3];
  for (int k = 0; k < 3; ++k)
    for (int d = 0; d < 3; ++d) e[k][d] = X[(k + 1) * 3 + d] - X[d];
  for (int d = 0; d < 3; ++d) r[d] = x[d] - X[d];
  const double det = Det3(e[0], e[1], e[2]);
  lambda[1]        = Det3(r, e[1], e[2]) / det;
  lambda[2]        = Det3(e[0], r, e[2]) / det;
  lambda[3]        = Det3(e[0], e[1], r) / det;
  lambda[0]        = 1 - lambda[1] - lambda[2] - lambda[3];
}

// Measure and outward unit normal of the face with vertices F (dim of them), seen from the cell centroid cc.
static void FaceMeasureNormal(PetscInt dim, const std::vector<std::array<double, 3>> &F, const double *cc, double &measure, double n[3])
{
  n[0] = n[1] = n[2] = 0;
  if (dim == 2) {
    const double dx = F[1][0] - F[0][0], dy = F[1][1] - F[0][1];
    measure = std::hypot(dx, dy);
    n[0] = dy / measure, n[1] = -dx / measure;
  } else {
    const double a[3] = {F[1][0] - F[0][0], F[1][1] - F[0][1], F[1][2] - F[0][2]}, b[3] = {F[2][0] - F[0][0], F[2][1] - F[0][1], F[2][2] - F[0][2]};
    const double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    const double len  = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    measure           = 0.5 * len;
    for (int d = 0; d < 3; ++d) n[d] = c[d] / len;
  }
  double s = 0;
  for (PetscInt d = 0; d < dim; ++d) {
    double fc = 0;
    for (const auto &v : F) fc += v[d] / F.size();
    s += (fc - cc[d]) * n[d];
  }
  if (s < 0)
    for (int d = 0; d < 3; ++d) n[d] = -n[d];
}

struct SpaceCase {
  std::string name;
  MeshOptions mesh;
  Element     element;
  std::vector<PetscInt> dirichlet, contact;
  // Expected counts from counting formulas.
  PetscInt numGlobal, numContact, numDirichlet;
  PetscInt dirichletAxis; // coordinate axis of the Dirichlet side
  double   dirichletValue;
};

static PetscErrorCode TestSpace(unit::Checker &ck, const SpaceCase &sc)
{
  MPI_Comm       comm = PETSC_COMM_WORLD;
  DM             dm   = nullptr;
  MeshInfo       info;
  Problem        problem;
  Space          space;
  const PetscInt dim = sc.mesh.dim, nb = dim + 1;
  const double   kappa = 2.5; // any positive value: K scales linearly
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, sc.mesh, &dm, info));
  PetscCall(unit::MakeProblem(comm, dim, {sc.dirichlet, sc.contact, "0"}, problem));
  PetscCall(SpaceCreate(dm, sc.element, problem, space));
  const std::string tag = sc.name;
  ck.Check(space.dim == dim && space.element == sc.element, tag + " dim and element");

  // DOF -> mesh point, from the space's own section.
  PetscSection sec;
  DM           sectionDM;
  PetscInt     pStart, pEnd, vStart, vEnd, fStart, fEnd;
  PetscCall(SpaceSectionDM(space, &sectionDM));
  PetscCall(DMGetLocalSection(sectionDM, &sec));
  PetscCall(PetscSectionGetChart(sec, &pStart, &pEnd));
  PetscCall(DMPlexGetDepthStratum(space.mesh, 0, &vStart, &vEnd));
  PetscCall(DMPlexGetHeightStratum(space.mesh, 1, &fStart, &fEnd));
  std::map<PetscInt, PetscInt> pointOf;
  for (PetscInt p = pStart; p < pEnd; ++p) {
    PetscInt ndof, off;
    PetscCall(PetscSectionGetDof(sec, p, &ndof));
    if (!ndof) continue;
    PetscCall(PetscSectionGetOffset(sec, p, &off));
    pointOf[off] = p;
  }
  ck.Check((PetscInt)pointOf.size() == space.numLocal, tag + " one point per local DOF", "%zu points, numLocal %d", pointOf.size(), (int)space.numLocal);
  PetscCall(DMDestroy(&sectionDM));

  const std::vector<PetscReal> dofPoint = DofPoints(space);
  double      basisErr = 0, dofPointErr = 0, symErr = 0, rowErr = 0, formulaErr = 0;
  bool        pointsOk = true, vertsOk = true;
  std::string pointsMsg;
  std::vector<std::array<double, 3>> cellV, faceV;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt cell = space.cStart + c;
    PetscCall(unit::PointVertices(space.mesh, cell, cellV));
    // The space's vertex table holds this cell's vertices, vertex k the one not on cone face k.
    const PetscInt *tcone;
    PetscCall(DMPlexGetCone(space.mesh, cell, &tcone));
    for (PetscInt k = 0; k < nb; ++k) {
      bool found = false;
      for (const auto &v : cellV) {
        double e = 0;
        for (PetscInt d = 0; d < dim; ++d) e = std::fmax(e, std::fabs(v[d] - space.X(c)[k * dim + d]));
        found = found || e == 0;
      }
      PetscCall(unit::PointVertices(space.mesh, tcone[k], faceV));
      for (const auto &v : faceV) {
        double e = 0;
        for (PetscInt d = 0; d < dim; ++d) e = std::fmax(e, std::fabs(v[d] - space.X(c)[k * dim + d]));
        found = found && e > 0;
      }
      vertsOk = vertsOk && found && (PetscInt)cellV.size() == nb;
    }
    double cc[3] = {0, 0, 0};
    for (const auto &v : cellV)
      for (PetscInt d = 0; d < dim; ++d) cc[d] += v[d] / nb;
    double vol;
    {
      const double a[3] = {cellV[1][0] - cellV[0][0], cellV[1][1] - cellV[0][1], cellV[1][2] - cellV[0][2]};
      const double b[3] = {cellV[2][0] - cellV[0][0], cellV[2][1] - cellV[0][1], cellV[2][2] - cellV[0][2]};
      if (dim == 2) vol = 0.5 * std::fabs(a[0] * b[1] - a[1] * b[0]);
      else {
        const double e[3] = {cellV[3][0] - cellV[0][0], cellV[3][1] - cellV[0][1], cellV[3][2] - cellV[0][2]};
        vol               = std::fabs(Det3(a, b, e)) / 6;
      }
    }
    const PetscInt *cone;
    PetscCall(DMPlexGetCone(space.mesh, cell, &cone));

    // For each DOF i of the cell: its mesh point, the point where phi_i must be 1, and the face F_i with
    // |F_i| n_i = -d |T| grad lambda (face of the DOF for CR, face opposite the vertex for P1).
    double   where[4][3], Fmeas[4], Fn[4][3];
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt dof = space.Dofs(c)[i];
      const PetscInt p   = pointOf.count(dof) ? pointOf[dof] : -1;
      const bool     inCell =
        sc.element == Element::CR ? std::find(cone, cone + nb, p) != cone + nb : (p >= vStart && p < vEnd && [&] {
          PetscInt *cl = nullptr, n;
          bool      in = false;
          DMPlexGetTransitiveClosure(space.mesh, cell, PETSC_TRUE, &n, &cl);
          for (PetscInt j = 0; j < n; ++j) in = in || cl[2 * j] == p;
          DMPlexRestoreTransitiveClosure(space.mesh, cell, PETSC_TRUE, &n, &cl);
          return in;
        }());
      if (!inCell && pointsOk) {
        pointsOk  = false;
        pointsMsg = Format("cell %d DOF %d (offset %d) is point %d, not a %s of the cell", (int)c, (int)i, (int)dof, (int)p, sc.element == Element::CR ? "face" : "vertex");
      }
      if (!inCell) continue;
      PetscCall(unit::PointVertices(space.mesh, p, faceV));
      for (PetscInt d = 0; d < dim; ++d) {
        where[i][d] = 0;
        for (const auto &v : faceV) where[i][d] += v[d] / faceV.size();
      }
      for (PetscInt d = 0; d < dim; ++d) dofPointErr = std::fmax(dofPointErr, std::fabs(dofPoint[dof * dim + d] - where[i][d]));
      if (sc.element == Element::P1) { // face opposite vertex p: the other cell vertices
        std::vector<std::array<double, 3>> opp;
        for (const auto &v : cellV)
          if (!(v[0] == faceV[0][0] && v[1] == faceV[0][1] && v[2] == faceV[0][2])) opp.push_back(v);
        faceV = opp;
      }
      FaceMeasureNormal(dim, faceV, cc, Fmeas[i], Fn[i]);
    }
    if (!pointsOk) continue;

    // phi_j(where_i) = delta_ij with lambda computed independently from the vertex table.
    for (PetscInt i = 0; i < nb; ++i) {
      double lambda[4];
      Barycentric(dim, space.X(c), where[i], lambda);
      PetscReal lam[4];
      for (PetscInt k = 0; k < nb; ++k) lam[k] = lambda[k];
      for (PetscInt j = 0; j < nb; ++j) basisErr = std::fmax(basisErr, std::fabs(space.BasisValue(c, j, lam) - (i == j ? 1.0 : 0.0)));
    }

    // Element stiffness.
    CellGeometry g;
    PetscReal    Ke[16];
    ComputeCellGeometry(dim, space.X(c), g);
    ElementStiffness(space, c, kappa, g, Ke);
    double kmax = 0;
    for (PetscInt i = 0; i < nb * nb; ++i) kmax = std::fmax(kmax, std::fabs(Ke[i]));
    const double scale = sc.element == Element::CR ? 1.0 : 1.0 / (dim * dim);
    for (PetscInt i = 0; i < nb; ++i) {
      double row = 0;
      for (PetscInt j = 0; j < nb; ++j) {
        row += Ke[i * nb + j];
        symErr = std::fmax(symErr, std::fabs(Ke[i * nb + j] - Ke[j * nb + i]) / kmax);
        double nn = 0;
        for (PetscInt d = 0; d < dim; ++d) nn += Fn[i][d] * Fn[j][d];
        const double expected = kappa * scale * Fmeas[i] * Fmeas[j] * nn / vol;
        formulaErr            = std::fmax(formulaErr, std::fabs(Ke[i * nb + j] - expected) / kmax);
      }
      rowErr = std::fmax(rowErr, std::fabs(row) / kmax);
    }
  }
  ck.Check(vertsOk, tag + " vertex table holds the cell's vertices");
  ck.Check(pointsOk, tag + " every cell DOF is a " + (sc.element == Element::CR ? "face" : "vertex") + " of its cell", "%s", pointsMsg.c_str());
  ck.Check(dofPointErr <= 1e-14, tag + " dofPoint is the DOF's vertex / face centroid", "max error %.3g", dofPointErr);
  ck.Check(basisErr <= 1e-13, tag + (sc.element == Element::CR ? " phi_i = delta_ij at face centroids" : " phi_i = delta_ij at vertices"), "max error %.3g", basisErr);
  ck.Check(symErr == 0, tag + " element stiffness symmetric", "max relative asymmetry %.3g", symErr);
  ck.Check(rowErr <= 1e-14, tag + " element stiffness rows sum to 0", "max relative row sum %.3g", rowErr);
  ck.Check(formulaErr <= 1e-13, tag + " element stiffness = kappa |F_i||F_j| n_i.n_j / " + (sc.element == Element::CR ? "|T|" : "(d^2 |T|)"), "max relative error %.3g", formulaErr);

  // DOF counts and classification.
  ck.Check(space.numGlobal == sc.numGlobal && space.numOwned == sc.numGlobal && space.numLocal == sc.numGlobal, tag + " DOF count", "numGlobal %d numOwned %d numLocal %d, expected %d", (int)space.numGlobal, (int)space.numOwned, (int)space.numLocal, (int)sc.numGlobal);
  ck.Check(space.numContactGlobal == sc.numContact && (PetscInt)space.contactOwned.size() == sc.numContact, tag + " contact DOF count", "numContactGlobal %d, contactOwned %zu, expected %d", (int)space.numContactGlobal, space.contactOwned.size(), (int)sc.numContact);
  ck.Check(space.numDirichletGlobal == sc.numDirichlet && (PetscInt)space.dirichletOwned.size() == sc.numDirichlet, tag + " Dirichlet DOF count", "numDirichletGlobal %d, dirichletOwned %zu, expected %d", (int)space.numDirichletGlobal, space.dirichletOwned.size(), (int)sc.numDirichlet);
  // Every contact DOF lies on the bottom (the last coordinate at its lower bound) and off the Dirichlet
  // side; every Dirichlet DOF on the Dirichlet side; every DOF on neither is classified free.
  bool        kindsOk = true;
  std::string kindsMsg;
  PetscInt    nContact = 0, nDirichlet = 0;
  for (PetscInt i = 0; i < space.numLocal; ++i) {
    std::vector<std::array<double, 3>> pv;
    PetscCall(unit::PointVertices(space.mesh, pointOf[i], pv));
    bool onBottom = true, onDir = true;
    for (const auto &v : pv) {
      onBottom = onBottom && v[dim - 1] == sc.mesh.lower[dim - 1];
      onDir    = onDir && v[sc.dirichletAxis] == sc.dirichletValue;
    }
    if (sc.element == Element::P1) onBottom = onBottom && !onDir; // shared vertices are Dirichlet
    const char expected = onDir ? kDirichlet : (onBottom ? kContact : kFree);
    nContact += expected == kContact;
    nDirichlet += expected == kDirichlet;
    if (space.kindLocal[i] != expected && kindsOk) {
      kindsOk  = false;
      kindsMsg = Format("DOF %d at (%g, %g, %g): kind %d, expected %d", (int)i, dofPoint[i * dim], dofPoint[i * dim + 1], dim == 3 ? dofPoint[i * dim + 2] : 0.0, (int)space.kindLocal[i], (int)expected);
    }
  }
  ck.Check(kindsOk, tag + " DOF kinds match the geometry", "%s", kindsMsg.c_str());
  ck.Check(nContact == sc.numContact && nDirichlet == sc.numDirichlet, tag + " geometric counts agree with the formulas", "contact %d dirichlet %d", (int)nContact, (int)nDirichlet);

  PetscCall(SpaceDestroy(space));
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

static std::vector<SpaceCase> Cases()
{
  std::vector<SpaceCase> out;
  const Diagonal diags[] = {Diagonal::Slash, Diagonal::Backslash, Diagonal::Crossed};
  const char    *dnames[] = {"slash", "backslash", "crossed"};
  // 2D N x M boxes (N != M so that the axes cannot be confused).
  for (int dg = 0; dg < 3; ++dg)
    for (int dirLeft = 0; dirLeft < 2; ++dirLeft)
      for (Element e : {Element::P1, Element::CR}) {
        const PetscInt N = 2, M = dirLeft ? 3 : 2;
        SpaceCase      sc;
        sc.mesh.dim      = 2;
        sc.mesh.faces[0] = N, sc.mesh.faces[1] = M;
        sc.mesh.diagonal = diags[dg];
        sc.element       = e;
        sc.contact       = {1};
        sc.dirichlet     = {dirLeft ? 4 : 3};
        sc.dirichletAxis = dirLeft ? 0 : 1, sc.dirichletValue = dirLeft ? 0.0 : 1.0;
        const PetscInt V = (N + 1) * (M + 1) + (dg == 2 ? N * M : 0);
        const PetscInt E = N * (M + 1) + M * (N + 1) + (dg == 2 ? 4 : 1) * N * M;
        if (e == Element::CR) sc.numGlobal = E, sc.numContact = N, sc.numDirichlet = dirLeft ? M : N;
        else sc.numGlobal = V, sc.numContact = dirLeft ? N : N + 1, sc.numDirichlet = dirLeft ? M + 1 : N + 1;
        sc.name = Format("2D %dx%d %s %s D=%s", (int)N, (int)M, dnames[dg], ElementName(e), dirLeft ? "left" : "top");
        out.push_back(sc);
      }
  // 3D N x M x L boxes, Kuhn split: 6 tets per cube.
  for (int big = 0; big < 2; ++big)
    for (int dirLeft = 0; dirLeft < 2; ++dirLeft)
      for (Element e : {Element::P1, Element::CR}) {
        const PetscInt N = big ? 2 : 1, M = 1, L = 1;
        SpaceCase      sc;
        sc.mesh.dim      = 3;
        sc.mesh.faces[0] = N, sc.mesh.faces[1] = M, sc.mesh.faces[2] = L;
        sc.element       = e;
        sc.contact       = {1};
        sc.dirichlet     = {dirLeft ? 6 : 2};
        sc.dirichletAxis = dirLeft ? 0 : 2, sc.dirichletValue = dirLeft ? 0.0 : 1.0;
        const PetscInt V = (N + 1) * (M + 1) * (L + 1);
        const PetscInt squares = N * M * (L + 1) + N * L * (M + 1) + M * L * (N + 1);
        const PetscInt F       = 2 * squares + 6 * N * M * L; // 2 triangles per grid square + 6 inside each cube
        if (e == Element::CR) sc.numGlobal = F, sc.numContact = 2 * N * M, sc.numDirichlet = dirLeft ? 2 * M * L : 2 * N * M;
        else sc.numGlobal = V, sc.numContact = dirLeft ? N * (M + 1) : (N + 1) * (M + 1), sc.numDirichlet = dirLeft ? (M + 1) * (L + 1) : (N + 1) * (M + 1);
        sc.name = Format("3D %dx%dx%d %s D=%s", (int)N, (int)M, (int)L, ElementName(e), dirLeft ? "left" : "top");
        out.push_back(sc);
      }
  return out;
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  TestHandCells(ck);
  for (const SpaceCase &sc : Cases()) {
    ierr = TestSpace(ck, sc);
    if (ierr) ck.PetscFailure(ierr, sc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

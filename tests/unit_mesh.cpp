// Unit tests of the built-in box meshes of MeshCreate: cell and vertex counts with and without uniform
// refinement, the "Face Sets" side numbering, the diagonal pattern in 2D, and DMPlexCheck.
#include "signorini/mesh.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

struct MeshCase {
  std::string name;
  MeshOptions opts;
};

static PetscErrorCode TestMesh(unit::Checker &ck, const MeshCase &mc)
{
  const MeshOptions &o   = mc.opts;
  const PetscInt     dim = o.dim, N = o.faces[0], M = o.faces[1], L = dim == 3 ? o.faces[2] : 1, k = o.refine;
  const std::string &tag = mc.name;
  DM                 dm  = nullptr;
  MeshInfo           info;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(PETSC_COMM_WORLD, o, &dm, info));

  // Cell counts: 2D 2NM (slash, backslash) or 4NM (crossed) triangles, 3D 6NML tetrahedra; each
  // refinement multiplies by 4 (2D) or 8 (3D).
  PetscInt coarse = dim == 2 ? (o.diagonal == Diagonal::Crossed ? 4 : 2) * N * M : 6 * N * M * L, factor = 1;
  for (PetscInt r = 0; r < k; ++r) factor *= dim == 2 ? 4 : 8;
  PetscInt cStart, cEnd, vStart, vEnd, fStart, fEnd, d;
  PetscCall(DMGetDimension(dm, &d));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vStart, &vEnd));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));
  ck.Check(d == dim, tag + " dimension", "got %d", (int)d);
  ck.Check(info.coarseCells == coarse, tag + " coarse cells", "got %d, expected %d", (int)info.coarseCells, (int)coarse);
  ck.Check(info.cells == coarse * factor && cEnd - cStart == coarse * factor, tag + " cells", "info %d, DM %d, expected %d", (int)info.cells, (int)(cEnd - cStart), (int)(coarse * factor));
  ck.Check(info.cellsPerRank.size() == 1 && info.cellsPerRank[0] == coarse * factor, tag + " cellsPerRank");
  // Vertices: the refined grid points, plus one centre per square for crossed.
  const PetscInt s = 1 << k; // refined grid spacing factor
  PetscInt nV = dim == 2 ? (N * s + 1) * (M * s + 1) : (N * s + 1) * (M * s + 1) * (L * s + 1);
  if (dim == 2 && o.diagonal == Diagonal::Crossed) {
    // A crossed square is refined into 4^k copies of the crossed pattern's triangles: count the vertices
    // with Euler's formula V = 1 + E - C; edges E = (3 C + boundary edges) / 2.
    const PetscInt C = coarse * factor, Eb = 2 * (N + M) * s;
    nV = 1 + (3 * C + Eb) / 2 - C;
  }
  ck.Check(vEnd - vStart == nV, tag + " vertices", "got %d, expected %d", (int)(vEnd - vStart), (int)nV);

  // Cell types and total volume.
  bool   typesOk = true;
  double volume  = 0, boxVolume = 1;
  for (PetscInt j = 0; j < dim; ++j) boxVolume *= o.upper[j] - o.lower[j];
  std::vector<std::array<double, 3>> X;
  for (PetscInt c = cStart; c < cEnd; ++c) {
    DMPolytopeType ct;
    PetscCall(DMPlexGetCellType(dm, c, &ct));
    typesOk = typesOk && ct == (dim == 2 ? DM_POLYTOPE_TRIANGLE : DM_POLYTOPE_TETRAHEDRON);
    PetscCall(unit::PointVertices(dm, c, X));
    double e[3][3] = {{0}};
    for (PetscInt a = 0; a < dim; ++a)
      for (PetscInt b = 0; b < dim; ++b) e[a][b] = X[a + 1][b] - X[0][b];
    const double det = dim == 2 ? e[0][0] * e[1][1] - e[0][1] * e[1][0]
                                : e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    volume += std::fabs(det) / (dim == 2 ? 2 : 6);
  }
  ck.Check(typesOk, tag + (dim == 2 ? " all cells are triangles" : " all cells are tetrahedra"));
  ck.Close(volume, boxVolume, 1e-13, tag + " cell volumes sum to the box volume");

  // Face Sets: side v holds exactly the expected number of height-1 faces, each lying on its side.
  // 2D sides 1 bottom (y lo), 2 right (x hi), 3 top (y hi), 4 left (x lo); 3D 1 bottom (z lo), 2 top,
  // 3 front (y lo), 4 back (y hi), 5 right (x hi), 6 left (x lo).
  static const PetscInt axis2[4] = {1, 0, 1, 0}, upper2[4] = {0, 1, 1, 0};
  static const PetscInt axis3[6] = {2, 2, 1, 1, 0, 0}, upper3[6] = {0, 1, 0, 1, 1, 0};
  DMLabel               faceSets;
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  if (!ck.Check(faceSets != nullptr, tag + " has a Face Sets label")) {
    PetscCall(DMDestroy(&dm));
    PetscFunctionReturn(0);
  }
  PetscInt labelled = 0;
  for (PetscInt v = 1; v <= 2 * dim; ++v) {
    const PetscInt ax = dim == 2 ? axis2[v - 1] : axis3[v - 1], up = dim == 2 ? upper2[v - 1] : upper3[v - 1];
    // Number of faces on side v: 2D the cells along the side; 3D two triangles per square of the side.
    PetscInt expected;
    if (dim == 2) expected = (ax == 1 ? N : M) * s;
    else {
      const PetscInt a = ax == 0 ? M : N, b = ax == 2 ? M : L; // the two other directions
      expected         = 2 * a * b * s * s;
    }
    const double plane = up ? o.upper[ax] : o.lower[ax], tol = 1e-12 * (o.upper[ax] - o.lower[ax]);
    IS           is;
    PetscInt     count = 0;
    bool         onSide = true;
    std::string  msg;
    PetscCall(DMLabelGetStratumIS(faceSets, v, &is));
    if (is) {
      PetscInt        n;
      const PetscInt *pts;
      PetscCall(ISGetLocalSize(is, &n));
      PetscCall(ISGetIndices(is, &pts));
      for (PetscInt j = 0; j < n; ++j) {
        if (pts[j] < fStart || pts[j] >= fEnd) continue;
        ++count;
        PetscCall(unit::PointVertices(dm, pts[j], X));
        double centroid[3] = {0, 0, 0};
        for (const auto &x : X)
          for (PetscInt q = 0; q < dim; ++q) centroid[q] += x[q] / X.size();
        bool ok = (PetscInt)X.size() == dim && std::fabs(centroid[ax] - plane) <= tol;
        for (const auto &x : X) ok = ok && std::fabs(x[ax] - plane) <= tol;
        if (!ok && onSide) msg = Format("face %d centroid (%g, %g, %g) is not on coordinate %d = %g", (int)pts[j], centroid[0], centroid[1], centroid[2], (int)ax, plane);
        onSide = onSide && ok;
      }
      PetscCall(ISRestoreIndices(is, &pts));
      PetscCall(ISDestroy(&is));
    }
    labelled += count;
    ck.Check(count == expected, tag + " Face Sets " + std::to_string(v) + " face count", "got %d, expected %d", (int)count, (int)expected);
    ck.Check(onSide, tag + " Face Sets " + std::to_string(v) + " faces lie on their side", "%s", msg.c_str());
  }
  // Every boundary face has a side value, no interior face has one.
  PetscInt boundary = 0, unlabelledBoundary = 0, labelledInterior = 0;
  for (PetscInt f = fStart; f < fEnd; ++f) {
    PetscInt nsupp, v;
    PetscCall(DMPlexGetSupportSize(dm, f, &nsupp));
    PetscCall(DMLabelGetValue(faceSets, f, &v));
    boundary += nsupp == 1;
    unlabelledBoundary += nsupp == 1 && !(v >= 1 && v <= 2 * dim);
    labelledInterior += nsupp != 1 && v != -1;
  }
  const PetscInt expectedBoundary = dim == 2 ? 2 * (N + M) * s : 4 * (N * M + N * L + M * L) * s * s;
  ck.Check(boundary == expectedBoundary && labelled == expectedBoundary, tag + " boundary face count", "support-1 faces %d, labelled %d, expected %d", (int)boundary, (int)labelled, (int)expectedBoundary);
  ck.Check(unlabelledBoundary == 0 && labelledInterior == 0, tag + " Face Sets exactly on the boundary", "%d unlabelled boundary faces, %d labelled interior faces", (int)unlabelledBoundary, (int)labelledInterior);

  // DMPlexCheck: orientation, skeleton, faces, geometry, point SF, interface cones.
  PetscCall(PetscPushErrorHandler(PetscReturnErrorHandler, NULL));
  PetscErrorCode ierr = DMPlexCheck(dm);
  PetscCall(PetscPopErrorHandler());
  ck.Check(ierr == 0, tag + " DMPlexCheck", "returned %d", (int)ierr);

  // CellVertexReader (and CellVertices, which uses it) against the definition, from transitive closures:
  // the cell's vertices, vertex k the one not on face k of the cone. Through the cones' strides and
  // through the cone section's offsets alike.
  {
    CellVertexReader strided, offsets;
    PetscCall(strided.Init(dm));
    PetscCall(offsets.Init(dm, false));
    std::string msg;
    for (PetscInt c = cStart; c < cEnd && msg.empty(); ++c) {
      PetscInt        vs[4], vo[4], n, *closure = NULL;
      const PetscInt *cone;
      strided.Vertices(c, vs);
      offsets.Vertices(c, vo);
      std::vector<PetscInt> cellVerts;
      PetscCall(DMPlexGetTransitiveClosure(dm, c, PETSC_TRUE, &n, &closure));
      for (PetscInt i = 0; i < n; ++i)
        if (closure[2 * i] >= vStart && closure[2 * i] < vEnd) cellVerts.push_back(closure[2 * i]);
      PetscCall(DMPlexRestoreTransitiveClosure(dm, c, PETSC_TRUE, &n, &closure));
      PetscCall(DMPlexGetCone(dm, c, &cone));
      for (PetscInt k = 0; k <= dim && msg.empty(); ++k) {
        bool onFace = false;
        PetscCall(DMPlexGetTransitiveClosure(dm, cone[k], PETSC_TRUE, &n, &closure));
        for (PetscInt i = 0; i < n; ++i) onFace = onFace || closure[2 * i] == vs[k];
        PetscCall(DMPlexRestoreTransitiveClosure(dm, cone[k], PETSC_TRUE, &n, &closure));
        const bool inCell = std::count(cellVerts.begin(), cellVerts.end(), vs[k]) == 1 && std::count(vs, vs + dim + 1, vs[k]) == 1;
        if (onFace || !inCell || vs[k] != vo[k]) msg = "cell " + std::to_string(c) + " vertex " + std::to_string(k);
      }
    }
    ck.Check(msg.empty(), tag + " CellVertexReader: vertex k of each cell is the one not on face k", "%s", msg.c_str());
  }

  // 2D diagonal pattern: interior edges that are neither horizontal nor vertical.
  if (dim == 2) {
    const double hx = (o.upper[0] - o.lower[0]) / (N * s), hy = (o.upper[1] - o.lower[1]) / (M * s);
    PetscInt     diagonals = 0;
    bool         ok        = true;
    std::string  msg;
    for (PetscInt e = fStart; e < fEnd; ++e) {
      PetscCall(unit::PointVertices(dm, e, X));
      const double dx = X[1][0] - X[0][0], dy = X[1][1] - X[0][1];
      if (std::fabs(dx) < 1e-12 * hx || std::fabs(dy) < 1e-12 * hy) continue;
      PetscInt nsupp;
      PetscCall(DMPlexGetSupportSize(dm, e, &nsupp));
      ++diagonals;
      bool good = nsupp == 2;
      if (o.diagonal == Diagonal::Crossed) good = good && std::fabs(std::fabs(dx) - hx / 2) < 1e-12 * hx && std::fabs(std::fabs(dy) - hy / 2) < 1e-12 * hy;
      else {
        // same length as a grid diagonal; slash along (1,1), backslash along (-1,1) (either orientation)
        good = good && std::fabs(std::fabs(dx) - hx) < 1e-12 * hx && std::fabs(std::fabs(dy) - hy) < 1e-12 * hy;
        good = good && (o.diagonal == Diagonal::Slash ? dx * dy > 0 : dx * dy < 0);
      }
      if (!good && ok) msg = Format("edge %d from (%g, %g) to (%g, %g)", (int)e, X[0][0], X[0][1], X[1][0], X[1][1]);
      ok = ok && good;
    }
    const char    *dir      = o.diagonal == Diagonal::Slash ? "(1,1)" : (o.diagonal == Diagonal::Backslash ? "(-1,1)" : "to the square centres");
    // Crossed at k = 0: 4 half diagonals per square; refining splits each in 2 and adds the mid-edges of
    // the triangles, of which those joining two half-diagonal midpoints are diagonal too.
    const PetscInt expected = o.diagonal == Diagonal::Crossed ? (k == 0 ? 4 * N * M : -1) : N * M * s * s;
    if (expected >= 0) ck.Check(diagonals == expected, tag + " number of diagonal edges", "got %d, expected %d", (int)diagonals, (int)expected);
    if (o.diagonal != Diagonal::Crossed || k == 0) ck.Check(ok, tag + " every diagonal edge is interior and runs along " + dir, "%s", msg.c_str());
  }
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

static std::vector<MeshCase> Cases()
{
  std::vector<MeshCase> out;
  const Diagonal diags[]  = {Diagonal::Slash, Diagonal::Backslash, Diagonal::Crossed};
  const char    *dnames[] = {"slash", "backslash", "crossed"};
  for (int dg = 0; dg < 3; ++dg)
    for (PetscInt k = 0; k <= 2; ++k) {
      MeshCase mc;
      mc.opts.dim      = 2;
      mc.opts.faces[0] = 3, mc.opts.faces[1] = 2;
      mc.opts.lower[0] = -1, mc.opts.lower[1] = 0.5;
      mc.opts.upper[0] = 2, mc.opts.upper[1] = 1.5;
      mc.opts.diagonal = diags[dg];
      mc.opts.refine   = k;
      mc.name          = Format("2D 3x2 %s refine %d", dnames[dg], (int)k);
      out.push_back(mc);
    }
  for (PetscInt k = 0; k <= 1; ++k) {
    MeshCase mc;
    mc.opts.dim      = 3;
    mc.opts.faces[0] = 2, mc.opts.faces[1] = 1, mc.opts.faces[2] = 3;
    mc.opts.lower[0] = -1, mc.opts.lower[1] = 0, mc.opts.lower[2] = 0.25;
    mc.opts.upper[0] = 1, mc.opts.upper[1] = 0.5, mc.opts.upper[2] = 1;
    mc.opts.refine   = k;
    mc.name          = Format("3D 2x1x3 refine %d", (int)k);
    out.push_back(mc);
  }
  {
    MeshCase mc;
    mc.opts.dim = 3;
    mc.opts.faces[0] = mc.opts.faces[1] = mc.opts.faces[2] = 1;
    mc.name = "3D 1x1x1 refine 0";
    out.push_back(mc);
  }
  return out;
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  for (const MeshCase &mc : Cases()) {
    ierr = TestMesh(ck, mc);
    if (ierr) ck.PetscFailure(ierr, mc.name + " (PETSc error)");
  }
  // The description names the box and the diagonal.
  {
    MeshOptions o;
    o.dim = 2, o.faces[0] = 3, o.faces[1] = 2, o.diagonal = Diagonal::Backslash;
    DM       dm = nullptr;
    MeshInfo info;
    ierr = MeshCreate(PETSC_COMM_WORLD, o, &dm, info);
    if (ierr) ck.PetscFailure(ierr, "description (PETSc error)");
    else ck.Check(info.description == "box 3x2 backslash", "description", "got '%s'", info.description.c_str());
    DMDestroy(&dm);
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

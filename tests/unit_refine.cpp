// Unit tests of the direct refinement of triangle meshes (RefineTriangles), against PETSc's own regular
// refinement (DMPlexTransform) of the same distributed coarse mesh as the independent computation: two
// levels of each, on box meshes of every diagonal pattern and on a Gmsh mesh with "Cell Sets".
// At every level the direct mesh must
//   - pass PETSc's consistency checks (symmetry, skeleton, faces, geometry with positive Jacobians, point
//     star forest, interface cones);
//   - have the same number of points of each depth, on this rank and shared with others;
//   - be the same geometric mesh: the same cell centroids and cell areas, the same vertices;
//   - carry the same labels: per value, the same face midpoints, vertices and cells;
//   - give a parent map under which every fine cell lies inside its parent;
//   - share points consistently: a shared vertex has the same coordinates on every rank.
// Runs on 1 and 2 ranks (ctest); 3 by hand.
#include "signorini/mesh.h"
#include "signorini/refine.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

using namespace signorini;

using Point3 = std::array<double, 3>;

// Sorted centroids (and measures as 4th entry), rounded to 1e-12, of the local points of height h carrying label value
// `value` (every point of that height when label is null).
static PetscErrorCode Centroids(DM dm, PetscInt height, DMLabel label, PetscInt value, std::vector<std::array<double, 4>> &out)
{
  PetscInt start, end;
  PetscFunctionBeginUser;
  out.clear();
  PetscCall(DMPlexGetHeightStratum(dm, height, &start, &end));
  for (PetscInt p = start; p < end; ++p) {
    if (label) {
      PetscInt v;
      PetscCall(DMLabelGetValue(label, p, &v));
      if (v != value) continue;
    }
    PetscReal vol, x[3] = {0, 0, 0};
    PetscCall(DMPlexComputeCellGeometryFVM(dm, p, &vol, x, NULL));
    // Rounded to 1e-12 before sorting, so that the last bits (the two meshes compute a midpoint's midpoint
    // in another order) cannot reorder the lists.
    const auto r = [](PetscReal v) { return std::round(v * 1e12) / 1e12; };
    out.push_back({r(x[0]), r(x[1]), r(x[2]), r(vol)});
  }
  std::sort(out.begin(), out.end());
  PetscFunctionReturn(0);
}

static double MaxDifference(const std::vector<std::array<double, 4>> &a, const std::vector<std::array<double, 4>> &b)
{
  if (a.size() != b.size()) return 1e300;
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i)
    for (int d = 0; d < 4; ++d) m = std::max(m, std::fabs(a[i][d] - b[i][d]));
  return m;
}

// Points of each depth: local, and leaves of the point star forest (shared, owned elsewhere).
static PetscErrorCode StratumCounts(DM dm, std::vector<PetscInt> &counts)
{
  PetscSF         sf;
  PetscInt        nroots, nleaves;
  const PetscInt *ilocal;
  PetscFunctionBeginUser;
  counts.assign(8, 0);
  for (PetscInt d = 0; d < 4; ++d) {
    PetscInt s, e;
    PetscCall(DMPlexGetDepthStratum(dm, d, &s, &e));
    counts[d] = e - s;
  }
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL));
  for (PetscInt l = 0; nroots >= 0 && l < nleaves; ++l) {
    PetscInt d;
    PetscCall(DMPlexGetPointDepth(dm, ilocal ? ilocal[l] : l, &d));
    ++counts[4 + d];
  }
  PetscFunctionReturn(0);
}

// Largest difference between a shared vertex's coordinates and those of its owner's copy.
static PetscErrorCode SharedVertexMismatch(DM dm, double *mismatch)
{
  PetscSF            sf;
  PetscInt           nroots, nleaves, vS, vE, cdim;
  const PetscInt    *ilocal;
  PetscSection       cs;
  Vec                coords;
  const PetscScalar *x;
  PetscFunctionBeginUser;
  *mismatch = 0;
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL));
  if (nroots < 0) PetscFunctionReturn(0);
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vS, &vE));
  PetscCall(DMGetCoordinateDim(dm, &cdim));
  PetscCall(DMGetCoordinateSection(dm, &cs));
  PetscCall(DMGetCoordinatesLocal(dm, &coords));
  PetscCall(VecGetArrayRead(coords, &x));
  // Root values: each point's coordinates (vertices) or zeros; broadcast to the leaves.
  std::vector<double> root(nroots * 3, 0.0), leaf(nroots * 3, 0.0);
  for (PetscInt v = vS; v < vE; ++v) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(cs, v, &off));
    for (PetscInt d = 0; d < cdim; ++d) root[v * 3 + d] = PetscRealPart(x[off + d]);
  }
  leaf = root;
  MPI_Datatype three;
  PetscCallMPI(MPI_Type_contiguous(3, MPI_DOUBLE, &three));
  PetscCallMPI(MPI_Type_commit(&three));
  PetscCall(PetscSFBcastBegin(sf, three, root.data(), leaf.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, three, root.data(), leaf.data(), MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&three));
  for (PetscInt l = 0; l < nleaves; ++l) {
    const PetscInt p = ilocal ? ilocal[l] : l;
    if (p < vS || p >= vE) continue;
    for (PetscInt d = 0; d < 3; ++d) *mismatch = std::max(*mismatch, std::fabs(leaf[p * 3 + d] - root[p * 3 + d]));
  }
  PetscCall(VecRestoreArrayRead(coords, &x));
  PetscFunctionReturn(0);
}

static PetscErrorCode CompareLevels(unit::Checker &ck, const std::string &tag, DM coarse, DM direct, DM transform, const std::vector<PetscInt> &parent)
{
  std::vector<std::array<double, 4>> a, b;
  PetscFunctionBeginUser;
  PetscCall(unit::CheckPlex(direct));
  ck.Check(true, tag + " passes DMPlexCheckSymmetry/Skeleton/Faces/Geometry/PointSF/InterfaceCones");

  std::vector<PetscInt> ca, cb;
  PetscCall(StratumCounts(transform, ca));
  PetscCall(StratumCounts(direct, cb));
  ck.Check(ca == cb, tag + " points of each depth, local and shared", "depth 0..3 %d %d %d %d (PETSc %d %d %d %d), shared %d %d %d %d (PETSc %d %d %d %d)", (int)cb[0], (int)cb[1], (int)cb[2], (int)cb[3], (int)ca[0], (int)ca[1], (int)ca[2], (int)ca[3], (int)cb[4], (int)cb[5], (int)cb[6], (int)cb[7], (int)ca[4], (int)ca[5], (int)ca[6], (int)ca[7]);

  PetscInt dim;
  PetscCall(DMGetDimension(direct, &dim));
  for (PetscInt h = 0; h <= dim; ++h) {
    PetscCall(Centroids(transform, h, NULL, 0, a));
    PetscCall(Centroids(direct, h, NULL, 0, b));
    const double      diff = MaxDifference(a, b);
    const std::string what = h == 0 ? "cells (centroids, measures)" : h == dim ? "vertices" : h == dim - 1 ? "edges (midpoints, lengths)" : "faces (centroids, areas)";
    ck.Check(diff < 1e-12, tag + " same " + what, "max difference %g", diff);
  }

  PetscInt numLabels;
  PetscCall(DMGetNumLabels(transform, &numLabels));
  for (PetscInt l = 0; l < numLabels; ++l) {
    const char *name;
    DMLabel     la, lb;
    PetscBool   skip1, skip2;
    PetscCall(DMGetLabelName(transform, l, &name));
    PetscCall(PetscStrcmp(name, "depth", &skip1));
    PetscCall(PetscStrcmp(name, "celltype", &skip2));
    if (skip1 || skip2) continue;
    PetscCall(DMGetLabel(transform, name, &la));
    PetscCall(DMGetLabel(direct, name, &lb));
    if (!ck.Check(lb != nullptr, tag + " has label " + name)) continue;
    IS              values;
    PetscInt        nv;
    const PetscInt *v;
    PetscCall(DMLabelGetValueIS(la, &values));
    PetscCall(ISGetLocalSize(values, &nv));
    PetscCall(ISGetIndices(values, &v));
    double worst = 0;
    for (PetscInt i = 0; i < nv; ++i)
      for (PetscInt h = 0; h <= dim; ++h) {
        PetscCall(Centroids(transform, h, la, v[i], a));
        PetscCall(Centroids(direct, h, lb, v[i], b));
        worst = std::max(worst, MaxDifference(a, b));
      }
    PetscCall(ISRestoreIndices(values, &v));
    PetscCall(ISDestroy(&values));
    ck.Check(worst < 1e-12, tag + " label " + name + ": same cells, faces and vertices per value", "max difference %g", worst);
  }

  // The global coordinate vector (made through the coordinate DM's star forest; -output writes it).
  Vec      ga, gb;
  PetscInt na, nb;
  PetscCall(DMGetCoordinates(transform, &ga));
  PetscCall(DMGetCoordinates(direct, &gb));
  PetscCall(VecGetSize(ga, &na));
  PetscCall(VecGetSize(gb, &nb));
  PetscScalar sa, sb;
  PetscReal   norma, normb;
  PetscCall(VecSum(ga, &sa));
  PetscCall(VecSum(gb, &sb));
  PetscCall(VecNorm(ga, NORM_2, &norma));
  PetscCall(VecNorm(gb, NORM_2, &normb));
  ck.Check(na == nb && std::fabs(sa - sb) <= 1e-12 * std::fabs(sa) && std::fabs(norma - normb) <= 1e-12 * norma, tag + " global coordinate vector (size, sum, norm)", "size %d, PETSc's %d; sum %g vs %g; norm %g vs %g", (int)nb, (int)na, (double)sb, (double)sa, (double)normb, (double)norma);
  double outside, mismatch;
  PetscCall(unit::ParentOutside(coarse, direct, parent, &outside));
  ck.Check(outside < 1e-12, tag + " every fine cell lies in its parent", "barycentric coordinate %g", -outside);
  PetscCall(SharedVertexMismatch(direct, &mismatch));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &mismatch, 1, MPI_DOUBLE, MPI_MAX, PetscObjectComm((PetscObject)direct)));
  ck.Check(mismatch == 0, tag + " shared vertices have the owner's coordinates", "max difference %g", mismatch);
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const std::string &name, const MeshOptions &o)
{
  DM       coarse;
  MeshInfo info;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(PETSC_COMM_WORLD, o, &coarse, info));
  DM a = coarse, b = coarse;
  PetscCall(PetscObjectReference((PetscObject)coarse));
  for (PetscInt level = 1; level <= 2; ++level) {
    DM                    fa, fb;
    std::vector<PetscInt> pa, pb;
    PetscCall(MeshRefine(a, &fa, &pa, Refinement::Transform));
    PetscCall(MeshRefine(b, &fb, &pb, Refinement::Direct));
    PetscCall(CompareLevels(ck, name + " level " + std::to_string(level), b, fb, fa, pb));
    PetscCall(DMDestroy(&a));
    PetscCall(DMDestroy(&b));
    a = fa, b = fb;
  }
  PetscCall(DMDestroy(&a));
  PetscCall(DMDestroy(&b));
  PetscFunctionReturn(0);
}

// SortDistinctPoints against std::sort (the independent computation), on sets dense enough for its bit per
// point and sparse enough for the comparison sort, with points at both ends of the chart and past a word.
static void TestSortDistinct(unit::Checker &ck)
{
  std::uint64_t state = 12345;
  const auto    next  = [&state]() { return state = state * 6364136223846793005ULL + 1442695040888963407ULL, (PetscInt)(state >> 33); };
  for (PetscInt end : {1, 63, 64, 65, 1000, 100003}) {
    for (PetscInt every : {1, 2, 7, 100, 1000}) {
      std::vector<PetscInt> p;
      for (PetscInt q = 0; q < end; ++q)
        if (q == 0 || q == end - 1 || next() % every == 0) p.push_back(q);
      for (size_t i = p.size(); i > 1; --i) std::swap(p[i - 1], p[next() % i]);
      std::vector<PetscInt> want = p;
      std::sort(want.begin(), want.end());
      SortDistinctPoints(p.data(), (PetscInt)p.size(), end);
      ck.Check(p == want, Format("SortDistinctPoints of %zu points in [0, %d)", want.size(), (int)end), "differs from std::sort");
    }
  }
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  struct Case {
    std::string name;
    MeshOptions o;
  };
  std::vector<Case> cases;
  for (Diagonal d : {Diagonal::Slash, Diagonal::Backslash, Diagonal::Crossed}) {
    Case c;
    c.name       = std::string("box 5x3 ") + (d == Diagonal::Slash ? "slash" : d == Diagonal::Backslash ? "backslash" : "crossed");
    c.o.faces[0] = 5, c.o.faces[1] = 3, c.o.diagonal = d;
    c.o.upper[0] = 2.5;
    cases.push_back(c);
  }
  Case box3;
  box3.name   = "box 3x2x2 tetrahedra";
  box3.o.dim  = 3;
  box3.o.faces[0] = 3, box3.o.faces[1] = 2, box3.o.faces[2] = 2;
  cases.push_back(box3);
  Case cube;
  cube.name   = "gmsh cube";
  cube.o.file = std::string(SIGNORINI_TEST_DATA) + "/cube.msh";
  cases.push_back(cube);
  Case gmsh;
  gmsh.name   = "gmsh square with Cell Sets";
  gmsh.o.file = std::string(SIGNORINI_TEST_DATA) + "/square.msh";
  cases.push_back(gmsh);
  TestSortDistinct(ck);
  for (const Case &c : cases) {
    PetscErrorCode ierr = TestCase(ck, c.name, c.o);
    if (ierr) ck.PetscFailure(ierr, c.name);
  }
  const int status = ck.Finish();
  PetscCall(PetscFinalize());
  return status;
}

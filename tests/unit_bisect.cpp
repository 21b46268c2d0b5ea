// Unit tests of the refinement of marked cells by bisection (RefineMarkedBisection, bisect.cpp), in 2D
// and 3D, on structured boxes (many edges of equal length: the tie-breaks decide) and on Gmsh meshes. The
// checks are invariants and an independent serial computation:
//   - PETSc's consistency checks (symmetry, skeleton, faces, geometry with positive Jacobians, point SF,
//     the same cones of shared points on every rank);
//   - conformity: no face has more than two cells; the cell complex has Euler characteristic 1 (a
//     hanging vertex would add a face or an edge beside the ones it splits); the boundary (faces with one
//     cell, not shared with another rank) has the coarse boundary's area (a hanging vertex would leave
//     faces with one cell inside the domain); the volume is the coarse volume;
//   - labels: the area of each "Face Sets" value is the coarse one; every child has its parent's
//     "Cell Sets" value;
//   - the parent map: the children of a coarse cell fill it (their volumes sum to its volume and their
//     centroids lie inside it);
//   - the marked cells are refined, cells far from them are not;
//   - the mesh is the one the same refinement makes of the whole mesh on one rank with its points numbered
//     backwards (the same cells: sorted centroids and volumes), also after repeated steps;
//   - repeated refinement towards a corner keeps the shape: the worst aspect ratio stops growing;
//   - on boxes of stretched cells (aspect ratio 100, 2D and 3D), no bisection makes an angle near 180
//     degrees: the largest face (and in 3D dihedral) angle stays within the bound at ThinCaseBound.
// With -bisect_time_faces n, it instead times one refinement of 10 % of the cells of a box of n^3 cubes
// cut into 6 n^3 tetrahedra (not a test: a measurement).
#include "signorini/localrefine.h"
#include "signorini/mesh.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <functional>
#include <string>
#include <vector>

using namespace signorini;

using Marker = std::function<bool(const PetscReal *centroid, const std::vector<std::array<double, 3>> &verts)>;

static double Distance(const PetscReal *x, PetscInt dim)
{
  double s = 0;
  for (PetscInt d = 0; d < dim; ++d) s += x[d] * x[d];
  return std::sqrt(s);
}

static PetscErrorCode Mark(DM dm, const Marker &marker, std::vector<char> &marked)
{
  PetscInt cS, cE;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  marked.assign(cE - cS, 0);
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal                          vol, x[3] = {0, 0, 0};
    std::vector<std::array<double, 3>> verts;
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, x, NULL));
    PetscCall(unit::PointVertices(dm, c, verts));
    marked[c - cS] = marker(x, verts);
  }
  PetscFunctionReturn(0);
}

// Points shared with another rank (leaves, and roots with leaves).
static PetscErrorCode SharedPoints(DM dm, std::vector<char> &shared)
{
  PetscSF         sf;
  PetscInt        pS, pE, nroots, nleaves;
  const PetscInt *ilocal, *degree;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(dm, &pS, &pE));
  shared.assign(pE - pS, 0);
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL));
  if (nroots < 0) PetscFunctionReturn(0);
  for (PetscInt l = 0; l < nleaves; ++l) shared[(ilocal ? ilocal[l] : l) - pS] = 1;
  PetscCall(PetscSFComputeDegreeBegin(sf, &degree));
  PetscCall(PetscSFComputeDegreeEnd(sf, &degree));
  for (PetscInt p = 0; p < nroots; ++p)
    if (degree[p]) shared[p] = 1;
  PetscFunctionReturn(0);
}

static bool IsLeaf(DM dm, PetscInt p)
{
  PetscSF         sf;
  PetscInt        nroots, nleaves, idx = -1;
  const PetscInt *ilocal;
  if (DMGetPointSF(dm, &sf) || PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL) || nroots < 0) return false;
  if (!ilocal) return p < nleaves;
  PetscFindInt(p, nleaves, ilocal, &idx); // DMPlex keeps the leaves sorted
  return idx >= 0;
}

// Points of each depth over all ranks, each counted on its owner.
static PetscErrorCode OwnedPoints(DM dm, std::vector<PetscInt> &count)
{
  PetscInt depth;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetDepth(dm, &depth));
  count.assign(depth + 1, 0);
  for (PetscInt d = 0; d <= depth; ++d) {
    PetscInt s, e;
    PetscCall(DMPlexGetDepthStratum(dm, d, &s, &e));
    for (PetscInt p = s; p < e; ++p) count[d] += !IsLeaf(dm, p);
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, count.data(), depth + 1, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)dm)));
  PetscFunctionReturn(0);
}

// Global sums: volume, boundary area, area of the boundary faces of each "Face Sets" value 1..8, and the largest number of cells
// of a face.
struct Measures {
  double   volume = 0, boundary = 0, faceSets[9] = {0};
  int      maxSupport = 0;
  PetscInt euler      = 0; // sum over depths d of (-1)^d (points of depth d, each counted on its owner)
};

static PetscErrorCode Measure(DM dm, Measures &m)
{
  MPI_Comm          comm = PetscObjectComm((PetscObject)dm);
  PetscInt          cS, cE, fS, fE, pS;
  DMLabel           faceSets;
  std::vector<char> shared;
  PetscFunctionBeginUser;
  m = Measures();
  PetscCall(DMPlexGetChart(dm, &pS, NULL));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fS, &fE));
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  PetscCall(SharedPoints(dm, shared));
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal vol;
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, NULL, NULL));
    m.volume += vol;
  }
  std::vector<PetscInt> owned;
  PetscCall(OwnedPoints(dm, owned));
  for (size_t d = 0; d < owned.size(); ++d) m.euler += (d % 2 ? -1 : 1) * owned[d];
  for (PetscInt f = fS; f < fE; ++f) {
    PetscInt  support, value = -1;
    PetscReal area, x[3];
    PetscCall(DMPlexGetSupportSize(dm, f, &support));
    m.maxSupport = std::max(m.maxSupport, (int)support);
    PetscCall(DMPlexComputeCellGeometryFVM(dm, f, &area, x, NULL));
    if (support != 1 || shared[f - pS]) continue; // only boundary faces count, each once
    m.boundary += area;
    if (faceSets) PetscCall(DMLabelGetValue(faceSets, f, &value));
    if (value >= 1 && value <= 8) m.faceSets[value] += area;
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &m.volume, 1, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &m.boundary, 1, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, m.faceSets, 9, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &m.maxSupport, 1, MPI_INT, MPI_MAX, comm));
  PetscFunctionReturn(0);
}

// All cells of the mesh on every rank: centroid and volume rounded to 1e-12, sorted.
static PetscErrorCode AllCells(DM dm, std::vector<std::array<double, 4>> &cells)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)dm);
  PetscInt    cS, cE;
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  std::vector<double> mine;
  const auto          r = [](double v) { return std::round(v * 1e12) / 1e12; };
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal vol, x[3] = {0, 0, 0};
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, x, NULL));
    for (double v : {x[0], x[1], x[2], vol}) mine.push_back(r(v));
  }
  int              n = (int)mine.size();
  std::vector<int> counts(size), displs(size + 1, 0);
  PetscCallMPI(MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (int p = 0; p < size; ++p) displs[p + 1] = displs[p] + counts[p];
  std::vector<double> all(displs[size]);
  PetscCallMPI(MPI_Allgatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm));
  cells.resize(all.size() / 4);
  for (size_t i = 0; i < cells.size(); ++i) cells[i] = {all[4 * i], all[4 * i + 1], all[4 * i + 2], all[4 * i + 3]};
  std::sort(cells.begin(), cells.end());
  PetscFunctionReturn(0);
}

// Worst aspect ratio over the cells (global): longest edge over the inradius, scaled to 1 for the regular
// simplex. The inradius is d |T| / (sum of the face measures).
static PetscErrorCode WorstAspect(DM dm, double *worst)
{
  PetscInt dim, cS, cE;
  PetscFunctionBeginUser;
  *worst = 0;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  for (PetscInt c = cS; c < cE; ++c) {
    const PetscInt *cone;
    PetscReal       vol, faces = 0, hmax = 0;
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, NULL, NULL));
    PetscCall(DMPlexGetCone(dm, c, &cone));
    for (PetscInt f = 0; f <= dim; ++f) {
      PetscReal area;
      PetscCall(DMPlexComputeCellGeometryFVM(dm, cone[f], &area, NULL, NULL));
      faces += area;
    }
    std::vector<std::array<double, 3>> v;
    PetscCall(unit::PointVertices(dm, c, v));
    for (size_t i = 0; i < v.size(); ++i)
      for (size_t j = i + 1; j < v.size(); ++j) hmax = std::max(hmax, std::hypot(v[i][0] - v[j][0], v[i][1] - v[j][1], v[i][2] - v[j][2]));
    const double inradius = dim * vol / faces, scale = dim == 2 ? 2 * std::sqrt(3.0) : 2 * std::sqrt(6.0);
    *worst = std::max(*worst, hmax / (scale * inradius));
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, worst, 1, MPI_DOUBLE, MPI_MAX, PetscObjectComm((PetscObject)dm)));
  PetscFunctionReturn(0);
}

// Largest angles over the cells (global), in degrees: of their faces' corners (a triangle's own), and in
// 3D between two faces at an edge (the dihedral angles; 0 in 2D).
static PetscErrorCode MaxAngles(DM dm, double *face, double *dihedral)
{
  PetscInt cS, cE;
  PetscFunctionBeginUser;
  double largest[2] = {0, 0};
  using Vec3        = std::array<double, 3>;
  const auto angle  = [](const Vec3 &u, const Vec3 &w) {
    const double dot = u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
    return std::acos(std::clamp(dot / std::sqrt((u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2])), -1.0, 1.0)) * 180 / M_PI;
  };
  const auto minus = [](const Vec3 &a, const Vec3 &b) { return Vec3{a[0] - b[0], a[1] - b[1], a[2] - b[2]}; };
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  for (PetscInt c = cS; c < cE; ++c) {
    std::vector<Vec3> v;
    PetscCall(unit::PointVertices(dm, c, v));
    const int n = (int)v.size();
    // The corner at p between a and b; for each edge (p, a) of a tetrahedron, the angle between the
    // components of the other two edges from p orthogonal to it.
    for (int p = 0; p < n; ++p)
      for (int a = 0; a < n; ++a)
        for (int b = a + 1; b < n; ++b) {
          if (a == p || b == p) continue;
          largest[0] = std::max(largest[0], angle(minus(v[a], v[p]), minus(v[b], v[p])));
          if (n < 4) continue;
          const int q = 6 - p - a - b; // the 4th vertex: the dihedral angle at edge (p, q)
          const Vec3 e = minus(v[q], v[p]), u = minus(v[a], v[p]), w = minus(v[b], v[p]);
          const double ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2], ue = (u[0] * e[0] + u[1] * e[1] + u[2] * e[2]) / ee, we = (w[0] * e[0] + w[1] * e[1] + w[2] * e[2]) / ee;
          largest[1] = std::max(largest[1], angle(Vec3{u[0] - ue * e[0], u[1] - ue * e[1], u[2] - ue * e[2]}, Vec3{w[0] - we * e[0], w[1] - we * e[1], w[2] - we * e[2]}));
        }
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, largest, 2, MPI_DOUBLE, MPI_MAX, PetscObjectComm((PetscObject)dm)));
  *face = largest[0], *dihedral = largest[1];
  PetscFunctionReturn(0);
}

// Every child lies in its parent and the children fill it; returns the worst relative volume defect and
// the largest barycentric coordinate outside [0, 1] of a child's centroid.
static PetscErrorCode ParentFit(DM coarse, DM fine, const std::vector<PetscInt> &parent, double *volumeDefect, double *outside)
{
  PetscInt dim, cS, cE, fcS, fcE;
  PetscFunctionBeginUser;
  *volumeDefect = *outside = 0;
  PetscCall(DMGetDimension(coarse, &dim));
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &cS, &cE));
  PetscCall(DMPlexGetHeightStratum(fine, 0, &fcS, &fcE));
  std::vector<double> sum(cE - cS, 0.0);
  for (PetscInt c = fcS; c < fcE; ++c) {
    PetscReal vol, x[3] = {0, 0, 0}, v0[3], J[9], invJ[9], detJ;
    PetscCall(DMPlexComputeCellGeometryFVM(fine, c, &vol, x, NULL));
    sum[parent[c - fcS]] += vol;
    PetscCall(DMPlexComputeCellGeometryAffineFEM(coarse, cS + parent[c - fcS], v0, J, invJ, &detJ));
    // reference coordinates on PETSc's simplex [-1, 1]^dim, barycentric (xi + 1) / 2 and 1 - their sum
    PetscReal last = 1;
    for (PetscInt i = 0; i < dim; ++i) {
      PetscReal xi = -1;
      for (PetscInt j = 0; j < dim; ++j) xi += invJ[i * dim + j] * (x[j] - v0[j]);
      *outside = std::max(*outside, -(double)(xi + 1) / 2);
      last -= (xi + 1) / 2;
    }
    *outside = std::max(*outside, -(double)last);
  }
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal vol;
    PetscCall(DMPlexComputeCellGeometryFVM(coarse, c, &vol, NULL, NULL));
    *volumeDefect = std::max(*volumeDefect, std::fabs(sum[c - cS] - vol) / vol);
  }
  PetscFunctionReturn(0);
}

// Box meshes carry no "Cell Sets": give them one (1: centroid x < 0.5, 2: beyond), to follow.
static PetscErrorCode EnsureCellSets(DM dm)
{
  PetscBool has;
  DMLabel   label;
  PetscInt  cS, cE;
  PetscFunctionBeginUser;
  PetscCall(DMHasLabel(dm, "Cell Sets", &has));
  if (has) PetscFunctionReturn(0);
  PetscCall(DMCreateLabel(dm, "Cell Sets"));
  PetscCall(DMGetLabel(dm, "Cell Sets", &label));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  for (PetscInt c = cS; c < cE; ++c) {
    PetscReal vol, x[3];
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, x, NULL));
    PetscCall(DMLabelSetValue(label, c, x[0] < 0.5 ? 1 : 2));
  }
  PetscFunctionReturn(0);
}

// The same mesh with the points of each depth numbered backwards: a refinement that depended on the
// numbering would differ from the one of the original.
static PetscErrorCode Renumber(DM *dm)
{
  PetscInt pS, pE, depth;
  IS       perm;
  DM       pdm;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(*dm, &pS, &pE));
  PetscCall(DMPlexGetDepth(*dm, &depth));
  std::vector<PetscInt> to(pE - pS);
  for (PetscInt d = 0; d <= depth; ++d) {
    PetscInt s, e;
    PetscCall(DMPlexGetDepthStratum(*dm, d, &s, &e));
    for (PetscInt p = s; p < e; ++p) to[p - pS] = s + e - 1 - p;
  }
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, pE - pS, to.data(), PETSC_COPY_VALUES, &perm));
  PetscCall(DMPlexPermute(*dm, perm, &pdm));
  PetscCall(ISDestroy(&perm));
  PetscCall(DMDestroy(dm));
  *dm = pdm;
  PetscFunctionReturn(0);
}

static PetscErrorCode CreateMesh(MPI_Comm comm, const MeshOptions &o, DM *dm)
{
  MeshInfo info;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, o, dm, info));
  PetscCall(EnsureCellSets(*dm));
  PetscFunctionReturn(0);
}

// One refinement of `coarse` with every check but the comparison with one rank.
static PetscErrorCode CheckStep(unit::Checker &ck, const std::string &tag, DM coarse, const std::vector<char> &marked, bool allEdges, const Marker &far, DM *fine)
{
  std::vector<PetscInt> parent;
  PetscFunctionBeginUser;
  PetscCall(RefineMarkedBisection(coarse, marked, fine, &parent, allEdges));
  PetscCall(DMPlexCheckSymmetry(*fine));
  PetscCall(DMPlexCheckSkeleton(*fine, 0));
  PetscCall(DMPlexCheckFaces(*fine, 0));
  PetscCall(DMPlexCheckGeometry(*fine));
  PetscCall(DMPlexCheckPointSF(*fine, NULL, PETSC_FALSE));
  PetscCall(DMPlexCheckInterfaceCones(*fine));
  ck.Check(true, tag + " passes DMPlexCheckSymmetry/Skeleton/Faces/Geometry/PointSF/InterfaceCones");

  Measures a, b;
  PetscCall(Measure(coarse, a));
  PetscCall(Measure(*fine, b));
  ck.Check(b.maxSupport <= 2, tag + " no face has more than two cells", "a face has %d", b.maxSupport);
  ck.Check(b.euler == a.euler && a.euler == 1, tag + " conforming: Euler characteristic of the cell complex 1 (as the coarse mesh's)", "fine %d, coarse %d", (int)b.euler, (int)a.euler);
  ck.Close(b.boundary, a.boundary, 1e-12, tag + " conforming: boundary area unchanged (no hanging faces)");
  ck.Close(b.volume, a.volume, 1e-12, tag + " volume unchanged");
  double worst = 0;
  for (int v = 1; v <= 8; ++v) worst = std::max(worst, std::fabs(b.faceSets[v] - a.faceSets[v]));
  ck.Check(worst <= 1e-12 * a.boundary, tag + " Face Sets: the area of every value unchanged", "largest difference %g", worst);

  DMLabel  cl, fl;
  PetscInt cS, fcS, fcE, wrong = 0;
  PetscCall(DMGetLabel(coarse, "Cell Sets", &cl));
  PetscCall(DMGetLabel(*fine, "Cell Sets", &fl));
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &cS, NULL));
  PetscCall(DMPlexGetHeightStratum(*fine, 0, &fcS, &fcE));
  for (PetscInt c = fcS; c < fcE; ++c) {
    PetscInt vc = -1, vf = -2;
    PetscCall(DMLabelGetValue(cl, cS + parent[c - fcS], &vc));
    if (fl) PetscCall(DMLabelGetValue(fl, c, &vf));
    wrong += vc != vf;
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &wrong, 1, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
  ck.Check(wrong == 0, tag + " Cell Sets: every child has its parent's value", "%d children differ", (int)wrong);

  double defect, outside;
  PetscCall(ParentFit(coarse, *fine, parent, &defect, &outside));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &defect, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &outside, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD));
  ck.Check(defect < 1e-12 && outside < 1e-12, tag + " children fill their parent", "volume defect %g, centroid outside by %g", defect, outside);

  std::vector<PetscInt> children(marked.size(), 0);
  for (PetscInt p : parent) ++children[p];
  std::vector<char> isFar;
  PetscCall(Mark(coarse, far, isFar));
  PetscInt badMarked = 0, badFar = 0, numMarked = 0, refined = 0;
  for (size_t c = 0; c < marked.size(); ++c) {
    numMarked += marked[c] != 0;
    refined += children[c] > 1;
    badMarked += marked[c] && children[c] < 2;
    badFar += isFar[c] && children[c] != 1;
  }
  PetscInt counts[4] = {badMarked, badFar, numMarked, refined};
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 4, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
  ck.Check(counts[2] > 0 && counts[0] == 0, tag + " every marked cell is refined", "%d of %d marked cells kept whole", (int)counts[0], (int)counts[2]);
  ck.Check(counts[1] == 0, tag + " cells far from the marked ones are not refined", "%d far cells refined (%d of the coarse cells refined)", (int)counts[1], (int)counts[3]);
  PetscFunctionReturn(0);
}

struct Case {
  std::string name;
  MeshOptions o;
  double      radius; // cells with centroid within radius of the origin are marked
  double      far;    // cells with centroid beyond this distance from the origin must stay whole
  bool        allEdges = false; // marked cells cut all their edges, not only the longest
  bool        thin     = false; // a box of cells much wider than high (2D) or thick (3D): see ThinCaseBound
};

// The largest angle that refinement may make on a 2D box of right triangles of width hx and height
// hy <= hx / 10. Every cell has one vertical (short) edge, of length s at distance d from the opposite
// vertex, and two long edges of slope at most hy / hx, with s / d <= hy / hx: the long edges are unsafe
// (the median to one has a slope within twice that bound, less than 30 degrees off it) and the longest,
// the short one safe. So bisect.cpp cuts each cell by its short edge alone or by all three edges, and the
// children are of the same kind: their edges are halves of the parent's, midlines parallel to them, and
// medians between two of the parent's edges (the one to the short edge between the long ones; the one to
// the longest edge, cut first, between it and the other long one), and s / d only shrinks. Their largest
// angle lies at an end of the vertical edge: 90 degrees plus a long edge's angle with the x-axis, at most
// 90 + atan(hy / hx) degrees. Rivara's closure there bisects the diagonal and makes angles near 180.
// On a 3D box of Kuhn tetrahedra of height hz <= hx / 10 (hx = hy) the coarse face and dihedral angles
// are at most 90 degrees. Cutting all six edges of a flat Kuhn tetrahedron makes eight Kuhn tetrahedra;
// a cone over a steep face makes right angles tilted by at most the slope hz / hx of an edge between
// layers; a single safe cut of a horizontal edge bisects a horizontal right isosceles face on a leg, which
// makes 90 + atan(1 / 2) degrees at the leg's midpoint (as in 2D), tilted likewise. So the bound is
// 90 + atan(1 / 2) + atan(hz / hx): observed (116.566 face, 116.565 dihedral), not derived. Rivara's
// closure makes face and dihedral angles of 179.19 degrees there.
static double ThinCaseBound(const Case &k)
{
  const double hx = (k.o.upper[0] - k.o.lower[0]) / k.o.faces[0], ht = (k.o.upper[k.o.dim - 1] - k.o.lower[k.o.dim - 1]) / k.o.faces[k.o.dim - 1];
  return 90 + (k.o.dim == 3 ? std::atan(0.5) : 0) * 180 / M_PI + std::atan(ht / hx) * 180 / M_PI;
}

// Refines `steps` times (first by the radius, then the cells near the origin), checking each step; each
// step is compared with the same steps on the whole mesh on one rank with its points numbered otherwise.
static PetscErrorCode TestCase(unit::Checker &ck, const Case &k, PetscInt steps)
{
  DM dm, serial = nullptr;
  PetscFunctionBeginUser;
  PetscCall(CreateMesh(PETSC_COMM_WORLD, k.o, &dm));
  // The whole mesh on one rank, numbered otherwise (on 1 rank, the run compares with a renumbered copy).
  PetscCall(CreateMesh(PETSC_COMM_SELF, k.o, &serial));
  PetscCall(Renumber(&serial));
  PetscInt dim;
  PetscCall(DMGetDimension(dm, &dim));
  double aspect0, angle0 = 0, dihedral0 = 0;
  PetscCall(WorstAspect(dm, &aspect0));
  if (k.thin) PetscCall(MaxAngles(dm, &angle0, &dihedral0));
  std::vector<double> aspect;
  for (PetscInt s = 0; s < steps; ++s) {
    const Marker near = [&](const PetscReal *x, const std::vector<std::array<double, 3>> &v) {
      if (s == 0) return Distance(x, dim) < k.radius;
      // then the cells closer to the origin than their diameter: a mesh graded towards the corner
      double closest = 1e300, diameter = 0;
      for (const auto &p : v) {
        closest = std::min(closest, std::hypot(p[0], p[1], p[2]));
        for (const auto &q : v) diameter = std::max(diameter, std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]));
      }
      return closest < diameter;
    };
    const Marker far = [&](const PetscReal *x, const std::vector<std::array<double, 3>> &) { return s == 0 && Distance(x, dim) > k.far; };
    std::vector<char> marked;
    DM                fine;
    PetscCall(Mark(dm, near, marked));
    const std::string tag = k.name + " step " + std::to_string(s + 1);
    PetscCall(CheckStep(ck, tag, dm, marked, k.allEdges, far, &fine));
    PetscCall(DMDestroy(&dm));
    dm = fine;
    {
      DM                                 sfine;
      std::vector<std::array<double, 4>> a, b;
      PetscCall(Mark(serial, near, marked));
      PetscCall(RefineMarkedBisection(serial, marked, &sfine, NULL, k.allEdges));
      PetscCall(DMDestroy(&serial));
      serial = sfine;
      PetscCall(AllCells(dm, a));
      PetscCall(AllCells(serial, b));
      ck.Check(a == b, tag + " the same cells as on one rank, numbered otherwise", "%zu cells, %zu on one rank", a.size(), b.size());
      std::vector<PetscInt> na, nb;
      PetscCall(OwnedPoints(dm, na));
      PetscCall(OwnedPoints(serial, nb));
      ck.Check(na == nb, tag + " the same number of vertices, edges, faces as on one rank (each shared point owned once)", "vertices %d, one rank %d", (int)na[0], (int)nb[0]);
    }
    double worst;
    PetscCall(WorstAspect(dm, &worst));
    aspect.push_back(worst);
    if (k.thin) {
      double angle, dihedral;
      PetscCall(MaxAngles(dm, &angle, &dihedral));
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "  %s: largest face angle %.4f, dihedral angle %.4f degrees\n", tag.c_str(), angle, dihedral));
      ck.Check(angle0 <= 90 + 1e-9 && angle <= ThinCaseBound(k) * (1 + 1e-9), tag + " no angle near 180 degrees: the largest face angle is within ThinCaseBound", "largest angle %.6f degrees (coarse %.6f), bound %.6f", angle, angle0, ThinCaseBound(k));
      ck.Check(dihedral0 <= 90 + 1e-9 && dihedral <= ThinCaseBound(k) * (1 + 1e-9), tag + " no dihedral angle near 180 degrees: within ThinCaseBound (0 in 2D)", "largest dihedral angle %.6f degrees (coarse %.6f), bound %.6f", dihedral, dihedral0, ThinCaseBound(k));
    }
    PetscInt cells, cS, cE;
    PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
    cells = cE - cS;
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &cells, 1, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
    PetscCall(PetscPrintf(PETSC_COMM_WORLD, "  %s: %d cells, worst aspect ratio %.3f (coarse %.3f)\n", tag.c_str(), (int)cells, worst, aspect0));
  }
  // Shape regularity: the worst aspect ratio of the last half of the steps is no worse than the first half's
  // (it saturates instead of growing with every bisection). Not on a flat 3D box: cuts of vertical edges
  // and cones over steep faces halve the cells' height but not their width (116 to 232 in four steps),
  // while the angles, the property that matters there, stay bounded (checked above).
  if (steps >= 4 && !(k.thin && k.o.dim == 3)) {
    const double early = *std::max_element(aspect.begin(), aspect.begin() + steps / 2), late = *std::max_element(aspect.begin() + steps / 2, aspect.end());
    ck.Check(late <= early * (1 + 1e-9), k.name + " repeated refinement keeps the shape: the worst aspect ratio stops growing", "worst aspect ratio %.3f in the first %d steps, %.3f after", early, (int)steps / 2, late);
  }
  PetscCall(DMDestroy(&dm));
  PetscCall(DMDestroy(&serial));
  PetscFunctionReturn(0);
}

// -bisect_time_faces n: one refinement of the cells with centroid x < fraction (-bisect_time_fraction,
// 0.1 by default) of a box of 6 n^3 tetrahedra (-bisect_time_dim 2: 2 n^2 triangles), by their longest
// edges or (-bisect_time_all) all edges.
static PetscErrorCode Time(PetscInt n)
{
  PetscReal fraction = 0.1;
  PetscBool all      = PETSC_FALSE;
  MeshOptions o;
  DM          dm, fine;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetReal(NULL, NULL, "-bisect_time_fraction", &fraction, NULL));
  PetscCall(PetscOptionsGetBool(NULL, NULL, "-bisect_time_all", &all, NULL));
  PetscInt dim = 3;
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-bisect_time_dim", &dim, NULL));
  o.dim = dim, o.faces[0] = o.faces[1] = o.faces[2] = n, o.coarsen = false;
  PetscCall(CreateMesh(PETSC_COMM_WORLD, o, &dm));
  std::vector<char> marked;
  PetscCall(Mark(dm, [&](const PetscReal *x, const std::vector<std::array<double, 3>> &) { return x[0] < fraction; }, marked));
  PetscLogDouble t0;
  double         seconds;
  std::clock_t   cpu0 = std::clock(); // the process's CPU time: wall time is noisy on a shared machine
  PetscCall(PetscTime(&t0));
  PetscCall(RefineMarkedBisection(dm, marked, &fine, NULL, all));
  PetscCall(SecondsSince(PETSC_COMM_WORLD, t0, &seconds));
  const double cpu = (double)(std::clock() - cpu0) / CLOCKS_PER_SEC;
  PetscInt counts[3] = {0, 0, 0}, cS, cE, fS, fE;
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cS, &cE));
  PetscCall(DMPlexGetHeightStratum(fine, 0, &fS, &fE));
  counts[0] = cE - cS, counts[1] = fE - fS;
  for (char m : marked) counts[2] += m;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 3, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
  PetscCall(PetscPrintf(PETSC_COMM_WORLD, "bisection: %d cells, %d marked, %d after: %.3f s (CPU %.3f s on rank 0)\n", (int)counts[0], (int)counts[2], (int)counts[1], seconds, cpu));
  PetscCall(DMDestroy(&fine));
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  PetscInt  timeFaces = 0;
  PetscBool timing;
  PetscCall(PetscOptionsGetInt(NULL, NULL, "-bisect_time_faces", &timeFaces, &timing));
  if (timing) {
    PetscCall(Time(timeFaces));
    PetscCall(PetscFinalize());
    return 0;
  }
  unit::Checker     ck;
  std::vector<Case> cases;
  Case              c;
  c.o.coarsen = false;
  c.name = "box 8x8 slash", c.o.faces[0] = c.o.faces[1] = 8, c.radius = 0.3, c.far = 0.8;
  cases.push_back(c);
  c.name = "box 8x8 crossed", c.o.diagonal = Diagonal::Crossed;
  cases.push_back(c);
  c.name = "box 4x4 backslash refined once", c.o.diagonal = Diagonal::Backslash, c.o.faces[0] = c.o.faces[1] = 4, c.o.refine = 1;
  cases.push_back(c);
  c.name = "box 4x4x4 tetrahedra", c.o.dim = 3, c.o.faces[2] = 4, c.o.faces[0] = c.o.faces[1] = 4, c.o.refine = 0, c.radius = 0.4, c.far = 1.0;
  cases.push_back(c);
  c.name = "box 2x2x2 tetrahedra refined once", c.o.faces[0] = c.o.faces[1] = c.o.faces[2] = 2, c.o.refine = 1;
  cases.push_back(c);
  Case square;
  square.name = "gmsh square with Cell Sets", square.o.file = std::string(SIGNORINI_TEST_DATA) + "/square.msh", square.radius = 0.3, square.far = 0.8;
  cases.push_back(square);
  Case cube;
  cube.name = "gmsh cube", cube.o.file = std::string(SIGNORINI_TEST_DATA) + "/cube.msh", cube.radius = 0.5, cube.far = 1.2;
  cases.push_back(cube);
  // Cells of aspect ratio 100; the closure refines whole columns, so a few steps only.
  Case thin;
  thin.name = "box 8x8 of aspect ratio 100", thin.o.coarsen = false, thin.o.upper[1] = 0.01, thin.radius = 0.3, thin.far = 0.8, thin.thin = true;
  cases.push_back(thin);
  // The same in 3D: flat Kuhn tetrahedra.
  thin.name = "box 4x4x4 of aspect ratio 100", thin.o.dim = 3, thin.o.faces[0] = thin.o.faces[1] = thin.o.faces[2] = 4, thin.o.upper[1] = 1, thin.o.upper[2] = 0.01;
  thin.far = 0.8;
  cases.push_back(thin);
  // The same with all edges of the marked cells cut (-adapt_refinement bisection_all), fewer steps.
  const size_t longest = cases.size();
  for (size_t i = 0; i < longest; ++i) {
    Case all = cases[i];
    all.name += ", all edges of marked cells", all.allEdges = true;
    cases.push_back(all);
  }
  for (const Case &k : cases) {
    PetscErrorCode ierr = TestCase(ck, k, k.thin ? 4 : k.allEdges ? 8 : 12);
    if (ierr) ck.PetscFailure(ierr, k.name);
  }
  const int status = ck.Finish();
  PetscCall(PetscFinalize());
  return status;
}

// Unit tests of the face tables of the space (SpaceCreate with interiorFaces; see InteriorFace in
// space.h), P1 and CR, 2D and 3D, on however many ranks the test runs (ctest runs it on 1 and 2). The
// expected values come from the mesh itself and from the geometry, not from the tables:
//   - the two cells of every interior face, without the vertex opposite the face, have exactly the face's
//     vertices (coordinates of the face point's closure in the DMPlex); CR: both give it the same DOF;
//   - every face of every local cell appears exactly once, as an interior face side, a shared face, or a
//     face on the box's boundary (all its vertices on one side of the box);
//   - (dim + 1) cells = 2 (interior faces) + boundary faces over all ranks, counting each shared face once,
//     and the face counts of the box (2D N x M: 3NM + N + M faces, 2(N + M) on the boundary);
//   - sharedFaceSF joins the two sides of every face between ranks: each owned entry has exactly one leaf,
//     and the owner's face centroid, sent over it, is the leaf's own face centroid.
#include "signorini/mesh.h"
#include "signorini/space.h"
#include "signorini/stages.h"
#include "unit_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

struct FaceCase {
  std::string name;
  MeshOptions mesh;
  Element     element;
};

static std::vector<FaceCase> Cases()
{
  std::vector<FaceCase> out;
  for (Element e : {Element::P1, Element::CR}) {
    FaceCase c2;
    c2.mesh.dim = 2, c2.mesh.faces[0] = 5, c2.mesh.faces[1] = 3, c2.mesh.refine = 1, c2.mesh.diagonal = Diagonal::Backslash;
    c2.element = e, c2.name = Format("2D 5x3 %s", ElementName(e));
    out.push_back(c2);
    FaceCase c3;
    c3.mesh.dim = 3, c3.mesh.faces[0] = 3, c3.mesh.faces[1] = 2, c3.mesh.faces[2] = 2, c3.mesh.refine = 1;
    c3.element = e, c3.name = Format("3D 3x2x2 %s", ElementName(e));
    out.push_back(c3);
  }
  return out;
}

using Point = std::array<double, 3>;

// The vertices of local cell c except vertex k (the face opposite it), sorted.
static std::vector<Point> FaceOfCell(const Space &s, PetscInt c, PetscInt k)
{
  std::vector<Point> out;
  const Space::Coords X = s.X(c);
  for (PetscInt j = 0; j <= s.dim; ++j) {
    if (j == k) continue;
    Point x{0, 0, 0};
    for (PetscInt d = 0; d < s.dim; ++d) x[d] = X[j * s.dim + d];
    out.push_back(x);
  }
  std::sort(out.begin(), out.end());
  return out;
}

static Point Centroid(const std::vector<Point> &v)
{
  Point x{0, 0, 0};
  for (const Point &p : v)
    for (int d = 0; d < 3; ++d) x[d] += p[d] / v.size();
  return x;
}

static PetscInt Sum(MPI_Comm comm, PetscInt v)
{
  PetscInt s;
  MPI_Allreduce(&v, &s, 1, MPIU_INT, MPI_SUM, comm);
  return s;
}

static PetscErrorCode TestCase(unit::Checker &ck, const FaceCase &fc)
{
  MPI_Comm          comm = PETSC_COMM_WORLD;
  const std::string tag  = fc.name;
  DM                dm   = nullptr;
  MeshInfo          info;
  Problem           problem;
  Space             s, plain;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, fc.mesh, &dm, info));
  PetscCall(unit::MakeProblem(comm, fc.mesh.dim, {{1}, {}}, problem));
  PetscCall(SpaceCreate(dm, fc.element, problem, plain));
  ck.Check(plain.interiorFaces.empty() && plain.sharedFaces.empty() && !plain.sharedFaceSF, tag + " no face tables unless asked for");
  PetscCall(SpaceDestroy(plain));
  PetscCall(SpaceCreate(dm, fc.element, problem, s, true));
  const PetscInt dim = s.dim, nb = s.Nb();
  PetscReal      lo[3], hi[3];
  for (PetscInt d = 0; d < dim; ++d) lo[d] = fc.mesh.lower[d], hi[d] = fc.mesh.upper[d];
  const auto onBox = [&](const std::vector<Point> &v) {
    for (PetscInt d = 0; d < dim; ++d)
      for (const PetscReal side : {lo[d], hi[d]})
        if (std::all_of(v.begin(), v.end(), [&](const Point &x) { return std::fabs(x[d] - side) < 1e-12; })) return true;
    return false;
  };

  // 1. Interior faces: both sides against the face point's own vertices.
  PetscInt badVerts = 0, badDof = 0;
  std::vector<int> seen(s.NumCells() * nb, 0);
  for (const InteriorFace &f : s.interiorFaces) {
    const PetscInt *cone;
    PetscCall(DMPlexGetCone(dm, s.cStart + f.cell[0], &cone));
    std::vector<Point> face;
    PetscCall(unit::PointVertices(dm, cone[f.local[0]], face));
    std::sort(face.begin(), face.end());
    badVerts += FaceOfCell(s, f.cell[0], f.local[0]) != face || FaceOfCell(s, f.cell[1], f.local[1]) != face || f.cell[0] == f.cell[1];
    if (s.element == Element::CR) badDof += s.Dofs(f.cell[0])[f.local[0]] != s.Dofs(f.cell[1])[f.local[1]];
    for (PetscInt j = 0; j < 2; ++j) ++seen[f.cell[j] * nb + f.local[j]];
  }
  for (const SharedFace &f : s.sharedFaces) ++seen[f.cell * nb + f.local];
  // 2. Every cell face once: interior or shared, or on the box's boundary (and then in neither table).
  PetscInt badCover = 0, boundary = 0;
  for (PetscInt c = 0; c < s.NumCells(); ++c)
    for (PetscInt k = 0; k < nb; ++k) {
      const bool outer = onBox(FaceOfCell(s, c, k));
      boundary += outer;
      badCover += seen[c * nb + k] != (outer ? 0 : 1);
    }
  badVerts = Sum(comm, badVerts), badDof = Sum(comm, badDof), badCover = Sum(comm, badCover);
  ck.Check(badVerts == 0, tag + " the two cells of every interior face share exactly the face's vertices", "%d faces wrong", (int)badVerts);
  if (s.element == Element::CR) ck.Check(badDof == 0, tag + " CR: both cells give an interior face the same DOF", "%d faces wrong", (int)badDof);
  ck.Check(badCover == 0, tag + " every cell face is once interior or shared, or on the boundary", "%d cell faces wrong", (int)badCover);

  // 3. Counts: each shared face once (its owned entry).
  PetscInt owned = 0;
  for (const SharedFace &f : s.sharedFaces) owned += f.owned;
  const PetscInt cells = Sum(comm, s.NumCells()), interior = Sum(comm, (PetscInt)s.interiorFaces.size() + owned), outer = Sum(comm, boundary);
  ck.Check((dim + 1) * cells == 2 * interior + outer, tag + " (dim+1) cells = 2 interior + boundary faces", "%d cells, %d interior, %d boundary", (int)cells, (int)interior, (int)outer);
  if (dim == 2) {
    const PetscInt N = fc.mesh.faces[0] << fc.mesh.refine, M = fc.mesh.faces[1] << fc.mesh.refine;
    ck.Check(interior + outer == 3 * N * M + N + M && outer == 2 * (N + M), tag + " face counts of the box", "%d interior, %d boundary for %dx%d", (int)interior, (int)outer, (int)N, (int)M);
  }
  PetscMPIInt size;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  ck.Check(size == 1 ? Sum(comm, (PetscInt)s.sharedFaces.size()) == 0 : Sum(comm, owned) > 0, tag + " shared faces only between ranks");

  // 4. sharedFaceSF: one leaf per owned entry, and the leaf's face is the owner's face.
  const PetscInt n = (PetscInt)s.sharedFaces.size();
  std::vector<PetscInt> one(n, 1), count(n, 0);
  std::vector<PetscReal> mine(3 * n), theirs(3 * n, NAN);
  for (PetscInt i = 0; i < n; ++i) {
    const Point x = Centroid(FaceOfCell(s, s.sharedFaces[i].cell, s.sharedFaces[i].local));
    for (int d = 0; d < 3; ++d) mine[3 * i + d] = x[d];
  }
  MPI_Datatype point3;
  PetscCallMPI(MPI_Type_contiguous(3, MPIU_REAL, &point3));
  PetscCallMPI(MPI_Type_commit(&point3));
  PetscCall(PetscSFReduceBegin(s.sharedFaceSF, MPIU_INT, one.data(), count.data(), MPI_SUM));
  PetscCall(PetscSFReduceEnd(s.sharedFaceSF, MPIU_INT, one.data(), count.data(), MPI_SUM));
  PetscCall(PetscSFBcastBegin(s.sharedFaceSF, point3, mine.data(), theirs.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(s.sharedFaceSF, point3, mine.data(), theirs.data(), MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&point3));
  PetscInt badCount = 0, badMatch = 0;
  for (PetscInt i = 0; i < n; ++i) {
    if (s.sharedFaces[i].owned) badCount += count[i] != 1;
    else
      for (int d = 0; d < 3; ++d) badMatch += !(std::fabs(theirs[3 * i + d] - mine[3 * i + d]) < 1e-12);
  }
  badCount = Sum(comm, badCount), badMatch = Sum(comm, badMatch);
  ck.Check(badCount == 0, tag + " sharedFaceSF: every owned shared face has exactly one leaf", "%d wrong", (int)badCount);
  ck.Check(badMatch == 0, tag + " sharedFaceSF: the owner's face centroid is the leaf's own", "%d coordinates differ", (int)badMatch);

  PetscCall(SpaceDestroy(s));
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  ierr = StagesRegister();
  for (const FaceCase &fc : Cases()) {
    ierr = TestCase(ck, fc);
    if (ierr) ck.PetscFailure(ierr, fc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

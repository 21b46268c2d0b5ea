#include "signorini/refine.h"
#include "signorini/mesh.h"

#include <petsc/private/dmpleximpl.h>  // DM_Plex: the cones, supports and depth state, see SymmetrizeCones
#include <petsc/private/sectionimpl.h> // the sizes of the supports, see SymmetrizeCones

#include <algorithm>
#include <array>
#include <cstdint>

namespace signorini {

namespace {

// The numbering of the fine points, a function of the coarse strata of one rank. Fine points are ordered
// as PETSc orders a plex: cells, vertices, (3D: faces,) edges.
//   cells:    2D 4 per coarse triangle (k = 0, 1, 2: the corner at its vertex k; 3: the middle one);
//             3D 8 per coarse tetrahedron (4 corners, then 4 around the diagonal of the inner octahedron)
//   vertices: the coarse vertices, then one midpoint per coarse edge
//   faces:    3D only: 4 per coarse face (as the triangles of 2D), then 8 inside each coarse tetrahedron
//   edges:    2 halves per coarse edge (h = 0 holds the edge's first cone vertex), then 3 inside each
//             coarse triangle (2D cells, 3D faces), then (3D) the diagonal of each coarse tetrahedron
// "Triangles" below are the coarse points cut into four: the cells in 2D, the faces in 3D.
struct FineNumbering {
  PetscInt dim = 2;
  PetscInt cS = 0, nC = 0, fS = 0, nF = 0, eS = 0, nE = 0, vS = 0, nV = 0; // coarse strata (faces: 3D)

  PetscInt CellsPer() const { return dim == 2 ? 4 : 8; }
  PetscInt Cell(PetscInt c, PetscInt k) const { return CellsPer() * (c - cS) + k; }
  PetscInt VertexStart() const { return CellsPer() * nC; }
  PetscInt Vertex(PetscInt v) const { return VertexStart() + (v - vS); }
  PetscInt Mid(PetscInt e) const { return VertexStart() + nV + (e - eS); }
  PetscInt FaceStart() const { return VertexStart() + nV + nE; } // 3D
  PetscInt FaceChild(PetscInt f, PetscInt k) const { return FaceStart() + 4 * (f - fS) + k; }
  PetscInt CellFace(PetscInt c, PetscInt j) const { return FaceStart() + 4 * nF + 8 * (c - cS) + j; }
  PetscInt EdgeStart() const { return dim == 2 ? VertexStart() + nV + nE : FaceStart() + 4 * nF + 8 * nC; }
  PetscInt Half(PetscInt e, PetscInt h) const { return EdgeStart() + 2 * (e - eS) + h; }
  PetscInt TriangleStart() const { return dim == 2 ? cS : fS; }
  PetscInt NumTriangles() const { return dim == 2 ? nC : nF; }
  PetscInt TriangleChild(PetscInt t, PetscInt k) const { return dim == 2 ? Cell(t, k) : FaceChild(t, k); }
  PetscInt TriangleEdge(PetscInt t, PetscInt j) const { return EdgeStart() + 2 * nE + 3 * (t - TriangleStart()) + j; }
  PetscInt Diagonal(PetscInt c) const { return EdgeStart() + 2 * nE + 3 * nF + (c - cS); } // 3D
  PetscInt End() const { return dim == 2 ? EdgeStart() + 2 * nE + 3 * nC : EdgeStart() + 2 * nE + 3 * nF + nC; }

  // The fine points that coarse point p becomes (at most 17); returns their number.
  PetscInt Children(PetscInt p, PetscInt ch[17]) const
  {
    PetscInt n = 0;
    if (p >= vS && p < vS + nV) {
      ch[n++] = Vertex(p);
    } else if (p >= eS && p < eS + nE) {
      ch[n++] = Mid(p), ch[n++] = Half(p, 0), ch[n++] = Half(p, 1);
    } else if (dim == 3 && p >= fS && p < fS + nF) {
      for (PetscInt k = 0; k < 4; ++k) ch[n++] = FaceChild(p, k);
      for (PetscInt j = 0; j < 3; ++j) ch[n++] = TriangleEdge(p, j);
    } else {
      for (PetscInt k = 0; k < CellsPer(); ++k) ch[n++] = Cell(p, k);
      if (dim == 2)
        for (PetscInt j = 0; j < 3; ++j) ch[n++] = TriangleEdge(p, j);
      else {
        for (PetscInt j = 0; j < 8; ++j) ch[n++] = CellFace(p, j);
        ch[n++] = Diagonal(p);
      }
    }
    return n;
  }
};

// One oriented edge of a coarse triangle: its ends in the direction of travel, and its halves in that
// direction, each with the orientation it has in a fine triangle (0: as stored, -1: reversed).
struct OrientedEdge {
  PetscInt from, to;      // coarse vertices
  PetscInt first, second; // fine half edges: the one at `from`, the one at `to`
  PetscInt orientation;
};

// The edges of coarse triangle t in its own order: edge k runs from vertex k to vertex k + 1.
PetscErrorCode TriangleEdges(const PlexCones &coarse, const FineNumbering &n, PetscInt t, OrientedEdge ed[3], const PetscInt **cone)
{
  PetscFunctionBeginUser;
  *cone                = coarse.Cone(t);
  const PetscInt *ornt = coarse.Orientation(t);
  for (PetscInt k = 0; k < 3; ++k) {
    const PetscInt *ends = coarse.Cone((*cone)[k]);
    PetscCheck(ornt[k] == 0 || ornt[k] == -1, PETSC_COMM_SELF, PETSC_ERR_SUP, "refinement: edge orientation %" PetscInt_FMT " in triangle %" PetscInt_FMT, ornt[k], t);
    const bool fwd = ornt[k] == 0;
    ed[k] = {fwd ? ends[0] : ends[1], fwd ? ends[1] : ends[0], n.Half((*cone)[k], fwd ? 0 : 1), n.Half((*cone)[k], fwd ? 1 : 0), ornt[k]};
  }
  for (PetscInt k = 0; k < 3; ++k)
    PetscCheck(ed[k].to == ed[(k + 1) % 3].from, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: the edges of triangle %" PetscInt_FMT " do not form a cycle", t);
  PetscFunctionReturn(0);
}

// The fine vertices of the four children of triangle t (v0, v1, v2) with midpoints m_k of edge k: the
// corners (v0, m0, m2), (m0, v1, m1), (m2, m1, v2) and the middle (m0, m1, m2). Each child's edge k runs
// from its vertex k to k + 1, so its vertex order is its orientation.
void TriangleChildVertices(const FineNumbering &n, const OrientedEdge ed[3], const PetscInt *cone, std::array<PetscInt, 3> child[4])
{
  const PetscInt v[3] = {n.Vertex(ed[0].from), n.Vertex(ed[1].from), n.Vertex(ed[2].from)};
  const PetscInt m[3] = {n.Mid(cone[0]), n.Mid(cone[1]), n.Mid(cone[2])};
  child[0] = {v[0], m[0], m[2]};
  child[1] = {m[0], v[1], m[1]};
  child[2] = {m[2], m[1], v[2]};
  child[3] = {m[0], m[1], m[2]};
}

PetscErrorCode SetEdgeHalves(DM coarse, DM fine, const FineNumbering &n)
{
  PlexCones       cones(fine);
  const PlexCones coarseCones(coarse);
  PetscFunctionBeginUser;
  for (PetscInt e = n.eS; e < n.eS + n.nE; ++e) {
    const PetscInt *cone = coarseCones.Cone(e);
    const PetscInt h0[2] = {n.Vertex(cone[0]), n.Mid(e)}, h1[2] = {n.Mid(e), n.Vertex(cone[1])};
    cones.SetCone(n.Half(e, 0), h0);
    cones.SetCone(n.Half(e, 1), h1);
  }
  PetscFunctionReturn(0);
}

// The four children of each coarse triangle (see TriangleChildVertices) and its three interior edges:
// edge j is stored from m_j to m_(j-1), (m0, m2), (m1, m0), (m2, m1); corner j uses it as stored, the
// middle triangle reversed.
PetscErrorCode SplitTriangles(DM coarse, DM fine, const FineNumbering &n)
{
  PlexCones       fineCones(fine);
  const PlexCones coarseCones(coarse);
  PetscFunctionBeginUser;
  for (PetscInt t = n.TriangleStart(); t < n.TriangleStart() + n.NumTriangles(); ++t) {
    const PetscInt *cone;
    OrientedEdge    ed[3];
    PetscCall(TriangleEdges(coarseCones, n, t, ed, &cone));
    const PetscInt m[3]        = {n.Mid(cone[0]), n.Mid(cone[1]), n.Mid(cone[2])};
    const PetscInt inner[3][2] = {{m[0], m[2]}, {m[1], m[0]}, {m[2], m[1]}};
    for (PetscInt j = 0; j < 3; ++j) fineCones.SetCone(n.TriangleEdge(t, j), inner[j]);
    const PetscInt o = 0, r = -1;
    const PetscInt cones[4][3] = {{ed[0].first, n.TriangleEdge(t, 0), ed[2].second},
                                  {ed[0].second, ed[1].first, n.TriangleEdge(t, 1)},
                                  {n.TriangleEdge(t, 2), ed[1].second, ed[2].first},
                                  {n.TriangleEdge(t, 1), n.TriangleEdge(t, 2), n.TriangleEdge(t, 0)}};
    const PetscInt ornts[4][3] = {{ed[0].orientation, o, ed[2].orientation},
                                  {ed[0].orientation, ed[1].orientation, o},
                                  {o, ed[1].orientation, ed[2].orientation},
                                  {r, r, r}};
    for (PetscInt k = 0; k < 4; ++k) {
      fineCones.SetCone(n.TriangleChild(t, k), cones[k]);
      fineCones.SetOrientation(n.TriangleChild(t, k), ornts[k]);
    }
  }
  PetscFunctionReturn(0);
}

// A fine point of a coarse tetrahedron known by its vertices: in stored order, and sorted (the key the
// lookups below compare).
template <int N>
struct Known {
  PetscInt                point;
  std::array<PetscInt, N> verts, key;
  Known(PetscInt p, const std::array<PetscInt, N> &v) : point(p), verts(v), key(v) { std::sort(key.begin(), key.end()); }
};

// The known point with the vertices `verts` (in any order), or null. A coarse tetrahedron has 25 fine
// edges and 24 fine faces on or in it, so a linear search is as fast as anything, with the keys compared
// entry by entry in line (std::array's == calls memcmp for each candidate, which then dominates).
template <int N>
static const Known<N> *Find(const std::vector<Known<N>> &known, std::array<PetscInt, N> verts)
{
  static_assert(N == 2 || N == 3, "edges and faces");
  // Sorted by compare-and-swap (std::sort's general machinery cost as much as the search).
  if (verts[0] > verts[1]) std::swap(verts[0], verts[1]);
  if (N == 3) {
    if (verts[N - 2] > verts[N - 1]) std::swap(verts[N - 2], verts[N - 1]);
    if (verts[0] > verts[1]) std::swap(verts[0], verts[1]);
  }
  for (const Known<N> &k : known) {
    PetscInt i = 0;
    while (i < N && k.key[i] == verts[i]) ++i;
    if (i == N) return &k;
  }
  return nullptr;
}

// Signed volume factor of four fine vertices (coordinates `x`, fine vertex v at (v - VertexStart) * 3).
static PetscReal Det(const std::vector<PetscReal> &x, const FineNumbering &n, const std::array<PetscInt, 4> &v)
{
  PetscReal e[3][3];
  for (PetscInt i = 0; i < 3; ++i)
    for (PetscInt d = 0; d < 3; ++d) e[i][d] = x[(v[i + 1] - n.VertexStart()) * 3 + d] - x[(v[0] - n.VertexStart()) * 3 + d];
  return e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
}

// The eight children of each coarse tetrahedron with vertices (w0, w1, w2, w3) in PETSc's order and edge
// midpoints M_ij: the corners (w0, M01, M02, M03), (M01, w1, M12, M13), (M02, M12, w2, M23),
// (M03, M13, M23, w3), and the inner octahedron cut by the diagonal M01-M23 (PETSc's choice, so that both
// refinements give the same mesh) into four around it. The cut-off faces of the corners and the four
// faces through the diagonal are the cell's interior faces. Faces and edges of each child are found by
// their vertices among the fine points of the coarse cell, and oriented against PETSc's reference
// tetrahedron, whose face k has vertices (0 1 2), (0 3 1), (0 2 3), (2 1 3).
PetscErrorCode SplitTetrahedra(DM coarse, DM fine, const FineNumbering &n, const std::vector<PetscReal> &x)
{
  static const PetscInt refFace[4][3] = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {2, 1, 3}};
  std::vector<Known<2>> edges;
  std::vector<Known<3>> faces;
  CellVertexReader      reader;
  PlexCones             fineCones(fine);
  const PlexCones       coarseCones(coarse);
  PetscFunctionBeginUser;
  PetscCall(reader.Init(coarse));
  PetscInt orientation[9]; // of a child's face, by where its first two vertices lie in the face's stored order
  PetscCall(TriangleOrientations(orientation));
  const auto place = [](const std::array<PetscInt, 3> &v, PetscInt x) { return v[0] == x ? 0 : v[1] == x ? 1 : 2; };
  for (PetscInt c = n.cS; c < n.cS + n.nC; ++c) {
    PetscInt verts[4];
    reader.Vertices(c, verts);
    const PetscInt  w[4]     = {n.Vertex(verts[3]), n.Vertex(verts[2]), n.Vertex(verts[1]), n.Vertex(verts[0])}; // PETSc's order
    const PetscInt *cellCone = coarseCones.Cone(c);
    // The fine edges and faces on the cell's boundary, with their stored vertex order.
    edges.clear();
    faces.clear();
    PetscInt mid[4][4] = {{-1, -1, -1, -1}, {-1, -1, -1, -1}, {-1, -1, -1, -1}, {-1, -1, -1, -1}}; // M_ij, from the edges of the faces
    for (PetscInt k = 0; k < 4; ++k) {
      const PetscInt *cone;
      OrientedEdge    ed[3];
      PetscCall(TriangleEdges(coarseCones, n, cellCone[k], ed, &cone));
      std::array<PetscInt, 3> child[4];
      TriangleChildVertices(n, ed, cone, child);
      for (PetscInt j = 0; j < 4; ++j) faces.emplace_back(n.FaceChild(cellCone[k], j), child[j]);
      const PetscInt m[3] = {n.Mid(cone[0]), n.Mid(cone[1]), n.Mid(cone[2])};
      for (PetscInt j = 0; j < 3; ++j) edges.emplace_back(n.TriangleEdge(cellCone[k], j), std::array<PetscInt, 2>{m[j], m[(j + 2) % 3]});
      for (PetscInt j = 0; j < 3; ++j)
        for (PetscInt a = 0; a < 4; ++a)
          for (PetscInt b = 0; b < 4; ++b)
            if (n.Vertex(ed[j].from) == w[a] && n.Vertex(ed[j].to) == w[b]) mid[a][b] = mid[b][a] = m[j];
    }
    for (PetscInt a = 0; a < 4; ++a)
      for (PetscInt b = a + 1; b < 4; ++b) PetscCheck(mid[a][b] >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: cell %" PetscInt_FMT " has no edge between its vertices %" PetscInt_FMT " and %" PetscInt_FMT, c, a, b);
    const PetscInt diagonal[2] = {mid[0][1], mid[2][3]};
    fineCones.SetCone(n.Diagonal(c), diagonal);
    edges.emplace_back(n.Diagonal(c), std::array<PetscInt, 2>{diagonal[0], diagonal[1]});
    const std::array<PetscInt, 3> inner[8] = {{mid[0][1], mid[0][2], mid[0][3]}, {mid[0][1], mid[1][2], mid[1][3]}, {mid[0][2], mid[1][2], mid[2][3]}, {mid[0][3], mid[1][3], mid[2][3]},
                                              {mid[0][1], mid[2][3], mid[0][2]}, {mid[0][1], mid[2][3], mid[0][3]}, {mid[0][1], mid[2][3], mid[1][2]}, {mid[0][1], mid[2][3], mid[1][3]}};
    for (PetscInt j = 0; j < 8; ++j) {
      PetscInt cone[3], ornt[3];
      for (PetscInt k = 0; k < 3; ++k) {
        const std::array<PetscInt, 2> want = {inner[j][k], inner[j][(k + 1) % 3]};
        const Known<2>               *e    = Find<2>(edges, want);
        PetscCheck(e, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: no edge for interior face %" PetscInt_FMT " of cell %" PetscInt_FMT, j, c);
        cone[k] = e->point;
        ornt[k] = e->verts[0] == want[0] ? 0 : -1;
      }
      fineCones.SetCone(n.CellFace(c, j), cone);
      fineCones.SetOrientation(n.CellFace(c, j), ornt);
      faces.emplace_back(n.CellFace(c, j), inner[j]);
    }
    // The children, each turned to the parent's handedness.
    std::array<PetscInt, 4> child[8] = {{w[0], mid[0][1], mid[0][2], mid[0][3]}, {mid[0][1], w[1], mid[1][2], mid[1][3]}, {mid[0][2], mid[1][2], w[2], mid[2][3]}, {mid[0][3], mid[1][3], mid[2][3], w[3]},
                                        {mid[0][1], mid[2][3], mid[0][2], mid[0][3]}, {mid[0][1], mid[2][3], mid[0][3], mid[1][3]}, {mid[0][1], mid[2][3], mid[1][3], mid[1][2]}, {mid[0][1], mid[2][3], mid[1][2], mid[0][2]}};
    const bool positive = Det(x, n, {w[0], w[1], w[2], w[3]}) > 0;
    for (PetscInt k = 0; k < 8; ++k) {
      if ((Det(x, n, child[k]) > 0) != positive) std::swap(child[k][2], child[k][3]);
      PetscInt cone[4], ornt[4];
      for (PetscInt f = 0; f < 4; ++f) {
        const std::array<PetscInt, 3> want = {child[k][refFace[f][0]], child[k][refFace[f][1]], child[k][refFace[f][2]]};
        const Known<3>               *face = Find<3>(faces, want);
        PetscCheck(face, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: no face %" PetscInt_FMT " for child %" PetscInt_FMT " of cell %" PetscInt_FMT, f, k, c);
        cone[f] = face->point;
        ornt[f] = orientation[3 * place(face->verts, want[0]) + place(face->verts, want[1])];
      }
      fineCones.SetCone(n.Cell(c, k), cone);
      fineCones.SetOrientation(n.Cell(c, k), ornt);
    }
  }
  PetscFunctionReturn(0);
}

// The cell types of the fine strata (see SetCellTypeStrata).
PetscErrorCode SetCellTypes(DM fine, const FineNumbering &n)
{
  std::vector<CellTypeStratum> strata = {{n.dim == 2 ? DM_POLYTOPE_TRIANGLE : DM_POLYTOPE_TETRAHEDRON, 0, n.VertexStart()},
                                         {DM_POLYTOPE_POINT, n.VertexStart(), n.VertexStart() + n.nV + n.nE},
                                         {DM_POLYTOPE_SEGMENT, n.EdgeStart(), n.End()}};
  PetscFunctionBeginUser;
  if (n.dim == 3) strata.push_back({DM_POLYTOPE_TRIANGLE, n.FaceStart(), n.EdgeStart()});
  PetscCall(SetCellTypeStrata(fine, strata));
  PetscFunctionReturn(0);
}

// A point shared with another rank is shared with the same children there: the children of leaf p are
// leaves whose roots are the same children of p's root, numbered with the owner's strata. (A shared edge
// or face has the same cone on every rank, so its children come in the same order.)
PetscErrorCode SetPointSF(DM coarse, DM fine, const FineNumbering &n)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)coarse);
  PetscSF            csf, fsf;
  PetscInt           nroots, nleaves;
  const PetscInt    *ilocal;
  const PetscSFNode *iremote;
  PetscMPIInt        size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(DMGetPointSF(coarse, &csf));
  PetscCall(PetscSFGetGraph(csf, &nroots, &nleaves, &ilocal, &iremote));
  if (nroots < 0) PetscFunctionReturn(0); // no graph: nothing is shared
  std::vector<FineNumbering> remote(size);
  PetscCallMPI(MPI_Allgather(&n, sizeof(FineNumbering), MPI_BYTE, remote.data(), sizeof(FineNumbering), MPI_BYTE, comm));
  std::vector<PetscInt>    leaves;
  std::vector<PetscSFNode> roots;
  for (PetscInt l = 0; l < nleaves; ++l) {
    const PetscInt p = ilocal ? ilocal[l] : l;
    PetscInt       mine[17], theirs[17];
    const PetscInt k = n.Children(p, mine);
    PetscCheck(remote[iremote[l].rank].Children(iremote[l].index, theirs) == k, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: shared point %" PetscInt_FMT " has another kind on rank %" PetscInt_FMT, p, iremote[l].rank);
    for (PetscInt j = 0; j < k; ++j) {
      leaves.push_back(mine[j]);
      roots.push_back({iremote[l].rank, theirs[j]});
    }
  }
  PetscCall(PetscSFCreate(comm, &fsf));
  PetscCall(PetscSFSetGraph(fsf, n.End(), (PetscInt)leaves.size(), leaves.data(), PETSC_COPY_VALUES, roots.data(), PETSC_COPY_VALUES));
  PetscCall(DMSetPointSF(fine, fsf));
  PetscCall(PetscSFDestroy(&fsf));
  PetscFunctionReturn(0);
}

// Every label but depth and cell type ("Face Sets", "Cell Sets", ...): the children of a labelled point
// carry its value, as in PETSc's refinement.
PetscErrorCode RefineLabels(DM coarse, DM fine, const FineNumbering &n)
{
  PetscFunctionBeginUser;
  PetscCall(ForEachLabelStratum(coarse, fine, [&](DMLabel flabel, PetscInt value, const PetscInt *points, PetscInt np) -> PetscErrorCode {
    PetscInt *children;
    PetscInt  count = 0;
    IS        fineIS;
    PetscFunctionBeginUser;
    PetscCall(PetscMalloc1(17 * np, &children));
    for (PetscInt j = 0; j < np; ++j) count += n.Children(points[j], children + count);
    SortDistinctPoints(children, count, n.End());
    PetscCall(ISCreateGeneral(PETSC_COMM_SELF, count, children, PETSC_OWN_POINTER, &fineIS));
    PetscCall(DMLabelSetStratumIS(flabel, value, fineIS));
    PetscCall(ISDestroy(&fineIS));
    PetscFunctionReturn(0);
  }));
  PetscFunctionReturn(0);
}

// Coordinates of the fine vertices, 3 per vertex (zero-padded): coarse vertices keep theirs, each
// midpoint is the mean of its edge's ends.
PetscErrorCode FineCoordinates(DM coarse, const FineNumbering &n, std::vector<PetscReal> &x)
{
  PetscSection       csec;
  Vec                cvec;
  const PetscScalar *cx;
  PetscInt           cdim;
  PetscFunctionBeginUser;
  PetscCall(DMGetCoordinateDim(coarse, &cdim));
  PetscCall(DMGetCoordinateSection(coarse, &csec));
  PetscCall(DMGetCoordinatesLocal(coarse, &cvec));
  PetscCall(VecGetArrayRead(cvec, &cx));
  x.assign((n.nV + n.nE) * 3, 0.0);
  for (PetscInt v = n.vS; v < n.vS + n.nV; ++v) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(csec, v, &off));
    for (PetscInt d = 0; d < cdim; ++d) x[(v - n.vS) * 3 + d] = PetscRealPart(cx[off + d]);
  }
  const PlexCones cones(coarse);
  for (PetscInt e = n.eS; e < n.eS + n.nE; ++e) {
    const PetscInt *cone = cones.Cone(e);
    for (PetscInt d = 0; d < 3; ++d) x[(n.nV + e - n.eS) * 3 + d] = 0.5 * (x[(cone[0] - n.vS) * 3 + d] + x[(cone[1] - n.vS) * 3 + d]);
  }
  PetscCall(VecRestoreArrayRead(cvec, &cx));
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode SetCellTypeStrata(DM dm, const std::vector<CellTypeStratum> &strata)
{
  DMLabel label;
  PetscFunctionBeginUser;
  PetscCall(DMCreateLabel(dm, "celltype"));
  PetscCall(DMGetLabel(dm, "celltype", &label));
  for (const CellTypeStratum &s : strata) {
    IS is;
    PetscCall(ISCreateStride(PETSC_COMM_SELF, s.end - s.start, s.start, 1, &is));
    PetscCall(DMLabelSetStratumIS(label, s.type, is));
    PetscCall(ISDestroy(&is));
  }
  PetscFunctionReturn(0);
}

PlexCones::PlexCones(DM dm)
{
  const DM_Plex *mesh = (const DM_Plex *)dm->data;
  cones = mesh->cones, ornts = mesh->coneOrientations, off = mesh->coneSection->atlasOff, pStart = mesh->coneSection->pStart;
}

PetscErrorCode TriangleOrientations(PetscInt orientation[9])
{
  const PetscInt stored[3] = {0, 1, 2};
  PetscInt       perm[3]   = {0, 1, 2};
  PetscFunctionBeginUser;
  std::fill(orientation, orientation + 9, 0);
  do PetscCall(DMPolytopeGetVertexOrientation(DM_POLYTOPE_TRIANGLE, stored, perm, &orientation[3 * perm[0] + perm[1]]));
  while (std::next_permutation(perm, perm + 3));
  PetscFunctionReturn(0);
}

PetscErrorCode SetDepthStrata(DM dm, const std::vector<std::array<PetscInt, 2>> &ranges)
{
  DMLabel depth;
  PetscFunctionBeginUser;
  PetscCall(DMCreateLabel(dm, "depth"));
  PetscCall(DMPlexGetDepthLabel(dm, &depth));
  for (PetscInt d = 0; d < (PetscInt)ranges.size(); ++d) {
    const std::array<PetscInt, 2> &r = ranges[d];
    if (r[0] >= r[1]) continue;
    IS is;
    PetscCall(ISCreateStride(PETSC_COMM_SELF, r[1] - r[0], r[0], 1, &is));
    PetscCall(DMLabelSetStratumIS(depth, d, is));
    PetscCall(ISDestroy(&is));
  }
  PetscInt numValues, maxValues = 0;
  PetscCall(DMLabelGetNumValues(depth, &numValues));
  PetscCallMPI(MPI_Allreduce(&numValues, &maxValues, 1, MPIU_INT, MPI_MAX, PetscObjectComm((PetscObject)dm)));
  for (PetscInt v = numValues; v < maxValues; ++v) PetscCall(DMLabelAddStratum(depth, v));
  PetscCall(PetscObjectStateGet((PetscObject)depth, &((DM_Plex *)dm->data)->depthState));
  PetscFunctionReturn(0);
}

PetscErrorCode SymmetrizeCones(DM dm)
{
  DM_Plex *mesh = (DM_Plex *)dm->data;
  PetscInt pStart, pEnd, size;
  PetscFunctionBeginUser;
  PetscCheck(!mesh->supports, PetscObjectComm((PetscObject)dm), PETSC_ERR_ARG_WRONGSTATE, "SymmetrizeCones: the supports are set already");
  PetscCall(DMPlexGetChart(dm, &pStart, &pEnd));
  PetscSection   cs = mesh->coneSection, ss = mesh->supportSection;
  const PetscInt n  = pEnd - pStart;
  PetscCheck(cs->pStart == pStart && ss->pStart == pStart && ss->pEnd == pEnd, PETSC_COMM_SELF, PETSC_ERR_PLIB, "SymmetrizeCones: unexpected sections");
  // Each point once in the support of every point in its cone; the sizes count up again as places fill.
  PetscInt *count = ss->atlasDof;
  std::fill(count, count + n, 0);
  for (PetscInt p = 0; p < n; ++p)
    for (PetscInt i = cs->atlasOff[p]; i < cs->atlasOff[p] + cs->atlasDof[p]; ++i) ++count[mesh->cones[i] - pStart];
  ss->maxDof = PETSC_MIN_INT; // recomputed when asked for (see PetscSectionInvalidateMaxDof_Internal)
  PetscCall(PetscSectionSetUp(ss));
  PetscCall(PetscSectionGetStorageSize(ss, &size));
  PetscCall(PetscMalloc1(size, &mesh->supports));
  // The sizes serve as each support's next place meanwhile (one array read at random per entry, not two),
  // and are sizes again once every place is filled.
  for (PetscInt q = 0; q < n; ++q) count[q] = ss->atlasOff[q];
  for (PetscInt p = 0; p < n; ++p)
    for (PetscInt i = cs->atlasOff[p]; i < cs->atlasOff[p] + cs->atlasDof[p]; ++i) mesh->supports[count[mesh->cones[i] - pStart]++] = p + pStart;
  for (PetscInt q = 0; q < n; ++q) count[q] -= ss->atlasOff[q];
  PetscFunctionReturn(0);
}

PetscErrorCode SetVertexCoordinates(DM dm, PetscInt cdim, PetscInt vStart, PetscInt n, const std::vector<PetscReal> &x)
{
  PetscSection sec;
  Vec          vec;
  PetscScalar *fx;
  PetscFunctionBeginUser;
  PetscCall(DMSetCoordinateDim(dm, cdim));
  PetscCall(PetscSectionCreate(PetscObjectComm((PetscObject)dm), &sec)); // the global section scans offsets over this comm
  PetscCall(PetscSectionSetNumFields(sec, 1));
  PetscCall(PetscSectionSetFieldComponents(sec, 0, cdim));
  PetscCall(PetscSectionSetChart(sec, vStart, vStart + n));
  for (PetscInt v = vStart; v < vStart + n; ++v) {
    PetscCall(PetscSectionSetDof(sec, v, cdim));
    PetscCall(PetscSectionSetFieldDof(sec, v, 0, cdim));
  }
  PetscCall(PetscSectionSetUp(sec));
  PetscCall(DMSetCoordinateSection(dm, cdim, sec));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, n * cdim, &vec));
  PetscCall(VecSetBlockSize(vec, cdim));
  PetscCall(PetscObjectSetName((PetscObject)vec, "coordinates"));
  PetscCall(VecGetArray(vec, &fx));
  for (PetscInt v = 0; v < n; ++v) // the section puts vertex vStart + v at v * cdim
    for (PetscInt d = 0; d < cdim; ++d) fx[v * cdim + d] = x[v * 3 + d];
  PetscCall(VecRestoreArray(vec, &fx));
  PetscCall(DMSetCoordinatesLocal(dm, vec));
  PetscCall(VecDestroy(&vec));
  PetscCall(PetscSectionDestroy(&sec));
  PetscFunctionReturn(0);
}

// Sorts n distinct points of [0, end). A stratum that holds every cell of a mesh (a Gmsh physical group)
// has millions of children, whose comparison sort weighed in every refinement: where they fill more than a
// 64th of the chart, a bit per point orders them in one pass over the chart instead.
void SortDistinctPoints(PetscInt *p, PetscInt n, PetscInt end)
{
  if (n < 2 || std::is_sorted(p, p + n)) return;
  if (n < end / 64) return std::sort(p, p + n);
  std::vector<std::uint64_t> bits((end + 63) / 64, 0);
  for (PetscInt i = 0; i < n; ++i) bits[p[i] >> 6] |= std::uint64_t(1) << (p[i] & 63);
  PetscInt k = 0;
  for (size_t w = 0; w < bits.size(); ++w)
    for (std::uint64_t b = bits[w]; b; b &= b - 1) p[k++] = (PetscInt)(64 * w + __builtin_ctzll(b));
}

PetscErrorCode ForEachLabelStratum(DM coarse, DM fine, const std::function<PetscErrorCode(DMLabel, PetscInt, const PetscInt *, PetscInt)> &stratum)
{
  PetscInt numLabels;
  PetscFunctionBeginUser;
  PetscCall(DMGetNumLabels(coarse, &numLabels));
  for (PetscInt l = 0; l < numLabels; ++l) {
    const char *name;
    DMLabel     clabel, flabel;
    IS          valueIS;
    PetscBool   isDepth, isType;
    PetscCall(DMGetLabelName(coarse, l, &name));
    PetscCall(PetscStrcmp(name, "depth", &isDepth));
    PetscCall(PetscStrcmp(name, "celltype", &isType));
    if (isDepth || isType) continue;
    PetscCall(DMGetLabel(coarse, name, &clabel));
    PetscCall(DMCreateLabel(fine, name));
    PetscCall(DMGetLabel(fine, name, &flabel));
    PetscInt defaultValue;
    PetscCall(DMLabelGetDefaultValue(clabel, &defaultValue));
    PetscCall(DMLabelSetDefaultValue(flabel, defaultValue));
    PetscCall(DMLabelGetValueIS(clabel, &valueIS));
    PetscInt        nv;
    const PetscInt *values;
    PetscCall(ISGetLocalSize(valueIS, &nv));
    PetscCall(ISGetIndices(valueIS, &values));
    for (PetscInt i = 0; i < nv; ++i) {
      IS              pointIS;
      PetscInt        np;
      const PetscInt *points;
      PetscCall(DMLabelGetStratumIS(clabel, values[i], &pointIS));
      if (!pointIS) continue;
      PetscCall(ISGetLocalSize(pointIS, &np));
      PetscCall(ISGetIndices(pointIS, &points));
      PetscCall(stratum(flabel, values[i], points, np));
      PetscCall(ISRestoreIndices(pointIS, &points));
      PetscCall(ISDestroy(&pointIS));
    }
    PetscCall(ISRestoreIndices(valueIS, &values));
    PetscCall(ISDestroy(&valueIS));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode RefineSimplices(DM coarse, DM *fine, std::vector<PetscInt> *parent)
{
  PetscInt      cE, eE, vE;
  FineNumbering n;
  DM            dm;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(coarse, &n.dim));
  PetscCheck(n.dim == 2 || n.dim == 3, PetscObjectComm((PetscObject)coarse), PETSC_ERR_SUP, "RefineSimplices: mesh dimension %" PetscInt_FMT, n.dim);
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &n.cS, &cE));
  PetscCall(DMPlexGetDepthStratum(coarse, 1, &n.eS, &eE));
  PetscCall(DMPlexGetDepthStratum(coarse, 0, &n.vS, &vE));
  n.nC = cE - n.cS, n.nE = eE - n.eS, n.nV = vE - n.vS;
  if (n.dim == 3) {
    PetscInt fE;
    PetscCall(DMPlexGetDepthStratum(coarse, 2, &n.fS, &fE));
    n.nF = fE - n.fS;
  }
  std::vector<PetscReal> x;
  PetscCall(FineCoordinates(coarse, n, x));

  PetscCall(DMCreate(PetscObjectComm((PetscObject)coarse), &dm));
  PetscCall(DMSetType(dm, DMPLEX));
  PetscCall(DMSetDimension(dm, n.dim));
  PetscCall(DMPlexSetChart(dm, 0, n.End()));
  for (PetscInt c = 0; c < n.VertexStart(); ++c) PetscCall(DMPlexSetConeSize(dm, c, n.dim + 1));
  if (n.dim == 3)
    for (PetscInt f = n.FaceStart(); f < n.EdgeStart(); ++f) PetscCall(DMPlexSetConeSize(dm, f, 3));
  for (PetscInt e = n.EdgeStart(); e < n.End(); ++e) PetscCall(DMPlexSetConeSize(dm, e, 2));
  PetscCall(DMSetUp(dm));
  PetscCall(SetEdgeHalves(coarse, dm, n));
  PetscCall(SplitTriangles(coarse, dm, n));
  if (n.dim == 3) PetscCall(SplitTetrahedra(coarse, dm, n, x));
  PetscCall(SymmetrizeCones(dm));
  PetscCall(SetCellTypes(dm, n));
  // depth 0 the vertices, 1 the edges, 2 the faces (3D), dim the cells (FineNumbering's strata)
  std::vector<std::array<PetscInt, 2>> depthRanges = {{n.VertexStart(), n.VertexStart() + n.nV + n.nE}, {n.EdgeStart(), n.End()}};
  if (n.dim == 3) depthRanges.push_back({n.FaceStart(), n.EdgeStart()});
  depthRanges.push_back({0, n.VertexStart()});
  PetscCall(SetDepthStrata(dm, depthRanges));
  PetscCall(SetPointSF(coarse, dm, n));
  PetscCall(RefineLabels(coarse, dm, n));
  PetscInt cdim;
  PetscCall(DMGetCoordinateDim(coarse, &cdim));
  PetscCall(SetVertexCoordinates(dm, cdim, n.VertexStart(), n.nV + n.nE, x));
  if (parent) {
    parent->resize(n.VertexStart());
    for (PetscInt c = 0; c < n.VertexStart(); ++c) (*parent)[c] = c / n.CellsPer();
  }
  *fine = dm;
  PetscFunctionReturn(0);
}

} // namespace signorini

// Refinement of marked cells by bisection of marked edges, for triangles and tetrahedra alike (see
// localrefine.h).
//
// Why it is conforming and the same on any number of ranks:
//  - Every rank orders edges the same way, by geometry only: longer first, ties broken by the midpoint's
//    coordinates, then by the endpoints' (exact doubles, so the same on every rank).
//  - A marked cell marks its longest edge; then every cell with a marked edge marks more edges by a rule
//    that marks more when it has more marks, to a fixed point. The fixed point is the least one containing
//    the first marks, so it does not depend on the order of the sweeps or on the distribution.
//  - The rule is Rivara's (a cell with a marked edge marks its longest edge: its first cut is its longest
//    edge, for the shape of the children) except for thin triangles. Bisecting an edge makes a child with
//    the angle between the edge and the median to its midpoint; in a stretched triangle the median to
//    the longest edge (and to the long leg of a right triangle) lies almost along it, so a longest-edge
//    cut makes an angle near 180 degrees, and P1 and Crouzeix-Raviart gradients lose accuracy with it
//    (the maximum angle condition). An edge is safe in a cell when in each of the cell's faces with it
//    that median makes at least 30 degrees with it (UnsafeCuts). A cell whose longest edge is unsafe is
//    cut either once, by its one marked edge if that is safe (the short leg of a thin right triangle, the
//    short edges of a flat tetrahedron: two children with angles of about 90 degrees), or by all edges
//    of one face when its edges are safe in the other faces (a cone over the face's four children), or
//    by all its edges (four or eight children close to similar to it: a flat Kuhn tetrahedron's eight
//    children are Kuhn tetrahedra again), see ThinRule. So is a tetrahedron with a cut below 10 degrees
//    (kCos2Flat) even if its longest edge is safe: Rivara's rule there cut its other marked edges in
//    children whose faces are not its own (angles of 178.85 degrees), and marked the longest edge, a
//    body diagonal, for a vertical edge, which spread the refinement over the whole of a flat box. Shape-
//    regular cells (right isosceles triangles, Kuhn tetrahedra of a cube, and their bisections included)
//    have a safe longest edge and no such cut, and are refined exactly as by Rivara.
//  - Each cell bisects its marked edges one after the other in the global order, each bisection cutting
//    every current child that has the whole edge (an edge not yet bisected is whole in some child).
//    Restricted to a face, this is the face's own sequence of bisections of its marked edges in the same
//    order (a cut by an edge off the face leaves the face's pieces whole), so the two cells of a face cut
//    it alike, whatever set of its edges is marked (a cut by an edge of the face splits exactly the pieces
//    of the face that have the whole edge). So any set of marked edges gives a conforming mesh, in 2D
//    and 3D.
// New vertices are the midpoints of the marked edges.
//
// The fine DMPlex is built directly, as refine.cpp builds the uniform one (PETSc's DMPlexInterpolate of
// the children's cell list costs 3 s for 300 k tetrahedra, ten times the rest): every child stays on its
// parent's rank; each fine point knows the coarse point it lies in (its carrier: a vertex, edge, face, or
// the cell itself), by which the children's edges and faces are told apart (FinePoints). The fine points in a
// shared coarse point are shared with the same ranks, and both sides list them in the same order (by
// global vertex numbers), which gives the point star forest; the vertex order stored in every edge and
// face is by global vertex numbers too, so shared points have the same cones on every rank.
#include "signorini/localrefine.h"
#include "signorini/mesh.h"
#include "signorini/refine.h"

#include <petsc/private/dmpleximpl.h>  // DM_Plex: the cones and supports, see BuildPlex
#include <petsc/private/sectionimpl.h> // the sizes of the cones, see BuildPlex

#include <algorithm>
#include <array>
#include <memory>
#include <numeric>
#include <tuple>

namespace signorini {

namespace {

// The vertex pairs of a simplex (a triangle's edges are the first three, in PETSc's cone order: edge k
// runs from vertex k to k + 1) and the faces of PETSc's reference tetrahedron.
const PetscInt kPair[6][2]    = {{0, 1}, {1, 2}, {2, 0}, {0, 3}, {1, 3}, {2, 3}};
const PetscInt kRefFace[4][3] = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {2, 1, 3}};

// By the set of a cell's local vertices (bits): the pair k of kPair with these two vertices, the vertex
// that three vertices miss (tetrahedra), -1 otherwise.
const PetscInt kPairOf[16]   = {-1, -1, -1, 0, -1, 2, 1, -1, -1, 3, 4, -1, 5, -1, -1, -1};
const PetscInt kOpposite[16] = {-1, -1, -1, -1, -1, -1, -1, 3, -1, -1, -1, 2, -1, 1, 0, -1};

// The coarse mesh of one rank as tables.
struct Coarse {
  PetscInt               dim = 0, cdim = 0, nce = 0; // nce: edges per cell
  PetscInt               pS = 0, pE = 0, cS = 0, cE = 0, fS = 0, fE = 0, eS = 0, eE = 0, vS = 0, vE = 0;
  std::vector<PetscReal> x;         // 3 per vertex (zero-padded)
  std::vector<PetscInt>  edgeVerts; // 2 per edge, as v - vS
  std::vector<PetscReal> edgeLen2;  // per edge, see EdgeOrder
  std::vector<PetscInt>  cellVerts; // dim + 1 per cell, as v - vS
  std::vector<PetscInt>  cellEdges; // nce per cell, as e - eS: the edge of the cell's vertex pair k (kPair)
  std::vector<PetscInt>  cellFaces; // 3D: 4 per cell, coarse points: face k is the one opposite vertex k
  std::vector<char>      tablePos;  // dim + 1 per cell: where vertex k stands in the cell tables of a space
                                    // on this mesh (CellVertices: opposite face tablePos[k] of the cone)
  PetscInt               NumCells() const { return cE - cS; }
  PetscInt               NumVertices() const { return vE - vS; }
  PetscInt               NumEdges() const { return eE - eS; }
};

PetscErrorCode ReadCoarse(DM dm, Coarse &m)
{
  PetscSection       csec;
  Vec                cvec;
  const PetscScalar *cx;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &m.dim));
  PetscCheck(m.dim == 2 || m.dim == 3, PetscObjectComm((PetscObject)dm), PETSC_ERR_SUP, "RefineMarkedBisection: mesh dimension %" PetscInt_FMT, m.dim);
  PetscCall(DMGetCoordinateDim(dm, &m.cdim));
  m.nce = m.dim == 2 ? 3 : 6;
  PetscCall(DMPlexGetChart(dm, &m.pS, &m.pE));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &m.cS, &m.cE));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &m.fS, &m.fE));
  PetscCall(DMPlexGetDepthStratum(dm, 1, &m.eS, &m.eE));
  PetscCall(DMPlexGetDepthStratum(dm, 0, &m.vS, &m.vE));
  PetscCall(DMGetCoordinateSection(dm, &csec));
  PetscCall(DMGetCoordinatesLocal(dm, &cvec));
  PetscCall(VecGetArrayRead(cvec, &cx));
  m.x.assign(3 * m.NumVertices(), 0.0);
  for (PetscInt v = m.vS; v < m.vE; ++v) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(csec, v, &off));
    for (PetscInt d = 0; d < m.cdim; ++d) m.x[3 * (v - m.vS) + d] = PetscRealPart(cx[off + d]);
  }
  PetscCall(VecRestoreArrayRead(cvec, &cx));
  const PlexCones plex(dm);
  m.edgeVerts.resize(2 * m.NumEdges());
  for (PetscInt e = m.eS; e < m.eE; ++e)
    for (PetscInt k = 0; k < 2; ++k) m.edgeVerts[2 * (e - m.eS) + k] = plex.Cone(e)[k] - m.vS;
  // A simplex's vertices in SimplexVertices' order: those of its first facet, then the one of its second
  // facet not on the first.
  const auto triangle = [&](PetscInt p, PetscInt *v) {
    const PetscInt *a = &m.edgeVerts[2 * (plex.Cone(p)[0] - m.eS)], *b = &m.edgeVerts[2 * (plex.Cone(p)[1] - m.eS)];
    v[0] = a[0], v[1] = a[1];
    for (PetscInt i = 0; i < 2; ++i)
      if (b[i] != v[0] && b[i] != v[1]) v[2] = b[i];
  };
  m.cellVerts.resize((m.dim + 1) * m.NumCells());
  m.tablePos.resize((m.dim + 1) * m.NumCells());
  m.cellEdges.resize(m.nce * m.NumCells());
  if (m.dim == 3) m.cellFaces.resize(4 * m.NumCells());
  for (PetscInt c = m.cS; c < m.cE; ++c) {
    PetscInt *cv = &m.cellVerts[(m.dim + 1) * (c - m.cS)];
    if (m.dim == 2) triangle(c, cv);
    else {
      PetscInt second[3] = {-1, -1, -1}; // all three set by triangle() (initialised for the compiler)
      triangle(plex.Cone(c)[0], cv), triangle(plex.Cone(c)[1], second);
      for (PetscInt i = 0; i < 3; ++i)
        if (std::find(cv, cv + 3, second[i]) == cv + 3) cv[3] = second[i];
    }
    // The cell-local vertices (bits) of coarse edge e.
    const auto bits = [&](PetscInt e) {
      const PetscInt a = m.edgeVerts[2 * e], b = m.edgeVerts[2 * e + 1];
      int            r = 0;
      for (PetscInt i = 0; i <= m.dim; ++i) r |= (cv[i] == a || cv[i] == b) << i;
      return r;
    };
    // The edges: the cone of a triangle, the edges of the faces of a tetrahedron (each twice). Each goes to
    // the place of its vertex pair, each face to the place of the vertex it misses.
    PetscInt *cellEdges = &m.cellEdges[m.nce * (c - m.cS)];
    int       placed    = 0; // the places filled (bits); an edge without two of the cell's vertices fills none
    const auto place     = [&](PetscInt e) {
      const int b = bits(e), k = kPairOf[b];
      if (k >= 0) cellEdges[k] = e, placed |= 1 << k;
      return b;
    };
    const PetscInt *ccone = plex.Cone(c);
    char           *pos   = &m.tablePos[(m.dim + 1) * (c - m.cS)];
    if (m.dim == 2)
      for (PetscInt k = 0; k < 3; ++k) {
        const int b = place(ccone[k] - m.eS), missed = 7 & ~b; // the vertex opposite edge k
        if (missed == 1 || missed == 2 || missed == 4) pos[missed >> 1] = (char)k;
      }
    else
      for (PetscInt f = 0; f < 4; ++f) {
        const PetscInt *fcone = plex.Cone(ccone[f]);
        int             on    = 0;
        for (PetscInt k = 0; k < 3; ++k) on |= place(fcone[k] - m.eS);
        if (kOpposite[on] >= 0) m.cellFaces[4 * (c - m.cS) + kOpposite[on]] = ccone[f], pos[kOpposite[on]] = (char)f;
        else placed = -1;
      }
    PetscCheck(placed == (1 << m.nce) - 1, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: cell %" PetscInt_FMT " is not a simplex of %" PetscInt_FMT " distinct edges", c, m.nce);
  }
  PetscFunctionReturn(0);
}

// The global order of edges (see the top of the file) as a comparison: before(e, f) when local edge e comes
// before f. Only edges of one cell are ever compared, so a comparison of edges of equal length computes
// the two keys from the coordinates instead of sorting all edges once (that sort was half of the
// refinement's time).
class EdgeOrder {
public:
  explicit EdgeOrder(const Coarse &m) : m_(m) {}
  // The squared length of every edge, which decides most comparisons (KeyOf's, bit for bit).
  static void Lengths(Coarse &m)
  {
    m.edgeLen2.resize(m.NumEdges());
    for (PetscInt e = 0; e < m.NumEdges(); ++e) m.edgeLen2[e] = EdgeOrder(m).KeyOf(e).len2;
  }
  bool operator()(PetscInt e, PetscInt f) const
  {
    const PetscReal *len2 = m_.edgeLen2.data();
    if (len2[e] != len2[f]) return len2[e] > len2[f];
    const Key a = KeyOf(e), b = KeyOf(f);
    return std::tie(a.mid, a.lo, a.hi) < std::tie(b.mid, b.lo, b.hi);
  }

private:
  struct Key {
    PetscReal                len2;
    std::array<PetscReal, 3> mid, lo, hi;
  };
  Key KeyOf(PetscInt e) const
  {
    const PetscReal         *a = &m_.x[3 * m_.edgeVerts[2 * e]], *b = &m_.x[3 * m_.edgeVerts[2 * e + 1]];
    std::array<PetscReal, 3> A = {a[0], a[1], a[2]}, B = {b[0], b[1], b[2]};
    Key                      k;
    k.len2 = 0;
    for (int d = 0; d < 3; ++d) {
      k.len2 += (B[d] - A[d]) * (B[d] - A[d]); // (b - a)^2 == (a - b)^2 exactly: independent of the cone order
      k.mid[d] = A[d] + B[d];
    }
    k.lo = std::min(A, B), k.hi = std::max(A, B);
    return k;
  }
  const Coarse &m_;
};

// How the coarse points are shared with other ranks (the charts of a DMPlex start at 0).
struct Sharing {
  PetscSF            sf = nullptr;     // the point star forest; null: nothing is shared
  std::vector<PetscInt> leaf;          // over the chart: index in the graph's leaves, or -1
  std::vector<char>  shared;           // over the chart: a leaf, or a root with leaves
  const PetscSFNode *remote = nullptr; // the graph's roots of the leaves
};

PetscErrorCode GetSharing(DM dm, const Coarse &m, Sharing &sh)
{
  PetscInt        nroots, nleaves;
  const PetscInt *ilocal, *degree;
  PetscFunctionBeginUser;
  PetscCheck(m.pS == 0, PETSC_COMM_SELF, PETSC_ERR_SUP, "RefineMarkedBisection: chart starts at %" PetscInt_FMT, m.pS);
  sh.leaf.assign(m.pE, -1);
  sh.shared.assign(m.pE, 0);
  PetscCall(DMGetPointSF(dm, &sh.sf));
  PetscCall(PetscSFGetGraph(sh.sf, &nroots, &nleaves, &ilocal, &sh.remote));
  if (nroots < 0) {
    sh.sf = nullptr;
    PetscFunctionReturn(0);
  }
  for (PetscInt l = 0; l < nleaves; ++l) {
    const PetscInt p = ilocal ? ilocal[l] : l;
    sh.leaf[p] = l, sh.shared[p] = 1;
  }
  PetscCall(PetscSFComputeDegreeBegin(sh.sf, &degree));
  PetscCall(PetscSFComputeDegreeEnd(sh.sf, &degree));
  for (PetscInt p = 0; p < nroots; ++p)
    if (degree[p]) sh.shared[p] = 1;
  PetscFunctionReturn(0);
}

// The owner's verdict on every shared edge: the marks are or-ed into the owner and sent back. Returns the
// edges whose mark this rank learnt from others.
PetscErrorCode SyncMarks(const Coarse &m, const Sharing &sh, std::vector<char> &mark, std::vector<PetscInt> &learnt)
{
  PetscFunctionBeginUser;
  learnt.clear();
  if (!sh.sf) PetscFunctionReturn(0);
  std::vector<int> leaf(m.pE, 0), root, back;
  for (PetscInt e = 0; e < m.NumEdges(); ++e) leaf[m.eS + e] = mark[e];
  root = leaf;
  PetscCall(PetscSFReduceBegin(sh.sf, MPI_INT, leaf.data(), root.data(), MPI_MAX));
  PetscCall(PetscSFReduceEnd(sh.sf, MPI_INT, leaf.data(), root.data(), MPI_MAX));
  back = root;
  PetscCall(PetscSFBcastBegin(sh.sf, MPI_INT, root.data(), back.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sh.sf, MPI_INT, root.data(), back.data(), MPI_REPLACE));
  for (PetscInt e = 0; e < m.NumEdges(); ++e)
    if (back[m.eS + e] && !mark[e]) {
      mark[e] = 1;
      learnt.push_back(e);
    }
  PetscFunctionReturn(0);
}

// A tetrahedron is thin if a cut makes an angle below 10 degrees (cos^2 above 0.97), even with a safe
// longest edge (see the top of the file). Kuhn tetrahedra of a cube and their bisections are not, as
// measured: paper-5.1-3d and manufactured-3d refine as before over three steps (with 30 degrees, or with
// Rivara's rule plus the unsafe-edge clause at 30 degrees, their meshes changed from the third step).
constexpr PetscReal kCos2Flat = 0.97;

// Which bisections of cell c would make a flat child: bit 4 k + i when in the face of c with edge k (of
// kPair) and vertex i, the median from i to the edge's midpoint makes an angle below 30 degrees with the
// edge (cos^2 above 3/4); *flat: whether one makes an angle below 10 degrees (kCos2Flat). Bisecting an
// edge makes the angles of these medians with it at the midpoint and keeps the faces' other angles
// (split or whole), so a safe bisection makes no face angle above max(parent's, 150 degrees) in the
// faces it splits. The sums are symmetric in the edge's two vertices (their difference flips sign
// exactly, their sum is the same), so every rank decides alike from the same coordinates.
int UnsafeCuts(const Coarse &m, PetscInt c, bool *flat)
{
  const PetscInt *cv   = &m.cellVerts[(m.dim + 1) * c];
  int             bits = 0;
  *flat                = false;
  for (PetscInt k = 0; k < m.nce; ++k)
    for (PetscInt i = 0; i <= m.dim; ++i) {
      if (i == kPair[k][0] || i == kPair[k][1]) continue;
      const PetscReal *a = &m.x[3 * cv[kPair[k][0]]], *b = &m.x[3 * cv[kPair[k][1]]], *p = &m.x[3 * cv[i]];
      PetscReal        uu = 0, ww = 0, uw = 0;
      for (int d = 0; d < 3; ++d) {
        const PetscReal u = b[d] - a[d], w = 0.5 * (a[d] + b[d]) - p[d];
        uu += u * u, ww += w * w, uw += u * w;
      }
      if (uw * uw > 0.75 * uu * ww) bits |= 1 << (4 * k + i);
      *flat = *flat || uw * uw > kCos2Flat * uu * ww;
    }
  return bits;
}

// The edges (bits k of kPair) that the rule of a thin cell c (see CloseMarks) adds to its marked
// edges `marked`, from its unsafe cuts (UnsafeCuts): Horn clauses, so the closure stays monotone (more
// marks never add fewer edges) and its least fixed point is independent of the order.
//  - An edge unsafe in a face, or two marked edges of a face, need that face cut by all its edges. In
//    2D the face is the cell. In 3D the face alone (a cone from the opposite vertex over the face's four
//    children) when its edges are safe in the other faces with them: the faces through the vertex are
//    cut once, safely. (A flat Kuhn tetrahedron's steep faces are such. Cutting all six edges instead
//    refined every cell of unit_bisect's flat box at every step, 384 -> 3072 -> 24576 cells: a marked
//    horizontal edge lies in a steep face in which it is unsafe, and every tetrahedron with it then
//    marked the other horizontal edges.) Otherwise the whole cell.
//  - Two opposite marked edges (3D) need all edges.
// What is left is no mark, one safe edge, a face, or all edges.
int ThinRule(const Coarse &m, int unsafe, int marked)
{
  const int all = (1 << m.nce) - 1;
  // The edges of the face opposite vertex f of a tetrahedron if they are safe in the other faces with
  // them, else all.
  const auto face = [&](PetscInt f) {
    if (m.dim == 2) return all;
    int edges = 0;
    for (PetscInt k = 0; k < 6; ++k)
      if (kPair[k][0] != f && kPair[k][1] != f) {
        if (unsafe >> (4 * k + f) & 1) return all;
        edges |= 1 << k;
      }
    return edges;
  };
  int add = 0;
  for (PetscInt k = 0; k < m.nce; ++k) {
    if (!(marked >> k & 1)) continue;
    for (PetscInt i = 0; i <= m.dim; ++i)
      if (unsafe >> (4 * k + i) & 1) add |= face(6 - kPair[k][0] - kPair[k][1] - i); // 2D: any
    for (PetscInt l = k + 1; l < m.nce; ++l) {
      if (!(marked >> l & 1)) continue;
      const int verts = 1 << kPair[k][0] | 1 << kPair[k][1] | 1 << kPair[l][0] | 1 << kPair[l][1];
      add |= verts == 15 ? all : face(kOpposite[verts]);
    }
  }
  return add;
}

// The closure of the marks (see the top of the file), with shared edges agreed between ranks.
PetscErrorCode CloseMarks(MPI_Comm comm, const Coarse &m, const Sharing &sh, const EdgeOrder &before, const std::vector<char> &marked, bool allEdges, std::vector<char> &mark)
{
  const PetscInt nc = m.NumCells(), ne = m.NumEdges();
  std::vector<PetscInt> longest(nc), starStart(ne + 1, 0), star(m.nce * nc), work;
  std::vector<int>      unsafe(nc, -1); // UnsafeCuts, found when the closure first reaches the cell
  std::vector<char>     rivara(nc), first(nc);
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < nc; ++c) {
    const PetscInt *edges = &m.cellEdges[m.nce * c];
    first[c]              = (char)(std::min_element(edges, edges + m.nce, before) - edges);
    longest[c]            = edges[(int)first[c]];
    for (PetscInt k = 0; k < m.nce; ++k) ++starStart[edges[k] + 1];
  }
  std::partial_sum(starStart.begin(), starStart.end(), starStart.begin());
  {
    std::vector<PetscInt> fill(starStart.begin(), starStart.end() - 1);
    for (PetscInt c = 0; c < nc; ++c)
      for (PetscInt k = 0; k < m.nce; ++k) star[fill[m.cellEdges[m.nce * c + k]]++] = c;
  }
  mark.assign(ne, 0);
  const auto markEdge = [&](PetscInt e) {
    if (!mark[e]) mark[e] = 1, work.push_back(e);
  };
  // The rule of cell c with a marked edge: Rivara's, or ThinRule.
  const auto close = [&](PetscInt c) {
    if (unsafe[c] < 0) {
      bool flat;
      unsafe[c] = UnsafeCuts(m, c, &flat);
      rivara[c] = !(unsafe[c] >> 4 * first[c] & 15) && !(m.dim == 3 && flat);
    }
    if (rivara[c]) return markEdge(longest[c]);
    const PetscInt *edges = &m.cellEdges[m.nce * c];
    int             marks = 0;
    for (PetscInt k = 0; k < m.nce; ++k) marks |= mark[edges[k]] << k;
    const int add = ThinRule(m, unsafe[c], marks);
    for (PetscInt k = 0; k < m.nce; ++k)
      if (add >> k & 1) markEdge(edges[k]);
  };
  for (PetscInt c = 0; c < nc; ++c)
    if (marked[c]) {
      if (allEdges)
        for (PetscInt k = 0; k < m.nce; ++k) markEdge(m.cellEdges[m.nce * c + k]);
      else markEdge(longest[c]);
    }
  for (;;) {
    while (!work.empty()) {
      const PetscInt e = work.back();
      work.pop_back();
      for (PetscInt i = starStart[e]; i < starStart[e + 1]; ++i) close(star[i]);
    }
    std::vector<PetscInt> learnt;
    PetscCall(SyncMarks(m, sh, mark, learnt));
    work = learnt;
    int any = !work.empty();
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_LOR, comm));
    if (!any) break;
  }
  PetscFunctionReturn(0);
}

// The children of the coarse cells of one rank, by the local ids of their vertices: coarse vertex v is
// v - vS, the midpoint of edge e is nV + e - eS.
struct Children {
  PetscInt              nv = 0;  // vertices per child
  std::vector<PetscInt> verts;   // nv per child, local ids
  std::vector<char>     on;      // nv per child: the parent's vertices (bit k: its vertex k) that the
                                 // child's vertex lies on (one: that vertex; two: their edge's midpoint)
  std::vector<PetscInt> start;   // children of coarse cell c: start[c] .. start[c + 1]
  std::unique_ptr<PetscReal[]> x; // 3 per local id (midpoints of unmarked edges unset, unused)
};

PetscReal Det(const Coarse &m, const PetscReal *x, const PetscInt *v)
{
  PetscReal J[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  for (PetscInt k = 0; k < m.dim; ++k)
    for (PetscInt d = 0; d < m.dim; ++d) J[k][d] = x[3 * v[k + 1] + d] - x[3 * v[0] + d];
  if (m.dim == 2) return J[0][0] * J[1][1] - J[0][1] * J[1][0];
  return J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
}

// Cuts every cell by its marked edges in the global order, and turns each child to PETSc's orientation
// (triangles counter-clockwise, tetrahedra with det[v1 - v0, v2 - v0, v3 - v0] < 0): with the cones of
// MakeCones, cells of positive Jacobian. Most cells of an adaptive step have no marked edge: such a cell
// is its own only child, written without the pieces' lists.
void Cut(const Coarse &m, const EdgeOrder &before, const std::vector<char> &mark, Children &ch)
{
  const PetscInt nV = m.NumVertices(), nb = m.dim + 1, nc = m.NumCells();
  ch.nv = nb;
  // Coordinates of the coarse vertices and of the midpoints of marked edges (the others are never read,
  // and are left unwritten: on a mesh of millions of edges, writing them cost more than cutting).
  ch.x.reset(new PetscReal[3 * (nV + m.NumEdges())]);
  std::copy(m.x.begin(), m.x.end(), ch.x.get());
  for (PetscInt e = 0; e < m.NumEdges(); ++e)
    if (mark[e])
      for (int d = 0; d < 3; ++d) ch.x[3 * (nV + e) + d] = 0.5 * (m.x[3 * m.edgeVerts[2 * e] + d] + m.x[3 * m.edgeVerts[2 * e + 1] + d]);
  // A child's vertices (local ids) and the parent's vertices each lies on (bits, see Children::on).
  struct Piece {
    std::array<PetscInt, 4> v;
    std::array<char, 4>     on;
  };
  const PetscReal sign = m.dim == 2 ? 1 : -1;
  const auto      emit = [&](Piece &t) {
    if (Det(m, ch.x.get(), t.v.data()) * sign < 0) std::swap(t.v[0], t.v[1]), std::swap(t.on[0], t.on[1]);
    for (PetscInt k = 0; k < nb; ++k) ch.verts.push_back(t.v[k]), ch.on.push_back(t.on[k]);
  };
  // Room for the children: a cell cut by all its edges has 2^(d) of them, at most.
  PetscInt cutCells = 0;
  for (PetscInt c = 0; c < nc; ++c) {
    bool any = false;
    for (PetscInt k = 0; k < m.nce; ++k) any |= mark[m.cellEdges[m.nce * c + k]] != 0;
    cutCells += any;
  }
  const size_t room = (size_t)nb * (nc + ((1 << m.dim) - 1) * cutCells);
  ch.verts.clear(), ch.on.clear(), ch.start.clear();
  ch.verts.reserve(room), ch.on.reserve(room), ch.start.reserve(nc + 1);
  ch.start.push_back(0);
  std::vector<Piece> cur, next;
  PetscInt           cuts[6];
  for (PetscInt c = 0; c < nc; ++c) {
    Piece whole{{0, 0, 0, 0}, {1, 2, 4, 8}};
    std::copy(&m.cellVerts[nb * c], &m.cellVerts[nb * c] + nb, whole.v.begin());
    PetscInt ncuts = 0;
    for (PetscInt k = 0; k < m.nce; ++k)
      if (mark[m.cellEdges[m.nce * c + k]]) cuts[ncuts++] = m.cellEdges[m.nce * c + k];
    if (ncuts == 0) {
      emit(whole);
      ch.start.push_back((PetscInt)(ch.verts.size() / nb));
      continue;
    }
    for (PetscInt i = 1; i < ncuts; ++i) // at most six: by insertion
      for (PetscInt j = i; j > 0 && before(cuts[j], cuts[j - 1]); --j) std::swap(cuts[j], cuts[j - 1]);
    cur.assign(1, whole);
    for (PetscInt i = 0; i < ncuts; ++i) {
      const PetscInt e = cuts[i], a = m.edgeVerts[2 * e], b = m.edgeVerts[2 * e + 1], mid = nV + e;
      next.clear();
      for (const Piece &t : cur) {
        const auto ia = std::find(t.v.begin(), t.v.begin() + nb, a) - t.v.begin(), ib = std::find(t.v.begin(), t.v.begin() + nb, b) - t.v.begin();
        if (ia == nb || ib == nb) {
          next.push_back(t);
          continue;
        }
        const char on = t.on[ia] | t.on[ib];
        next.push_back(t), next.back().v[ia] = mid, next.back().on[ia] = on;
        next.push_back(t), next.back().v[ib] = mid, next.back().on[ib] = on;
      }
      cur.swap(next);
    }
    for (Piece &t : cur) emit(t);
    ch.start.push_back((PetscInt)(ch.verts.size() / nb));
  }
}

// The coarse point of a fine vertex (local id): the vertex itself, or the edge of a midpoint.
PetscInt VertexCarrier(const Coarse &m, PetscInt id) { return id < m.NumVertices() ? m.vS + id : m.eS + id - m.NumVertices(); }

// Global numbers of the fine vertices by local id (-1: midpoint of an unmarked edge): owned vertices and
// midpoints of owned edges are numbered contiguously per rank, the others get their owner's number.
PetscErrorCode NumberVertices(DM dm, const Coarse &m, const Sharing &sh, const std::vector<char> &mark, std::vector<PetscInt> &gnum)
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)dm);
  const PetscInt nV   = m.NumVertices(), nId = nV + m.NumEdges();
  PetscFunctionBeginUser;
  const auto used = [&](PetscInt id) { return id < nV || mark[id - nV]; };
  PetscInt   n = 0, offset = 0;
  for (PetscInt id = 0; id < nId; ++id) n += used(id) && sh.leaf[VertexCarrier(m, id)] < 0;
  PetscCallMPI(MPI_Exscan(&n, &offset, 1, MPIU_INT, MPI_SUM, comm));
  PetscMPIInt r;
  PetscCallMPI(MPI_Comm_rank(comm, &r));
  if (r == 0) offset = 0;
  std::vector<PetscInt> root(m.pE, -1);
  for (PetscInt id = 0; id < nId; ++id)
    if (used(id) && sh.leaf[VertexCarrier(m, id)] < 0) root[VertexCarrier(m, id)] = offset++;
  std::vector<PetscInt> all = root;
  if (sh.sf) {
    PetscCall(PetscSFBcastBegin(sh.sf, MPIU_INT, root.data(), all.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sh.sf, MPIU_INT, root.data(), all.data(), MPI_REPLACE));
  }
  gnum.assign(nId, -1);
  for (PetscInt id = 0; id < nId; ++id)
    if (used(id)) gnum[id] = all[VertexCarrier(m, id)];
  PetscFunctionReturn(0);
}

// The fine mesh of one rank. Points: the children (cells) in order, the vertices (numbered by increasing
// global number), then in 3D the triangles, then the edges (both in the order FinePoints meets them).
// Edges and triangles store their vertices by increasing number.
struct Fine {
  PetscInt              dim = 0, nc = 0, nv = 0, nt = 0, ne = 0;
  std::vector<PetscInt> vertexOf, vertexId;     // local id -> fine vertex (-1: none), and back
  std::vector<PetscInt> edgeVerts, triVerts;     // 2, 3 fine vertices per point
  std::vector<PetscInt> edgeCarrier, triCarrier; // the coarse point it lies in (-1: inside a cell)
  std::vector<PetscInt> childEdge, childTri;     // per child: the edge of pair k, the triangle of face k (3D)
  std::vector<PetscInt> parentOf;                // per child: the coarse cell (as c - cStart)
  std::vector<PetscInt> childVerts;              // per child: its fine vertices (in Children::verts' order)
  std::vector<PetscInt> triSlot;                 // per triangle: a child face that is it (4 * child + face)
  PetscInt              Vertex(PetscInt i) const { return nc + i; }
  PetscInt              Tri(PetscInt j) const { return nc + nv + j; }
  PetscInt              Edge(PetscInt j) const { return nc + nv + nt + j; }
  PetscInt              End() const { return nc + nv + nt + ne; }
  // The edges (a, b), (b, c), (c, a) of triangle j (a < b < c), from a child that has it.
  void TriEdges(PetscInt j, PetscInt edge[3]) const
  {
    const PetscInt slot = triSlot[j], t = slot / 4, *r = kRefFace[slot % 4], *v = &childVerts[4 * t], *abc = &triVerts[3 * j];
    int            bit[3]; // of a, b, c: their vertex in the child
    for (PetscInt i = 0; i < 3; ++i) bit[v[r[i]] == abc[0] ? 0 : v[r[i]] == abc[1] ? 1 : 2] = 1 << r[i];
    for (PetscInt e = 0; e < 3; ++e) edge[e] = childEdge[6 * t + kPairOf[bit[e] | bit[(e + 1) % 3]]];
  }
};

// The distinct edges or triangles (their vertices sorted; 2 or 3 used) that the children of one coarse
// cell have in one carrier, and for each occurrence its item and its slot in Fine::childEdge or
// Fine::childTri. A cell has at most 8 children (see Cut): at most 48 occurrences.
struct CarrierItems {
  using Key                    = std::array<PetscInt, 3>;
  static constexpr int kMaxOcc = 48;
  int                  nOcc = 0, nKeys = 0;
  Key                  keys[kMaxOcc];
  int                  item[kMaxOcc];
  PetscInt             slot[kMaxOcc];
  void                 Clear() { nOcc = nKeys = 0; }
  void                 Add(const Key &key, PetscInt at)
  {
    int i = 0;
    while (i < nKeys && (keys[i][0] != key[0] || keys[i][1] != key[1] || keys[i][2] != key[2])) ++i; // a few at most
    if (i == nKeys) keys[nKeys++] = key;
    item[nOcc] = i, slot[nOcc++] = at;
  }
};

// Numbers the n items of one carrier, given in the order of their numbers (nvk vertices each). first: the
// carrier's first number, -1 until a cell meets it (then the items are new: they get numbers from the
// end of `carriers` on, their vertices and carrier, and *fresh is set); else the carrier's other cell
// numbered them, which must have met the same items.
PetscErrorCode NumberItems(const CarrierItems::Key *items, int n, PetscInt carrier, PetscInt nvk, PetscInt &first, std::vector<PetscInt> &verts, std::vector<PetscInt> &carriers, bool *fresh)
{
  PetscFunctionBeginUser;
  *fresh = first < 0;
  if (first < 0) {
    first = (PetscInt)carriers.size();
    carriers.resize(first + n, carrier);
    for (int i = 0; i < n; ++i) verts.insert(verts.end(), items[i].begin(), items[i].begin() + nvk);
  } else {
    const PetscInt end  = first + n; // the other cell's items end there too: no more of this carrier follow
    bool           same = end == (PetscInt)carriers.size() || (end < (PetscInt)carriers.size() && carriers[end] != carrier);
    for (int i = 0; i < n && same; ++i) same = carriers[first + i] == carrier && std::equal(items[i].begin(), items[i].begin() + nvk, &verts[nvk * (first + i)]);
    PetscCheck(same, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: coarse point %" PetscInt_FMT " is cut differently in its two cells", carrier);
  }
  PetscFunctionReturn(0);
}

// Numbers the items of one carrier (NumberItems) and writes the numbers into their slots. A carrier shared
// by two cells (a coarse face) numbers its items in the order of their vertices, so that both give each
// the same number; a cell's interior in the order met.
PetscErrorCode Place(const CarrierItems &items, bool shared, PetscInt carrier, PetscInt nvk, PetscInt &first, std::vector<PetscInt> &verts, std::vector<PetscInt> &carriers, PetscInt *slots, bool *fresh)
{
  const int          n = items.nKeys;
  int                rank[CarrierItems::kMaxOcc]; // of each item in the carrier
  CarrierItems::Key  ordered[CarrierItems::kMaxOcc];
  PetscFunctionBeginUser;
  for (int i = 0; i < n; ++i) {
    rank[i] = i;
    if (shared && n > 1) {
      rank[i] = 0;
      for (int j = 0; j < n; ++j) rank[i] += items.keys[j] < items.keys[i];
    }
    ordered[rank[i]] = items.keys[i];
  }
  PetscCall(NumberItems(ordered, n, carrier, nvk, first, verts, carriers, fresh));
  for (int o = 0; o < items.nOcc; ++o) slots[items.slot[o]] = first + rank[items.item[o]];
  PetscFunctionReturn(0);
}

// The fine points of one rank: vertices, then the edges and triangles of the children, each with its
// carrier, the coarse point it lies in. That is known from the parent's vertices its vertices lie on
// (bits, see Children::on): two make the coarse edge between them (a fine vertex is a coarse vertex or the
// midpoint of a coarse edge, so such a point lies on that edge), three in 3D the face they span, else the
// cell's interior. An edge or triangle is found from its carrier, not by sorting all of them: on a
// coarse edge it is that edge or one of its halves; inside a coarse face it is met by the children of the
// face's cells on this rank, which both number the face's items in the order of their vertices; inside a
// cell by that cell's children only. Edges and triangles are numbered as the children, coarse cell by
// coarse cell, first meet them, which keeps the points of a region of the mesh close in the chart (and
// the rows of a Crouzeix-Raviart matrix close). ch.verts becomes f.childVerts.
PetscErrorCode FinePoints(const Coarse &m, Children &ch, const std::vector<char> &mark, const std::vector<PetscInt> &gnum, Fine &f)
{
  using Key         = CarrierItems::Key;
  const PetscInt nb = ch.nv, nce = m.nce;
  PetscFunctionBeginUser;
  f.dim = m.dim, f.nc = (PetscInt)ch.verts.size() / nb;
  // The vertices by global number. A rank numbers its own in the order of their ids, so the numbers come
  // mostly ascending: the ascending run is kept, the few others sorted and merged into it.
  std::vector<std::pair<PetscInt, PetscInt>> byNumber, rising, others;
  rising.reserve(gnum.size());
  for (PetscInt id = 0; id < (PetscInt)gnum.size(); ++id) {
    if (gnum[id] < 0) continue;
    if (rising.empty() || gnum[id] > rising.back().first) rising.push_back({gnum[id], id});
    else others.push_back({gnum[id], id});
  }
  std::sort(others.begin(), others.end());
  byNumber.resize(rising.size() + others.size());
  std::merge(rising.begin(), rising.end(), others.begin(), others.end(), byNumber.begin());
  f.nv = (PetscInt)byNumber.size();
  f.vertexOf.assign(gnum.size(), -1);
  f.vertexId.resize(f.nv);
  for (PetscInt i = 0; i < f.nv; ++i) f.vertexOf[byNumber[i].second] = i, f.vertexId[i] = byNumber[i].second;
  f.parentOf.resize(f.nc);
  for (PetscInt c = 0; c < m.NumCells(); ++c)
    for (PetscInt k = ch.start[c]; k < ch.start[c + 1]; ++k) f.parentOf[k] = c;
  for (PetscInt &v : ch.verts) v = f.vertexOf[v]; // in place (ch.verts is not read after this): no fresh memory
  f.childVerts.swap(ch.verts);
  const PetscInt *cv = f.childVerts.data();
  const char     *on = ch.on.data();

  // The first number of the fine edges on each coarse edge, and of the edges and triangles inside each
  // coarse face (3D); -1: not met yet.
  std::vector<PetscInt> onEdge(m.NumEdges(), -1), inFaceE(m.dim == 3 ? m.fE - m.fS : 0, -1), inFaceT(inFaceE);
  f.childEdge.assign(nce * f.nc, -1);
  f.childTri.assign(m.dim == 3 ? 4 * f.nc : 0, -1);
  f.edgeVerts.clear(), f.edgeCarrier.clear(), f.triVerts.clear(), f.triCarrier.clear(), f.triSlot.clear();
  f.edgeVerts.reserve(2 * nce * f.nc), f.edgeCarrier.reserve(nce * f.nc); // bounds: pages beyond the edges stay untouched
  if (m.dim == 3) f.triVerts.reserve(12 * f.nc), f.triSlot.reserve(4 * f.nc), f.triCarrier.reserve(4 * f.nc);
  CarrierItems faceItems[4], cellItems;
  bool         fresh;
  // A child face's vertices, sorted (slot: 4 * child + face), and the child faces the new triangles among
  // `items` keep (see Fine::TriEdges).
  const auto keyOf = [&](PetscInt slot) {
    const PetscInt *r = kRefFace[slot % 4], *v = cv + 4 * (slot / 4);
    Key             key = {v[r[0]], v[r[1]], v[r[2]]};
    if (key[0] > key[1]) std::swap(key[0], key[1]);
    if (key[1] > key[2]) std::swap(key[1], key[2]);
    if (key[0] > key[1]) std::swap(key[0], key[1]);
    return key;
  };
  const auto slotsOf = [&](const CarrierItems &items) {
    f.triSlot.resize(f.triCarrier.size());
    for (int o = 0; o < items.nOcc; ++o) f.triSlot[f.childTri[items.slot[o]]] = items.slot[o];
  };
  // The edges or triangles of cell c's children that are not whole coarse points, by carrier: a coarse
  // face of c (3D), or c's interior.
  const auto group = [&](const Key &key, PetscInt slot, int bits) {
    if (m.dim == 3 && kOpposite[bits] >= 0) faceItems[kOpposite[bits]].Add(key, slot);
    else cellItems.Add(key, slot);
  };
  // Numbers the grouped items (nvk vertices each) into verts, carriers and slots; inFace: the first number of
  // each coarse face's items. onFresh(items) for each group numbered for the first time.
  const auto placeGroups = [&](PetscInt c, PetscInt nvk, std::vector<PetscInt> &inFace, std::vector<PetscInt> &verts, std::vector<PetscInt> &carriers, PetscInt *slots,
                               const auto &onFresh) -> PetscErrorCode {
    PetscFunctionBeginUser;
    for (PetscInt i = 0; i < 4 && m.dim == 3; ++i) {
      if (!faceItems[i].nKeys) continue;
      const PetscInt F = m.cellFaces[4 * c + i];
      PetscCall(Place(faceItems[i], true, F, nvk, inFace[F - m.fS], verts, carriers, slots, &fresh));
      if (fresh) onFresh(faceItems[i]);
    }
    if (cellItems.nKeys) {
      PetscInt inCell = -1;
      PetscCall(Place(cellItems, false, -1, nvk, inCell, verts, carriers, slots, &fresh));
      onFresh(cellItems);
    }
    PetscFunctionReturn(0);
  };
  for (PetscInt c = 0; c < m.NumCells(); ++c) {
    // Edges: those on coarse edges at once, the others by carrier.
    PetscCheck(ch.start[c + 1] - ch.start[c] <= 8, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: %" PetscInt_FMT " children", ch.start[c + 1] - ch.start[c]);
    // The fine edges on the cell's coarse edges: the whole edge, or its halves (the first one has the
    // edge's first vertex), made when first met.
    PetscInt onFirst[6], firstVertex[6];
    bool     halved[6];
    for (PetscInt p = 0; p < nce; ++p) {
      const PetscInt E = m.cellEdges[nce * c + p], A = f.vertexOf[m.edgeVerts[2 * E]];
      if (onEdge[E] < 0) {
        const PetscInt B = f.vertexOf[m.edgeVerts[2 * E + 1]], M = mark[E] ? f.vertexOf[m.NumVertices() + E] : -1;
        onEdge[E]        = (PetscInt)f.edgeCarrier.size();
        const PetscInt ends[3] = {A, mark[E] ? M : B, B};
        for (PetscInt h = 0; h < (mark[E] ? 2 : 1); ++h) {
          f.edgeVerts.push_back(std::min(ends[h], ends[h + 1])), f.edgeVerts.push_back(std::max(ends[h], ends[h + 1]));
          f.edgeCarrier.push_back(m.eS + E);
        }
      }
      onFirst[p] = onEdge[E], firstVertex[p] = A, halved[p] = mark[E];
    }
    for (auto &items : faceItems) items.Clear();
    cellItems.Clear();
    for (PetscInt t = ch.start[c]; t < ch.start[c + 1]; ++t)
      for (PetscInt k = 0; k < nce; ++k) {
        const PetscInt a = cv[nb * t + kPair[k][0]], b = cv[nb * t + kPair[k][1]], slot = nce * t + k;
        const int      bits = on[nb * t + kPair[k][0]] | on[nb * t + kPair[k][1]], p = kPairOf[bits];
        if (p >= 0) f.childEdge[slot] = onFirst[p] + (halved[p] && a != firstVertex[p] && b != firstVertex[p]);
        else group({std::min(a, b), std::max(a, b), -1}, slot, bits);
      }
    PetscCall(placeGroups(c, 2, inFaceE, f.edgeVerts, f.edgeCarrier, f.childEdge.data(), [](const CarrierItems &) {}));
    if (m.dim == 2) continue;
    // Triangles, each with a child face that is it (for its edges, Fine::TriEdges).
    if (ch.start[c + 1] - ch.start[c] == 1) { // an uncut cell (most of them): its faces are whole coarse faces
      const PetscInt t = ch.start[c];
      for (PetscInt k = 0; k < 4; ++k) {
        const PetscInt *r = kRefFace[k], F = m.cellFaces[4 * c + kOpposite[on[4 * t + r[0]] | on[4 * t + r[1]] | on[4 * t + r[2]]]];
        const Key       key = keyOf(4 * t + k);
        PetscCall(NumberItems(&key, 1, F, 3, inFaceT[F - m.fS], f.triVerts, f.triCarrier, &fresh));
        f.childTri[4 * t + k] = inFaceT[F - m.fS];
        if (fresh) f.triSlot.push_back(4 * t + k);
      }
      continue;
    }
    for (auto &items : faceItems) items.Clear();
    cellItems.Clear();
    for (PetscInt t = ch.start[c]; t < ch.start[c + 1]; ++t)
      for (PetscInt k = 0; k < 4; ++k) {
        const PetscInt *r = kRefFace[k];
        group(keyOf(4 * t + k), 4 * t + k, on[4 * t + r[0]] | on[4 * t + r[1]] | on[4 * t + r[2]]);
      }
    PetscCall(placeGroups(c, 3, inFaceT, f.triVerts, f.triCarrier, f.childTri.data(), slotsOf));
  }
  f.ne = (PetscInt)f.edgeCarrier.size(), f.nt = (PetscInt)f.triCarrier.size();
  PetscFunctionReturn(0);
}

// The cones and orientations of the children: their faces in PETSc's reference order.
PetscErrorCode CellCones(const Fine &f, PetscInt *cones, PetscInt *ornts)
{
  const PetscInt nb = f.dim + 1;
  PetscFunctionBeginUser;
  // A child's face k lists the triangle's vertices (a < b < c) in some order: the orientation depends only
  // on which of them comes first and second (code 3 * rank of the first + rank of the second).
  PetscInt orientation[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  if (f.dim == 3) PetscCall(TriangleOrientations(orientation));
  for (PetscInt t = 0; t < f.nc; ++t) {
    PetscInt       *cone = cones + nb * t, *ornt = ornts + nb * t;
    const PetscInt *v    = &f.childVerts[nb * t];
    if (f.dim == 2)
      for (PetscInt k = 0; k < 3; ++k) {
        cone[k] = f.Edge(f.childEdge[3 * t + k]);
        ornt[k] = v[kPair[k][0]] < v[kPair[k][1]] ? 0 : -1;
      }
    else
      for (PetscInt k = 0; k < 4; ++k) {
        const PetscInt  tri = f.childTri[4 * t + k], *r = kRefFace[k];
        const PetscInt *has  = &f.triVerts[3 * tri];
        const auto      rank = [has](PetscInt x) { return x == has[0] ? 0 : x == has[1] ? 1 : 2; };
        cone[k]              = f.Tri(tri);
        ornt[k]              = orientation[3 * rank(v[r[0]]) + rank(v[r[1]])];
      }
  }
  PetscFunctionReturn(0);
}

// The plex's cones, supports and depth strata, written straight into its arrays and sections: what
// DMPlexSetConeSize, DMPlexSetCone, DMPlexSymmetrize and DMPlexStratify make (the last two as the uniform
// refinement makes them, SymmetrizeCones and SetDepthStrata), but without their calls and checks per point
// and cone entry, which made them most of the refinement. Cones: an edge from its lower to its
// higher vertex; a triangle (a, b, c), a < b < c, with edges (a, b), (b, c), (c, a), the last reversed;
// a child's faces in PETSc's reference order. The depth of every point is known from its stratum in the
// chart (cells, vertices, triangles, edges).
PetscErrorCode BuildPlex(DM dm, const Fine &f)
{
  const PetscInt nb = f.dim + 1, end = f.End();
  PetscInt       size;
  PetscFunctionBeginUser;
  PetscCall(DMPlexSetChart(dm, 0, end));
  DM_Plex     *mesh = (DM_Plex *)dm->data;
  PetscSection cs   = mesh->coneSection;
  PetscCheck(cs->pStart == 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: unexpected chart");
  for (PetscInt p = 0; p < end; ++p) cs->atlasDof[p] = p < f.nc ? nb : p < f.Tri(0) ? 0 : p < f.Edge(0) ? 3 : 2;
  cs->maxDof = PETSC_MIN_INT; // recomputed when asked for (see PetscSectionInvalidateMaxDof_Internal)
  PetscCall(DMSetUp(dm));     // sets up the cone section, allocates the cones (the supports: SymmetrizeCones)
  PetscCall(PetscSectionGetStorageSize(cs, &size));
  PetscCheck(size == nb * f.nc + 3 * f.nt + 2 * f.ne, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: %" PetscInt_FMT " cone entries", size);
  PetscCall(CellCones(f, mesh->cones, mesh->coneOrientations));
  PetscInt *tcone = mesh->cones + nb * f.nc, *tornt = mesh->coneOrientations + nb * f.nc;
  for (PetscInt j = 0; j < f.nt; ++j) {
    PetscInt edge[3];
    f.TriEdges(j, edge);
    for (PetscInt e = 0; e < 3; ++e) tcone[3 * j + e] = f.Edge(edge[e]), tornt[3 * j + e] = e == 2 ? -1 : 0;
  }
  PetscInt *econe = tcone + 3 * f.nt, *eornt = tornt + 3 * f.nt;
  for (PetscInt j = 0; j < 2 * f.ne; ++j) econe[j] = f.Vertex(f.edgeVerts[j]), eornt[j] = 0;
  PetscCall(SymmetrizeCones(dm));
  // Depth strata, as DMPlexStratify makes them: vertices, edges, triangles (3D), cells.
  std::vector<std::array<PetscInt, 2>> depthRanges = {{f.Vertex(0), f.Vertex(f.nv)}, {f.Edge(0), end}};
  if (f.dim == 3) depthRanges.push_back({f.Tri(0), f.Tri(f.nt)});
  depthRanges.push_back({0, f.nc});
  PetscCall(SetDepthStrata(dm, depthRanges));
  PetscFunctionReturn(0);
}

// The point star forest: the fine points lying in a shared coarse point are shared with the same ranks,
// with the root on the coarse point's root rank. Both sides list them in the same order (by depth, then by
// the global numbers of their vertices), so the owner's list, sent through the coarse forest, pairs them.
PetscErrorCode SetPointSF(DM coarse, DM dm, const Coarse &m, const Sharing &sh, const std::vector<PetscInt> &gnum, const Fine &f)
{
  MPI_Comm comm = PetscObjectComm((PetscObject)coarse);
  PetscSF  fsf;
  PetscFunctionBeginUser;
  if (!sh.sf) PetscFunctionReturn(0);
  // (carrier, depth, global vertex numbers, fine point) of every fine point in a shared coarse point
  using Entry = std::tuple<PetscInt, PetscInt, std::array<PetscInt, 3>, PetscInt>;
  std::vector<Entry> entries;
  const auto         global = [&](PetscInt i) { return gnum[f.vertexId[i]]; };
  for (PetscInt i = 0; i < f.nv; ++i) {
    const PetscInt q = VertexCarrier(m, f.vertexId[i]);
    if (sh.shared[q]) entries.push_back({q, 0, {global(i), -1, -1}, f.Vertex(i)});
  }
  for (PetscInt j = 0; j < f.ne; ++j) {
    const PetscInt q = f.edgeCarrier[j];
    if (q >= 0 && sh.shared[q]) entries.push_back({q, 1, {global(f.edgeVerts[2 * j]), global(f.edgeVerts[2 * j + 1]), -1}, f.Edge(j)});
  }
  for (PetscInt j = 0; j < f.nt; ++j) {
    const PetscInt q = f.triCarrier[j];
    if (q >= 0 && sh.shared[q]) entries.push_back({q, 2, {global(f.triVerts[3 * j]), global(f.triVerts[3 * j + 1]), global(f.triVerts[3 * j + 2])}, f.Tri(j)});
  }
  std::sort(entries.begin(), entries.end());
  // Groups by carrier; the owner's groups get compact numbers, which the leaves learn.
  constexpr PetscInt    kBlock = 8; // a count and at most 7 points (a face: 4 triangles and 3 edges)
  std::vector<PetscInt> groupStart, compact(m.pE, -1), remoteCompact;
  for (size_t i = 0; i < entries.size(); ++i)
    if (i == 0 || std::get<0>(entries[i]) != std::get<0>(entries[i - 1])) groupStart.push_back((PetscInt)i);
  groupStart.push_back((PetscInt)entries.size());
  std::vector<PetscInt> blocks;
  PetscInt              numRoots = 0, numLeaves = 0;
  for (size_t g = 0; g + 1 < groupStart.size(); ++g) {
    const PetscInt q = std::get<0>(entries[groupStart[g]]), n = groupStart[g + 1] - groupStart[g];
    PetscCheck(n < kBlock, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: %" PetscInt_FMT " fine points in coarse point %" PetscInt_FMT, n, q);
    if (sh.leaf[q] >= 0) {
      ++numLeaves;
      continue;
    }
    compact[q] = numRoots++;
    blocks.push_back(n);
    for (PetscInt i = 0; i < kBlock - 1; ++i) blocks.push_back(i < n ? std::get<3>(entries[groupStart[g] + i]) : -1);
  }
  remoteCompact = compact;
  PetscCall(PetscSFBcastBegin(sh.sf, MPIU_INT, compact.data(), remoteCompact.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sh.sf, MPIU_INT, compact.data(), remoteCompact.data(), MPI_REPLACE));
  std::vector<PetscSFNode> groupRoots;
  for (size_t g = 0; g + 1 < groupStart.size(); ++g) {
    const PetscInt q = std::get<0>(entries[groupStart[g]]);
    if (sh.leaf[q] >= 0) groupRoots.push_back({sh.remote[sh.leaf[q]].rank, remoteCompact[q]});
  }
  PetscSF      gsf;
  MPI_Datatype block;
  PetscCall(PetscSFCreate(comm, &gsf));
  PetscCall(PetscSFSetGraph(gsf, numRoots, numLeaves, NULL, PETSC_COPY_VALUES, groupRoots.data(), PETSC_COPY_VALUES));
  std::vector<PetscInt> theirs(kBlock * numLeaves, -1);
  PetscCallMPI(MPI_Type_contiguous(kBlock, MPIU_INT, &block));
  PetscCallMPI(MPI_Type_commit(&block));
  PetscCall(PetscSFBcastBegin(gsf, block, blocks.data(), theirs.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(gsf, block, blocks.data(), theirs.data(), MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&block));
  PetscCall(PetscSFDestroy(&gsf));
  std::vector<std::pair<PetscInt, PetscSFNode>> leaves;
  for (size_t g = 0, l = 0; g + 1 < groupStart.size(); ++g) {
    const PetscInt q = std::get<0>(entries[groupStart[g]]), n = groupStart[g + 1] - groupStart[g];
    if (sh.leaf[q] < 0) continue;
    const PetscInt *their = &theirs[kBlock * l++];
    PetscCheck(their[0] == n, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: shared point %" PetscInt_FMT " has %" PetscInt_FMT " fine points here, %" PetscInt_FMT " on its owner", q, n, their[0]);
    for (PetscInt i = 0; i < n; ++i) leaves.push_back({std::get<3>(entries[groupStart[g] + i]), {sh.remote[sh.leaf[q]].rank, their[1 + i]}});
  }
  std::sort(leaves.begin(), leaves.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
  std::vector<PetscInt>    ilocal(leaves.size());
  std::vector<PetscSFNode> iremote(leaves.size());
  for (size_t i = 0; i < leaves.size(); ++i) ilocal[i] = leaves[i].first, iremote[i] = leaves[i].second;
  PetscCall(PetscSFCreate(comm, &fsf));
  PetscCall(PetscSFSetGraph(fsf, f.End(), (PetscInt)leaves.size(), ilocal.data(), PETSC_COPY_VALUES, iremote.data(), PETSC_COPY_VALUES));
  PetscCall(DMSetPointSF(dm, fsf));
  PetscCall(PetscSFDestroy(&fsf));
  PetscFunctionReturn(0);
}

// Every label but depth and cell type: a child carries its parent's values, a fine face lying in a coarse
// face that face's values. (Values on coarse edges and vertices are not carried: the solver reads cells
// and faces only.)
PetscErrorCode CarryLabels(DM coarse, DM fine, const Coarse &m, const Fine &f)
{
  // The fine faces in each coarse face: faces[start[F - fS] .. start[F - fS + 1]).
  const std::vector<PetscInt> &carrier = f.dim == 2 ? f.edgeCarrier : f.triCarrier;
  std::vector<PetscInt>        start(m.fE - m.fS + 1, 0), faces;
  for (PetscInt q : carrier)
    if (q >= m.fS && q < m.fE) ++start[q - m.fS + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  faces.resize(start.back());
  std::vector<PetscInt> fill(start.begin(), start.end() - 1);
  for (PetscInt j = 0; j < (PetscInt)carrier.size(); ++j)
    if (carrier[j] >= m.fS && carrier[j] < m.fE) faces[fill[carrier[j] - m.fS]++] = f.dim == 2 ? f.Edge(j) : f.Tri(j);
  // The children of each coarse cell are contiguous (see Cut).
  std::vector<PetscInt> children(m.NumCells() + 1, 0);
  for (PetscInt c : f.parentOf) ++children[c + 1];
  std::partial_sum(children.begin(), children.end(), children.begin());
  PetscFunctionBeginUser;
  // Each stratum is made at once from its sorted points (a general index set), not point by point; the
  // children of coarse cells in increasing order come in increasing order.
  PetscCall(ForEachLabelStratum(coarse, fine, [&](DMLabel label, PetscInt value, const PetscInt *points, PetscInt n) -> PetscErrorCode {
    PetscInt  count = 0, *pts;
    IS        is;
    PetscFunctionBeginUser;
    for (PetscInt i = 0; i < n; ++i) {
      const PetscInt q = points[i];
      if (q >= m.cS && q < m.cE) count += children[q - m.cS + 1] - children[q - m.cS];
      if (q >= m.fS && q < m.fE) count += start[q - m.fS + 1] - start[q - m.fS];
    }
    PetscCall(PetscMalloc1(count, &pts));
    PetscInt *at = pts;
    for (PetscInt i = 0; i < n; ++i) {
      const PetscInt q = points[i];
      if (q >= m.cS && q < m.cE)
        for (PetscInt t = children[q - m.cS]; t < children[q - m.cS + 1]; ++t) *at++ = t;
      if (q >= m.fS && q < m.fE) at = std::copy(faces.begin() + start[q - m.fS], faces.begin() + start[q - m.fS + 1], at);
    }
    SortDistinctPoints(pts, count, f.End());
    PetscCall(ISCreateGeneral(PETSC_COMM_SELF, count, pts, PETSC_OWN_POINTER, &is));
    PetscCall(DMLabelSetStratumIS(label, value, is));
    PetscCall(ISDestroy(&is));
    PetscFunctionReturn(0);
  }));
  PetscFunctionReturn(0);
}

// Where each child's vertices lie in its parent, for the transfer (RefineMarkedBisection). A child's
// vertex k in its cell tables is the one opposite face k of its cone, which CellCones makes the child's
// face kPair[k] (2D: it misses vertex k + 2 mod 3) or kRefFace[k] (3D: it misses vertex 3 - k); its bits
// (Children::on) name parent vertices in ReadCoarse's order, which tablePos turns into the parent's.
void ChildCorners(const Coarse &m, const Fine &f, Children &ch, std::vector<char> &corners)
{
  const PetscInt nb       = m.dim + 1;
  const int      from2[3] = {2, 0, 1}, from3[4] = {3, 2, 1, 0}; // the child's vertex opposite face k
  const int     *from     = m.dim == 2 ? from2 : from3;
  for (PetscInt t = 0; t < f.nc; ++t) { // in place: ch.on is not read after this
    const char *pos = &m.tablePos[nb * f.parentOf[t]];
    char       *on  = &ch.on[nb * t], was[4] = {on[0], on[1], on[2], nb == 4 ? on[3] : (char)0};
    for (PetscInt k = 0; k < nb; ++k) {
      const int b  = was[from[k]]; // without branches: the bits are as likely set as not
      int       at = (b & 1) << pos[0] | (b >> 1 & 1) << pos[1] | (b >> 2 & 1) << pos[2];
      if (nb == 4) at |= (b >> 3 & 1) << pos[3];
      on[k] = (char)at;
    }
  }
  corners.swap(ch.on);
}

} // namespace

PetscErrorCode RefineMarkedBisection(DM coarse, const std::vector<char> &marked, DM *fine, std::vector<PetscInt> *parent, bool allEdges, std::vector<char> *corners)
{
  Coarse   m;
  Sharing  sh;
  Children ch;
  Fine     f;
  DM       dm;
  // -log_view: the phases, under the stage of the caller
  static PetscLogEvent ev[5] = {0, 0, 0, 0, 0};
  static const char   *evName[5] = {"BisectRead", "BisectClose", "BisectFine", "BisectPlex", "BisectSFLabels"};
  PetscFunctionBeginUser;
  for (int i = 0; i < 5; ++i)
    if (!ev[i]) PetscCall(PetscLogEventRegister(evName[i], DM_CLASSID, &ev[i]));
  PetscCall(PetscLogEventBegin(ev[0], 0, 0, 0, 0));
  PetscCall(ReadCoarse(coarse, m));
  PetscCheck((PetscInt)marked.size() == m.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "RefineMarkedBisection: %zu marks for %" PetscInt_FMT " cells", marked.size(), m.NumCells());
  PetscCall(GetSharing(coarse, m, sh));
  PetscCall(PetscLogEventEnd(ev[0], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[1], 0, 0, 0, 0));
  EdgeOrder::Lengths(m);
  const EdgeOrder   before(m);
  std::vector<char> mark;
  PetscCall(CloseMarks(PetscObjectComm((PetscObject)coarse), m, sh, before, marked, allEdges, mark));
  PetscCall(PetscLogEventEnd(ev[1], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[2], 0, 0, 0, 0));
  Cut(m, before, mark, ch);
  std::vector<PetscInt> gnum;
  PetscCall(NumberVertices(coarse, m, sh, mark, gnum));
  PetscCall(FinePoints(m, ch, mark, gnum, f));
  PetscCall(PetscLogEventEnd(ev[2], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[3], 0, 0, 0, 0));

  PetscCall(DMCreate(PetscObjectComm((PetscObject)coarse), &dm));
  PetscCall(DMSetType(dm, DMPLEX));
  PetscCall(DMSetDimension(dm, m.dim));
  PetscCall(BuildPlex(dm, f));
  std::vector<CellTypeStratum> types = {{m.dim == 2 ? DM_POLYTOPE_TRIANGLE : DM_POLYTOPE_TETRAHEDRON, 0, f.nc}, {DM_POLYTOPE_POINT, f.Vertex(0), f.Vertex(f.nv)}, {DM_POLYTOPE_SEGMENT, f.Edge(0), f.End()}};
  if (m.dim == 3) types.push_back({DM_POLYTOPE_TRIANGLE, f.Tri(0), f.Tri(f.nt)});
  PetscCall(SetCellTypeStrata(dm, types));
  PetscCall(PetscLogEventEnd(ev[3], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[4], 0, 0, 0, 0));
  PetscCall(SetPointSF(coarse, dm, m, sh, gnum, f));
  {
    std::vector<PetscReal> x(3 * f.nv);
    for (PetscInt i = 0; i < f.nv; ++i) std::copy(&ch.x[3 * f.vertexId[i]], &ch.x[3 * f.vertexId[i]] + 3, &x[3 * i]);
    PetscCall(SetVertexCoordinates(dm, m.cdim, f.Vertex(0), f.nv, x));
  }
  PetscCall(CarryLabels(coarse, dm, m, f));
  const char *name;
  PetscCall(PetscObjectGetName((PetscObject)coarse, &name));
  PetscCall(PetscObjectSetName((PetscObject)dm, name));
  if (corners) ChildCorners(m, f, ch, *corners);
  if (parent) *parent = f.parentOf;
  *fine = dm;
  PetscCall(PetscLogEventEnd(ev[4], 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

} // namespace signorini

// Refinement of marked cells by bisection of marked edges, for triangles and tetrahedra alike (see
// localrefine.h).
//
// Why it is conforming and the same on any number of ranks:
//  - Every rank orders edges the same way, by geometry only: longer first, ties broken by the midpoint's
//    coordinates, then by the endpoints' (exact doubles, so the same on every rank).
//  - A marked cell marks its longest edge; then every cell with a marked edge marks its longest edge, to
//    a fixed point (Rivara's closure). The fixed point is the least one containing the first marks, so
//    it does not depend on the order of the sweeps or on the distribution.
//  - Each cell bisects its marked edges one after the other in the global order, each bisection cutting
//    every current child that has the whole edge (an edge not yet bisected is whole in some child).
//    Restricted to a face, this is the face's own sequence of bisections of its marked edges in the same
//    order (a cut by an edge off the face leaves the face's pieces whole), so the two cells of a face cut
//    it alike. The closure makes every cell's first cut its longest edge, for the shape of the children.
// New vertices are the midpoints of the marked edges. The fine mesh is made by PETSc from the cell list
// of the children (each on its parent's rank) with global vertex numbers: the old vertices and the
// midpoints are numbered by the owners of the coarse vertices and edges.
#include "signorini/localrefine.h"
#include "signorini/mesh.h"

#include <algorithm>
#include <array>
#include <numeric>
#include <tuple>

namespace signorini {

namespace {

// The coarse mesh of one rank as tables.
struct Coarse {
  PetscInt               dim = 0, cdim = 0, nce = 0; // nce: edges per cell
  PetscInt               pS = 0, pE = 0, cS = 0, cE = 0, fS = 0, fE = 0, eS = 0, eE = 0, vS = 0, vE = 0;
  std::vector<PetscReal> x;         // 3 per vertex (zero-padded)
  std::vector<PetscInt>  edgeVerts; // 2 per edge, as v - vS
  std::vector<PetscInt>  cellVerts; // dim + 1 per cell, as v - vS
  std::vector<PetscInt>  cellEdges; // nce per cell, as e - eS
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
  m.edgeVerts.resize(2 * m.NumEdges());
  for (PetscInt e = m.eS; e < m.eE; ++e) {
    const PetscInt *cone;
    PetscCall(DMPlexGetCone(dm, e, &cone));
    for (PetscInt k = 0; k < 2; ++k) m.edgeVerts[2 * (e - m.eS) + k] = cone[k] - m.vS;
  }
  m.cellVerts.resize((m.dim + 1) * m.NumCells());
  m.cellEdges.resize(m.nce * m.NumCells());
  for (PetscInt c = m.cS; c < m.cE; ++c) {
    PetscInt        verts[4], n = 0;
    const PetscInt *cone;
    PetscCall(SimplexVertices(dm, c, m.dim, verts));
    for (PetscInt k = 0; k <= m.dim; ++k) m.cellVerts[(m.dim + 1) * (c - m.cS) + k] = verts[k] - m.vS;
    // The edges: the cone of a triangle, the edges of the faces of a tetrahedron without repeats.
    PetscInt *edges = &m.cellEdges[m.nce * (c - m.cS)];
    PetscCall(DMPlexGetCone(dm, c, &cone));
    if (m.dim == 2)
      for (PetscInt k = 0; k < 3; ++k) edges[n++] = cone[k] - m.eS;
    else
      for (PetscInt f = 0; f < 4; ++f) {
        const PetscInt *fcone;
        PetscCall(DMPlexGetCone(dm, cone[f], &fcone));
        for (PetscInt k = 0; k < 3; ++k)
          if (std::find(edges, edges + n, fcone[k] - m.eS) == edges + n) edges[n++] = fcone[k] - m.eS;
      }
    PetscCheck(n == m.nce, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: cell %" PetscInt_FMT " has %" PetscInt_FMT " edges", c, n);
  }
  PetscFunctionReturn(0);
}

// rank[e] = position of local edge e in the global order (0: first, the longest). Local positions suffice:
// only edges of one cell are ever compared.
std::vector<PetscInt> EdgeOrder(const Coarse &m)
{
  struct Key {
    PetscReal             len2;
    std::array<PetscReal, 3> mid, lo, hi;
  };
  std::vector<Key> key(m.NumEdges());
  for (PetscInt e = 0; e < m.NumEdges(); ++e) {
    const PetscReal *a = &m.x[3 * m.edgeVerts[2 * e]], *b = &m.x[3 * m.edgeVerts[2 * e + 1]];
    std::array<PetscReal, 3> A = {a[0], a[1], a[2]}, B = {b[0], b[1], b[2]};
    Key &k = key[e];
    k.len2 = 0;
    for (int d = 0; d < 3; ++d) {
      k.len2 += (B[d] - A[d]) * (B[d] - A[d]); // (b - a)^2 == (a - b)^2 exactly: independent of the cone order
      k.mid[d] = A[d] + B[d];
    }
    k.lo = std::min(A, B), k.hi = std::max(A, B);
  }
  std::vector<PetscInt> byOrder(m.NumEdges()), rank(m.NumEdges());
  std::iota(byOrder.begin(), byOrder.end(), 0);
  std::sort(byOrder.begin(), byOrder.end(), [&](PetscInt i, PetscInt j) {
    const Key &a = key[i], &b = key[j];
    if (a.len2 != b.len2) return a.len2 > b.len2;
    return std::tie(a.mid, a.lo, a.hi) < std::tie(b.mid, b.lo, b.hi);
  });
  for (PetscInt i = 0; i < m.NumEdges(); ++i) rank[byOrder[i]] = i;
  return rank;
}

// The owner's verdict on every shared edge: the marks are or-ed into the owner and sent back. Returns the
// edges whose mark this rank learnt from others.
PetscErrorCode SyncMarks(DM dm, const Coarse &m, std::vector<char> &mark, std::vector<PetscInt> &learnt)
{
  PetscSF  sf;
  PetscInt nroots;
  PetscFunctionBeginUser;
  learnt.clear();
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, NULL, NULL, NULL));
  if (nroots < 0) PetscFunctionReturn(0);
  std::vector<int> leaf(m.pE - m.pS, 0), root, back;
  for (PetscInt e = 0; e < m.NumEdges(); ++e) leaf[m.eS + e - m.pS] = mark[e];
  root = leaf;
  PetscCall(PetscSFReduceBegin(sf, MPI_INT, leaf.data(), root.data(), MPI_MAX));
  PetscCall(PetscSFReduceEnd(sf, MPI_INT, leaf.data(), root.data(), MPI_MAX));
  back = root;
  PetscCall(PetscSFBcastBegin(sf, MPI_INT, root.data(), back.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sf, MPI_INT, root.data(), back.data(), MPI_REPLACE));
  for (PetscInt e = 0; e < m.NumEdges(); ++e)
    if (back[m.eS + e - m.pS] && !mark[e]) {
      mark[e] = 1;
      learnt.push_back(e);
    }
  PetscFunctionReturn(0);
}

// Rivara's closure of the marks (see the top of the file), with shared edges agreed between ranks.
PetscErrorCode CloseMarks(DM dm, const Coarse &m, const std::vector<PetscInt> &rank, const std::vector<char> &marked, std::vector<char> &mark)
{
  MPI_Comm comm = PetscObjectComm((PetscObject)dm);
  const PetscInt nc = m.NumCells(), ne = m.NumEdges();
  std::vector<PetscInt> longest(nc), starStart(ne + 1, 0), star(m.nce * nc), work;
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < nc; ++c) {
    const PetscInt *edges = &m.cellEdges[m.nce * c];
    longest[c]            = *std::min_element(edges, edges + m.nce, [&](PetscInt a, PetscInt b) { return rank[a] < rank[b]; });
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
  for (PetscInt c = 0; c < nc; ++c)
    if (marked[c]) markEdge(longest[c]);
  for (;;) {
    while (!work.empty()) {
      const PetscInt e = work.back();
      work.pop_back();
      for (PetscInt i = starStart[e]; i < starStart[e + 1]; ++i) markEdge(longest[star[i]]);
    }
    std::vector<PetscInt> learnt;
    PetscCall(SyncMarks(dm, m, mark, learnt));
    work = learnt;
    int any = !work.empty();
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_LOR, comm));
    if (!any) break;
  }
  PetscFunctionReturn(0);
}

// Fine vertices of one rank, by local id: coarse vertex v is v, the midpoint of edge e is nV + e.
struct Children {
  PetscInt              nv = 0;  // vertices per child
  std::vector<PetscInt> verts;   // nv per child, local ids
  std::vector<PetscInt> start;   // children of coarse cell c: start[c] .. start[c + 1]
  std::vector<PetscReal> x;      // 3 per local id (midpoints of unmarked edges unused)
};

PetscReal Det(const Coarse &m, const std::vector<PetscReal> &x, const PetscInt *v)
{
  PetscReal J[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  for (PetscInt k = 0; k < m.dim; ++k)
    for (PetscInt d = 0; d < m.dim; ++d) J[k][d] = x[3 * v[k + 1] + d] - x[3 * v[0] + d];
  if (m.dim == 2) return J[0][0] * J[1][1] - J[0][1] * J[1][0];
  return J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1]) - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0]) + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0]);
}

// Cuts every cell by its marked edges in the global order, and turns each child to PETSc's orientation
// (triangles counter-clockwise, tetrahedra with det[v1 - v0, v2 - v0, v3 - v0] < 0) so that the cell
// list gives cells of positive Jacobian.
void Cut(const Coarse &m, const std::vector<PetscInt> &rank, const std::vector<char> &mark, Children &ch)
{
  const PetscInt nV = m.NumVertices(), nb = m.dim + 1;
  ch.nv = nb;
  ch.x.assign(3 * (nV + m.NumEdges()), 0.0);
  std::copy(m.x.begin(), m.x.end(), ch.x.begin());
  for (PetscInt e = 0; e < m.NumEdges(); ++e)
    for (int d = 0; d < 3; ++d) ch.x[3 * (nV + e) + d] = 0.5 * (m.x[3 * m.edgeVerts[2 * e] + d] + m.x[3 * m.edgeVerts[2 * e + 1] + d]);
  ch.start.assign(1, 0);
  ch.verts.clear();
  std::vector<std::array<PetscInt, 4>> cur, next;
  std::vector<PetscInt>                cuts;
  const PetscReal                      sign = m.dim == 2 ? 1 : -1;
  for (PetscInt c = 0; c < m.NumCells(); ++c) {
    cur.assign(1, {0, 0, 0, 0});
    std::copy(&m.cellVerts[nb * c], &m.cellVerts[nb * c] + nb, cur[0].begin());
    cuts.clear();
    for (PetscInt k = 0; k < m.nce; ++k)
      if (mark[m.cellEdges[m.nce * c + k]]) cuts.push_back(m.cellEdges[m.nce * c + k]);
    std::sort(cuts.begin(), cuts.end(), [&](PetscInt a, PetscInt b) { return rank[a] < rank[b]; });
    for (PetscInt e : cuts) {
      const PetscInt a = m.edgeVerts[2 * e], b = m.edgeVerts[2 * e + 1], mid = nV + e;
      next.clear();
      for (const auto &t : cur) {
        const auto ia = std::find(t.begin(), t.begin() + nb, a) - t.begin(), ib = std::find(t.begin(), t.begin() + nb, b) - t.begin();
        if (ia == nb || ib == nb) {
          next.push_back(t);
          continue;
        }
        next.push_back(t), next.back()[ia] = mid;
        next.push_back(t), next.back()[ib] = mid;
      }
      cur.swap(next);
    }
    for (auto &t : cur) {
      if (Det(m, ch.x, t.data()) * sign < 0) std::swap(t[0], t[1]);
      ch.verts.insert(ch.verts.end(), t.begin(), t.begin() + nb);
    }
    ch.start.push_back((PetscInt)(ch.verts.size() / nb));
  }
}

// Global numbers of the fine vertices (-1: midpoint of an unmarked edge): owned vertices and midpoints of
// owned marked edges are numbered contiguously per rank, the others get their owner's number.
PetscErrorCode NumberVertices(DM dm, const Coarse &m, const std::vector<char> &mark, std::vector<PetscInt> &gnum, PetscInt *numOwned, std::vector<PetscInt> &owned)
{
  MPI_Comm        comm = PetscObjectComm((PetscObject)dm);
  PetscSF         sf;
  PetscInt        nroots, nleaves;
  const PetscInt *ilocal;
  PetscFunctionBeginUser;
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL));
  std::vector<char> isLeaf(m.pE - m.pS, 0);
  for (PetscInt l = 0; nroots >= 0 && l < nleaves; ++l) isLeaf[(ilocal ? ilocal[l] : l) - m.pS] = 1;
  const PetscInt nV = m.NumVertices();
  owned.clear();
  for (PetscInt v = 0; v < nV; ++v)
    if (!isLeaf[m.vS + v - m.pS]) owned.push_back(v);
  for (PetscInt e = 0; e < m.NumEdges(); ++e)
    if (mark[e] && !isLeaf[m.eS + e - m.pS]) owned.push_back(nV + e);
  PetscInt n = (PetscInt)owned.size(), offset = 0;
  PetscCallMPI(MPI_Exscan(&n, &offset, 1, MPIU_INT, MPI_SUM, comm));
  PetscMPIInt r;
  PetscCallMPI(MPI_Comm_rank(comm, &r));
  if (r == 0) offset = 0;
  *numOwned = n;
  // Over the coarse chart: a vertex carries its own number, an edge its midpoint's.
  const auto point = [&](PetscInt id) { return id < nV ? m.vS + id : m.eS + id - nV; };
  std::vector<PetscInt> root(m.pE - m.pS, -1);
  for (PetscInt i = 0; i < n; ++i) root[point(owned[i]) - m.pS] = offset + i;
  std::vector<PetscInt> all = root;
  if (nroots >= 0) {
    PetscCall(PetscSFBcastBegin(sf, MPIU_INT, root.data(), all.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sf, MPIU_INT, root.data(), all.data(), MPI_REPLACE));
  }
  gnum.assign(nV + m.NumEdges(), -1);
  for (PetscInt id = 0; id < nV + m.NumEdges(); ++id)
    if (id < nV || mark[id - nV]) gnum[id] = all[point(id) - m.pS];
  PetscFunctionReturn(0);
}

// Every label but depth and cell type: a child cell carries its parent's values, a child face lying on a
// coarse face that face's values. (Values on coarse edges and vertices are not carried.) A child face
// lies on coarse face F if and only if its vertices are among F's vertices and the midpoints of F's
// edges: a midpoint of another edge of the cell lies off F's plane.
PetscErrorCode CarryLabels(DM coarse, DM fine, const Coarse &m, const std::vector<char> &mark, const Children &ch, const std::vector<PetscInt> &finePoint)
{
  PetscInt numLabels;
  PetscFunctionBeginUser;
  PetscCall(DMGetNumLabels(coarse, &numLabels));
  for (PetscInt l = 0; l < numLabels; ++l) {
    const char *name;
    DMLabel     clabel, flabel;
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
    // (point, value) of the labelled coarse cells and faces, sorted by point.
    std::vector<std::pair<PetscInt, PetscInt>> cells, faces;
    IS                                         valueIS;
    PetscInt                                   nv;
    const PetscInt                            *values;
    PetscCall(DMLabelGetValueIS(clabel, &valueIS));
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
      for (PetscInt j = 0; j < np; ++j) {
        if (points[j] >= m.cS && points[j] < m.cE) cells.push_back({points[j], values[i]});
        if (points[j] >= m.fS && points[j] < m.fE) faces.push_back({points[j], values[i]});
      }
      PetscCall(ISRestoreIndices(pointIS, &points));
      PetscCall(ISDestroy(&pointIS));
    }
    PetscCall(ISRestoreIndices(valueIS, &values));
    PetscCall(ISDestroy(&valueIS));
    for (const auto &cv : cells)
      for (PetscInt k = ch.start[cv.first - m.cS]; k < ch.start[cv.first - m.cS + 1]; ++k) PetscCall(DMLabelSetValue(flabel, k, cv.second));
    std::sort(faces.begin(), faces.end());
    for (PetscInt c = m.cS; c < m.cE && !faces.empty(); ++c) {
      const PetscInt *cone;
      PetscCall(DMPlexGetCone(coarse, c, &cone));
      for (PetscInt f = 0; f <= m.dim; ++f) {
        const auto range = std::equal_range(faces.begin(), faces.end(), std::make_pair(cone[f], PETSC_MIN_INT), [](const auto &a, const auto &b) { return a.first < b.first; });
        if (range.first == range.second) continue;
        // The fine vertices on the face: its vertices and the midpoints of its marked edges.
        std::vector<PetscInt> on;
        PetscInt              fv[4];
        PetscCall(SimplexVertices(coarse, cone[f], m.dim - 1, fv));
        for (PetscInt k = 0; k < m.dim; ++k) on.push_back(fv[k] - m.vS);
        const PetscInt *edges = &cone[f], *fcone;
        PetscInt        ne    = 1;
        if (m.dim == 3) {
          PetscCall(DMPlexGetCone(coarse, cone[f], &fcone));
          edges = fcone, ne = 3;
        }
        for (PetscInt k = 0; k < ne; ++k)
          if (mark[edges[k] - m.eS]) on.push_back(m.NumVertices() + edges[k] - m.eS);
        for (PetscInt k = ch.start[c - m.cS]; k < ch.start[c - m.cS + 1]; ++k) {
          const PetscInt *t = &ch.verts[ch.nv * k];
          for (PetscInt omit = 0; omit < ch.nv; ++omit) {
            PetscInt join[3], n = 0;
            for (PetscInt j = 0; j < ch.nv; ++j)
              if (j != omit && std::find(on.begin(), on.end(), t[j]) != on.end()) join[n++] = finePoint[t[j]];
            if (n != m.dim) continue;
            PetscInt        numCovered;
            const PetscInt *covered;
            PetscCall(DMPlexGetFullJoin(fine, n, join, &numCovered, &covered));
            PetscCheck(numCovered == 1, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: no face for a child of cell %" PetscInt_FMT, c);
            for (auto it = range.first; it != range.second; ++it) PetscCall(DMLabelSetValue(flabel, covered[0], it->second));
            PetscCall(DMPlexRestoreJoin(fine, n, join, &numCovered, &covered));
          }
        }
      }
    }
  }
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode RefineMarkedBisection(DM coarse, const std::vector<char> &marked, DM *fine, std::vector<PetscInt> *parent)
{
  MPI_Comm  comm = PetscObjectComm((PetscObject)coarse);
  Coarse    m;
  Children  ch;
  DM        dm;
  PetscFunctionBeginUser;
  PetscCall(ReadCoarse(coarse, m));
  PetscCheck((PetscInt)marked.size() == m.NumCells(), PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "RefineMarkedBisection: %zu marks for %" PetscInt_FMT " cells", marked.size(), m.NumCells());
  const std::vector<PetscInt> rank = EdgeOrder(m);
  std::vector<char>           mark;
  PetscCall(CloseMarks(coarse, m, rank, marked, mark));
  Cut(m, rank, mark, ch);

  std::vector<PetscInt> gnum, owned;
  PetscInt              numOwned;
  PetscCall(NumberVertices(coarse, m, mark, gnum, &numOwned, owned));
  std::vector<PetscReal> coords(m.cdim * numOwned);
  for (PetscInt i = 0; i < numOwned; ++i)
    for (PetscInt d = 0; d < m.cdim; ++d) coords[m.cdim * i + d] = ch.x[3 * owned[i] + d];
  const PetscInt        numChildren = (PetscInt)ch.verts.size() / ch.nv;
  std::vector<PetscInt> cells(ch.verts.size());
  for (size_t i = 0; i < cells.size(); ++i) cells[i] = gnum[ch.verts[i]];
  PetscCall(DMPlexCreateFromCellListParallelPetsc(comm, m.dim, numChildren, numOwned, PETSC_DETERMINE, ch.nv, PETSC_TRUE, cells.data(), m.cdim, coords.data(), NULL, NULL, &dm));

  // PETSc numbers the local vertices by increasing global number (DMPlexBuildFromCellListParallel).
  PetscInt vS, vE;
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vS, &vE));
  std::vector<std::pair<PetscInt, PetscInt>> byNumber;
  for (PetscInt id = 0; id < (PetscInt)gnum.size(); ++id)
    if (gnum[id] >= 0) byNumber.push_back({gnum[id], id});
  std::sort(byNumber.begin(), byNumber.end());
  PetscCheck((PetscInt)byNumber.size() == vE - vS, PETSC_COMM_SELF, PETSC_ERR_PLIB, "RefineMarkedBisection: %zu fine vertices, PETSc made %" PetscInt_FMT, byNumber.size(), vE - vS);
  std::vector<PetscInt> finePoint(gnum.size(), -1);
  for (size_t i = 0; i < byNumber.size(); ++i) finePoint[byNumber[i].second] = vS + (PetscInt)i;
  PetscCall(CarryLabels(coarse, dm, m, mark, ch, finePoint));

  const char *name;
  PetscCall(PetscObjectGetName((PetscObject)coarse, &name));
  PetscCall(PetscObjectSetName((PetscObject)dm, name));
  if (parent) {
    parent->resize(numChildren);
    for (PetscInt c = 0; c < m.NumCells(); ++c)
      for (PetscInt k = ch.start[c]; k < ch.start[c + 1]; ++k) (*parent)[k] = c;
  }
  *fine = dm;
  PetscFunctionReturn(0);
}

} // namespace signorini

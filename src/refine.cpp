#include "signorini/refine.h"

#include <algorithm>
#include <cstring>

namespace signorini {

namespace {

// The numbering of the fine points, a function of the coarse strata of one rank. Fine points are ordered
// as PETSc orders a 2D plex: cells, vertices, edges.
//   cells:    4 per coarse cell (k = 0, 1, 2: the corner at the cell's vertex k; k = 3: the middle one)
//   vertices: the coarse vertices, then one midpoint per coarse edge
//   edges:    2 halves per coarse edge (h = 0 holds the edge's first cone vertex), then 3 interior edges
//             per coarse cell (j joins the midpoints of the cell's edges j and j - 1, see SetCellCones)
struct FineNumbering {
  PetscInt cS = 0, nC = 0, eS = 0, nE = 0, vS = 0, nV = 0; // coarse strata: first point and count

  PetscInt Cell(PetscInt c, PetscInt k) const { return 4 * (c - cS) + k; }
  PetscInt VertexStart() const { return 4 * nC; }
  PetscInt Vertex(PetscInt v) const { return VertexStart() + (v - vS); }
  PetscInt Mid(PetscInt e) const { return VertexStart() + nV + (e - eS); }
  PetscInt EdgeStart() const { return VertexStart() + nV + nE; }
  PetscInt Half(PetscInt e, PetscInt h) const { return EdgeStart() + 2 * (e - eS) + h; }
  PetscInt Inner(PetscInt c, PetscInt j) const { return EdgeStart() + 2 * nE + 3 * (c - cS) + j; }
  PetscInt End() const { return EdgeStart() + 2 * nE + 3 * nC; }

  // The fine points that coarse point p becomes (at most 7); returns their number.
  PetscInt Children(PetscInt p, PetscInt ch[7]) const
  {
    if (p >= vS && p < vS + nV) {
      ch[0] = Vertex(p);
      return 1;
    }
    if (p >= eS && p < eS + nE) {
      ch[0] = Mid(p), ch[1] = Half(p, 0), ch[2] = Half(p, 1);
      return 3;
    }
    for (PetscInt k = 0; k < 4; ++k) ch[k] = Cell(p, k);
    for (PetscInt j = 0; j < 3; ++j) ch[4 + j] = Inner(p, j);
    return 7;
  }
};

// One oriented edge of a coarse triangle: the halves in the direction of travel, each with the
// orientation it has in a fine cell (0: as stored, -1: reversed).
struct OrientedEdge {
  PetscInt from, to;               // coarse vertices
  PetscInt first, second;          // fine half edges: the one at `from`, the one at `to`
  PetscInt orientation;            // of both halves in the fine cells
};

PetscErrorCode SetEdgeCones(DM coarse, DM fine, const FineNumbering &n)
{
  PetscFunctionBeginUser;
  for (PetscInt e = n.eS; e < n.eS + n.nE; ++e) {
    const PetscInt *cone;
    PetscCall(DMPlexGetCone(coarse, e, &cone));
    const PetscInt h0[2] = {n.Vertex(cone[0]), n.Mid(e)}, h1[2] = {n.Mid(e), n.Vertex(cone[1])};
    PetscCall(DMPlexSetCone(fine, n.Half(e, 0), h0));
    PetscCall(DMPlexSetCone(fine, n.Half(e, 1), h1));
  }
  PetscFunctionReturn(0);
}

// The four children of each coarse triangle (v0, v1, v2) with edge k from v_k to v_(k+1) and midpoints
// m_k: corners (v0, m0, m2), (m0, v1, m1), (m2, m1, v2) and the middle (m0, m1, m2). Interior edge j
// is stored from m_j to m_(j-1): (m0, m2), (m1, m0), (m2, m1); corner j uses it as stored, the middle
// triangle reversed.
PetscErrorCode SetCellCones(DM coarse, DM fine, const FineNumbering &n)
{
  PetscFunctionBeginUser;
  for (PetscInt c = n.cS; c < n.cS + n.nC; ++c) {
    const PetscInt *cone, *ornt;
    OrientedEdge    ed[3];
    PetscCall(DMPlexGetCone(coarse, c, &cone));
    PetscCall(DMPlexGetConeOrientation(coarse, c, &ornt));
    for (PetscInt k = 0; k < 3; ++k) {
      const PetscInt *ends;
      PetscCall(DMPlexGetCone(coarse, cone[k], &ends));
      PetscCheck(ornt[k] == 0 || ornt[k] == -1, PETSC_COMM_SELF, PETSC_ERR_SUP, "refinement: edge orientation %" PetscInt_FMT " in cell %" PetscInt_FMT, ornt[k], c);
      const bool fwd = ornt[k] == 0;
      ed[k] = {fwd ? ends[0] : ends[1], fwd ? ends[1] : ends[0], n.Half(cone[k], fwd ? 0 : 1), n.Half(cone[k], fwd ? 1 : 0), ornt[k]};
    }
    for (PetscInt k = 0; k < 3; ++k)
      PetscCheck(ed[k].to == ed[(k + 1) % 3].from, PETSC_COMM_SELF, PETSC_ERR_PLIB, "refinement: the edges of cell %" PetscInt_FMT " do not form a cycle", c);
    const PetscInt m[3] = {n.Mid(cone[0]), n.Mid(cone[1]), n.Mid(cone[2])};
    const PetscInt inner[3][2] = {{m[0], m[2]}, {m[1], m[0]}, {m[2], m[1]}};
    for (PetscInt j = 0; j < 3; ++j) PetscCall(DMPlexSetCone(fine, n.Inner(c, j), inner[j]));
    const PetscInt o = 0, r = -1;
    const PetscInt cones[4][3] = {{ed[0].first, n.Inner(c, 0), ed[2].second},
                                  {ed[0].second, ed[1].first, n.Inner(c, 1)},
                                  {n.Inner(c, 2), ed[1].second, ed[2].first},
                                  {n.Inner(c, 1), n.Inner(c, 2), n.Inner(c, 0)}};
    const PetscInt ornts[4][3] = {{ed[0].orientation, o, ed[2].orientation},
                                  {ed[0].orientation, ed[1].orientation, o},
                                  {o, ed[1].orientation, ed[2].orientation},
                                  {r, r, r}};
    for (PetscInt k = 0; k < 4; ++k) {
      PetscCall(DMPlexSetCone(fine, n.Cell(c, k), cones[k]));
      PetscCall(DMPlexSetConeOrientation(fine, n.Cell(c, k), ornts[k]));
    }
  }
  PetscFunctionReturn(0);
}

// The cell-type label as three contiguous strata (stride index sets): the fine mesh is born stratified,
// so no point goes through DMPlexSetCellType's hash.
PetscErrorCode SetCellTypes(DM fine, const FineNumbering &n)
{
  DMLabel        label;
  const PetscInt starts[4] = {0, n.VertexStart(), n.EdgeStart(), n.End()};
  const DMPolytopeType types[3] = {DM_POLYTOPE_TRIANGLE, DM_POLYTOPE_POINT, DM_POLYTOPE_SEGMENT};
  PetscFunctionBeginUser;
  PetscCall(DMCreateLabel(fine, "celltype"));
  PetscCall(DMGetLabel(fine, "celltype", &label));
  for (PetscInt s = 0; s < 3; ++s) {
    IS is;
    PetscCall(ISCreateStride(PETSC_COMM_SELF, starts[s + 1] - starts[s], starts[s], 1, &is));
    PetscCall(DMLabelSetStratumIS(label, types[s], is));
    PetscCall(ISDestroy(&is));
  }
  PetscFunctionReturn(0);
}

// A point shared with another rank is shared with the same children there: the children of leaf p are
// leaves whose roots are the same children of p's root, numbered with the owner's strata.
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
    PetscInt       mine[7], theirs[7];
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
      PetscInt *children;
      PetscInt  count = 0;
      PetscCall(PetscMalloc1(7 * np, &children));
      for (PetscInt j = 0; j < np; ++j) count += n.Children(points[j], children + count);
      std::sort(children, children + count);
      PetscCall(ISRestoreIndices(pointIS, &points));
      PetscCall(ISDestroy(&pointIS));
      IS fineIS;
      PetscCall(ISCreateGeneral(PETSC_COMM_SELF, count, children, PETSC_OWN_POINTER, &fineIS));
      PetscCall(DMLabelSetStratumIS(flabel, values[i], fineIS));
      PetscCall(ISDestroy(&fineIS));
    }
    PetscCall(ISRestoreIndices(valueIS, &values));
    PetscCall(ISDestroy(&valueIS));
  }
  PetscFunctionReturn(0);
}

// Coarse vertices keep their coordinates; each midpoint is the mean of its edge's ends.
PetscErrorCode SetCoordinates(DM coarse, DM fine, const FineNumbering &n)
{
  PetscSection       csec, fsec;
  Vec                cvec, fvec;
  const PetscScalar *cx;
  PetscScalar       *fx;
  PetscInt           cdim;
  PetscFunctionBeginUser;
  PetscCall(DMGetCoordinateDim(coarse, &cdim));
  PetscCall(DMGetCoordinateSection(coarse, &csec));
  PetscCall(DMGetCoordinatesLocal(coarse, &cvec));
  PetscCall(DMSetCoordinateDim(fine, cdim));
  PetscCall(PetscSectionCreate(PetscObjectComm((PetscObject)fine), &fsec)); // the global section scans offsets over this comm
  PetscCall(PetscSectionSetNumFields(fsec, 1));
  PetscCall(PetscSectionSetFieldComponents(fsec, 0, cdim));
  PetscCall(PetscSectionSetChart(fsec, n.VertexStart(), n.EdgeStart()));
  for (PetscInt v = n.VertexStart(); v < n.EdgeStart(); ++v) {
    PetscCall(PetscSectionSetDof(fsec, v, cdim));
    PetscCall(PetscSectionSetFieldDof(fsec, v, 0, cdim));
  }
  PetscCall(PetscSectionSetUp(fsec));
  PetscCall(DMSetCoordinateSection(fine, cdim, fsec));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, (n.nV + n.nE) * cdim, &fvec));
  PetscCall(VecSetBlockSize(fvec, cdim));
  PetscCall(PetscObjectSetName((PetscObject)fvec, "coordinates"));
  PetscCall(VecGetArrayRead(cvec, &cx));
  PetscCall(VecGetArray(fvec, &fx));
  // The fine section puts vertex v at (v - VertexStart()) * cdim: coarse vertices first, then midpoints.
  for (PetscInt v = n.vS; v < n.vS + n.nV; ++v) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(csec, v, &off));
    for (PetscInt d = 0; d < cdim; ++d) fx[(v - n.vS) * cdim + d] = cx[off + d];
  }
  for (PetscInt e = n.eS; e < n.eS + n.nE; ++e) {
    const PetscInt *cone;
    PetscInt        o0, o1;
    PetscCall(DMPlexGetCone(coarse, e, &cone));
    PetscCall(PetscSectionGetOffset(csec, cone[0], &o0));
    PetscCall(PetscSectionGetOffset(csec, cone[1], &o1));
    for (PetscInt d = 0; d < cdim; ++d) fx[(n.nV + e - n.eS) * cdim + d] = 0.5 * (cx[o0 + d] + cx[o1 + d]);
  }
  PetscCall(VecRestoreArray(fvec, &fx));
  PetscCall(VecRestoreArrayRead(cvec, &cx));
  PetscCall(DMSetCoordinatesLocal(fine, fvec));
  PetscCall(VecDestroy(&fvec));
  PetscCall(PetscSectionDestroy(&fsec));
  PetscFunctionReturn(0);
}

} // namespace

PetscErrorCode RefineTriangles(DM coarse, DM *fine, std::vector<PetscInt> *parent)
{
  PetscInt      dim, cE, eE, vE;
  FineNumbering n;
  DM            dm;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(coarse, &dim));
  PetscCheck(dim == 2, PetscObjectComm((PetscObject)coarse), PETSC_ERR_SUP, "RefineTriangles: mesh dimension %" PetscInt_FMT ", not 2", dim);
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &n.cS, &cE));
  PetscCall(DMPlexGetDepthStratum(coarse, 1, &n.eS, &eE));
  PetscCall(DMPlexGetDepthStratum(coarse, 0, &n.vS, &vE));
  n.nC = cE - n.cS, n.nE = eE - n.eS, n.nV = vE - n.vS;

  PetscCall(DMCreate(PetscObjectComm((PetscObject)coarse), &dm));
  PetscCall(DMSetType(dm, DMPLEX));
  PetscCall(DMSetDimension(dm, 2));
  PetscCall(DMPlexSetChart(dm, 0, n.End()));
  for (PetscInt c = 0; c < 4 * n.nC; ++c) PetscCall(DMPlexSetConeSize(dm, c, 3));
  for (PetscInt e = n.EdgeStart(); e < n.End(); ++e) PetscCall(DMPlexSetConeSize(dm, e, 2));
  PetscCall(DMSetUp(dm));
  PetscCall(SetEdgeCones(coarse, dm, n));
  PetscCall(SetCellCones(coarse, dm, n));
  PetscCall(DMPlexSymmetrize(dm));
  PetscCall(SetCellTypes(dm, n));
  PetscCall(DMPlexStratify(dm));
  PetscCall(SetPointSF(coarse, dm, n));
  PetscCall(RefineLabels(coarse, dm, n));
  PetscCall(SetCoordinates(coarse, dm, n));
  if (parent) {
    parent->resize(4 * n.nC);
    for (PetscInt c = 0; c < 4 * n.nC; ++c) (*parent)[c] = c / 4;
  }
  *fine = dm;
  PetscFunctionReturn(0);
}

} // namespace signorini

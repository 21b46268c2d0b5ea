// Uniform (regular) refinement of a distributed triangle or tetrahedron mesh, built directly as a DMPlex.
//
// PETSc 3.18's DMPlexTransformApply makes the same mesh through a general cell-transform framework: it
// inserts every new point into a cell-type hash, copies and sorts every label into the coordinate DM, and
// looks each new point up through the transform; at 2D N = 2048 that is 15 s, most of the set-up. Here
// the numbering of the fine points is arithmetic in the coarse ones (a vertex stays a vertex, an edge
// gives its midpoint and two halves, a triangle four triangles and three interior edges, a tetrahedron
// eight tetrahedra, eight interior faces and one interior edge), so the cones, the point star forest and
// the labels are written in one pass each, and the cell-type label is made of stride index sets.
//
// The mesh is the one PETSc's regular refinement makes: each triangle is cut at its edge midpoints into
// three corners and the middle one; each tetrahedron into four corners and an octahedron, which is cut
// into four along the same diagonal PETSc chooses. Every child keeps the orientation of its parent.
#pragma once

#include "signorini/common.h"

#include <petscdmplex.h>

#include <algorithm>
#include <array>
#include <functional>

namespace signorini {

// Collective. `coarse` must be an interpolated simplex DMPlex of dimension 2 or 3 (any distribution,
// overlap 0). If `parent` is given, parent[c] is the coarse cell (as c - cStart) of fine cell c (fine
// cells start at 0).
PetscErrorCode RefineSimplices(DM coarse, DM *fine, std::vector<PetscInt> *parent);

// Building blocks of the meshes built directly (here and in bisect.cpp).
// The cell-type label as contiguous strata, one stride index set each: a mesh born stratified needs no
// point to go through DMPlexSetCellType's hash.
struct CellTypeStratum {
  DMPolytopeType type;
  PetscInt       start, end;
};
PetscErrorCode SetCellTypeStrata(DM dm, const std::vector<CellTypeStratum> &strata);
// A plex's cones and cone orientations straight in its arrays: read, DMPlexGetCone's and
// DMPlexGetConeOrientation's results; written (a plex being built, its cone sizes set and its arrays
// allocated by DMSetUp), what DMPlexSetCone and DMPlexSetConeOrientation write. Without a call, checks and
// a section look-up per point, which add up over millions of points. Valid while the cone section stays.
struct PlexCones {
  PetscInt       *cones = nullptr, *ornts = nullptr;
  const PetscInt *off    = nullptr;
  PetscInt        pStart = 0;
  explicit PlexCones(DM dm);
  const PetscInt *Cone(PetscInt p) const { return cones + off[p - pStart]; }
  const PetscInt *Orientation(PetscInt p) const { return ornts + off[p - pStart]; }
  template <size_t N>
  void SetCone(PetscInt p, const PetscInt (&c)[N]) { std::copy(c, c + N, cones + off[p - pStart]); }
  template <size_t N>
  void SetOrientation(PetscInt p, const PetscInt (&o)[N]) { std::copy(o, o + N, ornts + off[p - pStart]); }
};
// The orientation of a triangle listed by a cell in some order of its stored vertices: it depends only on
// where the first two come from, orientation[3 * place of the first + place of the second] (PETSc asked
// once per order instead of once per face).
PetscErrorCode TriangleOrientations(PetscInt orientation[9]);
// The depth label as DMPlexStratify makes it for a chart whose points of depth d are the contiguous range
// ranges[d] = {start, end} (d = 0 .. dim): one stride stratum a depth, every depth on every rank
// (collective), and the plex's depth state. Without DMPlexStratify's calls per point and per support.
PetscErrorCode SetDepthStrata(DM dm, const std::vector<std::array<PetscInt, 2>> &ranges);
// The supports from the cones, as DMPlexSymmetrize makes them (each point's supports by increasing point),
// for a plex whose cones are set and whose supports are not, without its calls per point and cone entry.
PetscErrorCode SymmetrizeCones(DM dm);
// Local coordinates of the vertices vStart .. vStart + n - 1, from x with 3 numbers per vertex (the first
// cdim are used).
PetscErrorCode SetVertexCoordinates(DM dm, PetscInt cdim, PetscInt vStart, PetscInt n, const std::vector<PetscReal> &x);
// Creates in `fine` every label of `coarse` but depth and cell type, with its default value, and calls
// `stratum(fine label, value, points, number of points)` for each value with the coarse points carrying it.
PetscErrorCode ForEachLabelStratum(DM coarse, DM fine, const std::function<PetscErrorCode(DMLabel, PetscInt, const PetscInt *, PetscInt)> &stratum);

// Sorts n distinct mesh points of [0, end) in place (the points of a label stratum).
void SortDistinctPoints(PetscInt *p, PetscInt n, PetscInt end);

} // namespace signorini

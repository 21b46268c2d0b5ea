// Uniform (regular) refinement of a distributed triangle mesh, built directly as a DMPlex.
//
// PETSc 3.18's DMPlexTransformApply makes the same mesh through a general cell-transform framework: it
// inserts every new point into a cell-type hash, copies and sorts every label into the coordinate DM, and
// looks each new point up through the transform; at 2D N = 2048 that is 15 s, most of the set-up. Here
// the numbering of the fine points is arithmetic in the coarse ones (a vertex stays a vertex, an edge
// gives its midpoint and two halves, a triangle four triangles and three interior edges), so the cones,
// the point star forest and the labels are written in one pass each, and the cell-type label is made of
// stride index sets.
//
// Each triangle is cut at its edge midpoints into three corner triangles and the middle one, as in
// PETSc's regular refinement; every child keeps the orientation of its parent.
#pragma once

#include "signorini/common.h"

#include <petscdmplex.h>

namespace signorini {

// Collective. `coarse` must be an interpolated 2D simplex DMPlex (any distribution, overlap 0). If
// `parent` is given, parent[c] is the coarse cell (as c - cStart) of fine cell c (fine cells start at 0).
PetscErrorCode RefineTriangles(DM coarse, DM *fine, std::vector<PetscInt> *parent);

} // namespace signorini

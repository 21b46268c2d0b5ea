// Conforming refinement of marked cells of a distributed simplex mesh, for adaptive refinement. The new
// mesh keeps the distribution (every child on its parent's rank), the "Face Sets" and "Cell Sets" labels,
// and is the same on any number of ranks: the closure that keeps it conforming is decided by geometry
// only (edge lengths, ties broken by coordinates), never by a rank's numbering.
#pragma once

#include "signorini/common.h"

#include <petscdmplex.h>
#include <petscdmplextransform.h>

namespace signorini {

// Collective. marked[c - cStart] != 0 for the cells to refine (the closure may refine more). parent[c] of
// fine cell c (fine cells start at 0) is the coarse cell (c - cStart) containing it.
// By bisection of marked edges (2D and 3D; bisect.cpp).
// allEdges: a marked cell marks all its edges (each marked triangle becomes 4 cells, h halves), not only its
// longest (2 cells).
// corners[c * (dim + 1) + k], when asked for: the vertices of parent[c] (bit j: its vertex j, both in the
// order of the cell tables of a space, CellVertices) on which vertex k of fine cell c lies: one at a parent
// vertex, two at the midpoint of their edge (the only points bisection makes).
PetscErrorCode RefineMarkedBisection(DM coarse, const std::vector<char> &marked, DM *fine, std::vector<PetscInt> *parent, bool allEdges = false, std::vector<char> *corners = nullptr);
// By PETSc's skeleton-based refinement, DMPlexTransform "refine_sbr" (2D only; localrefine.cpp).
PetscErrorCode RefineMarkedSBR(DM coarse, const std::vector<char> &marked, DM *fine, std::vector<PetscInt> *parent);
// PETSc's refinement of `coarse` by a DMPlexTransform of `type`, restricted to the points of `active`
// (value DM_ADAPT_REFINE; null: all), with the parent map as above when asked for.
PetscErrorCode TransformRefine(DM coarse, DMPlexTransformType type, DMLabel active, DM *fine, std::vector<PetscInt> *parent);
// The refinement of marked cells by one of the two (SBR: triangles only, an input error otherwise), with
// the corners of the bisection when asked for (SBR leaves them empty).
enum class LocalRefinement { Bisection, BisectionAll, SBR };
PetscErrorCode RefineMarked(DM coarse, const std::vector<char> &marked, LocalRefinement how, DM *fine, std::vector<PetscInt> *parent, std::vector<char> *corners = nullptr);

} // namespace signorini

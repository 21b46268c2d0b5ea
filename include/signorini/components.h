// The connected components of a mesh, for the checks that each piece of the domain determines u: a piece
// with neither a Dirichlet nor a contact face floats (u + c solves it for every c), one with contact but no
// Dirichlet face needs a load that pushes it towards the obstacle. The scene's parts decide this for the
// whole domain only when the domain is in one piece.
#pragma once

#include "signorini/common.h"

#include <array>
#include <functional>
#include <vector>

namespace signorini {

// A graph distributed over ranks: its nodes are the local items 0..numItems-1, each of the numCells lists
// (cellItems(c) gives `per` items) joins its items, and an item held by several ranks is one node:
// shareOwners(values) overwrites the value of every copy of an item another rank owns with the owner's
// value (a star forest's broadcast).
struct ItemGraph {
  PetscInt                                               numItems = 0, numCells = 0, per = 0;
  std::function<const PetscInt *(PetscInt)>              cellItems;
  std::function<PetscErrorCode(std::vector<PetscInt> &)> shareOwners;
};

// Collective. component[i]: the component of item i, numbered 0..*count-1 alike on every rank (in the
// order of the lowest rank, then the first local item, that holds a piece of it); -1 for an item in no
// list. The work is one pass over the lists and one exchange of the pairs of pieces that meet at shared
// items, gathered on every rank (their number grows with the ranks, not with the mesh).
PetscErrorCode ConnectedComponents(MPI_Comm comm, const ItemGraph &graph, std::vector<PetscInt> &component, PetscInt *count);

// Collective. For each of `count` components, the lowest (x, then y, then z) of the points that the ranks
// give for it (point(i, x) for i < n: item i's point, in component[i], -1 to skip it): a point that names
// the component in a message in the same way on any number of ranks. Components without a point keep
// +infinity.
PetscErrorCode LowestPoints(MPI_Comm comm, PetscInt dim, PetscInt n, const std::vector<PetscInt> &component, PetscInt count, const std::function<void(PetscInt, PetscReal *)> &point,
                            std::vector<std::array<PetscReal, 3>> &lowest);

} // namespace signorini

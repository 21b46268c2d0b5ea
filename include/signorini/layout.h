// The layout of a space's DOFs without the mesh: a DMShell that creates the space's local and global
// vectors and exchanges values between them (DMGlobalToLocal, DMLocalToGlobal with INSERT_VALUES or
// ADD_VALUES) exactly as the DMPlex with the space's section does.
//
// Built from the local and global sections alone: it keeps the local index of every owned DOF and a star
// forest of the ghost DOFs only (the local copies of DOFs another rank owns), so on one rank it holds no
// forest at all, where the section's star forest of the DMPlex lists every local DOF. With it, the space
// needs the mesh only while its tables are built (SpaceReleaseMesh).
#pragma once

#include "signorini/common.h"

namespace signorini {

// A DMShell with the local and global layout and the local/global exchange of `dm`, a DM with a local
// section (e.g. output fields on a DMPlex clone). Collective.
PetscErrorCode LayoutCreateFromDM(DM dm, DM *layout);
// The same from the two sections themselves (the global one as PetscSectionCreateGlobalSection makes it),
// without a DM that carries them. Collective on comm.
PetscErrorCode LayoutCreate(MPI_Comm comm, PetscSection local, PetscSection global, DM *layout);

// Checks that section s gives the points [start, end) one DOF each and nothing else, in point order, so
// that the local entry of point p is p - start (what the cell tables and the output's derived fields use
// instead of a lookup per point). A section without a permutation numbers its points in chart order, so
// the storage size and the last offset settle it.
PetscErrorCode LayoutCheckPointOrder(PetscSection s, PetscInt start, PetscInt end);

} // namespace signorini

// The layout of a space's DOFs without the mesh: a DMShell that creates the space's local and global
// vectors and exchanges values between them (DMGlobalToLocal, DMLocalToGlobal with INSERT_VALUES or
// ADD_VALUES) exactly as the DMPlex with the space's section does, through the same star forest.
//
// Once a space's tables are built, the solve and everything measured after it (KKT residuals, energy,
// errors, prolongation to the next level) need nothing else from the mesh; the distributed DMPlex, about
// a sixth of the memory at the solve's peak, can then be freed (SpaceReleaseMesh).
#pragma once

#include "signorini/common.h"

namespace signorini {

// A DMShell with the local and global layout and the local/global exchange of `dm`, a DM with a local
// section whose DOFs are one per point (the space's DMPlex clone). Keeps only the section's star forest
// and, for INSERT_VALUES into a global vector, the local index of each owned DOF. Collective.
PetscErrorCode LayoutCreateFromDM(DM dm, DM *layout);

} // namespace signorini

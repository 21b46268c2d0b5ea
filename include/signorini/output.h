// Output of the mesh and the solution for visualisation: HDF5 written by PETSc's HDF5 viewer (XDMF layout)
// plus an XDMF file that ParaView and VisIt open.
//
// P1 solutions are vertex fields. A CR solution lives on faces, which PETSc's viewer writes only as a raw
// /fields entry with no visualisation, so two fields a viewer can show are derived from it: the cell mean
// (the value at the centroid) and the vertex average of the cellwise linear function.
#pragma once

#include "signorini/space.h"

namespace signorini {

struct OutputOptions {
  std::string file; // FILE.h5; the XDMF file is FILE.xmf
};

PetscErrorCode OutputOptionsFromCommandLine(MPI_Comm comm, OutputOptions &o);
// Pushes the Output stage. Both files are written under temporary names and renamed at the end.
PetscErrorCode WriteSolution(const Space &space, Vec u, const OutputOptions &o);

} // namespace signorini

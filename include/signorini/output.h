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

// The output in two steps, so that the mesh need not stay in memory through the solve: OutputBegin, while
// the space still has its mesh, writes the mesh (geometry and topology) into FILE.h5.tmp and keeps only the
// layouts of the vertex and cell fields; OutputEnd, after the solve, adds the fields, renames the file and
// writes FILE.xmf (also under a temporary name first). A run that ends in between leaves no file behind:
// the Output object removes FILE.h5.tmp when it is destroyed before OutputEnd. Both push the Output stage.
struct Output {
  OutputOptions opts;
  DM            cellLayout = nullptr, vertLayout = nullptr;
  PetscInt      dim = 2, nv = 0, nc = 0; // global vertex and cell counts, for the XDMF file
  PetscMPIInt   rank = 0;
  bool          pending = false; // FILE.h5.tmp exists and is not renamed yet
  Output() = default;
  Output(const Output &) = delete;
  Output &operator=(const Output &) = delete;
  ~Output();
};
PetscErrorCode OutputBegin(const Space &space, const OutputOptions &o, Output &out);
PetscErrorCode OutputEnd(const Space &space, Vec u, Output &out);
// Both steps at once, for a space that keeps its mesh.
PetscErrorCode WriteSolution(const Space &space, Vec u, const OutputOptions &o);

} // namespace signorini

// Output of the mesh and the solution for visualisation: one HDF5 file, written by PETSc's HDF5 viewer in
// parallel, and XDMF 3 files next to it that ParaView and meshio open, one grid each (meshio reads one grid
// per file):
//   FILE.xmf          the mesh (triangles or tetrahedra): u_h at the vertices and the cell mean of u_h, and
//                     with an estimate the indicator eta_T of every cell ("eta", estimate.h);
//   FILE-contact.xmf  with a contact part, the faces of Gamma_C (segments or triangles), each with its own
//                     vertices: u_h, psi, the contact pressure (A u - b) / measure and the active set (1 where
//                     u = psi) at the contact DOFs, i.e. at the face vertices for P1 and on the faces for CR;
//   FILE-dofs.xmf     for CR, the DOFs as points (the face midpoints) with the DOF values of u_h.
// Coordinates have dim components (GeometryType XY in 2D). All files appear together or not at all (files.h).
//
// P1 solutions are vertex fields. A CR solution lives on faces, which PETSc's viewer writes only as a raw
// /fields entry with no visualisation, so two fields a viewer can show are derived from it: the cell mean
// (the value at the centroid) and the vertex average of the cellwise linear function.
#pragma once

#include "signorini/assembly.h"
#include "signorini/files.h"

namespace signorini {

struct OutputOptions {
  std::string file;          // FILE.h5
  bool        contact = false; // the scene has a contact part: FILE-contact.xmf
  bool        cr      = false; // CR element: FILE-dofs.xmf
};

// Reads -output and claims its files (files.h); the element and the contact part decide which files.
PetscErrorCode OutputOptionsFromCommandLine(MPI_Comm comm, Element element, const Problem &problem, OutputOptions &o);
// The files an output writes, FILE.h5 first.
std::vector<std::string> OutputFiles(const OutputOptions &o);
// Collective, at options time: claims every file of OutputFiles for `option` (FileClaim).
PetscErrorCode OutputClaim(MPI_Comm comm, const std::string &option, const OutputOptions &o);

// The output in two steps, so that the mesh need not stay in memory through the solve: OutputBegin, while
// the space still has its mesh, writes the mesh (geometry and topology) into a temporary file (files.h) and
// keeps only the layouts of the vertex and cell fields; OutputEnd, after the solve, adds the fields, writes
// the XDMF files and renames them all onto their names. A run that ends in between leaves no file behind:
// the Output object removes its temporary files when it is destroyed before OutputEnd. Both push the
// Output stage.
struct Output {
  OutputOptions opts;
  DM            cellLayout = nullptr, vertLayout = nullptr;
  PetscInt      dim = 2, nv = 0, nc = 0; // global vertex and cell counts, for the XDMF file
  FileSet       files;                   // FILE.h5 from OutputBegin on, the XDMF files in OutputEnd
  std::string   h5;                      // the temporary name of FILE.h5
  Output() = default;
  Output(const Output &) = delete;
  Output &operator=(const Output &) = delete;
  ~Output();
};
PetscErrorCode OutputBegin(const Space &space, const OutputOptions &o, Output &out);
// cellEta2: the estimate's indicators squared per local cell (Estimate::cellEta2), or empty: no "eta" field.
PetscErrorCode OutputEnd(const Space &space, const Problem &problem, const System &sys, Vec u, Output &out, const std::vector<PetscReal> &cellEta2 = {});
// Both steps at once, for a space that keeps its mesh.
PetscErrorCode WriteSolution(const Space &space, const Problem &problem, const System &sys, Vec u, const OutputOptions &o);

} // namespace signorini

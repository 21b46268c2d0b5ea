// Checks of a Gmsh mesh file that PETSc's reader (DMPlexCreateGmsh, 3.18) does not make or reports
// misleadingly: the file is scanned before PETSc reads it, and the mesh PETSc built is checked for
// coincident vertices. All functions here are rank-local: CreateFromGmsh (mesh.cpp) calls them on rank 0
// and shares the verdict with CheckAll.
#pragma once

#include "signorini/common.h"

#include <petscdmplex.h>

namespace signorini {

// The nodes that the elements of a Gmsh file use, in the order of the file: PETSc numbers its vertices in
// this order, so vertex k of the mesh is node tag[k] of the file. Empty when the file was not scanned.
struct GmshNodes {
  std::vector<long>   tag;
  std::vector<double> xyz; // 3 coordinates per node
};

// Checks the file named `file` (called `name` in messages) before PETSc reads it: that it is a Gmsh file
// (and not msh version 1), and for ASCII msh 2.2 and 4.1 files, that every element is a first-order
// one, names only nodes of $Nodes and none twice, and that the elements below the mesh dimension are faces
// of its cells. Returns the problem in one line, or "" (also for what is left to PETSc: binary files,
// other versions, text the scan does not understand). Fills `nodes` when the scan got through the file.
std::string GmshCheckFile(const std::string &file, const std::string &name, GmshNodes &nodes);

// The physical names of a Gmsh file ($PhysicalNames, before $Nodes in msh 2.2 and 4.1, ASCII or binary):
// (dimension, tag, name) each, none where the file has none. Returns false where the file cannot be opened.
struct GmshPhysicalName {
  int         dim;
  long        tag;
  std::string name;
};
bool GmshPhysicalNames(const std::string &file, std::vector<GmshPhysicalName> &names);

// Two vertices of `dm` closer than 1e-10 times the shortest edge at either of them are one point listed
// twice: a mesh with a duplicated node is cut along it (a crack), which changes the problem without a
// sign. Returns the problem (naming the nodes by their numbers in the file when `nodes` matches the
// mesh's vertices), or "".
std::string CheckCoincidentVertices(DM dm, const std::string &name, const GmshNodes &nodes);

} // namespace signorini

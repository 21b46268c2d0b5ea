// Convergence study: one scene solved on a sequence of nested meshes with each element, with the error of
// every solution against the exact solution (when the scene has one) and/or against a reference solution
// on a further refined mesh, beside what each solution cost.
//
// All levels come from refining the distributed base mesh in parallel, so the reference is solved once
// and every coarse solution is compared with it on the fine mesh, cell by cell, without gathering.
#pragma once

#include "signorini/assembly.h"
#include "signorini/contact.h"
#include "signorini/error.h"
#include "signorini/mesh.h"

namespace signorini {

struct StudyOptions {
  PetscInt             levels = 0;          // number of mesh levels studied (0: no study, a single run)
  PetscInt             referenceRefine = 0; // refinements of the finest study level for the reference (0: none)
  Element              referenceElement = Element::P1;
  std::vector<Element> elements = {Element::P1, Element::CR};
  std::string          file;     // JSON output
  std::string          profiles; // prefix of the finest level's solution (HDF5) and contact profile (CSV)
};

// The problem says which profile files are written (contact profiles only with a contact part).
PetscErrorCode StudyOptionsFromCommandLine(MPI_Comm comm, const Problem &problem, StudyOptions &o);

struct StudyRow {
  std::string element;
  PetscInt    level = 0, N = 0, cells = 0, dofs = 0;
  PetscReal   h = 0;
  SolveResult solve;
  bool        hasExact = false, hasReference = false;
  ErrorNorms  exact, reference;
  double      solveSeconds = 0, totalSeconds = 0, peakRSS = 0; // peak resident memory (bytes, max over ranks)
};

// `base` is level 0 (the distributed, possibly refined, mesh of MeshCreate); `N0` its cells per side
// (box meshes; 0 for files). Prints the table and writes the JSON if asked.
PetscErrorCode RunStudy(DM base, PetscInt N0, PetscReal h0, Problem &problem, const AssemblyOptions &assembly, PetscInt errorDegree, const StudyOptions &o);

} // namespace signorini

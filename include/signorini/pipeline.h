// The scene on one mesh: space -> assembly -> solve -> checks -> estimate. Every run goes through it, in the loop
// over meshes in main, whether it solves one mesh, a sequence of nested levels or a convergence study:
// those are strategies (strategy.h) that differ only in which meshes they hand it and what they carry
// from one mesh to the next (an initial guess for the solve).
#pragma once

#include "signorini/contact.h"
#include "signorini/estimate.h"

#include <functional>

namespace signorini {

// The discrete problem on one mesh and its solution. Destroy frees all of it.
struct MeshSolution {
  Space       space;
  System      sys;
  Vec         u = nullptr; // global vector of the space, named "u": the initial guess, then the solution
  SolveResult result;
  double      setupSeconds = 0; // space and assembly (withMesh excluded), max over ranks
  Estimate    estimate;         // of the error of u, once solved (unless -estimate none)
  PetscErrorCode Destroy();
};

struct PipelineOptions {
  Element         element = Element::CR;
  AssemblyOptions assembly;
  SolveOptions    solve;          // solve.initialGuess: u holds an initial guess when Solve is called
  bool            kktHint = true; // print the KKT warning (kkthint.h) after the solve
  EstimateOptions estimate;       // the estimate of the error after the solve (m.estimate)
  bool            keepMesh = false; // the space keeps its mesh (HDF5 output after the solve)
  // Called once the space is built, while it still holds the mesh (e.g. to begin the output file), and
  // before the assembly: it may drop the caller's references to the mesh, so that without keepMesh the
  // mesh is freed before the assembly and the solve need the memory. Its time is not set-up time.
  std::function<PetscErrorCode(const Space &)> withMesh;
};

// Space (Setup stage) and system (Assemble stage) of the scene on `mesh`, and the vector u (zero).
PetscErrorCode PipelineSetUp(DM mesh, const Problem &problem, const PipelineOptions &o, MeshSolution &m);
// The solve on m's mesh (from u with o.solve.initialGuess, else from u_D), then the checks of the answer
// and, with o.estimate.enabled, the estimate of its error (Estimate stage).
PetscErrorCode PipelineSolve(const Problem &problem, const PipelineOptions &o, MeshSolution &m);

} // namespace signorini

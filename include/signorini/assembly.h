// Assembly of the discrete problem a_h(u, v) = chi(v): the stiffness matrix with kappa constant per cell,
// the load (f over cells, g over Gamma_N), Dirichlet values eliminated symmetrically, and the discrete
// energy J(u_h) = 1/2 a_h(u_h, u_h) - chi(u_h).
#pragma once

#include "signorini/quadrature.h"
#include "signorini/space.h"

namespace signorini {

struct AssemblyOptions {
  // Load quadrature: "accurate" uses a rule exact for f * phi with f a polynomial of degree loadDegree - 1;
  // "centroid" the one-point rule, i.e. f replaced by its value at each cell centroid (the paper's choice).
  bool     centroid   = false;
  PetscInt loadDegree = 4;
};
PetscErrorCode AssemblyOptionsFromCommandLine(MPI_Comm comm, AssemblyOptions &o);

struct System {
  Mat                    A = nullptr;    // stiffness, Dirichlet rows and columns replaced by identity
  Vec                    b = nullptr;    // load with Dirichlet values and their column contributions folded in
  Vec                    load = nullptr; // chi as a vector (before elimination): chi(v) = load . v
  Vec                    uD = nullptr;   // Dirichlet values on Dirichlet DOFs, 0 elsewhere
  std::vector<PetscReal> kappa;          // per local cell, or one value when kappa is constant
  Quadrature             cellRule, faceRule;
  PetscReal              Kappa(PetscInt c) const { return kappa.size() == 1 ? kappa[0] : kappa[c]; }
};

// Pushes the Setup (matrix creation) and Assemble stages.
PetscErrorCode AssembleSystem(const Space &space, const Problem &problem, const AssemblyOptions &opts, System &sys);
PetscErrorCode SystemDestroy(System &sys);
// J(u) = 1/2 a_h(u, u) - chi(u), computed cell by cell from the unreduced element matrices.
PetscErrorCode DiscreteEnergy(const Space &space, const System &sys, Vec u, PetscReal *J);
// Element stiffness of cell c (nb x nb, row-major).
void ElementStiffness(const Space &space, PetscInt c, PetscReal kappa, const CellGeometry &g, PetscReal *Ke);

} // namespace signorini

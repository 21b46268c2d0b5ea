// The data of a scene: which boundary parts carry which condition, and the functions f, g, u_D, psi,
// kappa and (optionally) the exact solution with its gradient, all read from the options database.
#pragma once

#include "signorini/expression.h"

#include <petscdm.h>

#include <memory>

namespace signorini {

// What ProblemCheckMesh found on the coarse mesh: the boundary faces, all and those in no named part,
// where kappa du/dn = 0 holds, and the centroid of one of them; the pieces of the domain (components.h:
// cells joined through their faces; refinement keeps them), and how many have contact but no Dirichlet
// faces (the assembly checks their loads: they must push each such piece towards the obstacle); how many
// conditions of the scene the exact solution fails (exactcheck.h; -1 without one).
struct CoarseFindings {
  PetscInt  faces = 0, unnamed = 0;
  PetscReal example[3] = {0, 0, 0};
  PetscInt  pieces = 1, contactOnly = 0;
  PetscInt  exactFailed = -1;
};

struct Problem {
  std::string           scene = "custom";
  std::vector<PetscInt> dirichlet, neumann, contact; // "Face Sets" values of Gamma_D, Gamma_N, Gamma_C
  std::unique_ptr<Expression> f, g, uD, psi, kappa; // all but uD and psi may use cell_set ("Cell Sets" value, -1 if none)
  std::unique_ptr<Expression> exact, exactGrad;     // null when the scene has no exact solution
  std::string                 exactGradText;
  CoarseFindings              coverage; // set by ProblemCheckMesh
  bool HasContact() const { return !contact.empty(); }
  bool HasNeumann() const { return !neumann.empty() && !g->IsZero(); }
  bool HasExact() const { return exact != nullptr; }
};

// Reads the options, parses the scalar expressions, and checks that the boundary parts determine u.
PetscErrorCode ProblemFromCommandLine(MPI_Comm comm, Problem &p);
// Once the mesh dimension is known: parses the exact gradient (dim components). Also checks that the
// boundary parts determine u, for problems built without ProblemFromCommandLine.
PetscErrorCode ProblemSetUp(MPI_Comm comm, PetscInt dim, Problem &p);
// Collective. ProblemSetUp with the dimension of `dm`, a check that every boundary part named in the
// options exists on `dm`, and p.coverage (a note is printed where faces are in no part). Run on the coarse
// mesh, before the refinement, so that a mistyped part fails at once instead of after minutes of
// refinement (refinement keeps the "Face Sets" values).
PetscErrorCode ProblemCheckMesh(DM dm, Problem &p);
// "option -bc_contact: boundary part 7 does not exist on the mesh ...", shared with the space's own check.
std::string MissingPartMessage(const char *option, PetscInt value);

} // namespace signorini

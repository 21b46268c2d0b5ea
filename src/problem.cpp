#include "signorini/problem.h"

#include "signorini/mesh.h"
#include "signorini/options.h"

#include <algorithm>

namespace signorini {

// Without a Dirichlet or a contact part, u is determined only up to a constant.
static PetscErrorCode CheckDetermined(MPI_Comm comm, const Problem &p)
{
  PetscFunctionBeginUser;
  if (p.dirichlet.empty() && p.contact.empty())
    SIGNORINI_INPUT_ERROR(comm, "options -bc_dirichlet/-bc_contact: the scene has neither a Dirichlet nor a contact part, so u is not determined (singular problem)");
  PetscFunctionReturn(0);
}

PetscErrorCode ProblemFromCommandLine(MPI_Comm comm, Problem &p)
{
  std::string f = "0", g = "0", uD = "0", psi = "0", kappa = "1", ex, exg;
  bool        hasExact = false, hasGrad = false;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Scene: boundary parts and data (expressions in x, y, z, cell_set; constant pi)", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-scene", "Name of the scene, reported in the summary", p.scene));
  PetscCall(OptionIntList(PetscOptionsObject, "-bc_dirichlet", "Face Sets values of Gamma_D, comma separated", p.dirichlet, PETSC_MIN_INT, PETSC_MAX_INT));
  PetscCall(OptionIntList(PetscOptionsObject, "-bc_neumann", "Face Sets values of Gamma_N", p.neumann, PETSC_MIN_INT, PETSC_MAX_INT));
  PetscCall(OptionIntList(PetscOptionsObject, "-bc_contact", "Face Sets values of Gamma_C (u >= psi there)", p.contact, PETSC_MIN_INT, PETSC_MAX_INT));
  PetscCall(OptionString(PetscOptionsObject, "-f", "Source f in -div(kappa grad u) = f; cell_set is the Cell Sets value of the cell integrated over", f));
  PetscCall(OptionString(PetscOptionsObject, "-g", "Neumann flux g = kappa du/dn on Gamma_N; cell_set is that of the one cell next to the Neumann face", g));
  PetscCall(OptionString(PetscOptionsObject, "-u_D", "Dirichlet value on Gamma_D (a value at boundary points, which may touch cells of several sets: no cell_set)", uD));
  PetscCall(OptionString(PetscOptionsObject, "-psi", "Obstacle on Gamma_C (a value at boundary points, which may touch cells of several sets: no cell_set)", psi));
  PetscCall(OptionString(PetscOptionsObject, "-kappa", "Coefficient kappa > 0, taken constant per cell (value at the centroid); cell_set is the cell's Cell Sets value", kappa));
  PetscCall(OptionString(PetscOptionsObject, "-exact_u", "Exact solution, if known (cell_set: that of the cell of the error integral)", ex, &hasExact));
  PetscCall(OptionString(PetscOptionsObject, "-exact_grad", "Gradient of the exact solution, dim comma-separated components (cell_set as in -exact_u)", exg, &hasGrad));
  PetscOptionsEnd();

  const std::pair<const char *, std::vector<PetscInt> *> parts[] = {{"-bc_dirichlet", &p.dirichlet}, {"-bc_neumann", &p.neumann}, {"-bc_contact", &p.contact}};
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      for (PetscInt v : *parts[a].second)
        if (std::count(parts[b].second->begin(), parts[b].second->end(), v))
          SIGNORINI_INPUT_ERROR(comm, "options %s and %s: boundary part %" PetscInt_FMT " is named in both", parts[a].first, parts[b].first, v);
  PetscCall(CheckDetermined(comm, p));

  PetscCall(Expression::Create(comm, "-f", f, 1, p.f));
  PetscCall(Expression::Create(comm, "-g", g, 1, p.g));
  PetscCall(Expression::Create(comm, "-u_D", uD, 1, p.uD, Expression::At::Point));
  PetscCall(Expression::Create(comm, "-psi", psi, 1, p.psi, Expression::At::Point));
  PetscCall(Expression::Create(comm, "-kappa", kappa, 1, p.kappa));
  if (hasExact != hasGrad) SIGNORINI_INPUT_ERROR(comm, "options -exact_u and -exact_grad: give both or neither");
  if (hasExact) PetscCall(Expression::Create(comm, "-exact_u", ex, 1, p.exact));
  p.exactGradText = exg;
  PetscFunctionReturn(0);
}

PetscErrorCode ProblemSetUp(MPI_Comm comm, PetscInt dim, Problem &p)
{
  PetscFunctionBeginUser;
  PetscCall(CheckDetermined(comm, p));
  if (p.exact) PetscCall(Expression::Create(comm, "-exact_grad", p.exactGradText, (int)dim, p.exactGrad));
  PetscFunctionReturn(0);
}

std::string MissingPartMessage(const char *option, PetscInt value)
{
  return Format("option %s: boundary part %d does not exist on the mesh (no face carries that \"Face Sets\" value)", option, (int)value);
}

PetscErrorCode ProblemCheckMesh(DM dm, Problem &p)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)dm);
  PetscInt              dim;
  DMLabel               faceSets;
  std::vector<PetscInt> faces;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(ProblemSetUp(comm, dim, p));
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  const std::pair<const char *, const std::vector<PetscInt> *> parts[] = {{"-bc_dirichlet", &p.dirichlet}, {"-bc_neumann", &p.neumann}, {"-bc_contact", &p.contact}};
  for (const auto &part : parts)
    for (PetscInt value : *part.second) {
      PetscCall(LabelFaces(dm, faceSets, value, faces));
      PetscInt local = (PetscInt)faces.size(), global;
      PetscCallMPI(MPI_Allreduce(&local, &global, 1, MPIU_INT, MPI_SUM, comm));
      if (global == 0) SIGNORINI_INPUT_ERROR(comm, "%s", MissingPartMessage(part.first, value).c_str());
    }
  PetscFunctionReturn(0);
}

} // namespace signorini

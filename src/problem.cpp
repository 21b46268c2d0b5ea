#include "signorini/problem.h"

#include "signorini/mesh.h"

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
  char      scene[256] = "custom", dir[256] = "", neu[256] = "", con[256] = "";
  char      f[4096] = "0", g[4096] = "0", uD[4096] = "0", psi[4096] = "0", kappa[4096] = "1", ex[4096] = "", exg[4096] = "";
  PetscBool hasExact = PETSC_FALSE, hasGrad = PETSC_FALSE;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Scene: boundary parts and data (expressions in x, y, z; constant pi)", "signorini");
  PetscCall(PetscOptionsString("-scene", "Name of the scene, reported in the summary", "", scene, scene, sizeof scene, NULL));
  PetscCall(PetscOptionsString("-bc_dirichlet", "Face Sets values of Gamma_D, comma separated", "", dir, dir, sizeof dir, NULL));
  PetscCall(PetscOptionsString("-bc_neumann", "Face Sets values of Gamma_N", "", neu, neu, sizeof neu, NULL));
  PetscCall(PetscOptionsString("-bc_contact", "Face Sets values of Gamma_C (u >= psi there)", "", con, con, sizeof con, NULL));
  PetscCall(PetscOptionsString("-f", "Source f in -div(kappa grad u) = f", "", f, f, sizeof f, NULL));
  PetscCall(PetscOptionsString("-g", "Neumann flux g = kappa du/dn on Gamma_N", "", g, g, sizeof g, NULL));
  PetscCall(PetscOptionsString("-u_D", "Dirichlet value on Gamma_D", "", uD, uD, sizeof uD, NULL));
  PetscCall(PetscOptionsString("-psi", "Obstacle on Gamma_C", "", psi, psi, sizeof psi, NULL));
  PetscCall(PetscOptionsString("-kappa", "Coefficient kappa > 0, taken constant per cell (value at the centroid); may use cell_set", "", kappa, kappa, sizeof kappa, NULL));
  PetscCall(PetscOptionsString("-exact_u", "Exact solution, if known", "", ex, ex, sizeof ex, &hasExact));
  PetscCall(PetscOptionsString("-exact_grad", "Gradient of the exact solution, dim comma-separated components", "", exg, exg, sizeof exg, &hasGrad));
  PetscOptionsEnd();

  p.scene = scene;
  PetscCall(ParseIntList(comm, "-bc_dirichlet", dir, p.dirichlet));
  PetscCall(ParseIntList(comm, "-bc_neumann", neu, p.neumann));
  PetscCall(ParseIntList(comm, "-bc_contact", con, p.contact));
  const std::pair<const char *, std::vector<PetscInt> *> parts[] = {{"-bc_dirichlet", &p.dirichlet}, {"-bc_neumann", &p.neumann}, {"-bc_contact", &p.contact}};
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      for (PetscInt v : *parts[a].second)
        if (std::count(parts[b].second->begin(), parts[b].second->end(), v))
          SIGNORINI_INPUT_ERROR(comm, "options %s and %s: boundary part %" PetscInt_FMT " is named in both", parts[a].first, parts[b].first, v);
  PetscCall(CheckDetermined(comm, p));

  PetscCall(Expression::Create(comm, "-f", f, 1, p.f));
  PetscCall(Expression::Create(comm, "-g", g, 1, p.g));
  PetscCall(Expression::Create(comm, "-u_D", uD, 1, p.uD));
  PetscCall(Expression::Create(comm, "-psi", psi, 1, p.psi));
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

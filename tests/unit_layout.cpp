// Unit tests of the mesh-free DOF layout (layout.h) and SpaceReleaseMesh, on 2D and 3D box meshes, P1 and
// CR, refined in parallel so that ranks share DOFs (ctest runs it on 1 and 2 ranks). The reference is the
// DMPlex clone of the space, i.e. PETSc's own section-based exchange:
//   - local and global sizes equal the plex's;
//   - DMGlobalToLocal gives exactly the plex's local vector;
//   - DMLocalToGlobal with ADD_VALUES, from local values that differ between the copies of a shared DOF,
//     gives the plex's sums; with INSERT_VALUES every owned entry is the owner's own copy;
//   - the space's vectors come from the shell; after SpaceReleaseMesh the mesh can be destroyed, and the
//     exchange still gives the same values.
#include "signorini/mesh.h"
#include "signorini/space.h"
#include "unit_check.h"

#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

struct LayoutCase {
  std::string name;
  MeshOptions mesh;
  Element     element;
};

static std::vector<PetscScalar> Values(Vec v)
{
  const PetscScalar *a;
  PetscInt           n;
  VecGetLocalSize(v, &n);
  VecGetArrayRead(v, &a);
  std::vector<PetscScalar> out(a, a + n);
  VecRestoreArrayRead(v, &a);
  return out;
}

static PetscReal MaxDiff(const std::vector<PetscScalar> &a, const std::vector<PetscScalar> &b)
{
  if (a.size() != b.size()) return PETSC_MAX_REAL;
  PetscReal d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, PetscAbsScalar(a[i] - b[i]));
  return d;
}

// Global -> local (INSERT) and local -> global (ADD and INSERT) of `dm`, from a global vector whose
// entries are a function of the global index and a local vector whose entries differ from rank to rank.
// Returns the three results, concatenated.
static PetscErrorCode Exchange(DM dm, std::vector<PetscScalar> &out)
{
  Vec         g, l;
  PetscInt    rstart, n;
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(PetscObjectComm((PetscObject)dm), &rank));
  PetscCall(DMCreateGlobalVector(dm, &g));
  PetscCall(DMCreateLocalVector(dm, &l));
  PetscCall(VecGetOwnershipRange(g, &rstart, NULL));
  PetscCall(VecGetLocalSize(g, &n));
  for (PetscInt i = 0; i < n; ++i) PetscCall(VecSetValue(g, rstart + i, std::sin(1.0 + rstart + i), INSERT_VALUES));
  PetscCall(VecAssemblyBegin(g));
  PetscCall(VecAssemblyEnd(g));
  out.clear();
  PetscCall(DMGlobalToLocal(dm, g, INSERT_VALUES, l));
  for (PetscScalar v : Values(l)) out.push_back(v);
  PetscCall(VecGetLocalSize(l, &n));
  for (PetscInt i = 0; i < n; ++i) PetscCall(VecSetValue(l, i, 1000.0 * rank + std::cos(1.0 + i), INSERT_VALUES));
  PetscCall(VecAssemblyBegin(l));
  PetscCall(VecAssemblyEnd(l));
  PetscCall(VecSet(g, 0.5));
  PetscCall(DMLocalToGlobal(dm, l, ADD_VALUES, g));
  for (PetscScalar v : Values(g)) out.push_back(v);
  PetscCall(DMLocalToGlobal(dm, l, INSERT_VALUES, g));
  for (PetscScalar v : Values(g)) out.push_back(v);
  PetscCall(VecDestroy(&g));
  PetscCall(VecDestroy(&l));
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const LayoutCase &lc)
{
  MPI_Comm comm = PETSC_COMM_WORLD;
  DM       dm;
  MeshInfo info;
  Problem  problem;
  Space    space;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, lc.mesh, &dm, info));
  PetscCall(unit::MakeProblem(comm, lc.mesh.dim, {{lc.mesh.dim == 2 ? 3 : 2}, {1}}, problem));
  PetscCall(SpaceCreate(dm, lc.element, problem, space)); // space.dm: the layout
  DM plexDM; // the mesh with the space's section: PETSc's own exchange, the reference
  PetscCall(SpaceSectionDM(space, &plexDM));

  PetscBool isShell;
  PetscCall(PetscObjectTypeCompare((PetscObject)space.dm, DMSHELL, &isShell));
  ck.Check(isShell, lc.name + " the space's vectors come from the layout shell");
  std::vector<PetscScalar> plex, shell;
  PetscCall(Exchange(plexDM, plex));
  Vec      gp, gs, lp, ls;
  PetscInt ngp, ngs, nlp, nls;
  PetscCall(DMCreateGlobalVector(plexDM, &gp));
  PetscCall(DMCreateGlobalVector(space.dm, &gs));
  PetscCall(DMCreateLocalVector(plexDM, &lp));
  PetscCall(DMCreateLocalVector(space.dm, &ls));
  PetscCall(VecGetLocalSize(gp, &ngp));
  PetscCall(VecGetLocalSize(gs, &ngs));
  PetscCall(VecGetSize(lp, &nlp));
  PetscCall(VecGetSize(ls, &nls));
  ck.Check(ngp == ngs && nlp == nls && ngs == space.numOwned && nls == space.numLocal, lc.name + " sizes equal the plex's", "global %d/%d, local %d/%d", (int)ngp, (int)ngs, (int)nlp, (int)nls);
  PetscCall(VecDestroy(&gp));
  PetscCall(VecDestroy(&lp));
  PetscCall(VecDestroy(&ls));
  PetscCall(Exchange(space.dm, shell));
  const PetscReal d = MaxDiff(plex, shell);
  ck.Check(d == 0, lc.name + " exchange equals the plex's (G2L, L2G add and insert)", "max difference %g", (double)d);

  // INSERT_VALUES into a global vector: the owner's own copy, whatever the other copies hold
  {
    const size_t             nl = (size_t)space.numLocal, ng = (size_t)space.numOwned;
    std::vector<PetscScalar> inserted(shell.end() - ng, shell.end());
    PetscMPIInt              rank;
    PetscCallMPI(MPI_Comm_rank(comm, &rank));
    // the global entries G2L INSERT put into the local vector identify which local copy is the owned one
    PetscInt rstart;
    PetscCall(VecGetOwnershipRange(gs, &rstart, NULL));
    PetscInt hits = 0;
    for (size_t i = 0; i < nl; ++i)
      for (size_t k = 0; k < ng; ++k)
        if (shell[i] == std::sin(1.0 + rstart + (PetscInt)k) && inserted[k] == 1000.0 * rank + std::cos(1.0 + (PetscInt)i)) {
          ++hits;
          break;
        }
    ck.Check(hits == (PetscInt)ng, lc.name + " INSERT_VALUES takes the owner's copy", "%d of %d owned entries", (int)hits, (int)ng);
  }
  PetscCall(VecDestroy(&gs));

  // SpaceReleaseMesh: the mesh can go, and the exchange does not change
  PetscCall(SpaceReleaseMesh(space));
  ck.Check(space.mesh == nullptr, lc.name + " SpaceReleaseMesh drops the mesh");
  PetscCall(DMDestroy(&plexDM));
  PetscCall(DMDestroy(&dm));
  PetscCall(Exchange(space.dm, shell));
  const PetscReal d2 = MaxDiff(plex, shell);
  ck.Check(d2 == 0, lc.name + " exchange after the mesh is destroyed equals the plex's", "max difference %g", (double)d2);
  PetscCall(SpaceDestroy(space));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker           ck;
  std::vector<LayoutCase> cases;
  for (Element e : {Element::P1, Element::CR}) {
    LayoutCase lc;
    lc.element       = e;
    lc.mesh.dim      = 2;
    lc.mesh.faces[0] = 3, lc.mesh.faces[1] = 2;
    lc.mesh.refine   = 2;
    lc.name          = Format("2D 3x2 refine 2 %s", ElementName(e));
    cases.push_back(lc);
    lc.mesh.dim      = 3;
    lc.mesh.faces[0] = 2, lc.mesh.faces[1] = 1, lc.mesh.faces[2] = 1;
    lc.mesh.refine   = 1;
    lc.name          = Format("3D 2x1x1 refine 1 %s", ElementName(e));
    cases.push_back(lc);
  }
  for (const LayoutCase &lc : cases) {
    ierr = TestCase(ck, lc);
    if (ierr) ck.PetscFailure(ierr, lc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

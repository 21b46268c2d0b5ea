#include "signorini/layout.h"

#include <petscdmshell.h>
#include <petscsf.h>

namespace signorini {

namespace {
struct Layout {
  PetscSF               sf = nullptr; // leaves: local DOFs; roots: the owned entries of a global vector
  PetscInt              numLocal = 0, numOwned = 0;
  std::vector<PetscInt> ownedLocal;   // local index of each owned DOF (its own copy among the leaves)
};

PetscErrorCode LayoutDestroy(void *ctx)
{
  auto *l = static_cast<Layout *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(PetscSFDestroy(&l->sf));
  delete l;
  PetscFunctionReturn(0);
}

Layout &Get(DM dm)
{
  void *ctx = nullptr;
  DMShellGetContext(dm, &ctx); // cannot fail on the shells made here
  return *static_cast<Layout *>(ctx);
}

PetscErrorCode CreateGlobal(DM dm, Vec *v)
{
  PetscFunctionBeginUser;
  PetscCall(VecCreateMPI(PetscObjectComm((PetscObject)dm), Get(dm).numOwned, PETSC_DETERMINE, v));
  PetscCall(VecSetDM(*v, dm));
  PetscFunctionReturn(0);
}

PetscErrorCode CreateLocal(DM dm, Vec *v)
{
  PetscFunctionBeginUser;
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, Get(dm).numLocal, v));
  PetscCall(VecSetDM(*v, dm));
  PetscFunctionReturn(0);
}

// Every local copy receives its owner's value (INSERT_VALUES only, as with DMPlex).
PetscErrorCode GlobalToLocal(DM dm, Vec g, InsertMode mode, Vec l)
{
  const Layout      &L = Get(dm);
  const PetscScalar *ga;
  PetscScalar       *la;
  PetscFunctionBeginUser;
  PetscCheck(mode == INSERT_VALUES, PetscObjectComm((PetscObject)dm), PETSC_ERR_SUP, "global to local exchange supports INSERT_VALUES only");
  PetscCall(VecGetArrayRead(g, &ga));
  PetscCall(VecGetArray(l, &la));
  PetscCall(PetscSFBcastBegin(L.sf, MPIU_SCALAR, ga, la, MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(L.sf, MPIU_SCALAR, ga, la, MPI_REPLACE));
  PetscCall(VecRestoreArray(l, &la));
  PetscCall(VecRestoreArrayRead(g, &ga));
  PetscFunctionReturn(0);
}

// ADD_VALUES adds every local copy into the owner's entry; INSERT_VALUES takes the owner's own copy and
// ignores the others (as DMPlex does), so the result does not depend on the order messages arrive in.
PetscErrorCode LocalToGlobal(DM dm, Vec l, InsertMode mode, Vec g)
{
  const Layout      &L = Get(dm);
  const PetscScalar *la;
  PetscScalar       *ga;
  PetscFunctionBeginUser;
  PetscCheck(mode == INSERT_VALUES || mode == ADD_VALUES, PetscObjectComm((PetscObject)dm), PETSC_ERR_SUP, "local to global exchange supports INSERT_VALUES and ADD_VALUES only");
  PetscCall(VecGetArrayRead(l, &la));
  PetscCall(VecGetArray(g, &ga));
  if (mode == INSERT_VALUES) {
    for (PetscInt i = 0; i < L.numOwned; ++i) ga[i] = la[L.ownedLocal[i]];
  } else {
    PetscCall(PetscSFReduceBegin(L.sf, MPIU_SCALAR, la, ga, MPIU_SUM));
    PetscCall(PetscSFReduceEnd(L.sf, MPIU_SCALAR, la, ga, MPIU_SUM));
  }
  PetscCall(VecRestoreArray(g, &ga));
  PetscCall(VecRestoreArrayRead(l, &la));
  PetscFunctionReturn(0);
}

PetscErrorCode Nothing(DM, Vec, InsertMode, Vec) { return 0; }
} // namespace

PetscErrorCode LayoutCreateFromDM(DM dm, DM *layout)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)dm);
  PetscSF            sf;
  PetscSection       local, global;
  PetscInt           nroots, nleaves;
  const PetscInt    *leaves;
  const PetscSFNode *remote;
  PetscMPIInt        rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  auto *L = new Layout;
  PetscCall(DMGetLocalSection(dm, &local));
  PetscCall(DMGetGlobalSection(dm, &global));
  PetscCall(PetscSectionGetStorageSize(local, &L->numLocal));
  PetscCall(PetscSectionGetConstrainedStorageSize(global, &L->numOwned));
  PetscCall(DMGetSectionSF(dm, &sf));
  PetscCall(PetscObjectReference((PetscObject)sf));
  L->sf = sf;
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &leaves, &remote));
  L->ownedLocal.assign(L->numOwned, -1);
  for (PetscInt i = 0; i < nleaves; ++i)
    if (remote[i].rank == rank) L->ownedLocal[remote[i].index] = leaves ? leaves[i] : i;
  bool complete = nroots == L->numOwned;
  for (PetscInt o : L->ownedLocal) complete = complete && o >= 0;
  if (!complete) {
    PetscCall(LayoutDestroy(L));
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_PLIB, "the section's star forest does not map every owned DOF to a local copy");
  }
  PetscCall(DMShellCreate(comm, layout));
  PetscCall(DMShellSetContext(*layout, L));
  PetscCall(DMShellSetDestroyContext(*layout, LayoutDestroy));
  PetscCall(DMShellSetCreateGlobalVector(*layout, CreateGlobal));
  PetscCall(DMShellSetCreateLocalVector(*layout, CreateLocal));
  PetscCall(DMShellSetGlobalToLocal(*layout, GlobalToLocal, Nothing));
  PetscCall(DMShellSetLocalToGlobal(*layout, LocalToGlobal, Nothing));
  PetscFunctionReturn(0);
}

} // namespace signorini

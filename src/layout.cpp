#include "signorini/layout.h"

#include <petscdmshell.h>
#include <petscsf.h>

namespace signorini {

namespace {
struct Layout {
  PetscInt              numLocal = 0, numOwned = 0;
  std::vector<PetscInt> ownedLocal;     // local index of each owned DOF (its owner's own copy)
  PetscSF               ghosts = nullptr; // leaves: the local copies of DOFs other ranks own; roots: owned DOFs
};

PetscErrorCode LayoutDestroy(void *ctx)
{
  auto *l = static_cast<Layout *>(ctx);
  PetscFunctionBeginUser;
  PetscCall(PetscSFDestroy(&l->ghosts));
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
  PetscCall(PetscSFBcastBegin(L.ghosts, MPIU_SCALAR, ga, la, MPI_REPLACE));
  for (PetscInt i = 0; i < L.numOwned; ++i) la[L.ownedLocal[i]] = ga[i];
  PetscCall(PetscSFBcastEnd(L.ghosts, MPIU_SCALAR, ga, la, MPI_REPLACE));
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
    for (PetscInt i = 0; i < L.numOwned; ++i) ga[i] += la[L.ownedLocal[i]];
    PetscCall(PetscSFReduceBegin(L.ghosts, MPIU_SCALAR, la, ga, MPIU_SUM));
    PetscCall(PetscSFReduceEnd(L.ghosts, MPIU_SCALAR, la, ga, MPIU_SUM));
  }
  PetscCall(VecRestoreArray(g, &ga));
  PetscCall(VecRestoreArrayRead(l, &la));
  PetscFunctionReturn(0);
}

PetscErrorCode Nothing(DM, Vec, InsertMode, Vec) { return 0; }
} // namespace

PetscErrorCode LayoutCheckPointOrder(PetscSection s, PetscInt start, PetscInt end)
{
  PetscInt n, last = 0;
  PetscFunctionBeginUser;
  PetscCall(PetscSectionGetStorageSize(s, &n));
  if (end > start) PetscCall(PetscSectionGetOffset(s, end - 1, &last));
  PetscCheck(n == end - start && (end == start || last == end - 1 - start), PETSC_COMM_SELF, PETSC_ERR_PLIB, "the section does not number its points [%" PetscInt_FMT ", %" PetscInt_FMT ") in order, one DOF each", start, end);
  PetscFunctionReturn(0);
}

PetscErrorCode LayoutCreateFromDM(DM dm, DM *layout)
{
  PetscSection local, global;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalSection(dm, &local));
  PetscCall(DMGetGlobalSection(dm, &global));
  PetscCall(LayoutCreate(PetscObjectComm((PetscObject)dm), local, global, layout));
  PetscFunctionReturn(0);
}

PetscErrorCode LayoutCreate(MPI_Comm comm, PetscSection local, PetscSection global, DM *layout)
{
  PetscInt    pStart, pEnd;
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  auto *L = new Layout;
  PetscCall(PetscSectionGetStorageSize(local, &L->numLocal));
  PetscCall(PetscSectionGetConstrainedStorageSize(global, &L->numOwned));
  // The owner of a global index, from the ranges of all ranks; a ghost's root is its owner's offset.
  std::vector<PetscInt> ranges;
  PetscCall(OwnershipRanges(comm, L->numOwned, ranges));
  const PetscInt           rstart = ranges[rank];
  std::vector<PetscInt>    leaves;
  std::vector<PetscSFNode> roots;
  L->ownedLocal.assign(L->numOwned, -1);
  PetscCall(PetscSectionGetChart(local, &pStart, &pEnd));
  for (PetscInt p = pStart; p < pEnd; ++p) {
    PetscInt dof, loff, goff;
    PetscCall(PetscSectionGetDof(local, p, &dof));
    if (!dof) continue;
    PetscCall(PetscSectionGetOffset(local, p, &loff));
    PetscCall(PetscSectionGetOffset(global, p, &goff));
    for (PetscInt d = 0; d < dof; ++d) {
      if (goff >= 0) {
        L->ownedLocal[goff - rstart + d] = loff + d;
        continue;
      }
      const PetscInt    g     = -(goff + 1) + d; // PETSc's encoding of a DOF another rank owns
      const PetscMPIInt owner = OwnerOf(ranges, g);
      leaves.push_back(loff + d);
      roots.push_back({owner, g - ranges[owner]});
    }
  }
  bool complete = true;
  for (PetscInt o : L->ownedLocal) complete = complete && o >= 0;
  if (!complete) {
    PetscCall(LayoutDestroy(L));
    SETERRQ(PETSC_COMM_SELF, PETSC_ERR_PLIB, "the global section leaves an owned DOF without a local copy");
  }
  PetscCall(PetscSFCreate(comm, &L->ghosts));
  PetscCall(PetscSFSetGraph(L->ghosts, L->numOwned, (PetscInt)leaves.size(), leaves.data(), PETSC_COPY_VALUES, roots.data(), PETSC_COPY_VALUES));
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

#include "signorini/localrefine.h"

#include <petsc/private/dmplextransformimpl.h> // DMPlexTransform::trType, see GeneralStrata

namespace signorini {

// PETSc 3.18's DMLabel keeps a stratum of contiguous points as a stride index set, whose ISGetIndices
// allocates and fills the whole array on every call, and DMPlexTransformGetTargetPoint looks up the
// point's position in the stratum of its refinement type for every point it makes: with a label of
// refinement types (SBR) a contiguous stratum (all vertices, typically) makes DMPlexTransformApply
// quadratic in the mesh size (4 s for 10^5 cells, most of it in ISGetIndices_Stride). Made general
// index sets once, in place, the strata cost a binary search per look-up. 3.18 has no accessor for the
// transform's label, hence the private header.
static PetscErrorCode GeneralStrata(DMLabel label)
{
  IS              values;
  const PetscInt *v;
  PetscInt        n;
  PetscFunctionBeginUser;
  if (!label) PetscFunctionReturn(0);
  PetscCall(DMLabelGetValueIS(label, &values));
  PetscCall(ISGetLocalSize(values, &n));
  PetscCall(ISGetIndices(values, &v));
  for (PetscInt i = 0; i < n; ++i) {
    IS stratum; // the label's own index set (one more reference)
    PetscCall(DMLabelGetStratumIS(label, v[i], &stratum));
    if (stratum) PetscCall(ISToGeneral(stratum));
    PetscCall(ISDestroy(&stratum));
  }
  PetscCall(ISRestoreIndices(values, &v));
  PetscCall(ISDestroy(&values));
  PetscFunctionReturn(0);
}

PetscErrorCode TransformRefine(DM coarse, DMPlexTransformType type, DMLabel active, DM *fine, std::vector<PetscInt> *parent)
{
  DMPlexTransform tr;
  PetscInt        dim, cStart, cEnd, fcStart, fcEnd;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(coarse, &dim));
  PetscCall(DMPlexTransformCreate(PetscObjectComm((PetscObject)coarse), &tr));
  PetscCall(DMPlexTransformSetDM(tr, coarse));
  PetscCall(DMPlexTransformSetType(tr, type));
  if (active) PetscCall(DMPlexTransformSetActive(tr, active));
  PetscCall(DMPlexTransformSetUp(tr));
  PetscCall(GeneralStrata(tr->trType));
  PetscCall(DMPlexTransformApply(tr, coarse, fine));
  if (parent) {
    // From each coarse cell to the children its refinement type makes. (3.18's DMPlexTransformGetSourcePoint,
    // the way back, assumes that the cells of one refinement type are numbered contiguously, which a
    // transform driven by a label, as SBR is, does not give.)
    PetscCall(DMPlexGetHeightStratum(coarse, 0, &cStart, &cEnd));
    PetscCall(DMPlexGetHeightStratum(*fine, 0, &fcStart, &fcEnd));
    parent->assign(fcEnd - fcStart, -1);
    for (PetscInt c = cStart; c < cEnd; ++c) {
      DMPolytopeType ct, *rct;
      PetscInt       Nct, *rsize, *rcone, *rornt;
      PetscCall(DMPlexGetCellType(coarse, c, &ct));
      PetscCall(DMPlexTransformCellTransform(tr, ct, c, NULL, &Nct, &rct, &rsize, &rcone, &rornt));
      for (PetscInt n = 0; n < Nct; ++n) {
        if (DMPolytopeTypeGetDim(rct[n]) != dim) continue;
        for (PetscInt r = 0; r < rsize[n]; ++r) {
          PetscInt child;
          PetscCall(DMPlexTransformGetTargetPoint(tr, ct, rct[n], c, r, &child));
          (*parent)[child - fcStart] = c - cStart;
        }
      }
    }
    for (PetscInt p : *parent) PetscCheck(p >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "%s refinement: a fine cell without parent", type);
  }
  PetscCall(DMPlexTransformDestroy(&tr));
  PetscFunctionReturn(0);
}

// SBR (Plaza and Carey's skeleton-based refinement) splits the edges of the marked cells, then, until
// nothing changes, the longest edge of every cell with a split edge, the split edges made consistent
// between ranks through the point star forest (DMLabelPropagate*). Which edge is a cell's longest
// depends only on the coordinates and, for equal lengths, the cell's cone order, which the distribution
// keeps: so the refined mesh does not depend on the number of ranks. Every child stays on its parent's
// rank, and every label but depth and cell type is carried to the children.
PetscErrorCode RefineMarkedSBR(DM coarse, const std::vector<char> &marked, DM *fine, std::vector<PetscInt> *parent)
{
  DMLabel  active;
  PetscInt dim, cStart, cEnd;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(coarse, &dim));
  PetscCheck(dim == 2, PetscObjectComm((PetscObject)coarse), PETSC_ERR_SUP, "refine_sbr refines triangles only, not a mesh of dimension %d", (int)dim);
  PetscCall(DMPlexGetHeightStratum(coarse, 0, &cStart, &cEnd));
  PetscCheck((PetscInt)marked.size() == cEnd - cStart, PETSC_COMM_SELF, PETSC_ERR_ARG_SIZ, "%d marks for %d cells", (int)marked.size(), (int)(cEnd - cStart));
  // The active label is not one of the mesh's labels, so it is not carried to the fine mesh.
  PetscCall(DMLabelCreate(PETSC_COMM_SELF, "adapt", &active));
  for (PetscInt c = cStart; c < cEnd; ++c)
    if (marked[c - cStart]) PetscCall(DMLabelSetValue(active, c, DM_ADAPT_REFINE));
  PetscCall(TransformRefine(coarse, DMPLEXREFINESBR, active, fine, parent));
  PetscCall(DMLabelDestroy(&active));
  PetscCall(PetscObjectSetName((PetscObject)*fine, "mesh"));
  PetscFunctionReturn(0);
}

PetscErrorCode RefineMarked(DM coarse, const std::vector<char> &marked, LocalRefinement how, DM *fine, std::vector<PetscInt> *parent, std::vector<char> *corners)
{
  PetscInt dim;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(coarse, &dim));
  if (corners) corners->clear();
  if (how != LocalRefinement::SBR) PetscCall(RefineMarkedBisection(coarse, marked, fine, parent, how == LocalRefinement::BisectionAll, corners));
  else if (dim == 2) PetscCall(RefineMarkedSBR(coarse, marked, fine, parent));
  else SIGNORINI_INPUT_ERROR(PetscObjectComm((PetscObject)coarse), "option -adapt_refinement: sbr refines triangles only; use bisection or bisection_all for tetrahedra");
  PetscFunctionReturn(0);
}

} // namespace signorini

// Geometric multigrid over the uniform refinement hierarchy for the reduced (inactive-set) systems of the
// contact solve (-vi_pc_type mg with nested iteration).
//
// Transfers: P_l maps the DOFs of level l-1 to those of level l by the rules of transfer.h, assembled as a
// matrix (fine x coarse): a fine DOF's row holds the coarse basis functions of its parent cell at the DOF's
// point, averaged over the fine cells that hold the DOF (P1: all give the same row; CR: a fine face on a
// coarse face takes the mean of both sides). Rows of fine Dirichlet DOFs and columns of coarse Dirichlet
// DOFs are left empty: the correction never touches u_D (the Dirichlet rows of A are identity rows that
// the smoother solves exactly).
//
// Truncation on the active set (the rule chosen here): the finest level keeps the rows of its inactive
// set I_L only (the rows of active DOFs removed, as in truncated nonsmooth Newton multigrid, Graeser &
// Kornhuber 2009); a coarse DOF stays in the coarse space iff its column of the row-truncated P is not
// zero, i.e. iff its truncated basis function is not zero; the next coarser transfer keeps the rows of
// those DOFs, and so on. The coarse operators are the Galerkin products P_t^T A P_t of the truncated
// transfers, which stay SPD; with the symmetric smoothing the V-cycle is symmetric, so CG stays
// applicable. (The coarse levels' own stiffness matrices restricted to the kept DOFs were measured as the
// alternative: without the truncation of the operator, paper-5.1 P1 N = 512 took 45 CG iterations on the
// finest level instead of 8, and CR's iterations grew with every level.)
#pragma once

#include "signorini/space.h"
#include "signorini/transfer.h"

#include <petscksp.h>

#include <vector>

namespace signorini {

// P (global fine x global coarse), parent as in transfer.h. Collective.
PetscErrorCode ProlongationMatrix(const Space &coarse, const Space &fine, const std::vector<PetscInt> &parent, Mat *P);
// The embedding of P1 into CR on one mesh (P1 is a subspace of CR): a face's row holds 1/d for each of its
// vertices (Dirichlet rows and columns empty, as above). Collective.
PetscErrorCode P1ToCRMatrix(const Space &p1, const Space &cr, Mat *Q);

// Adaptive refinement (adapt.h) may redistribute the fine mesh before the fine space exists, so the P1
// transfer to it is first recorded on the fine cells, on the ranks of their parents, travels with the
// cells (MigrateCellValues) and is assembled once the fine space exists. The rows are those of
// ProlongationMatrix for P1 (the coarse basis functions at the fine vertex, which any nested refinement,
// uniform or not, reproduces exactly), the columns the coarse space's global indices, which stay valid
// however the fine mesh is distributed.
struct TransferRecord {
  // Per fine cell (c - cStart) the dim + 1 coarse global columns of its parent cell (-1: a Dirichlet
  // DOF), then for each of its dim + 1 vertices in the order of the cell tables the weights of those
  // columns (the parent's barycentric coordinates of the vertex, 0 where below 1e-12 in magnitude): a
  // CellValues whose "DOFs per cell" are the (dim + 1) (dim + 2) / 2 pairs of values.
  CellValues cells;
  PetscInt   coarseOwned = 0, coarseGlobal = 0; // the coarse space's layout
};
// On the fine mesh alone (P1 coarse space). Local to each rank.
PetscErrorCode RecordP1Transfer(const Space &coarse, DM fine, const std::vector<PetscInt> &parent, TransferRecord &r);
// P (global fine x global coarse) from the record of fine's cells, fine a P1 space. Collective.
PetscErrorCode AssembleP1Transfer(const TransferRecord &r, const Space &fine, Mat *P);

// The transfers between consecutive levels, coarse to fine: P[l] maps level l to level l+1. Only the
// matrices are kept (no meshes, no spaces).
struct Hierarchy {
  std::vector<Mat> P;
  PetscErrorCode   Destroy();
};

// Pt = P restricted to the rows `rows` (owned global fine indices, ascending) and to the columns that are
// not zero there, listed in *cols (owned global coarse indices, ascending). P's entries must be
// nonnegative, as those of the multigrid's transfers are (P1 basis values, vertex means): the CR-to-CR
// prolongation has negative ones and is not truncated. Collective.
PetscErrorCode TruncateTransfer(Mat P, IS rows, IS *cols, Mat *Pt);
// The same Pt as TruncateTransfer's (rows, cols as it returns them) without a copy of P's entries: a shell
// that applies P on vectors zero outside them (Mult, MultAdd, MultTranspose, MultTransposeAdd, with the
// results of the AIJ copy bit for bit). It keeps P and a work vector of each of P's sizes. Collective.
PetscErrorCode TruncatedTransferShell(Mat P, IS rows, IS cols, Mat *T);

// Makes pc a symmetric multigrid V-cycle for A_II = A (the inactive-set block; inactive: its rows, owned
// global indices of the finest level of h, ascending) with the truncated transfers of h and Galerkin
// coarse operators; smoother symmetric Gauss-Seidel (one sweep before, one after), BoomerAMG on the coarsest level.
// The -mg_levels_* and -mg_coarse_* options (with pc's prefix) still decide. Sets pc up.
PetscErrorCode HierarchyMGSetUp(PC pc, const Hierarchy &h, Mat A, IS inactive);

} // namespace signorini

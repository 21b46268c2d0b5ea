// Unit tests of the inactive-set blocks of the contact Jacobian (AmgReuseJacobian), which store no entries
// and act through the whole matrix, on however many ranks the test runs (ctest runs it on 1 and 2).
// Compared with an independent computation: the AIJ block that MatCreateSubMatrix extracts from A.
//   - the block's product, transpose product and diagonal equal those of the extracted block, for an
//     inactive set with holes on every rank, for all rows, and for a set that leaves one rank empty;
//   - a second product with another vector still matches (the entries outside I stay zero);
//   - the block has the sizes of the extracted one, and the Jacobian itself acts as A.
#include "signorini/amgreuse.h"
#include "signorini/common.h"
#include "unit_check.h"

#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

// An SPD matrix with a 2D five-point pattern and row-dependent diagonal, so that every entry matters.
static PetscErrorCode MakeMatrix(MPI_Comm comm, PetscInt nx, PetscInt ny, Mat *A)
{
  PetscInt rstart, rend;
  PetscFunctionBeginUser;
  PetscCall(MatCreateAIJ(comm, PETSC_DECIDE, PETSC_DECIDE, nx * ny, nx * ny, 5, NULL, 2, NULL, A));
  PetscCall(MatGetOwnershipRange(*A, &rstart, &rend));
  for (PetscInt r = rstart; r < rend; ++r) {
    const PetscInt i = r % nx, j = r / nx;
    PetscCall(MatSetValue(*A, r, r, 4.0 + (r % 7), INSERT_VALUES));
    if (i > 0) PetscCall(MatSetValue(*A, r, r - 1, -1.0, INSERT_VALUES));
    if (i + 1 < nx) PetscCall(MatSetValue(*A, r, r + 1, -1.0, INSERT_VALUES));
    if (j > 0) PetscCall(MatSetValue(*A, r, r - nx, -1.0, INSERT_VALUES));
    if (j + 1 < ny) PetscCall(MatSetValue(*A, r, r + nx, -1.0, INSERT_VALUES));
  }
  PetscCall(MatAssemblyBegin(*A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

static PetscErrorCode FillVector(Vec x, PetscReal phase)
{
  PetscInt     rstart, n;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(VecGetOwnershipRange(x, &rstart, NULL));
  PetscCall(VecGetLocalSize(x, &n));
  PetscCall(VecGetArray(x, &a));
  for (PetscInt k = 0; k < n; ++k) a[k] = std::sin(phase + 0.7 * (rstart + k));
  PetscCall(VecRestoreArray(x, &a));
  PetscFunctionReturn(0);
}

// max |a - b| / max |b|
static PetscErrorCode RelativeDifference(Vec a, Vec b, PetscReal *rel)
{
  Vec       d;
  PetscReal nd, nb;
  PetscFunctionBeginUser;
  PetscCall(VecDuplicate(a, &d));
  PetscCall(VecWAXPY(d, -1.0, b, a));
  PetscCall(VecNorm(d, NORM_INFINITY, &nd));
  PetscCall(VecNorm(b, NORM_INFINITY, &nb));
  *rel = nd / PetscMax(nb, PETSC_SMALL);
  PetscCall(VecDestroy(&d));
  PetscFunctionReturn(0);
}

// Owned rows that stay inactive: keep(global row) decides.
template <class Keep>
static PetscErrorCode MakeSet(Mat A, Keep keep, IS *is)
{
  PetscInt rstart, rend;
  PetscFunctionBeginUser;
  PetscCall(MatGetOwnershipRange(A, &rstart, &rend));
  std::vector<PetscInt> rows;
  for (PetscInt r = rstart; r < rend; ++r)
    if (keep(r)) rows.push_back(r);
  PetscCall(ISCreateGeneral(PetscObjectComm((PetscObject)A), (PetscInt)rows.size(), rows.data(), PETSC_COPY_VALUES, is));
  PetscFunctionReturn(0);
}

static PetscErrorCode CompareBlocks(unit::Checker &ck, Mat J, Mat A, IS is, const std::string &name)
{
  Mat       B, R;
  Vec       x, yB, yR;
  PetscInt  mB, nB, MB, NB, mR, nR, MR, NR;
  PetscReal rel;
  PetscFunctionBeginUser;
  PetscCall(MatCreateSubMatrix(J, is, is, MAT_INITIAL_MATRIX, &B));
  PetscCall(MatCreateSubMatrix(A, is, is, MAT_INITIAL_MATRIX, &R));
  PetscCall(MatGetLocalSize(B, &mB, &nB));
  PetscCall(MatGetSize(B, &MB, &NB));
  PetscCall(MatGetLocalSize(R, &mR, &nR));
  PetscCall(MatGetSize(R, &MR, &NR));
  ck.Check(mB == mR && nB == nR && MB == MR && NB == NR, name + ": block sizes", "block %d x %d (local %d x %d), extracted %d x %d (local %d x %d)", (int)MB, (int)NB, (int)mB, (int)nB, (int)MR, (int)NR, (int)mR, (int)nR);
  PetscCall(MatCreateVecs(R, &x, &yR));
  PetscCall(VecDuplicate(yR, &yB));
  for (int pass = 0; pass < 2; ++pass) {
    PetscCall(FillVector(x, 1.3 * pass));
    PetscCall(MatMult(B, x, yB));
    PetscCall(MatMult(R, x, yR));
    PetscCall(RelativeDifference(yB, yR, &rel));
    ck.Check(rel <= 1e-14, Format("%s: product %d", name.c_str(), pass + 1), "relative difference %.3g", (double)rel);
  }
  PetscCall(MatMultTranspose(B, x, yB));
  PetscCall(MatMultTranspose(R, x, yR));
  PetscCall(RelativeDifference(yB, yR, &rel));
  ck.Check(rel <= 1e-14, name + ": transpose product", "relative difference %.3g", (double)rel);
  PetscCall(MatGetDiagonal(B, yB));
  PetscCall(MatGetDiagonal(R, yR));
  PetscCall(RelativeDifference(yB, yR, &rel));
  ck.Check(rel == 0, name + ": diagonal", "relative difference %.3g", (double)rel);
  PetscCall(VecDestroy(&x));
  PetscCall(VecDestroy(&yB));
  PetscCall(VecDestroy(&yR));
  PetscCall(MatDestroy(&B));
  PetscCall(MatDestroy(&R));
  PetscFunctionReturn(0);
}

static PetscErrorCode Run(unit::Checker &ck)
{
  MPI_Comm        comm = PETSC_COMM_WORLD;
  Mat             A, J;
  SNES            snes;
  AmgReuseOptions opts;
  AmgReuseStats   stats;
  PetscFunctionBeginUser;
  PetscCall(MakeMatrix(comm, 13, 11, &A));
  PetscCall(SNESCreate(comm, &snes));
  PetscCall(SNESSetType(snes, SNESVINEWTONRSLS));
  PetscCall(AmgReuseInstall(snes, opts, &stats));
  PetscCall(AmgReuseJacobian(snes, A, &J));
  PetscBool shell;
  PetscCall(PetscObjectTypeCompare((PetscObject)J, MATSHELL, &shell));
  ck.Check(shell && J != A, "with BoomerAMG in the re-use shell the Jacobian hands out entry-free blocks");
  {
    Vec       x, yJ, yA;
    PetscReal rel;
    PetscCall(MatCreateVecs(A, &x, &yA));
    PetscCall(VecDuplicate(yA, &yJ));
    PetscCall(FillVector(x, 0.4));
    PetscCall(MatMult(J, x, yJ));
    PetscCall(MatMult(A, x, yA));
    PetscCall(RelativeDifference(yJ, yA, &rel));
    ck.Check(rel == 0, "the Jacobian acts as A", "relative difference %.3g", (double)rel);
    PetscCall(VecDestroy(&x));
    PetscCall(VecDestroy(&yJ));
    PetscCall(VecDestroy(&yA));
  }
  PetscInt rows;
  PetscCall(MatGetSize(A, &rows, NULL));
  IS is;
  PetscCall(MakeSet(A, [](PetscInt r) { return r % 5 != 2 && r % 11 != 0; }, &is));
  PetscCall(CompareBlocks(ck, J, A, is, "set with holes"));
  PetscCall(ISDestroy(&is));
  PetscCall(MakeSet(A, [](PetscInt) { return true; }, &is));
  PetscCall(CompareBlocks(ck, J, A, is, "all rows"));
  PetscCall(ISDestroy(&is));
  PetscCall(MakeSet(A, [rows](PetscInt r) { return r < rows / 3; }, &is)); // the last rank keeps none
  PetscCall(CompareBlocks(ck, J, A, is, "first third of the rows"));
  PetscCall(ISDestroy(&is));
  PetscCall(MatDestroy(&J));
  PetscCall(SNESDestroy(&snes));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  ierr = Run(ck);
  if (ierr) ck.PetscFailure(ierr, "entry-free blocks (PETSc error)");
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

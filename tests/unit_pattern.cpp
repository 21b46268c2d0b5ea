// Unit tests of the stiffness matrix's preallocation (CreateStiffnessMatrix, used by AssembleSystem) on
// small 2D and 3D box meshes, P1 and CR, on however many ranks the test runs (ctest runs it on 1 and 2):
//   - no mallocs during assembly and no slack (nz_allocated == nz_used, summed over ranks);
//   - the same pattern, row by row, and the same values as a matrix preallocated independently by PETSc's
//     DMCreateMatrix (DMPlexPreallocate walks the mesh topology, not our cell table) and assembled from the
//     same element matrices with the same Dirichlet elimination;
//   - an insertion outside the pattern fails (MAT_NEW_NONZERO_ALLOCATION_ERR), and the matrix type and
//     symmetry flag are as documented.
#include "signorini/assembly.h"
#include "signorini/mesh.h"
#include "signorini/pattern.h"
#include "signorini/space.h"
#include "unit_check.h"

#include <algorithm>
#include <string>
#include <vector>

using namespace signorini;

struct PatternCase {
  std::string name;
  MeshOptions mesh;
  Element     element;
  PetscInt    dirichlet, contact; // "Face Sets" values
};

// The reference: DMCreateMatrix's preallocation, the same element matrices, the same elimination.
static PetscErrorCode ReferenceMatrix(const Space &space, const System &sys, Mat *B)
{
  const PetscInt nb = space.Nb();
  PetscReal      Ke[16];
  PetscInt       rstart;
  PetscFunctionBeginUser;
  DM sectionDM;
  PetscCall(SpaceSectionDM(space, &sectionDM));
  PetscCall(DMCreateMatrix(sectionDM, B));
  PetscCall(DMDestroy(&sectionDM));
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    CellGeometry g;
    ComputeCellGeometry(space.dim, space.X(c), g);
    ElementStiffness(space, c, sys.Kappa(c), g, Ke);
    PetscCall(MatSetValuesLocal(*B, nb, space.Dofs(c), nb, space.Dofs(c), Ke, ADD_VALUES));
  }
  PetscCall(MatAssemblyBegin(*B, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*B, MAT_FINAL_ASSEMBLY));
  PetscCall(MatGetOwnershipRange(*B, &rstart, NULL));
  std::vector<PetscInt> rows(space.dirichletOwned);
  for (PetscInt &r : rows) r += rstart;
  PetscCall(MatZeroRowsColumns(*B, (PetscInt)rows.size(), rows.data(), 1.0, NULL, NULL));
  PetscFunctionReturn(0);
}

// Number of owned rows whose column indices differ between A and B (collective: summed over ranks).
static PetscErrorCode PatternDifferences(Mat A, Mat B, PetscInt *differ)
{
  PetscInt rstart, rend, local = 0;
  PetscFunctionBeginUser;
  PetscCall(MatGetOwnershipRange(A, &rstart, &rend));
  for (PetscInt r = rstart; r < rend; ++r) {
    PetscInt        na, nb;
    const PetscInt *ca, *cb;
    PetscCall(MatGetRow(A, r, &na, &ca, NULL));
    std::vector<PetscInt> colsA(ca, ca + na);
    PetscCall(MatRestoreRow(A, r, &na, &ca, NULL));
    PetscCall(MatGetRow(B, r, &nb, &cb, NULL));
    std::vector<PetscInt> colsB(cb, cb + nb);
    PetscCall(MatRestoreRow(B, r, &nb, &cb, NULL));
    local += colsA != colsB;
  }
  PetscCallMPI(MPI_Allreduce(&local, differ, 1, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)A)));
  PetscFunctionReturn(0);
}

// Tries to add a value at a column of an owned row outside the pattern (within the owned column range,
// so the error comes from the diagonal block's allocation check on this rank). Returns, summed over ranks,
// the number of ranks where such an insertion was attempted and the number where it was refused.
static PetscErrorCode OutsidePatternRefused(Mat A, PetscInt *attempted, PetscInt *refused)
{
  PetscInt rstart, rend, local[2] = {0, 0};
  PetscFunctionBeginUser;
  PetscCall(MatGetOwnershipRange(A, &rstart, &rend));
  for (PetscInt r = rstart; r < rend && !local[0]; ++r) {
    PetscInt        n;
    const PetscInt *cols;
    PetscCall(MatGetRow(A, r, &n, &cols, NULL));
    std::vector<PetscInt> present(cols, cols + n);
    PetscCall(MatRestoreRow(A, r, &n, &cols, NULL));
    for (PetscInt c = rstart; c < rend && !local[0]; ++c) {
      if (std::find(present.begin(), present.end(), c) != present.end()) continue;
      local[0] = 1;
      PetscCall(PetscPushErrorHandler(PetscReturnErrorHandler, NULL));
      const PetscErrorCode ierr = MatSetValue(A, r, c, 1.0, ADD_VALUES);
      PetscCall(PetscPopErrorHandler());
      local[1] = ierr != 0;
    }
  }
  PetscInt sums[2];
  PetscCallMPI(MPI_Allreduce(local, sums, 2, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)A)));
  *attempted = sums[0], *refused = sums[1];
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const PatternCase &pc)
{
  MPI_Comm        comm = PETSC_COMM_WORLD;
  DM              dm   = nullptr;
  MeshInfo        info;
  Problem         problem;
  Space           space;
  System          sys;
  Mat             B;
  AssemblyOptions opts;
  PetscMPIInt     size;
  const std::string &tag = pc.name;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(MeshCreate(comm, pc.mesh, &dm, info));
  // u_D = x puts values into the elimination; kappa takes cell-wise different values
  PetscCall(unit::MakeProblem(comm, pc.mesh.dim, {{pc.dirichlet}, {pc.contact}, "1", "0", "x", "0", "1 + x + 2 * y"}, problem));
  PetscCall(SpaceCreate(dm, pc.element, problem, space));
  PetscCall(AssembleSystem(space, problem, opts, sys));

  MatInfo mi;
  PetscCall(MatGetInfo(sys.A, MAT_GLOBAL_SUM, &mi));
  ck.Check(mi.mallocs == 0, tag + " no mallocs during assembly", "%g mallocs", mi.mallocs);
  ck.Check(mi.nz_allocated == mi.nz_used, tag + " exact preallocation (nz_allocated == nz_used)", "allocated %g, used %g", mi.nz_allocated, mi.nz_used);
  PetscBool aij;
  PetscCall(PetscObjectTypeCompare((PetscObject)sys.A, size == 1 ? MATSEQAIJ : MATMPIAIJ, &aij));
  ck.Check(aij, tag + (size == 1 ? " type seqaij" : " type mpiaij"));
  PetscBool known, symmetric;
  PetscCall(MatIsSymmetricKnown(sys.A, &known, &symmetric));
  ck.Check(known && symmetric, tag + " marked symmetric after assembly and elimination");

  PetscCall(ReferenceMatrix(space, sys, &B));
  MatInfo ri;
  PetscCall(MatGetInfo(B, MAT_GLOBAL_SUM, &ri));
  ck.Check(ri.nz_used == mi.nz_used, tag + " nonzero count equals DMCreateMatrix's", "ours %g, DMCreateMatrix %g", mi.nz_used, ri.nz_used);
  PetscInt differ;
  PetscCall(PatternDifferences(sys.A, B, &differ));
  ck.Check(differ == 0, tag + " pattern equals DMCreateMatrix's row by row", "%d rows differ", (int)differ);
  PetscReal normA, normDiff;
  PetscCall(MatNorm(sys.A, NORM_FROBENIUS, &normA));
  PetscCall(MatAXPY(B, -1.0, sys.A, differ ? DIFFERENT_NONZERO_PATTERN : SAME_NONZERO_PATTERN));
  PetscCall(MatNorm(B, NORM_FROBENIUS, &normDiff));
  ck.Check(normA > 0 && normDiff == 0, tag + " values equal the DMCreateMatrix-preallocated assembly", "|A| %g, |A - B| %g", (double)normA, (double)normDiff);
  PetscCall(MatDestroy(&B));

  PetscInt attempted = 0, refused = 0;
  PetscCall(OutsidePatternRefused(sys.A, &attempted, &refused));
  ck.Check(attempted > 0 && refused == attempted, tag + " insertion outside the pattern is refused", "%d of %d attempts refused", (int)refused, (int)attempted);

  PetscCall(SystemDestroy(sys));
  PetscCall(SpaceDestroy(space));
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

static std::vector<PatternCase> Cases()
{
  std::vector<PatternCase> out;
  for (Element e : {Element::P1, Element::CR}) {
    PatternCase pc;
    pc.element       = e;
    pc.mesh.dim      = 2;
    pc.mesh.faces[0] = 6, pc.mesh.faces[1] = 5;
    pc.mesh.diagonal = Diagonal::Crossed; // vertices of valence 4 and 8
    pc.dirichlet = 3, pc.contact = 1;
    pc.name = Format("2D 6x5 crossed %s", ElementName(e));
    out.push_back(pc);
    pc.mesh.faces[0] = 3, pc.mesh.faces[1] = 2;
    pc.mesh.diagonal = Diagonal::Backslash;
    pc.mesh.refine   = 2; // parallel refinement: rows shared along the refined partition boundary
    pc.name          = Format("2D 3x2 backslash refine 2 %s", ElementName(e));
    out.push_back(pc);
    pc.mesh.dim      = 3;
    pc.mesh.faces[0] = 3, pc.mesh.faces[1] = 3, pc.mesh.faces[2] = 2;
    pc.mesh.refine   = 0;
    pc.dirichlet = 2, pc.contact = 1;
    pc.name = Format("3D 3x3x2 %s", ElementName(e));
    out.push_back(pc);
    pc.mesh.faces[0] = 2, pc.mesh.faces[1] = 1, pc.mesh.faces[2] = 1;
    pc.mesh.refine   = 1;
    pc.name          = Format("3D 2x1x1 refine 1 %s", ElementName(e));
    out.push_back(pc);
  }
  return out;
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  for (const PatternCase &pc : Cases()) {
    ierr = TestCase(ck, pc);
    if (ierr) ck.PetscFailure(ierr, pc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

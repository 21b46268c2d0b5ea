// Unit tests of the size prediction (sizes.h): the counts predicted for a box (from its grid) and for a
// refined mesh (from the refinement recurrences) against the points of the meshes MeshCreate builds, and
// the predicted matrix nonzeros against the exact sparsity of DMCreateMatrix for one DOF per vertex (P1)
// and per face (CR). Independent computations: PETSc's own strata and preallocation. One rank (the strata
// of a distributed mesh count shared points twice).
#include "signorini/sizes.h"
#include "unit_check.h"

#include <string>

using namespace signorini;

// Exact nonzeros of the matrix with one DOF per vertex or per face (height 1).
static PetscErrorCode MatrixNonzeros(DM dm, bool vertices, double *nz)
{
  PetscSection s;
  PetscInt     pStart, pEnd, qStart, qEnd;
  Mat          A;
  MatInfo      info;
  DM           copy;
  PetscFunctionBeginUser;
  PetscCall(DMClone(dm, &copy));
  PetscCall(DMPlexGetChart(copy, &pStart, &pEnd));
  if (vertices) PetscCall(DMPlexGetDepthStratum(copy, 0, &qStart, &qEnd));
  else PetscCall(DMPlexGetHeightStratum(copy, 1, &qStart, &qEnd));
  PetscCall(PetscSectionCreate(PETSC_COMM_WORLD, &s));
  PetscCall(PetscSectionSetChart(s, pStart, pEnd));
  for (PetscInt p = qStart; p < qEnd; ++p) PetscCall(PetscSectionSetDof(s, p, 1));
  PetscCall(PetscSectionSetUp(s));
  PetscCall(DMSetLocalSection(copy, s));
  PetscCall(PetscSectionDestroy(&s));
  PetscCall(DMCreateMatrix(copy, &A));
  PetscCall(MatGetInfo(A, MAT_GLOBAL_SUM, &info));
  *nz = info.nz_allocated;
  PetscCall(MatDestroy(&A));
  PetscCall(DMDestroy(&copy));
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const std::string &tag, const MeshOptions &o, const MeshCounts &coarse)
{
  DM         dm;
  MeshInfo   info;
  MeshCounts actual;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(PETSC_COMM_WORLD, o, &dm, info));
  PetscCall(CountMesh(dm, actual));
  const MeshCounts p = Refined(coarse, o.refine);
  ck.Check(p.v == actual.v && p.e == actual.e && p.f == actual.f && p.c == actual.c, tag + ": predicted points", "predicted V %g E %g F %g C %g, mesh V %g E %g F %g C %g", p.v, p.e, p.f, p.c, actual.v, actual.e, actual.f, actual.c);
  for (Element e : {Element::P1, Element::CR}) {
    double nz = 0;
    PetscCall(MatrixNonzeros(dm, e == Element::P1, &nz));
    ck.Check(Nonzeros(p, e) == nz, tag + ": predicted " + ElementName(e) + " nonzeros", "predicted %g, DMCreateMatrix %g", Nonzeros(p, e), nz);
  }
  PetscCall(DMDestroy(&dm));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  MeshOptions   o;
  o.faces[0] = 3, o.faces[1] = 5, o.faces[2] = 2;
  for (Diagonal d : {Diagonal::Slash, Diagonal::Crossed})
    for (PetscInt k : {0, 2}) {
      o.diagonal = d, o.refine = k;
      PetscCall(TestCase(ck, Format("2D box 3x5 %s refine %d", d == Diagonal::Slash ? "slash" : "crossed", (int)k), o, BoxCounts(o)));
    }
  o.dim = 3;
  for (PetscInt k : {0, 2}) {
    o.refine = k;
    PetscCall(TestCase(ck, Format("3D box 3x5x2 refine %d", (int)k), o, BoxCounts(o)));
  }
  // A Gmsh mesh: the prediction starts from the counts of the read coarse mesh.
  for (const char *name : {"square.msh", "cube.msh"}) {
    MeshOptions g;
    DM          coarse;
    MeshInfo    info;
    MeshCounts  counts;
    g.file = std::string(SIGNORINI_TEST_DATA) + "/" + name;
    PetscCall(MeshCreate(PETSC_COMM_WORLD, g, &coarse, info));
    PetscCall(CountMesh(coarse, counts));
    PetscCall(DMDestroy(&coarse));
    g.refine = 1;
    PetscCall(TestCase(ck, Format("%s refine 1", name), g, counts));
  }
  const int failed = ck.Finish();
  PetscCall(PetscFinalize());
  return failed;
}

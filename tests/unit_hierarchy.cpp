// Unit tests of the multigrid transfers over the refinement hierarchy (hierarchy.h), P1 and CR, 2D and 3D,
// on however many ranks the test runs (ctest: 1 and 2), over three nested levels:
//   - the assembled prolongation P applied to a coarse function equals the transfer of transfer.h
//     (Prolongate, tested on its own in unit_prolongation) at every fine DOF that is not Dirichlet, for a
//     coarse function that vanishes on Gamma_D (P leaves Dirichlet rows and columns empty);
//   - the multigrid's hierarchy as nested iteration builds it (P1: the transfers above; CR: P1 on every
//     level, then P1 to CR on the finest mesh), and on it:
//   - the truncated transfer of an inactive set I (contact DOFs with x < 0.5 active) is P restricted to
//     the rows of I and the kept coarse columns: embedded back into the full spaces it vanishes on the
//     active DOFs (where P itself does not) and equals P on I; every coarse column it drops is zero on I;
//   - P1: the transfer recorded on the fine cells and assembled (adapt.h) has P's entries bit for bit;
//   - CR: the transfer from P1 on the same mesh (the multigrid's level below a CR level) gives each face
//     the mean of the P1 function's values at the face's vertices, computed here from the cell tables, and
//     has the entries of its construction by MatSetValues bit for bit; the P1 space made from the CR
//     space's tables (SpaceCreateP1Of) is SpaceCreate's (also on the adaptive meshes below);
//   - the Galerkin coarse operators of the multigrid preconditioner (PCMG's MatPtAP, on each coarser
//     level) equal R A P computed directly, column by column, with matrix-vector products only, from
//     the inactive-set block and the truncated transfers;
//   - over three adaptive steps (bisection of the cells near one corner, the new mesh redistributed on
//     more than one rank), the P1 transfers recorded on the new cells and assembled on the new space
//     (adapt.h): P uH equals the transfer of transfer.h (EvaluateOnCells, moved with the cells,
//     ApplyCellValues) off Gamma_D, P reproduces a linear function that vanishes on Gamma_D exactly (on
//     one rank, without the redistribution, ProlongationMatrix gives the same entries bit for bit), and
//     the Galerkin coarse operators of the multigrid over those levels (for CR with P1 to CR on top)
//     equal R A P.
#include "signorini/assembly.h"
#include "signorini/hierarchy.h"
#include "signorini/localrefine.h"
#include "signorini/mesh.h"
#include "signorini/stages.h"
#include "signorini/transfer.h"
#include "unit_check.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

struct HierarchyCase {
  std::string name;
  MeshOptions mesh;
  Element     element;
  PetscInt    dirichlet, contact;
};

// A smooth generic function of the DOF points, zero at Dirichlet DOFs: a global vector of the space.
static PetscErrorCode Generic(const Space &s, Vec u)
{
  Vec          loc;
  PetscScalar *a;
  PetscFunctionBeginUser;
  const std::vector<PetscReal> points = DofPoints(s);
  PetscCall(DMGetLocalVector(s.dm, &loc));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < s.numLocal; ++i) {
    const PetscReal *x = &points[i * s.dim];
    a[i]               = s.kindLocal[i] == kDirichlet ? 0.0 : std::sin(7 * x[0] + 3 * x[1] + (s.dim == 3 ? 5 * x[2] : 0.0)) + 1.5;
  }
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(s.dm, loc, INSERT_VALUES, u));
  PetscCall(DMRestoreLocalVector(s.dm, &loc));
  PetscFunctionReturn(0);
}

// The inactive set of the test: every owned DOF except contact DOFs with x < 0.5 (owned global indices).
static PetscErrorCode TestInactiveSet(const Space &s, IS *inactive, std::vector<char> &active)
{
  PetscInt rstart;
  Vec      u;
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(s.dm, &u));
  PetscCall(VecGetOwnershipRange(u, &rstart, NULL));
  // The owned x coordinate of every DOF, through the layout (owned index -> point).
  Vec          loc;
  PetscScalar *a;
  const std::vector<PetscReal> points = DofPoints(s);
  PetscCall(DMGetLocalVector(s.dm, &loc));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < s.numLocal; ++i) a[i] = points[i * s.dim];
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(s.dm, loc, INSERT_VALUES, u));
  PetscCall(DMRestoreLocalVector(s.dm, &loc));
  std::vector<char> isContact(s.numOwned, 0);
  for (PetscInt i : s.contactOwned) isContact[i] = 1;
  const PetscScalar    *x;
  std::vector<PetscInt> idx;
  active.assign(s.numOwned, 0);
  PetscCall(VecGetArrayRead(u, &x));
  for (PetscInt i = 0; i < s.numOwned; ++i) {
    active[i] = isContact[i] && PetscRealPart(x[i]) < 0.5;
    if (!active[i]) idx.push_back(rstart + i);
  }
  PetscCall(VecRestoreArrayRead(u, &x));
  PetscCall(VecDestroy(&u));
  PetscCall(ISCreateGeneral(PETSC_COMM_WORLD, (PetscInt)idx.size(), idx.data(), PETSC_COPY_VALUES, inactive));
  PetscFunctionReturn(0);
}

// full = embedding of the sub-vector (entries at the global indices `kept`) into a vector of full's size.
static PetscErrorCode Embed(IS kept, Vec sub, Vec full)
{
  VecScatter sc;
  PetscFunctionBeginUser;
  PetscCall(VecSet(full, 0));
  PetscCall(VecScatterCreate(sub, NULL, full, kept, &sc));
  PetscCall(VecScatterBegin(sc, sub, full, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(sc, sub, full, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterDestroy(&sc));
  PetscFunctionReturn(0);
}

static PetscErrorCode RestrictTo(IS kept, Vec full, Vec sub)
{
  VecScatter sc;
  PetscFunctionBeginUser;
  PetscCall(VecScatterCreate(full, kept, sub, NULL, &sc));
  PetscCall(VecScatterBegin(sc, full, sub, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(sc, full, sub, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterDestroy(&sc));
  PetscFunctionReturn(0);
}

// max over the columns e_j of |R A P e_j - Ac e_j| / max |Ac|, R = P^T, from matrix-vector products only.
static PetscErrorCode GalerkinError(Mat A, Mat P, Mat Ac, PetscReal *err)
{
  Vec       e, Pe, APe, RAPe, Ace;
  PetscInt  N, cstart, cend;
  PetscReal scale;
  PetscFunctionBeginUser;
  PetscCall(MatCreateVecs(P, &e, &Pe));
  PetscCall(VecDuplicate(Pe, &APe));
  PetscCall(VecDuplicate(e, &RAPe));
  PetscCall(VecDuplicate(e, &Ace));
  PetscCall(VecGetSize(e, &N));
  PetscCall(VecGetOwnershipRange(e, &cstart, &cend));
  PetscCall(MatNorm(Ac, NORM_INFINITY, &scale));
  *err = 0;
  for (PetscInt j = 0; j < N; ++j) {
    PetscReal d;
    PetscCall(VecSet(e, 0));
    if (j >= cstart && j < cend) PetscCall(VecSetValue(e, j, 1.0, INSERT_VALUES));
    PetscCall(VecAssemblyBegin(e));
    PetscCall(VecAssemblyEnd(e));
    PetscCall(MatMult(P, e, Pe));
    PetscCall(MatMult(A, Pe, APe));
    PetscCall(MatMultTranspose(P, APe, RAPe));
    PetscCall(MatMult(Ac, e, Ace));
    PetscCall(VecAXPY(Ace, -1.0, RAPe));
    PetscCall(VecNorm(Ace, NORM_INFINITY, &d));
    *err = std::max(*err, d / scale);
  }
  for (Vec *v : {&e, &Pe, &APe, &RAPe, &Ace}) PetscCall(VecDestroy(v));
  PetscFunctionReturn(0);
}

static PetscErrorCode CheckGalerkin(unit::Checker &ck, const std::string &tag, const Space &fine, const Problem &problem, const Hierarchy &mg, IS inactive, PetscInt expected);

// Whether P is allocated to exactly its entries, and the entries allocated and used. PETSc counts the
// allocation it made; a transfer made on one rank lies on arrays handed to PETSc (hierarchy.cpp), sized
// to its entries there, of which PETSc counts none: those are told apart by the container that owns them.
static PetscErrorCode AllocatedToEntries(Mat P, bool *exact, PetscReal *allocated, PetscReal *used)
{
  MatInfo     info;
  PetscObject arrays;
  PetscFunctionBeginUser;
  PetscCall(MatGetInfo(P, MAT_GLOBAL_SUM, &info));
  PetscCall(PetscObjectQuery((PetscObject)P, "signorini_transfer_arrays", &arrays));
  *allocated = info.nz_allocated, *used = info.nz_used;
  *exact     = arrays ? info.nz_allocated == 0 : info.nz_allocated == info.nz_used;
  PetscFunctionReturn(0);
}

// Whether A and B hold the same entries, bit for bit, in the same places (row by row, owned rows). Collective.
static PetscErrorCode SameEntries(Mat A, Mat B, PetscBool *same)
{
  PetscInt rStart, rEnd, M[2], N[2];
  PetscFunctionBeginUser;
  PetscCall(MatGetSize(A, &M[0], &N[0]));
  PetscCall(MatGetSize(B, &M[1], &N[1]));
  *same = (PetscBool)(M[0] == M[1] && N[0] == N[1]);
  PetscCall(MatGetOwnershipRange(A, &rStart, &rEnd));
  for (PetscInt r = rStart; r < rEnd && *same; ++r) {
    const PetscInt    *ca, *cb;
    const PetscScalar *va, *vb;
    PetscInt           na, nb;
    PetscCall(MatGetRow(A, r, &na, &ca, &va));
    PetscCall(MatGetRow(B, r, &nb, &cb, &vb));
    *same = (PetscBool)(na == nb);
    for (PetscInt k = 0; k < na && *same; ++k) *same = (PetscBool)(ca[k] == cb[k] && va[k] == vb[k]);
    PetscCall(MatRestoreRow(B, r, &nb, &cb, &vb));
    PetscCall(MatRestoreRow(A, r, &na, &ca, &va));
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, same, 1, MPIU_BOOL, MPI_LAND, PetscObjectComm((PetscObject)A)));
  PetscFunctionReturn(0);
}

// The transfer from P1 to CR on one mesh as it was first built, entry by entry with MatSetValues (a face's
// row: 1/d at each of its vertices but the Dirichlet ones; Dirichlet rows empty): the reference of
// P1ToCRMatrix's construction.
static PetscErrorCode P1ToCRBySetValues(const Space &p1, const Space &cr, Mat *Q)
{
  const PetscInt *gf, *gc;
  PetscFunctionBeginUser;
  const PetscInt dim = cr.dim, nb = cr.Nb();
  PetscCall(MatCreateAIJ(PetscObjectComm((PetscObject)cr.dm), cr.numOwned, p1.numOwned, cr.numGlobal, p1.numGlobal, dim, NULL, dim, NULL, Q));
  PetscCall(ISLocalToGlobalMappingGetIndices(cr.ltog, &gf));
  PetscCall(ISLocalToGlobalMappingGetIndices(p1.ltog, &gc));
  for (PetscInt c = 0; c < cr.NumCells(); ++c)
    for (PetscInt i = 0; i < nb; ++i) {
      const PetscInt dof = cr.Dofs(c)[i];
      if (cr.kindLocal[dof] == kDirichlet) continue;
      for (PetscInt j = 0; j < nb; ++j) {
        const PetscInt    v = cr.cellVert[c * nb + j];
        const PetscScalar w = 1.0 / dim;
        if (j != i && p1.kindLocal[v] != kDirichlet) PetscCall(MatSetValues(*Q, 1, &gf[dof], 1, &gc[v], &w, INSERT_VALUES));
      }
    }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(p1.ltog, &gc));
  PetscCall(ISLocalToGlobalMappingRestoreIndices(cr.ltog, &gf));
  PetscCall(MatAssemblyBegin(*Q, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*Q, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

// What differs between two spaces that should be the same P1 space (SpaceCreate's and SpaceCreateP1Of's):
// sizes, numbering, DOF kinds, tables; empty if nothing (on any rank). Collective.
static PetscErrorCode SpaceDifference(const Space &a, const Space &b, std::string &what)
{
  const PetscInt *ga, *gb;
  PetscInt        na, nb;
  PetscFunctionBeginUser;
  what.clear();
  if (a.element != b.element || a.numLocal != b.numLocal || a.numOwned != b.numOwned || a.numGlobal != b.numGlobal || a.numContactGlobal != b.numContactGlobal || a.numDirichletGlobal != b.numDirichletGlobal) what = "sizes";
  else if (a.kindLocal != b.kindLocal || a.dirichletOwned != b.dirichletOwned || a.contactOwned != b.contactOwned) what = "DOF kinds";
  else if (a.cellVert != b.cellVert || a.vertX != b.vertX || a.cellSet != b.cellSet || a.boundary.size() != b.boundary.size()) what = "tables";
  else {
    PetscCall(ISLocalToGlobalMappingGetSize(a.ltog, &na));
    PetscCall(ISLocalToGlobalMappingGetSize(b.ltog, &nb));
    PetscCall(ISLocalToGlobalMappingGetIndices(a.ltog, &ga));
    PetscCall(ISLocalToGlobalMappingGetIndices(b.ltog, &gb));
    if (na != nb || !std::equal(ga, ga + na, gb)) what = "global numbering";
    PetscCall(ISLocalToGlobalMappingRestoreIndices(b.ltog, &gb));
    PetscCall(ISLocalToGlobalMappingRestoreIndices(a.ltog, &ga));
  }
  PetscInt bad = !what.empty(), any;
  PetscCallMPI(MPI_Allreduce(&bad, &any, 1, MPIU_INT, MPI_MAX, PetscObjectComm((PetscObject)a.dm)));
  if (any && what.empty()) what = "on another rank";
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const HierarchyCase &hc)
{
  MPI_Comm           comm = PETSC_COMM_WORLD;
  const std::string &tag  = hc.name;
  DM                 fineDM;
  MeshInfo           info;
  MeshLevels         levels;
  Problem            problem;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, hc.mesh, &fineDM, info, &levels, -1));
  const PetscInt L = levels.Count();
  ck.Check(L == 3, tag + " three nested levels", "%d levels", (int)L);
  PetscCall(unit::MakeProblem(comm, hc.mesh.dim, {{hc.dirichlet}, {hc.contact}, "1", "0", "0", "0"}, problem));
  std::vector<Space> spaces(L);
  for (PetscInt l = 0; l < L; ++l) PetscCall(SpaceCreate(levels.dm[l], hc.element, problem, spaces[l]));
  Hierarchy h;
  for (PetscInt l = 1; l < L; ++l) {
    Mat P;
    PetscCall(ProlongationMatrix(spaces[l - 1], spaces[l], levels.parent[l], &P));
    h.P.push_back(P);
  }

  // 1. P uH = Prolongate(uH) off Gamma_D, for every pair of levels.
  for (PetscInt l = 1; l < L; ++l) {
    Vec       uH, uh, ref;
    PetscReal err, size;
    PetscCall(DMCreateGlobalVector(spaces[l - 1].dm, &uH));
    PetscCall(DMCreateGlobalVector(spaces[l].dm, &uh));
    PetscCall(VecDuplicate(uh, &ref));
    PetscCall(Generic(spaces[l - 1], uH));
    PetscCall(MatMult(h.P[l - 1], uH, uh));
    PetscCall(Prolongate(spaces[l - 1], uH, spaces[l], levels.parent[l], ref));
    {
      PetscScalar *a;
      PetscCall(VecGetArray(ref, &a));
      for (PetscInt i : spaces[l].dirichletOwned) a[i] = 0;
      PetscCall(VecRestoreArray(ref, &a));
    }
    PetscCall(VecNorm(ref, NORM_INFINITY, &size));
    PetscCall(VecAXPY(ref, -1.0, uh));
    PetscCall(VecNorm(ref, NORM_INFINITY, &err));
    ck.Check(size > 0.5 && err < 1e-13 * size, tag + Format(" level %d: P uH equals the transfer of transfer.h off Gamma_D", (int)l), "max error %.3e of %.3e", (double)err, (double)size);
    for (Vec *v : {&uH, &uh, &ref}) PetscCall(VecDestroy(v));
    bool      exact;
    PetscReal allocated, used;
    PetscCall(AllocatedToEntries(h.P[l - 1], &exact, &allocated, &used));
    ck.Check(exact, tag + Format(" level %d: P is allocated to its entries", (int)l), "%.0f allocated for %.0f entries", (double)allocated, (double)used);
    if (hc.element == Element::P1) { // the adaptive multigrid's construction of the same transfer (adapt.h)
      TransferRecord rec;
      Mat            R;
      PetscBool      same;
      PetscCall(RecordP1Transfer(spaces[l - 1], levels.dm[l], levels.parent[l], rec));
      PetscCall(AssembleP1Transfer(rec, spaces[l], &R));
      PetscCall(SameEntries(h.P[l - 1], R, &same));
      ck.Check(same, tag + Format(" level %d: the transfer recorded on the fine cells and assembled has P's entries bit for bit", (int)l), "differs");
      PetscCall(AllocatedToEntries(R, &exact, &allocated, &used));
      ck.Check(exact, tag + Format(" level %d: the recorded transfer is allocated to its entries", (int)l), "%.0f allocated for %.0f entries", (double)allocated, (double)used);
      PetscCall(MatDestroy(&R));
    }
  }

  // The multigrid's hierarchy, as nested iteration builds it: P1 the transfers above; CR P1 on every level
  // with its transfers, then from P1 to CR on the finest mesh.
  const bool         cr = hc.element == Element::CR;
  std::vector<Space> p1s(cr ? L : 0);
  Hierarchy          mg;
  for (PetscInt l = 0; cr && l < L; ++l) {
    PetscCall(SpaceCreate(levels.dm[l], Element::P1, problem, p1s[l]));
    if (l == 0) continue;
    Mat P;
    PetscCall(ProlongationMatrix(p1s[l - 1], p1s[l], levels.parent[l], &P));
    mg.P.push_back(P);
  }
  if (!cr)
    for (Mat P : h.P) {
      PetscCall(PetscObjectReference((PetscObject)P));
      mg.P.push_back(P);
    }
  const Space &below = cr ? p1s[L - 1] : spaces[L - 2]; // the space below the finest level

  // 1b. CR: from P1 on the same mesh, each face gets the mean of its vertices' values.
  if (cr) {
    const Space &p1 = p1s[L - 1];
    Mat          Q;
    Vec   v, w, ref, loc;
    PetscScalar *a;
    const Space &cr = spaces[L - 1];
    PetscCall(P1ToCRMatrix(p1, cr, &Q));
    PetscCall(DMCreateGlobalVector(p1.dm, &v));
    PetscCall(DMCreateGlobalVector(cr.dm, &w));
    PetscCall(VecDuplicate(w, &ref));
    PetscCall(Generic(p1, v));
    PetscCall(MatMult(Q, v, w));
    // expected: per face of every cell, the mean over the face's vertices (all but vertex i of face i)
    PetscCall(DMGetLocalVector(cr.dm, &loc));
    PetscCall(VecGetArray(loc, &a));
    for (PetscInt c = 0; c < cr.NumCells(); ++c) {
      const Space::Coords X = cr.X(c);
      for (PetscInt i = 0; i < cr.Nb(); ++i) {
        PetscReal mean = 0;
        for (PetscInt j = 0; j < cr.Nb(); ++j) {
          if (j == i) continue;
          const PetscReal *x = &X.x[j * cr.dim];
          // Generic() at the vertex, zero where the vertex is a Dirichlet DOF of P1 (on Gamma_D)
          const bool onDirichlet = p1.kindLocal[cr.cellVert[c * cr.Nb() + j]] == kDirichlet;
          mean += onDirichlet ? 0.0 : std::sin(7 * x[0] + 3 * x[1] + (cr.dim == 3 ? 5 * x[2] : 0.0)) + 1.5;
        }
        a[cr.Dofs(c)[i]] = cr.kindLocal[cr.Dofs(c)[i]] == kDirichlet ? 0.0 : mean / cr.dim;
      }
    }
    PetscCall(VecRestoreArray(loc, &a));
    PetscCall(DMLocalToGlobal(cr.dm, loc, INSERT_VALUES, ref));
    PetscCall(DMRestoreLocalVector(cr.dm, &loc));
    PetscReal err, size;
    PetscCall(VecNorm(ref, NORM_INFINITY, &size));
    PetscCall(VecAXPY(ref, -1.0, w));
    PetscCall(VecNorm(ref, NORM_INFINITY, &err));
    ck.Check(size > 0.5 && err < 1e-13 * size, tag + " from P1 on the same mesh: each face gets the mean of its vertices", "max error %.3e of %.3e", (double)err, (double)size);
    // built row by row into an exact allocation: the entries of the construction by MatSetValues
    Mat       Qref;
    PetscBool same;
    PetscCall(P1ToCRBySetValues(p1, cr, &Qref));
    PetscCall(SameEntries(Q, Qref, &same));
    ck.Check(same, tag + " from P1 on the same mesh: the entries of the construction by MatSetValues, bit for bit", "differs");
    PetscCall(MatDestroy(&Qref));
    // the P1 space made from the CR space's tables is SpaceCreate's
    Space       p1Of;
    std::string what;
    PetscCall(SpaceCreateP1Of(levels.dm[L - 1], cr, problem, p1Of));
    PetscCall(SpaceDifference(p1, p1Of, what));
    ck.Check(what.empty(), tag + " the P1 space made from the CR space is SpaceCreate's", "differs: %s", what.c_str());
    PetscCall(SpaceDestroy(p1Of));
    for (Vec *x : {&v, &w, &ref}) PetscCall(VecDestroy(x));
    mg.P.push_back(Q);
  }

  // 2. The truncated transfer of the finest level.
  IS                inactive, kept;
  Mat               Pt;
  std::vector<char> active;
  PetscCall(TestInactiveSet(spaces[L - 1], &inactive, active));
  PetscCall(TruncateTransfer(mg.P.back(), inactive, &kept, &Pt));
  {
    Vec       xc, xk, y, yFull, ref;
    PetscReal onActive = 0, refOnActive = 0, onInactive = 0, dropped = 0;
    PetscCall(MatCreateVecs(mg.P.back(), &xc, &ref));
    PetscCall(VecDuplicate(ref, &yFull));
    PetscCall(MatCreateVecs(Pt, &xk, &y));
    PetscCall(Generic(below, xc));
    PetscCall(RestrictTo(kept, xc, xk));
    PetscCall(MatMult(Pt, xk, y));
    PetscCall(Embed(inactive, y, yFull));
    PetscCall(Embed(kept, xk, xc)); // xc: zero off the kept columns now
    PetscCall(MatMult(mg.P.back(), xc, ref));
    const PetscScalar *a, *b;
    PetscCall(VecGetArrayRead(yFull, &a));
    PetscCall(VecGetArrayRead(ref, &b));
    for (PetscInt i = 0; i < spaces[L - 1].numOwned; ++i) {
      if (active[i]) onActive = std::max(onActive, std::fabs(PetscRealPart(a[i]))), refOnActive = std::max(refOnActive, std::fabs(PetscRealPart(b[i])));
      else onInactive = std::max(onInactive, std::fabs(PetscRealPart(a[i] - b[i])));
    }
    PetscCall(VecRestoreArrayRead(ref, &b));
    PetscCall(VecRestoreArrayRead(yFull, &a));
    PetscCall(VecDestroy(&yFull));
    // The dropped columns: a coarse function on them only is zero on I.
    PetscCall(Generic(below, xc));
    {
      Vec mask;
      PetscCall(VecDuplicate(xc, &mask));
      PetscCall(VecSet(xk, 1));
      PetscCall(Embed(kept, xk, mask));
      PetscCall(VecShift(mask, -1.0));
      PetscCall(VecPointwiseMult(xc, xc, mask)); // -xc on the dropped columns, 0 on the kept ones
      PetscCall(MatMult(mg.P.back(), xc, ref));
      PetscCall(VecGetArrayRead(ref, &b));
      for (PetscInt i = 0; i < spaces[L - 1].numOwned; ++i)
        if (!active[i]) dropped = std::max(dropped, std::fabs(PetscRealPart(b[i])));
      PetscCall(VecRestoreArrayRead(ref, &b));
      PetscCall(VecDestroy(&mask));
    }
    PetscReal r[4] = {onActive, refOnActive, onInactive, dropped};
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, r, 4, MPIU_REAL, MPI_MAX, comm));
    PetscInt nActive = 0;
    for (char c : active) nActive += c;
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &nActive, 1, MPIU_INT, MPI_SUM, comm));
    ck.Check(nActive > 0 && r[0] == 0 && r[1] > 0.1, tag + " the truncated transfer vanishes on the active DOFs (P does not)", "%d active, truncated %.3e, P %.3e", (int)nActive, (double)r[0], (double)r[1]);
    ck.Check(r[2] < 1e-14, tag + " the truncated transfer equals P on the inactive rows", "max difference %.3e", (double)r[2]);
    ck.Check(r[3] == 0, tag + " every dropped coarse column is zero on the inactive rows", "max %.3e", (double)r[3]);
    for (Vec *v : {&xc, &xk, &y, &ref}) PetscCall(VecDestroy(v));
  }

  // 2b. The shell that the multigrid applies instead of the copy Pt gives Pt's results bit for bit, in
  // every operation the cycle uses, and again on a second round (its work vectors stay zero outside the
  // kept rows and columns between uses).
  {
    Mat       T;
    Vec       xc, xf, w, a, b, ac, bc;
    PetscBool same[4] = {PETSC_TRUE, PETSC_TRUE, PETSC_TRUE, PETSC_TRUE};
    PetscCall(TruncatedTransferShell(mg.P.back(), inactive, kept, &T));
    PetscCall(MatCreateVecs(Pt, &xc, &xf));
    for (Vec *v : {&w, &a, &b}) PetscCall(VecDuplicate(xf, v));
    PetscCall(VecDuplicate(xc, &ac));
    PetscCall(VecDuplicate(xc, &bc));
    for (PetscInt round = 1; round <= 2; ++round) {
      PetscBool eq;
      PetscCall(VecSetRandom(xc, NULL));
      PetscCall(VecSetRandom(xf, NULL));
      PetscCall(VecSetRandom(w, NULL));
      PetscCall(MatMult(Pt, xc, a));
      PetscCall(MatMult(T, xc, b));
      PetscCall(VecEqual(a, b, &eq));
      same[0] = (PetscBool)(same[0] && eq);
      PetscCall(VecCopy(w, a));
      PetscCall(VecCopy(w, b));
      PetscCall(MatMultAdd(Pt, xc, a, a)); // in place, as the cycle interpolates
      PetscCall(MatMultAdd(T, xc, b, b));
      PetscCall(VecEqual(a, b, &eq));
      same[1] = (PetscBool)(same[1] && eq);
      PetscCall(MatMultTranspose(Pt, xf, ac));
      PetscCall(MatMultTranspose(T, xf, bc));
      PetscCall(VecEqual(ac, bc, &eq));
      same[2] = (PetscBool)(same[2] && eq);
      PetscCall(MatMultTransposeAdd(Pt, xf, xc, ac));
      PetscCall(MatMultTransposeAdd(T, xf, xc, bc));
      PetscCall(VecEqual(ac, bc, &eq));
      same[3] = (PetscBool)(same[3] && eq);
    }
    ck.Check(same[0] && same[1] && same[2] && same[3], tag + " the entry-free truncated transfer gives the copy's results bit for bit", "Mult %d MultAdd %d MultTranspose %d MultTransposeAdd %d", (int)same[0], (int)same[1], (int)same[2], (int)same[3]);
    for (Vec *v : {&xc, &xf, &w, &a, &b, &ac, &bc}) PetscCall(VecDestroy(v));
    PetscCall(MatDestroy(&T));
  }

  // 3. The Galerkin coarse operators of the preconditioner on every coarser level equal R A P.
  PetscCall(CheckGalerkin(ck, tag, spaces[L - 1], problem, mg, inactive, cr ? L + 1 : L));
  PetscCall(MatDestroy(&Pt));
  PetscCall(ISDestroy(&kept));
  PetscCall(ISDestroy(&inactive));
  PetscCall(h.Destroy());
  PetscCall(mg.Destroy());
  for (Space &s : p1s) PetscCall(SpaceDestroy(s));
  for (Space &s : spaces) PetscCall(SpaceDestroy(s));
  PetscCall(MeshLevelsDestroy(levels));
  PetscCall(DMDestroy(&fineDM));
  PetscFunctionReturn(0);
}

// The multigrid preconditioner over the hierarchy mg for the inactive-set block of the stiffness matrix
// on `fine`: `expected` levels, and on each coarser one the Galerkin operator R A P.
static PetscErrorCode CheckGalerkin(unit::Checker &ck, const std::string &tag, const Space &fine, const Problem &problem, const Hierarchy &mg, IS inactive, PetscInt expected)
{
  PetscFunctionBeginUser;
  {
    Mat A, Aii;
    PC  pc;
    System sys;
    PetscCall(AssembleSystem(fine, problem, AssemblyOptions(), sys));
    A = sys.A;
    PetscCall(MatCreateSubMatrix(A, inactive, inactive, MAT_INITIAL_MATRIX, &Aii));
    PetscCall(PCCreate(PetscObjectComm((PetscObject)A), &pc));
    PetscCall(HierarchyMGSetUp(pc, mg, Aii, inactive));
    PetscInt nl;
    PetscCall(PCMGGetLevels(pc, &nl));
    ck.Check(nl == expected, tag + " the preconditioner has one level per mesh level (CR: and P1 on the finest mesh)", "%d levels", (int)nl);
    for (PetscInt l = nl - 1; l > 0; --l) {
      KSP       fineK, coarseK;
      Mat       Af, Ac, P;
      PetscReal err = PETSC_MAX_REAL;
      PetscCall(PCMGGetSmoother(pc, l, &fineK));
      PetscCall(PCMGGetSmoother(pc, l - 1, &coarseK));
      PetscCall(KSPGetOperators(fineK, &Af, NULL));
      PetscCall(KSPGetOperators(coarseK, &Ac, NULL));
      PetscCall(PCMGGetInterpolation(pc, l, &P));
      PetscCall(GalerkinError(Af, P, Ac, &err));
      ck.Check(err < 1e-13, tag + Format(" level %d: the Galerkin coarse operator equals R A P", (int)(l - 1)), "max relative error %.3e", (double)err);
    }
    if (nl == expected) {
      // the finest level operates with the inactive-set block itself
      KSP k;
      Mat Af;
      PetscCall(PCMGGetSmoother(pc, nl - 1, &k));
      PetscCall(KSPGetOperators(k, &Af, NULL));
      ck.Check(Af == Aii, tag + " the finest level operator is the inactive-set block");
    }
    PetscCall(PCDestroy(&pc));
    PetscCall(MatDestroy(&Aii));
    PetscCall(SystemDestroy(sys));
  }
  PetscFunctionReturn(0);
}

// max over the owned DOFs of fine that are not on Gamma_D of |a - b|, and of |b| (max over ranks).
static PetscErrorCode DiffOffDirichlet(const Space &fine, Vec a, Vec b, PetscReal *diff, PetscReal *size)
{
  const PetscScalar *x, *y;
  std::vector<char>  dirichlet(fine.numOwned, 0);
  PetscReal          r[2] = {0, 0};
  PetscFunctionBeginUser;
  for (PetscInt i : fine.dirichletOwned) dirichlet[i] = 1;
  PetscCall(VecGetArrayRead(a, &x));
  PetscCall(VecGetArrayRead(b, &y));
  for (PetscInt i = 0; i < fine.numOwned; ++i)
    if (!dirichlet[i]) r[0] = std::max(r[0], std::fabs(PetscRealPart(x[i] - y[i]))), r[1] = std::max(r[1], std::fabs(PetscRealPart(y[i])));
  PetscCall(VecRestoreArrayRead(b, &y));
  PetscCall(VecRestoreArrayRead(a, &x));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, r, 2, MPIU_REAL, MPI_MAX, PetscObjectComm((PetscObject)a)));
  *diff = r[0], *size = r[1];
  PetscFunctionReturn(0);
}

// The P1 interpolant of 1 - x_dim (the last coordinate), which vanishes on the top side, Gamma_D here.
static PetscErrorCode LinearOffTop(const Space &s, Vec u)
{
  Vec          loc;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(s.dm, &loc));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < s.numLocal; ++i) a[i] = 1 - s.vertX[i * s.dim + s.dim - 1];
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(s.dm, loc, INSERT_VALUES, u));
  PetscCall(DMRestoreLocalVector(s.dm, &loc));
  PetscFunctionReturn(0);
}

// Three adaptive steps from a box: the cells whose centroid lies within 0.45 of the corner at the origin
// are bisected (all edges), the new mesh redistributed (on more than one rank), and the P1 transfer of each
// step recorded on the new cells, moved with them and assembled on the new space, as adapt.cpp does.
static PetscErrorCode TestAdaptive(unit::Checker &ck, const HierarchyCase &hc)
{
  MPI_Comm       comm = PETSC_COMM_WORLD;
  const PetscInt dim  = hc.mesh.dim;
  DM             mesh;
  MeshInfo       info;
  Problem        problem;
  Space          coarse, fine;
  Hierarchy      mg;
  PetscMPIInt    size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  MeshOptions mo = hc.mesh;
  mo.refine      = 1;
  PetscCall(MeshCreate(comm, mo, &mesh, info));
  PetscCall(unit::MakeProblem(comm, dim, {{hc.dirichlet}, {hc.contact}, "1", "0", "0", "0"}, problem));
  PetscCall(SpaceCreate(mesh, Element::P1, problem, coarse));
  const std::string tag = Format("adaptive %dD %s", (int)dim, ElementName(hc.element));
  for (PetscInt step = 1; step <= 3; ++step) {
    std::vector<char>     marked(coarse.NumCells(), 0);
    std::vector<PetscInt> parent;
    TransferRecord        rec;
    CellValues            carried;
    DM                    refined;
    Vec                   uH, uh, ref;
    Mat                   P;
    PetscReal             diff, norm;
    for (PetscInt c = 0; c < coarse.NumCells(); ++c) {
      const Space::Coords X = coarse.X(c);
      PetscReal           r2 = 0;
      for (PetscInt d = 0; d < dim; ++d) {
        PetscReal m = 0;
        for (PetscInt k = 0; k <= dim; ++k) m += X.x[k * dim + d] / (dim + 1);
        r2 += m * m;
      }
      marked[c] = r2 < 0.45 * 0.45;
    }
    PetscCall(RefineMarked(mesh, marked, LocalRefinement::BisectionAll, &refined, &parent));
    PetscCall(DMCreateGlobalVector(coarse.dm, &uH));
    PetscCall(Generic(coarse, uH));
    PetscCall(RecordP1Transfer(coarse, refined, parent, rec));
    PetscCall(EvaluateOnCells(coarse, uH, nullptr, refined, parent, carried));
    if (size > 1) { // always moved: the transfer has to follow its cells
      DM      dist;
      PetscSF migration;
      PetscCall(RedistributeMesh(refined, &dist, &migration));
      PetscCall(MigrateCellValues(refined, migration, dist, rec.cells));
      PetscCall(MigrateCellValues(refined, migration, dist, carried));
      PetscCall(PetscSFDestroy(&migration));
      PetscCall(DMDestroy(&refined));
      refined = dist;
    }
    PetscCall(DMDestroy(&mesh));
    mesh = refined;
    PetscCall(SpaceCreate(mesh, Element::P1, problem, fine));
    PetscCall(AssembleP1Transfer(rec, fine, &P));
    if (size == 1) { // the cells stayed with their parents: the adaptive multigrid builds P from the two spaces
      Mat       Pd;
      PetscBool same;
      PetscCall(ProlongationMatrix(coarse, fine, parent, &Pd));
      PetscCall(SameEntries(P, Pd, &same));
      ck.Check(same, tag + Format(" step %d: ProlongationMatrix gives the recorded transfer's entries bit for bit", (int)step), "differs");
      PetscCall(MatDestroy(&Pd));
    }
    PetscCall(DMCreateGlobalVector(fine.dm, &uh));
    PetscCall(VecDuplicate(uh, &ref));
    // a generic function: as the solution's transfer carries it
    PetscCall(MatMult(P, uH, uh));
    PetscCall(ApplyCellValues(fine, carried, nullptr, ref));
    PetscCall(DiffOffDirichlet(fine, uh, ref, &diff, &norm));
    ck.Check(norm > 0.5 && diff < 1e-13 * norm, tag + Format(" step %d (%d -> %d DOFs): P uH equals the transfer of transfer.h off Gamma_D", (int)step, (int)coarse.numGlobal, (int)fine.numGlobal), "max difference %.3e of %.3e", (double)diff, (double)norm);
    // a linear function that vanishes on Gamma_D: reproduced exactly
    PetscCall(LinearOffTop(coarse, uH));
    PetscCall(MatMult(P, uH, uh));
    PetscCall(LinearOffTop(fine, ref));
    PetscCall(DiffOffDirichlet(fine, uh, ref, &diff, &norm));
    ck.Check(norm > 0.5 && diff < 1e-13 * norm, tag + Format(" step %d: P reproduces 1 - x_%d (zero on Gamma_D) exactly", (int)step, (int)dim), "max difference %.3e of %.3e", (double)diff, (double)norm);
    mg.P.push_back(P);
    for (Vec *v : {&uH, &uh, &ref}) PetscCall(VecDestroy(v));
    PetscCall(SpaceDestroy(coarse));
    std::swap(coarse, fine);
  }
  // The multigrid over the four meshes (CR: and P1 to CR on the last one), on the test's inactive set.
  const bool cr = hc.element == Element::CR;
  Space      top;
  IS         inactive;
  std::vector<char> active;
  if (cr) {
    Mat Q;
    Space       p1Of;
    std::string what;
    PetscCall(SpaceCreate(mesh, Element::CR, problem, top));
    PetscCall(P1ToCRMatrix(coarse, top, &Q));
    mg.P.push_back(Q);
    PetscCall(SpaceCreateP1Of(mesh, top, problem, p1Of)); // the adaptive multigrid's P1 space, on a redistributed mesh
    PetscCall(SpaceDifference(coarse, p1Of, what));
    ck.Check(what.empty(), tag + " the P1 space made from the CR space is SpaceCreate's", "differs: %s", what.c_str());
    PetscCall(SpaceDestroy(p1Of));
  }
  const Space &finest = cr ? top : coarse;
  PetscCall(TestInactiveSet(finest, &inactive, active));
  PetscCall(CheckGalerkin(ck, tag, finest, problem, mg, inactive, cr ? 5 : 4));
  PetscCall(ISDestroy(&inactive));
  PetscCall(mg.Destroy());
  PetscCall(SpaceDestroy(top));
  PetscCall(SpaceDestroy(coarse));
  PetscCall(DMDestroy(&mesh));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  ierr = StagesRegister();
  std::vector<HierarchyCase> cases;
  for (Element e : {Element::P1, Element::CR}) {
    HierarchyCase c2;
    c2.mesh.dim = 2, c2.mesh.faces[0] = 5, c2.mesh.faces[1] = 3, c2.mesh.refine = 2, c2.mesh.coarsen = false;
    c2.element = e, c2.dirichlet = 3, c2.contact = 1, c2.name = Format("2D 5x3 %s", ElementName(e));
    HierarchyCase c3;
    c3.mesh.dim = 3, c3.mesh.faces[0] = 2, c3.mesh.faces[1] = 2, c3.mesh.faces[2] = 1, c3.mesh.refine = 2, c3.mesh.coarsen = false;
    c3.element = e, c3.dirichlet = 2, c3.contact = 1, c3.name = Format("3D 2x2x1 %s", ElementName(e));
    cases.push_back(c2), cases.push_back(c3);
  }
  for (const HierarchyCase &hc : cases) {
    ierr = TestCase(ck, hc);
    if (ierr) ck.PetscFailure(ierr, hc.name + " (PETSc error)");
    ierr = TestAdaptive(ck, hc);
    if (ierr) ck.PetscFailure(ierr, "adaptive " + hc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

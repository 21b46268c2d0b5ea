// Unit tests of the transfer between nested meshes (transfer.h), P1 and CR, 2D and 3D, on however many
// ranks the test runs (ctest runs it on 1 and 2), from a mesh to its uniform refinement (nested iteration),
// to the refinement of its marked cells (adaptive refinement: the cells left of x = 0.45), and to that
// refinement redistributed, the values evaluated on the fine cells and migrated with them. The expected values never use the parent map: every
// fine DOF point is located among the coarse cells by brute force (barycentric coordinates), and the
// coarse function is evaluated there independently.
//   - a globally affine function is reproduced exactly by both elements;
//   - P1: a generic coarse function is reproduced exactly at every fine vertex;
//   - CR: a generic (discontinuous) coarse function is reproduced exactly at fine face centroids inside a
//     coarse cell, and at fine faces on a coarse interior face the result is the mean of the two sides;
//   - after the active-set transfer and the projection: Dirichlet DOFs carry the fine system's u_D, every
//     contact DOF satisfies u >= psi, fine contact DOFs on active coarse contact DOFs are exactly psi, the
//     others max(P uH, psi), and free DOFs keep the prolongated value.
#include "signorini/assembly.h"
#include "signorini/contact.h"
#include "signorini/localrefine.h"
#include "signorini/mesh.h"
#include "signorini/transfer.h"
#include "signorini/stages.h"
#include "unit_check.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

using namespace signorini;

enum class Refine { Uniform, Marked, Redistributed };

struct ProlongationCase {
  std::string name;
  MeshOptions mesh;
  Refine      refine = Refine::Uniform;
  LocalRefinement how = LocalRefinement::Bisection; // of the marked cells
  Element     element;
  PetscInt    dirichlet, contact; // "Face Sets" values
};

static const char *kPsi = "0.1 * x - 0.05", *kUD = "1 + x";

// Barycentric coordinates of x in local cell c of space s.
static void Barycentric(const Space &s, PetscInt c, const PetscReal *x, PetscReal *lambda)
{
  CellGeometry g;
  ComputeCellGeometry(s.dim, s.X(c), g);
  PetscReal sum = 0;
  for (PetscInt k = 1; k <= s.dim; ++k) {
    lambda[k] = 0;
    for (PetscInt d = 0; d < s.dim; ++d) lambda[k] += g.gradLambda[k][d] * (x[d] - s.X(c)[d]);
    sum += lambda[k];
  }
  lambda[0] = 1 - sum;
}

// Global vector of the space with value f(x) at every DOF point.
static PetscErrorCode Interpolate(const Space &s, const std::function<PetscReal(const PetscReal *)> &f, Vec u)
{
  Vec          loc;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(s.dm, &loc));
  PetscCall(VecGetArray(loc, &a));
  const std::vector<PetscReal> points = DofPoints(s);
  for (PetscInt i = 0; i < s.numLocal; ++i) a[i] = f(&points[i * s.dim]);
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(s.dm, loc, INSERT_VALUES, u));
  PetscCall(DMRestoreLocalVector(s.dm, &loc));
  PetscFunctionReturn(0);
}

static PetscReal MaxOverRanks(MPI_Comm comm, PetscReal v)
{
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPIU_REAL, MPI_MAX, comm);
  return v;
}

static PetscInt SumOverRanks(MPI_Comm comm, PetscInt v)
{
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPIU_INT, MPI_SUM, comm);
  return v;
}

// Every rank's `mine`, concatenated in rank order, on every rank.
static PetscErrorCode AllGather(MPI_Comm comm, const std::vector<PetscReal> &mine, std::vector<PetscReal> &all)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  int              n = (int)mine.size();
  std::vector<int> counts(size), displs(size, 0);
  PetscCallMPI(MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (int p = 1; p < size; ++p) displs[p] = displs[p - 1] + counts[p - 1];
  all.resize(displs[size - 1] + counts[size - 1]);
  PetscCallMPI(MPI_Allgatherv(mine.data(), n, MPIU_REAL, all.data(), counts.data(), displs.data(), MPIU_REAL, comm));
  PetscFunctionReturn(0);
}

// All coarse cells of all ranks, as vertex coordinates ((dim+1)*dim each), so that a point on a coarse
// face cut by the partition finds the cells on both sides.
static PetscErrorCode GatherCells(MPI_Comm comm, const Space &coarse, std::vector<PetscReal> &all)
{
  std::vector<PetscReal> mine;
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < coarse.NumCells(); ++c) {
    const Space::Coords X = coarse.X(c);
    mine.insert(mine.end(), X.x, X.x + coarse.Nb() * coarse.dim);
  }
  PetscCall(AllGather(comm, mine, all));
  PetscFunctionReturn(0);
}

// Expected prolongation at x of the coarse function whose DOF values are f at the DOF points, from the
// cell geometry alone: the mean over the coarse cells containing x of each cell's function,
//   P1: sum_k f(X_k) lambda_k,   CR: sum_k f(centroid of the face opposite X_k) (1 - d lambda_k).
// nCells: how many cells contain x (1 inside a cell or on the box boundary, 2 on an interior face for CR).
// spread: the largest difference between the values of those cells at x (the jump across a CR face).
static PetscReal Expected(PetscInt dim, Element e, const std::vector<PetscReal> &cells, const std::function<PetscReal(const PetscReal *)> &f, const PetscReal *x, PetscInt &nCells, PetscReal &spread)
{
  const PetscInt nb = dim + 1, stride = nb * dim;
  PetscReal      sum = 0, vmin = PETSC_MAX_REAL, vmax = -PETSC_MAX_REAL;
  nCells             = 0;
  for (size_t off = 0; off < cells.size(); off += stride) {
    const PetscReal *X = &cells[off];
    CellGeometry     g;
    ComputeCellGeometry(dim, X, g);
    PetscReal lambda[4], lsum = 0;
    for (PetscInt k = 1; k <= dim; ++k) {
      lambda[k] = 0;
      for (PetscInt d = 0; d < dim; ++d) lambda[k] += g.gradLambda[k][d] * (x[d] - X[d]);
      lsum += lambda[k];
    }
    lambda[0] = 1 - lsum;
    if (*std::min_element(lambda, lambda + nb) < -1e-10) continue;
    ++nCells;
    PetscReal v = 0;
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal point[3] = {0, 0, 0};
      for (PetscInt d = 0; d < dim; ++d) {
        if (e == Element::P1) point[d] = X[k * dim + d];
        else
          for (PetscInt j = 0; j < nb; ++j)
            if (j != k) point[d] += X[j * dim + d] / dim;
      }
      v += f(point) * (e == Element::P1 ? lambda[k] : 1 - dim * lambda[k]);
    }
    sum += v, vmin = std::min(vmin, v), vmax = std::max(vmax, v);
  }
  spread = nCells ? vmax - vmin : 0;
  return nCells ? sum / nCells : 0;
}

static PetscErrorCode TestCase(unit::Checker &ck, const ProlongationCase &pc)
{
  MPI_Comm          comm = PETSC_COMM_WORLD;
  const std::string tag  = pc.name;
  DM                fineDM = nullptr, coarseDM = nullptr, before = nullptr; // before: the fine mesh before its redistribution
  PetscSF           migration = nullptr;
  std::vector<PetscInt> parent;  // of the fine mesh (before its redistribution)
  std::vector<char>     corners; // of the bisection (RefineMarked), by which the adaptive steps evaluate
  MeshInfo          info;
  MeshLevels        levels;
  Problem           problem;
  Space             coarse, fine;
  System            fineSys;
  Vec               uH, uh, locH, loch, lowerH, lowerh, uRef;
  const PetscScalar *aH, *ah;
  PetscFunctionBeginUser;
  if (pc.refine == Refine::Uniform) {
    PetscCall(MeshCreate(comm, pc.mesh, &fineDM, info, &levels, -1));
    ck.Check(levels.Count() == 2 && levels.dm[1] == fineDM && levels.parent[1].size() > 0, tag + " MeshCreate keeps the coarse level and the parent map");
    coarseDM = levels.dm[0];
    PetscCall(PetscObjectReference((PetscObject)coarseDM));
    parent = levels.parent[1];
  } else {
    PetscInt          cStart, cEnd;
    std::vector<char> marked;
    PetscCall(MeshCreate(comm, pc.mesh, &coarseDM, info));
    PetscCall(DMPlexGetHeightStratum(coarseDM, 0, &cStart, &cEnd));
    for (PetscInt c = cStart; c < cEnd; ++c) {
      PetscReal vol, x[3];
      PetscCall(DMPlexComputeCellGeometryFVM(coarseDM, c, &vol, x, NULL));
      marked.push_back(x[0] < 0.45);
    }
    PetscCall(RefineMarked(coarseDM, marked, pc.how, &fineDM, &parent, &corners));
    ck.Check(corners.empty() == (pc.how == LocalRefinement::SBR), tag + " the bisection gives its corners, PETSc's refine_sbr none");
    if (pc.refine == Refine::Redistributed) {
      DM dist;
      PetscCall(RedistributeMesh(fineDM, &dist, &migration));
      if (dist) before = fineDM, fineDM = dist;
      // On more than one rank the load of the refined cells is rebalanced: some cells change rank.
      PetscMPIInt size, rank;
      PetscCallMPI(MPI_Comm_size(comm, &size));
      PetscCallMPI(MPI_Comm_rank(comm, &rank));
      PetscInt           nleaves, fcStart, fcEnd, movedCells = 0;
      const PetscInt    *ilocal;
      const PetscSFNode *iremote;
      if (migration) {
        PetscCall(PetscSFGetGraph(migration, NULL, &nleaves, &ilocal, &iremote));
        PetscCall(DMPlexGetHeightStratum(fineDM, 0, &fcStart, &fcEnd));
        for (PetscInt l = 0; l < nleaves; ++l) {
          const PetscInt q = ilocal ? ilocal[l] : l;
          movedCells += q >= fcStart && q < fcEnd && iremote[l].rank != rank;
        }
      }
      movedCells = SumOverRanks(comm, movedCells);
      ck.Check(size == 1 ? !migration : movedCells > 0, tag + " the redistribution moves cells (on more than one rank)", "%d cells moved", (int)movedCells);
    }
  }
  PetscCall(unit::MakeProblem(comm, pc.mesh.dim, {{pc.dirichlet}, {pc.contact}, "1", "0", kUD, kPsi}, problem));
  PetscCall(SpaceCreate(coarseDM, pc.element, problem, coarse));
  PetscCall(SpaceCreate(fineDM, pc.element, problem, fine));
  PetscCall(AssembleSystem(fine, problem, AssemblyOptions(), fineSys));
  PetscCall(DMCreateGlobalVector(coarse.dm, &uH));
  PetscCall(DMCreateGlobalVector(fine.dm, &uh));
  PetscCall(VecDuplicate(uH, &lowerH));
  PetscCall(VecDuplicate(uh, &lowerh));
  PetscCall(VecDuplicate(uh, &uRef));
  PetscCall(DMGetLocalVector(coarse.dm, &locH));
  PetscCall(DMGetLocalVector(fine.dm, &loch));
  const PetscInt               dim          = fine.dim;
  const std::vector<PetscReal> finePoints   = DofPoints(fine);
  const std::vector<PetscReal> coarsePoints = DofPoints(coarse);
  // The evaluation on the fine cells by the bisection's corners against the one by their coordinates
  // (independent: it locates each DOF point in its parent by geometry): the same values to round-off, the
  // same active flags, for every function transferred below.
  PetscReal  cornerError = 0;
  PetscInt   cornerFlags = 0, cornerRuns = 0;
  const auto compareCorners = [&](Vec uH, Vec lowerH) -> PetscErrorCode {
    CellValues byCorners, byCoordinates;
    PetscFunctionBeginUser;
    if (corners.empty()) PetscFunctionReturn(0);
    PetscCall(EvaluateOnCells(coarse, uH, lowerH, before ? before : fineDM, parent, byCorners, &corners));
    PetscCall(EvaluateOnCells(coarse, uH, lowerH, before ? before : fineDM, parent, byCoordinates));
    const size_t nb = coarse.Nb();
    for (size_t k = 0; k < byCorners.data.size(); ++k) {
      if (k % (2 * nb) < nb) cornerError = std::max(cornerError, std::fabs(byCorners.data[k] - byCoordinates.data[k]));
      else cornerFlags += byCorners.data[k] != byCoordinates.data[k];
    }
    ++cornerRuns;
    PetscFunctionReturn(0);
  };
  // The coarse function uH onto the fine space: its values, and with lowerH its active set.
  const auto transfer = [&](Vec uH, Vec lowerH, Vec lowerh, Vec uh) -> PetscErrorCode {
    PetscFunctionBeginUser;
    PetscCall(compareCorners(uH, lowerH));
    if (migration) {
      CellValues cv;
      PetscCall(EvaluateOnCells(coarse, uH, lowerH, before, parent, cv, &corners));
      PetscCall(MigrateCellValues(before, migration, fineDM, cv));
      PetscCall(ApplyCellValues(fine, cv, lowerH ? lowerh : nullptr, uh));
    } else {
      PetscCall(Prolongate(coarse, uH, fine, parent, uh));
      if (lowerH) PetscCall(TransferActiveSet(coarse, uH, lowerH, fine, parent, lowerh, uh));
    }
    PetscFunctionReturn(0);
  };

  // 1. A globally affine function: exact for both elements.
  auto affine = [dim](const PetscReal *x) { return 1.0 + 2.0 * x[0] - 3.0 * x[1] + (dim == 3 ? 0.5 * x[2] : 0.0); };
  PetscCall(Interpolate(coarse, affine, uH));
  PetscCall(transfer(uH, nullptr, nullptr, uh));
  PetscCall(Interpolate(fine, affine, uRef));
  PetscCall(VecAXPY(uRef, -1.0, uh));
  PetscReal err;
  PetscCall(VecNorm(uRef, NORM_INFINITY, &err));
  ck.Check(err < 1e-13, tag + " affine function reproduced exactly", "max error %.3e", (double)err);

  // 2. A generic coarse function (for CR discontinuous across coarse faces, except at their centroids).
  auto generic = [dim](const PetscReal *x) { return std::sin(7 * x[0] + 3 * x[1] + (dim == 3 ? 5 * x[2] : 0.0)) + std::cos(11 * x[0] * x[1]); };
  PetscCall(Interpolate(coarse, generic, uH));
  PetscCall(transfer(uH, nullptr, nullptr, uh));
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locH));
  PetscCall(DMGlobalToLocal(fine.dm, uh, INSERT_VALUES, loch));
  PetscCall(VecGetArrayRead(locH, &aH));
  PetscCall(VecGetArrayRead(loch, &ah));
  std::vector<PetscReal> allCells;
  PetscCall(GatherCells(comm, coarse, allCells));
  PetscReal errInside = 0, errFace = 0, jump = 0;
  PetscInt  nInside = 0, nFace = 0, unlocated = 0, badParent = 0;
  for (PetscInt i = 0; i < fine.numLocal; ++i) {
    PetscInt        nCells;
    PetscReal       spread;
    const PetscReal expected = Expected(dim, pc.element, allCells, generic, &finePoints[i * dim], nCells, spread);
    jump                     = std::max(jump, spread);
    const PetscReal e        = std::fabs(PetscRealPart(ah[i]) - expected);
    unlocated += nCells == 0;
    if (pc.element == Element::CR && nCells == 2) errFace = std::max(errFace, e), ++nFace;
    else errInside = std::max(errInside, e), ++nInside;
  }
  // The parent map itself: each fine cell's centroid lies in its (local) parent.
  for (PetscInt c = 0; !migration && c < fine.NumCells(); ++c) {
    CellGeometry g;
    PetscReal    lambda[4];
    ComputeCellGeometry(dim, fine.X(c), g);
    const PetscInt pcell = parent[c];
    if (pcell < 0 || pcell >= coarse.NumCells()) {
      ++badParent;
      continue;
    }
    Barycentric(coarse, pcell, g.centroid, lambda);
    badParent += *std::min_element(lambda, lambda + coarse.Nb()) < 1e-10;
  }
  PetscCall(VecRestoreArrayRead(loch, &ah));
  PetscCall(VecRestoreArrayRead(locH, &aH));
  errInside = MaxOverRanks(comm, errInside), errFace = MaxOverRanks(comm, errFace), jump = MaxOverRanks(comm, jump);
  nInside = SumOverRanks(comm, nInside), nFace = SumOverRanks(comm, nFace), unlocated = SumOverRanks(comm, unlocated), badParent = SumOverRanks(comm, badParent);
  ck.Check(badParent == 0, tag + " every fine cell lies inside its parent, a local coarse cell", "%d fine cells outside", (int)badParent);
  ck.Check(unlocated == 0, tag + " every fine DOF point lies in a coarse cell", "%d not located", (int)unlocated);
  if (pc.element == Element::P1) ck.Check(nInside > 0 && errInside < 1e-13, tag + " P1: coarse function reproduced exactly at every fine vertex", "max error %.3e over %d", (double)errInside, (int)nInside);
  else {
    ck.Check(nInside > 0 && errInside < 1e-13, tag + " CR: coarse values reproduced at fine face centroids inside coarse cells", "max error %.3e over %d", (double)errInside, (int)nInside);
    ck.Check(nFace > 0 && errFace < 1e-13 && jump > 1e-3, tag + " CR: mean of the two sides at fine faces on coarse faces (where the coarse function jumps)", "max error %.3e over %d, max jump %.3e", (double)errFace, (int)nFace, (double)jump);
  }

  // 3. Active-set transfer and projection. The coarse function: generic off Gamma_C; on Gamma_C psi
  // (active) for x < 0.4, below psi (infeasible) for 0.4 <= x < 0.7, above psi beyond.
  PetscCall(ContactLowerBound(coarse, problem, lowerH));
  PetscCall(ContactLowerBound(fine, problem, lowerh));
  auto psi = [](const PetscReal *x) { return 0.1 * x[0] - 0.05; };
  auto withContact = [&](const PetscReal *x, char kind) {
    if (kind != kContact) return generic(x);
    return x[0] < 0.4 ? psi(x) : (x[0] < 0.7 ? psi(x) - 0.2 : psi(x) + 0.3 + 0.1 * generic(x));
  };
  {
    Vec          loc;
    PetscScalar *a;
    PetscCall(DMGetLocalVector(coarse.dm, &loc));
    PetscCall(VecGetArray(loc, &a));
    for (PetscInt i = 0; i < coarse.numLocal; ++i) a[i] = withContact(&coarsePoints[i * dim], coarse.kindLocal[i]);
    PetscCall(VecRestoreArray(loc, &a));
    PetscCall(DMLocalToGlobal(coarse.dm, loc, INSERT_VALUES, uH));
    PetscCall(DMRestoreLocalVector(coarse.dm, &loc));
  }
  PetscCall(transfer(uH, nullptr, nullptr, uh));
  PetscCall(VecCopy(uh, uRef)); // plain prolongation
  PetscCall(transfer(uH, lowerH, lowerh, uh));
  PetscCall(ProjectOntoConstraints(fineSys, fine.dirichletOwned, lowerh, uh));
  cornerError = MaxOverRanks(comm, cornerError), cornerFlags = SumOverRanks(comm, cornerFlags), cornerRuns = SumOverRanks(comm, cornerRuns);
  if (!corners.empty() || cornerRuns > 0)
    ck.Check(cornerRuns > 0 && cornerError < 1e-13 && cornerFlags == 0, tag + " the bisection's corners place every fine DOF point as its coordinates do", "max difference %.3e, %d active flags differ, %d comparisons", (double)cornerError, (int)cornerFlags, (int)cornerRuns);

  // Expected, independently: a fine contact DOF is forced onto psi when the coarse contact DOFs that
  // support its point on Gamma_C (P1: the vertices of the coarse boundary face with a positive
  // barycentric weight; CR: the coarse contact face containing it) are all at or below psi.
  PetscCall(DMGlobalToLocal(coarse.dm, uH, INSERT_VALUES, locH));
  PetscCall(VecGetArrayRead(locH, &aH));
  const PetscScalar *lH;
  Vec                locLH;
  PetscCall(DMGetLocalVector(coarse.dm, &locLH));
  PetscCall(DMGlobalToLocal(coarse.dm, lowerH, INSERT_VALUES, locLH));
  PetscCall(VecGetArrayRead(locLH, &lH));
  // All coarse faces on Gamma_C of all ranks (a redistributed fine mesh need not have its points' coarse
  // cells on the same rank): the cell's vertices, the vertex opposite the face, and for each cell DOF
  // whether it is an active contact DOF.
  const PetscInt    nb = coarse.Nb(), record = nb * dim + 1 + nb;
  std::vector<PetscReal> mineFaces, contactFaces;
  for (const BoundaryFace &bf : coarse.boundary) {
    if (bf.part != pc.contact) continue;
    const Space::Coords X = coarse.X(bf.cell);
    mineFaces.insert(mineFaces.end(), X.x, X.x + nb * dim);
    mineFaces.push_back(bf.opposite);
    for (PetscInt j = 0; j < nb; ++j) {
      const PetscInt J = coarse.Dofs(bf.cell)[j];
      mineFaces.push_back(coarse.kindLocal[J] == kContact && PetscRealPart(aH[J] - lH[J]) <= 1e-10);
    }
  }
  PetscCall(AllGather(comm, mineFaces, contactFaces));
  std::vector<char> forced(fine.numLocal, 0);
  for (PetscInt i = 0; i < fine.numLocal; ++i) {
    if (fine.kindLocal[i] != kContact) continue;
    const PetscReal *x = &finePoints[i * dim];
    bool             found = false, active = true;
    for (size_t off = 0; off < contactFaces.size(); off += record) {
      const PetscReal *X = &contactFaces[off], *flags = X + nb * dim + 1;
      const PetscInt   opposite = (PetscInt)X[nb * dim];
      CellGeometry     g;
      PetscReal        lambda[4];
      ComputeCellGeometry(dim, X, g);
      signorini::Barycentric(dim, g, X, x, lambda);
      if (*std::min_element(lambda, lambda + nb) < -1e-10 || std::fabs(lambda[opposite]) > 1e-10) continue;
      found = true;
      for (PetscInt j = 0; j < nb; ++j) {
        const bool on = pc.element == Element::P1 ? (j != opposite && lambda[j] > 1e-10) : j == opposite;
        if (on) active = active && flags[j] > 0;
      }
      break;
    }
    forced[i] = found && active;
  }
  PetscCall(VecRestoreArrayRead(locLH, &lH));
  PetscCall(DMRestoreLocalVector(coarse.dm, &locLH));
  PetscCall(VecRestoreArrayRead(locH, &aH));

  const PetscScalar *u, *p, *lo, *d;
  PetscCall(VecGetArrayRead(uh, &u));
  PetscCall(VecGetArrayRead(uRef, &p));
  PetscCall(VecGetArrayRead(lowerh, &lo));
  PetscCall(VecGetArrayRead(fineSys.uD, &d));
  // owned index -> local index, through the global section's offsets
  std::vector<PetscInt> ownedToLocal(fine.numOwned, -1);
  {
    PetscSection gs, ls;
    PetscInt     pStart, pEnd, rstart;
    DM           sectionDM; // the fine mesh with the space's section
    PetscCall(SpaceSectionDM(fine, &sectionDM));
    PetscCall(DMGetGlobalSection(sectionDM, &gs));
    PetscCall(DMGetLocalSection(sectionDM, &ls));
    PetscCall(PetscSectionGetChart(ls, &pStart, &pEnd));
    PetscCall(VecGetOwnershipRange(uh, &rstart, NULL));
    for (PetscInt q = pStart; q < pEnd; ++q) {
      PetscInt ndof, goff, loff;
      PetscCall(PetscSectionGetDof(ls, q, &ndof));
      if (!ndof) continue;
      PetscCall(PetscSectionGetOffset(gs, q, &goff));
      PetscCall(PetscSectionGetOffset(ls, q, &loff));
      if (goff >= 0) ownedToLocal[goff - rstart] = loff;
    }
    PetscCall(DMDestroy(&sectionDM));
  }
  PetscReal dirErr = 0, minGap = PETSC_MAX_REAL, forcedErr = 0, otherErr = 0, freeErr = 0;
  PetscInt  nForced = 0, nOther = 0, nBelow = 0;
  std::vector<char> isDir(fine.numOwned, 0), isCon(fine.numOwned, 0);
  for (PetscInt i : fine.dirichletOwned) isDir[i] = 1;
  for (PetscInt i : fine.contactOwned) isCon[i] = 1;
  for (PetscInt i = 0; i < fine.numOwned; ++i) {
    const PetscReal ui = PetscRealPart(u[i]), pi = PetscRealPart(p[i]), li = PetscRealPart(lo[i]);
    if (isDir[i]) dirErr = std::max(dirErr, std::fabs(ui - PetscRealPart(d[i])));
    else if (isCon[i]) {
      minGap = std::min(minGap, ui - li);
      nBelow += pi < li;
      if (forced[ownedToLocal[i]]) forcedErr = std::max(forcedErr, std::fabs(ui - li)), ++nForced;
      else otherErr = std::max(otherErr, std::fabs(ui - std::max(pi, li))), ++nOther;
    } else freeErr = std::max(freeErr, std::fabs(ui - pi));
  }
  PetscCall(VecRestoreArrayRead(fineSys.uD, &d));
  PetscCall(VecRestoreArrayRead(lowerh, &lo));
  PetscCall(VecRestoreArrayRead(uRef, &p));
  PetscCall(VecRestoreArrayRead(uh, &u));
  PetscReal mins = -minGap;
  dirErr = MaxOverRanks(comm, dirErr), mins = MaxOverRanks(comm, mins), forcedErr = MaxOverRanks(comm, forcedErr);
  otherErr = MaxOverRanks(comm, otherErr), freeErr = MaxOverRanks(comm, freeErr);
  nForced = SumOverRanks(comm, nForced), nOther = SumOverRanks(comm, nOther), nBelow = SumOverRanks(comm, nBelow);
  ck.Check(dirErr == 0, tag + " Dirichlet DOFs carry the fine system's u_D after projection", "max difference %.3e", (double)dirErr);
  ck.Check(-mins >= 0 && nBelow > 0, tag + " every contact DOF satisfies u >= psi after projection (some were below before)", "min(u - psi) %.3e, %d below before", (double)-mins, (int)nBelow);
  ck.Check(nForced > 0 && forcedErr == 0, tag + " fine contact DOFs on active coarse contact DOFs are exactly psi", "%d such DOFs, max |u - psi| %.3e", (int)nForced, (double)forcedErr);
  ck.Check(nOther > 0 && otherErr < 1e-14, tag + " the other contact DOFs are max(P uH, psi)", "%d such DOFs, max error %.3e", (int)nOther, (double)otherErr);
  ck.Check(freeErr == 0, tag + " free DOFs keep the prolongated value", "max change %.3e", (double)freeErr);

  PetscCall(DMRestoreLocalVector(coarse.dm, &locH));
  PetscCall(DMRestoreLocalVector(fine.dm, &loch));
  for (Vec *v : {&uH, &uh, &lowerH, &lowerh, &uRef}) PetscCall(VecDestroy(v));
  PetscCall(SystemDestroy(fineSys));
  PetscCall(SpaceDestroy(coarse));
  PetscCall(SpaceDestroy(fine));
  PetscCall(MeshLevelsDestroy(levels));
  PetscCall(DMDestroy(&fineDM));
  PetscCall(DMDestroy(&coarseDM));
  PetscCall(DMDestroy(&before));
  PetscCall(PetscSFDestroy(&migration));
  PetscFunctionReturn(0);
}

static std::vector<ProlongationCase> Cases()
{
  std::vector<ProlongationCase> out;
  for (Element e : {Element::P1, Element::CR}) {
    ProlongationCase c2;
    c2.mesh.dim = 2, c2.mesh.faces[0] = 5, c2.mesh.faces[1] = 3, c2.mesh.refine = 1, c2.mesh.diagonal = Diagonal::Backslash;
    c2.element = e, c2.dirichlet = 3, c2.contact = 1;
    c2.name = Format("2D 5x3 %s", ElementName(e));
    out.push_back(c2);
    ProlongationCase c3;
    c3.mesh.dim = 3, c3.mesh.faces[0] = 3, c3.mesh.faces[1] = 2, c3.mesh.faces[2] = 2, c3.mesh.refine = 1;
    c3.element = e, c3.dirichlet = 2, c3.contact = 1;
    c3.name = Format("3D 3x2x2 %s", ElementName(e));
    out.push_back(c3);
    for (const ProlongationCase &c : {c2, c3})
      for (LocalRefinement how : {LocalRefinement::Bisection, LocalRefinement::SBR})
        for (Refine r : {Refine::Marked, Refine::Redistributed}) {
          if (how == LocalRefinement::SBR && c.mesh.dim == 3) continue;
          ProlongationCase m = c;
          m.refine = r, m.how = how;
          m.name   = Format("%s, marked cells refined (%s)%s", c.name.c_str(), how == LocalRefinement::SBR ? "sbr" : "bisection", r == Refine::Redistributed ? " and redistributed" : "");
          out.push_back(m);
        }
  }
  return out;
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  ierr = StagesRegister();
  for (const ProlongationCase &pc : Cases()) {
    ierr = TestCase(ck, pc);
    if (ierr) ck.PetscFailure(ierr, pc.name + " (PETSc error)");
  }
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

// The reconstruction for the Crouzeix-Raviart element (estimate.h): Marini's face fluxes from the
// residual of each cell, and the vertex average of u_h as the conforming companion.
#include "signorini/estimate.h"
#include "signorini/contact.h"

#include <algorithm>
#include <cmath>

namespace signorini {

namespace {
// Per local vertex: the sum of kappa_T |T| u_h|_T(a) over the cells T at the vertex a, the sum of their
// weights kappa_T |T|, and how many Dirichlet, contact and active contact faces touch it.
constexpr int kVertexData = 5;
// The companion solve's relative tolerance (preconditioned residual): the closest N can be 1/200 of the
// average's, and the solve must get within a small fraction of it.
constexpr PetscReal kCompanionRtol = 1e-6;

// Sums the `width` values of every vertex over the ranks that hold a copy: onto the owner, then back.
PetscErrorCode SumOverRanks(const Space &space, PetscInt width, std::vector<PetscReal> &data)
{
  MPI_Datatype unit;
  PetscFunctionBeginUser;
  PetscCheck(space.vertexSF, PetscObjectComm((PetscObject)space.dm), PETSC_ERR_ORDER, "the CR estimate needs the space's vertex exchange (SpaceCreate with vertexExchange)");
  if (width == 1) unit = MPIU_REAL; // reductions take a basic type as it is
  else {
    PetscCallMPI(MPI_Type_contiguous((PetscMPIInt)width, MPIU_REAL, &unit));
    PetscCallMPI(MPI_Type_commit(&unit));
  }
  const std::vector<PetscReal> copies(data); // the leaves' own sums; the roots accumulate in data
  PetscCall(PetscSFReduceBegin(space.vertexSF, unit, copies.data(), data.data(), MPI_SUM));
  PetscCall(PetscSFReduceEnd(space.vertexSF, unit, copies.data(), data.data(), MPI_SUM));
  PetscCall(PetscSFBcastBegin(space.vertexSF, unit, data.data(), data.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(space.vertexSF, unit, data.data(), data.data(), MPI_REPLACE));
  if (width > 1) PetscCallMPI(MPI_Type_free(&unit));
  PetscFunctionReturn(0);
}

// The cell loop: the face fluxes of every cell and the vertex sums of u_h. With phi_k = 1 - d lambda_k,
// Phi_k = kappa |T| grad u_h . grad phi_k - int_T f phi_k is row k of the element's residual, and
// u_h(X_k) = sum_i a_i - d a_k. The vertex average weighs each cell by kappa_T |T|, the weight its
// values have in the nonconformity |||u_h - v|||: across a kappa jump of 1e6 the plain average put v
// on the side where kappa is small and the estimate 30 times above the error (stiff-layers-across), the
// weighted one 2 times; on meshes of equal cells and constant kappa the two are the same.
// (The dimension a template parameter, as in the other cell loops: their short loops unroll.)
template <PetscInt dim>
void FluxesAndVertexSumsD(const Space &space, const Problem &problem, const System &sys, const PetscScalar *a, Reconstruction &r, std::vector<PetscReal> &vdata, std::string &error)
{
  constexpr PetscInt     nb = dim + 1;
  std::vector<PetscReal> work;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.XD<dim>(c);
    CellGeometry        g;
    CellLoad            load;
    PetscReal           grad[3], S = 0;
    ComputeCellGeometryD<dim>(X, g);
    space.GradD<dim>(c, a, g, grad);
    GetCellLoad(space, problem, sys, c, X, g, work, load, error);
    r.oscillation[c]      = load.oscillation;
    const PetscReal total = load.Total(dim), kv = sys.Kappa(c) * g.volume;
    const PetscInt *dofs  = space.Dofs(c);
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal dot = 0;
      for (PetscInt d = 0; d < dim; ++d) dot += grad[d] * g.gradLambda[k][d];
      r.flux[c * nb + k] = -dim * kv * dot - (total - dim * load.moment[k]);
      S += PetscRealPart(a[dofs[k]]);
    }
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal *v = &vdata[kVertexData * space.cellVert[c * nb + k]];
      v[0] += kv * (S - dim * PetscRealPart(a[dofs[k]]));
      v[1] += kv;
    }
  }
}
void FluxesAndVertexSums(const Space &space, const Problem &problem, const System &sys, const PetscScalar *a, Reconstruction &r, std::vector<PetscReal> &vdata, std::string &error)
{
  WithDim(space.dim, [&](auto D) { FluxesAndVertexSumsD<D>(space, problem, sys, a, r, vdata, error); });
}

// The cells' gradients of the barycentric coordinates scaled by (kappa_T |T|)^{1/2}, (d+1) d values a
// cell, so that the stiffness products below make no geometry (only kept while the iterations run).
std::vector<PetscReal> ScaledGradients(const Space &space, const System &sys)
{
  const PetscInt         dim = space.dim, nb = space.Nb();
  std::vector<PetscReal> sg(space.NumCells() * nb * dim);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.X(c);
    CellGeometry        g;
    ComputeCellGeometry(dim, X, g);
    const PetscReal s = std::sqrt(sys.Kappa(c) * g.volume);
    for (PetscInt k = 0; k < nb; ++k)
      for (PetscInt d = 0; d < dim; ++d) sg[(c * nb + k) * dim + d] = s * g.gradLambda[k][d];
  }
  return sg;
}

// y = A x: per vertex z, y_z = sum_T kappa_T |T| grad x_T . grad lambda_z over the cells at z (summed over
// ranks; 0 where v is held, on Gamma_D), A the P1 stiffness.
PetscErrorCode StiffnessProduct(const Space &space, const std::vector<PetscReal> &sg, const Reconstruction &r, const std::vector<PetscReal> &x, std::vector<PetscReal> &y)
{
  const PetscInt dim = space.dim, nb = space.Nb(), nv = (PetscInt)x.size();
  PetscFunctionBeginUser;
  y.assign(nv, 0.0);
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscInt  *vert = &space.cellVert[c * nb];
    const PetscReal *G    = &sg[c * nb * dim];
    PetscReal        w[3] = {0, 0, 0};
    for (PetscInt k = 0; k < nb; ++k)
      for (PetscInt d = 0; d < dim; ++d) w[d] += x[vert[k]] * G[k * dim + d];
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal dot = 0;
      for (PetscInt d = 0; d < dim; ++d) dot += w[d] * G[k * dim + d];
      y[vert[k]] += dot;
    }
  }
  PetscCall(SumOverRanks(space, 1, y));
  for (PetscInt v = 0; v < nv; ++v)
    if (!r.movable[v]) y[v] = 0;
  PetscFunctionReturn(0);
}

// Global numbers of the vertices whose companion value may move (movable, over all ranks; -1 for the others),
// and how many this rank owns: the rows of the companion's linear system.
PetscErrorCode MovableNumbers(const Space &space, const Reconstruction &r, std::vector<PetscInt> &num, PetscInt &owned)
{
  MPI_Comm       comm = PetscObjectComm((PetscObject)space.dm);
  const PetscInt nv   = (PetscInt)r.companion.size();
  PetscInt       first = 0;
  PetscFunctionBeginUser;
  owned = 0;
  for (PetscInt v = 0; v < nv; ++v) owned += r.owned[v] && r.movable[v];
  PetscCallMPI(MPI_Exscan(&owned, &first, 1, MPIU_INT, MPI_SUM, comm));
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) first = 0; // MPI_Exscan leaves rank 0's result undefined
  num.assign(nv, -1);
  for (PetscInt v = 0, i = first; v < nv; ++v)
    if (r.owned[v] && r.movable[v]) num[v] = i++;
  PetscCall(PetscSFBcastBegin(space.vertexSF, MPIU_INT, num.data(), num.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(space.vertexSF, MPIU_INT, num.data(), num.data(), MPI_REPLACE));
  PetscFunctionReturn(0);
}

// The P1 stiffness sum_T kappa_T |T| grad lambda_i . grad lambda_j on the movable vertices (rows and columns
// by `num`; entries of held vertices are left out, PETSc ignores negative indices), each cell's entries
// given once by the rank that has the cell.
PetscErrorCode CompanionMatrix(const Space &space, const System &sys, const std::vector<PetscInt> &num, PetscInt owned, Mat *A)
{
  const PetscInt         dim = space.dim, nb = space.Nb(), nc = space.NumCells();
  std::vector<PetscInt>  ci(nc * nb * nb), cj(nc * nb * nb);
  std::vector<PetscReal> val(nc * nb * nb);
  PetscFunctionBeginUser;
  for (PetscInt c = 0, at = 0; c < nc; ++c) {
    CellGeometry g;
    ComputeCellGeometry(dim, space.X(c), g);
    const PetscReal kv   = sys.Kappa(c) * g.volume;
    const PetscInt *vert = &space.cellVert[c * nb];
    for (PetscInt i = 0; i < nb; ++i)
      for (PetscInt j = 0; j < nb; ++j, ++at) {
        PetscReal dot = 0;
        for (PetscInt d = 0; d < dim; ++d) dot += g.gradLambda[i][d] * g.gradLambda[j][d];
        ci[at] = num[vert[i]], cj[at] = num[vert[j]], val[at] = kv * dot;
      }
  }
  PetscCall(MatCreate(PetscObjectComm((PetscObject)space.dm), A));
  PetscCall(MatSetSizes(*A, owned, owned, PETSC_DETERMINE, PETSC_DETERMINE));
  PetscCall(MatSetType(*A, MATAIJ));
  PetscCall(MatSetPreallocationCOO(*A, (PetscCount)ci.size(), ci.data(), cj.data()));
  PetscCall(MatSetValuesCOO(*A, val.data(), INSERT_VALUES));
  PetscCall(MatSetOption(*A, MAT_SPD, PETSC_TRUE));
  PetscFunctionReturn(0);
}
} // namespace

// The rest of the way to the minimiser of N^2 from the current companion: A w = res (res the residual b - A v
// at every local vertex, 0 on the held ones) by conjugate gradients preconditioned with BoomerAMG on the
// assembled matrix (options prefix -estimate_companion_), and v += w. A solve that fails leaves v as it is.
PetscErrorCode CompanionSolve(const Space &space, const System &sys, const std::vector<PetscReal> &res, Reconstruction &r)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)space.dm);
  const PetscInt        nv   = (PetscInt)r.companion.size();
  std::vector<PetscInt> num;
  PetscInt              owned, its;
  Mat                   A;
  Vec                   rhs, w;
  KSP                   ksp;
  PC                    pc;
  KSPConvergedReason    reason;
  PetscFunctionBeginUser;
  PetscCall(MovableNumbers(space, r, num, owned));
  PetscCall(CompanionMatrix(space, sys, num, owned, &A));
  PetscCall(MatCreateVecs(A, &w, &rhs));
  {
    PetscScalar *b;
    PetscCall(VecGetArray(rhs, &b));
    for (PetscInt v = 0, i = 0; v < nv; ++v)
      if (r.owned[v] && r.movable[v]) b[i++] = res[v];
    PetscCall(VecRestoreArray(rhs, &b));
  }
  PetscCall(KSPCreate(comm, &ksp));
  PetscCall(KSPSetOptionsPrefix(ksp, "estimate_companion_"));
  PetscCall(KSPSetOperators(ksp, A, A));
  PetscCall(KSPSetType(ksp, KSPCG));
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PCSetType(pc, PCHYPRE));
  PetscCall(PCHYPRESetType(pc, "boomeramg"));
  PetscCall(KSPSetTolerances(ksp, kCompanionRtol, PETSC_DEFAULT, kCGDivergenceTolerance, 200));
  PetscCall(KSPSetFromOptions(ksp));
  PetscCall(KSPSolve(ksp, rhs, w));
  PetscCall(KSPGetConvergedReason(ksp, &reason));
  PetscCall(KSPGetIterationNumber(ksp, &its));
  if (reason > 0) {
    std::vector<PetscReal> step(nv, 0.0);
    const PetscScalar     *x;
    PetscCall(VecGetArrayRead(w, &x));
    for (PetscInt v = 0, i = 0; v < nv; ++v)
      if (r.owned[v] && r.movable[v]) step[v] = PetscRealPart(x[i++]);
    PetscCall(VecRestoreArrayRead(w, &x));
    PetscCall(PetscSFBcastBegin(space.vertexSF, MPIU_REAL, step.data(), step.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(space.vertexSF, MPIU_REAL, step.data(), step.data(), MPI_REPLACE));
    for (PetscInt v = 0; v < nv; ++v) r.companion[v] += step[v];
  }
  PetscCall(PetscInfo(space.dm, "CR estimate: companion solve %s in %d iterations\n", KSPConvergedReasons[reason], (int)its));
  PetscCall(KSPDestroy(&ksp));
  PetscCall(VecDestroy(&w));
  PetscCall(VecDestroy(&rhs));
  PetscCall(MatDestroy(&A));
  PetscFunctionReturn(0);
}

// Brings the companion v closer to u_h where the vertex average is far from the closest conforming one: on
// cells of aspect ratio 1000, where the average's values at the vertices across a thin cell differ by the
// nonconformity along its long side (N 25 to 80 times the error), and where cells of a large kappa touch at a
// vertex only (a checkerboard of kappa 1 and 1e6: the average splits the difference of u_h's two values
// there, and kappa turns that into N 100 times its minimum). N^2 = |||u_h - v|||^2 is a quadratic in the
// movable vertex values whose Hessian is the P1 stiffness A (twice): its minimiser solves A v = b with b_z =
// (kappa grad_h u_h, grad lambda_z); CellTerms (estimate.cpp) has summed the residual r = b - A v of the
// average and diag A in the loop it makes anyway, so deciding costs no cell loop. The preconditioned
// (Jacobi) conjugate gradients lower N^2 by alpha r.z at each step, monotonically. Whether to run them is
// decided from the first residual: the first step lowers N^2 by at least r.z / (d + 1) (A <= (d + 1) diag
// A, cell by cell), and r.z / N^2 is below 0.02 on the meshes of shape-regular cells here (the average is
// then within 1 % of the minimum of N, not worth the extra cell loops), 0.05 to 0.2 on adapted meshes (a
// few steps gain 5 to 15 %), and 0.25 to 1 on the checkerboard and the stretched cells. They stop when a
// step lowers N^2 by less than 1 % (at most 100 steps). On the checkerboard that is a plateau, not the
// minimum (Jacobi needs hundreds of steps there, growing like 1 / h, and stopped with N 40 to 180 times
// its minimum): where the steps have removed more than half of N^2, the average was far off and the
// remaining gap may be as large again, so the rest is solved for with BoomerAMG (CompanionSolve), which
// costs more than the steps on the adapted meshes (6 s at 2.9 M DOFs in 3D) and is not needed there.
// Every iterate keeps Gamma_D's values; on Gamma_C the iterates may fall below psi (holding those vertices
// at psi left the index of stiff-stretched-3d at 3.8, letting them move and raising them to psi at the end
// gives 2.0), so v is raised to psi there at the end, which keeps it a valid companion. The bound holds for
// any such v: this only makes it sharper.
PetscErrorCode ImproveCompanion(const Space &space, const System &sys, std::vector<PetscReal> &vertexSums, PetscReal n2, Reconstruction &r, bool &improved)
{
  MPI_Comm               comm = PetscObjectComm((PetscObject)space.dm);
  const PetscInt         nv   = (PetscInt)r.companion.size();
  const PetscReal        start = n2;
  std::vector<PetscReal> res, diag, z, p, q;
  PetscFunctionBeginUser;
  improved = false;
  PetscCall(SumOverRanks(space, 2, vertexSums));
  { // the decision first, without the iteration's vectors (on most meshes it is no): r.z as the loop below computes it
    PetscReal local = 0, rz0;
    for (PetscInt v = 0; v < nv; ++v) {
      const PetscReal rv = r.movable[v] ? vertexSums[2 * v] : 0, dv = vertexSums[2 * v + 1];
      if (r.owned[v]) local += rv * (dv > 0 ? rv / dv : 0);
    }
    PetscCallMPI(MPI_Allreduce(&local, &rz0, 1, MPIU_REAL, MPI_SUM, comm));
    if (!(rz0 > 0.1 * n2)) PetscFunctionReturn(0);
  }
  res.resize(nv), diag.resize(nv), z.resize(nv), p.resize(nv);
  for (PetscInt v = 0; v < nv; ++v) res[v] = r.movable[v] ? vertexSums[2 * v] : 0, diag[v] = vertexSums[2 * v + 1];
  const auto Dot = [&](const std::vector<PetscReal> &a, const std::vector<PetscReal> &b, PetscReal &sum) {
    PetscReal local = 0;
    for (PetscInt v = 0; v < nv; ++v)
      if (r.owned[v]) local += a[v] * b[v];
    return MPI_Allreduce(&local, &sum, 1, MPIU_REAL, MPI_SUM, comm);
  };
  const auto Precondition = [&]() {
    for (PetscInt v = 0; v < nv; ++v) z[v] = diag[v] > 0 ? res[v] / diag[v] : 0;
  };
  Precondition();
  PetscReal rz;
  PetscCallMPI(Dot(res, z, rz));
  p = z;
  std::vector<PetscReal> sg = ScaledGradients(space, sys);
  PetscInt               steps = 0;
  while (steps < 100) {
    PetscReal pq, rzNext;
    PetscCall(StiffnessProduct(space, sg, r, p, q));
    PetscCallMPI(Dot(p, q, pq));
    if (!(pq > 0)) break;
    const PetscReal alpha = rz / pq;
    for (PetscInt v = 0; v < nv; ++v) r.companion[v] += alpha * p[v], res[v] -= alpha * q[v];
    n2 -= alpha * rz;
    if (++steps, alpha * rz < 0.01 * n2) break;
    Precondition();
    PetscCallMPI(Dot(res, z, rzNext));
    for (PetscInt v = 0; v < nv; ++v) p[v] = z[v] + rzNext / rz * p[v];
    rz = rzNext;
  }
  PetscCall(PetscInfo(space.dm, "CR estimate: %d conjugate-gradient steps towards the closest companion, N^2 %g -> %g\n", (int)steps, (double)start, (double)n2));
  std::vector<PetscReal>().swap(sg);
  if (n2 < 0.5 * start) PetscCall(CompanionSolve(space, sys, res, r));
  for (PetscInt v = 0; v < nv; ++v) r.companion[v] = std::max(r.companion[v], r.lower[v]);
  improved = true;
  PetscFunctionReturn(0);
}

PetscErrorCode ReconstructCR(const Space &space, const Problem &problem, const System &sys, Vec u, Reconstruction &r)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)space.dm);
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  PetscFunctionBeginUser;
  const PetscInt dim = space.dim, nb = space.Nb(), nv = (PetscInt)space.vertX.size() / dim;
  r.flux.assign(space.NumCells() * nb, 0.0);
  r.oscillation.assign(space.NumCells(), 0.0);
  std::vector<PetscReal> vdata(kVertexData * nv, 0.0);
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  FluxesAndVertexSums(space, problem, sys, a, r, vdata, error);
  // The active contact faces (u_h - psi at the midpoint within the solver's ActiveTolerance) mark their
  // vertices, where v may be held at psi (Reconstruction::pinned).
  PetscReal activeTol;
  PetscCall(ActiveToleranceOf(u, &activeTol));
  for (const BoundaryFace &bf : space.boundary) {
    if (space.kindLocal[bf.dof] != kContact) continue;
    PetscReal x[3];
    space.DofPoint(bf.cell, bf.opposite, x);
    if (PetscRealPart(a[bf.dof]) - problem.psi->Scalar(x, dim, error) > activeTol) continue;
    for (PetscInt k = 0; k < nb; ++k)
      if (k != bf.opposite) vdata[kVertexData * space.cellVert[bf.cell * nb + k] + 4] += 1;
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));

  // On Gamma_C the flux is the DOF's residual, >= 0 at the discrete solution: a negative value is what
  // the solver's tolerance left, and is set to 0 so that sigma . n >= 0 holds as the bound needs. Those
  // beyond round-off of the cell's fluxes are counted (-info), a sign of a loosely converged solve.
  PetscInt clipped = 0;
  for (const BoundaryFace &bf : space.boundary) {
    const char kind = space.kindLocal[bf.dof];
    if (kind == kFree) continue;
    for (PetscInt k = 0; k < nb; ++k)
      if (k != bf.opposite) vdata[kVertexData * space.cellVert[bf.cell * nb + k] + (kind == kDirichlet ? 2 : 3)] += 1;
    PetscReal &phi = r.flux[bf.cell * nb + bf.opposite];
    if (kind != kContact || phi >= 0) continue;
    PetscReal scale = 0;
    for (PetscInt k = 0; k < nb; ++k) scale = std::max(scale, std::fabs(r.flux[bf.cell * nb + k]));
    if (phi < -1e-8 * scale) ++clipped;
    phi = 0;
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &clipped, 1, MPIU_INT, MPI_SUM, comm));
  PetscCall(PetscInfo(space.dm, "CR estimate: %d negative contact fluxes beyond round-off set to 0\n", (int)clipped));

  // v: the weighted average of u_h over the cells at each vertex (over all ranks), u_D on Gamma_D, raised to psi on
  // Gamma_C (Gamma_D wins where the two meet, where psi <= u_D: SpaceCreate checks it); then improved where
  // that pays (ImproveCompanion).
  PetscCall(SumOverRanks(space, kVertexData, vdata));
  r.companion.resize(nv);
  r.lower.assign(nv, PETSC_MIN_REAL);
  r.movable.assign(nv, 1);
  r.owned.assign(nv, 1);
  r.pinned.assign(nv, 0);
  PetscInt anyPinned = 0;
  for (PetscInt v = 0; v < nv; ++v) {
    const PetscReal *d = &vdata[kVertexData * v], *x = &space.vertX[v * dim];
    r.companion[v]     = d[1] > 0 ? d[0] / d[1] : 0.0;
    if (d[2] > 0) r.companion[v] = problem.uD->Scalar(x, dim, error), r.movable[v] = 0;
    else if (d[3] > 0) {
      r.lower[v] = problem.psi->Scalar(x, dim, error), r.companion[v] = std::max(r.companion[v], r.lower[v]);
      if (d[4] > 0) r.pinned[v] = 1, anyPinned = 1;
    }
  }
  PetscCall(CheckAll(comm, error.empty(), error));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &anyPinned, 1, MPIU_INT, MPI_MAX, comm));
  r.anyPinned = anyPinned > 0;
  PetscInt        nleaves;
  const PetscInt *leaves;
  PetscCall(PetscSFGetGraph(space.vertexSF, NULL, &nleaves, &leaves, NULL));
  for (PetscInt l = 0; l < nleaves; ++l) r.owned[leaves ? leaves[l] : l] = 0;
  PetscFunctionReturn(0);
}

} // namespace signorini

// The reconstruction for the Crouzeix-Raviart element (estimate.h): Marini's face fluxes from the
// residual of each cell, and the vertex average of u_h as the conforming companion.
#include "signorini/estimate.h"

#include <algorithm>

namespace signorini {

namespace {
// Per local vertex: the sum of kappa_T |T| u_h|_T(a) over the cells T at the vertex a, the sum of their
// weights kappa_T |T|, and how many Dirichlet and contact faces touch it.
constexpr int kVertexData = 4;

// Sums the kVertexData values of every vertex over the ranks that hold a copy: onto the owner, then back.
PetscErrorCode SumOverRanks(const Space &space, std::vector<PetscReal> &data)
{
  MPI_Datatype unit;
  PetscFunctionBeginUser;
  PetscCheck(space.vertexSF, PetscObjectComm((PetscObject)space.dm), PETSC_ERR_ORDER, "the CR estimate needs the space's vertex exchange (SpaceCreate with vertexExchange)");
  PetscCallMPI(MPI_Type_contiguous(kVertexData, MPIU_REAL, &unit));
  PetscCallMPI(MPI_Type_commit(&unit));
  const std::vector<PetscReal> copies(data); // the leaves' own sums; the roots accumulate in data
  PetscCall(PetscSFReduceBegin(space.vertexSF, unit, copies.data(), data.data(), MPI_SUM));
  PetscCall(PetscSFReduceEnd(space.vertexSF, unit, copies.data(), data.data(), MPI_SUM));
  PetscCall(PetscSFBcastBegin(space.vertexSF, unit, data.data(), data.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(space.vertexSF, unit, data.data(), data.data(), MPI_REPLACE));
  PetscCallMPI(MPI_Type_free(&unit));
  PetscFunctionReturn(0);
}

// The cell loop: the face fluxes of every cell and the vertex sums of u_h. With phi_k = 1 - d lambda_k,
// Phi_k = kappa |T| grad u_h . grad phi_k - int_T f phi_k is row k of the element's residual, and
// u_h(X_k) = sum_i a_i - d a_k. The vertex average weighs each cell by kappa_T |T|, the weight its
// values have in the nonconformity |||u_h - v|||: across a kappa jump of 1e6 the plain average put v
// on the side where kappa is small and the estimate 30 times above the error (stiff-layers-across), the
// weighted one 2 times; on meshes of equal cells and constant kappa the two are the same.
PetscErrorCode FluxesAndVertexSums(const Space &space, const Problem &problem, const System &sys, const PetscScalar *a, Reconstruction &r, std::vector<PetscReal> &vdata, std::string &error)
{
  const PetscInt         dim = space.dim, nb = space.Nb();
  std::vector<PetscReal> work;
  PetscFunctionBeginUser;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.X(c);
    CellGeometry        g;
    CellLoad            load;
    PetscReal           grad[3], S = 0;
    ComputeCellGeometry(dim, X, g);
    space.Grad(c, a, g, grad);
    ComputeCellLoad(space, problem, sys, c, X, g, work, load, error);
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
  PetscFunctionReturn(0);
}
} // namespace

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
  PetscCall(FluxesAndVertexSums(space, problem, sys, a, r, vdata, error));
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
  // Gamma_C (Gamma_D wins where the two meet, where psi <= u_D: SpaceCreate checks it).
  PetscCall(SumOverRanks(space, vdata));
  r.companion.resize(nv);
  for (PetscInt v = 0; v < nv; ++v) {
    const PetscReal *d = &vdata[kVertexData * v], *x = &space.vertX[v * dim];
    r.companion[v]     = d[1] > 0 ? d[0] / d[1] : 0.0;
    if (d[2] > 0) r.companion[v] = problem.uD->Scalar(x, dim, error);
    else if (d[3] > 0) r.companion[v] = std::max(r.companion[v], problem.psi->Scalar(x, dim, error));
  }
  PetscCall(CheckAll(comm, error.empty(), error));
  PetscFunctionReturn(0);
}

} // namespace signorini

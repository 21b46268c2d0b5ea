// Unit tests of the equilibrated flux of a P1 solution (ReconstructP1, src/equilibrate.cpp), 2D and 3D, on
// however many ranks the test runs (ctest runs it on 1 and 2). Every expected value is computed here from
// the data, independently of the reconstruction:
//   - invariants (scenes with Dirichlet, Neumann and contact parts, kappa varying per cell, with and
//     without active contact): per cell the outward fluxes sum to -int_T f by the assembly's cell rule; the
//     two sides of every interior face, also between ranks (sharedFaceSF), carry opposite fluxes; Neumann
//     faces carry int_F g by the face rule, the other faces of the box without a condition 0; contact faces
//     carry fluxes >= 0 whose sum is the sum of the discrete contact reactions (A u - b) over Gamma_C;
//   - exactness: for an affine u (f = 0, kappa constant, u_D and g its data) sigma = kappa grad u;
//   - Prager-Synge: on the manufactured Poisson problems u = prod sin(pi x_i), the flux distance
//     F = ||kappa^{-1/2}(kappa grad u_h - sigma)|| plus the oscillation of f bounds the true energy error
//     (all three by quadrature of degree 8 here), at three mesh sizes; the efficiency index is printed;
//   - the same F on 2 ranks as for the same scene built and solved on one rank (PETSC_COMM_SELF);
//   - all of the above on cells of aspect ratio 1000 too (the patch problems in the full mass matrices);
//   - the same flux from the 2D patch solve along the cells around each vertex (cycle or path, the
//     default) as from the general sparse elimination of the same patch problems (to round-off), and in
//     3D from the faces matched through small vertex numbers (the default) as by hashing their vertices.
#include "signorini/contact.h"
#include "signorini/estimate.h"
#include "signorini/mesh.h"
#include "signorini/stages.h"
#include "unit_check.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace signorini;

struct Scene {
  std::string           name;
  MeshOptions           mesh;
  unit::SceneData       data;
  std::vector<PetscInt> neumann;
  int                   active = -1; // 1: contact must be active somewhere, 0: nowhere, -1: no contact part
};

// A solved scene: P1 space with face tables, system, solution, reconstruction.
struct Solved {
  DM             dm = nullptr;
  Problem        problem;
  Space          space;
  System         sys;
  Vec            u = nullptr;
  SolveResult    result;
  Reconstruction r;
  PetscErrorCode Destroy()
  {
    PetscFunctionBeginUser;
    PetscCall(VecDestroy(&u));
    PetscCall(SystemDestroy(sys));
    PetscCall(SpaceDestroy(space));
    PetscCall(DMDestroy(&dm));
    PetscFunctionReturn(0);
  }
};

static PetscErrorCode SolveScene(MPI_Comm comm, const Scene &sc, Solved &s)
{
  MeshInfo info;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(comm, sc.mesh, &s.dm, info));
  PetscCall(unit::MakeProblem(comm, sc.mesh.dim, sc.data, s.problem));
  s.problem.neumann = sc.neumann;
  PetscCall(SpaceCreate(s.dm, Element::P1, s.problem, s.space, true));
  PetscCall(AssembleSystem(s.space, s.problem, AssemblyOptions(), s.sys));
  PetscCall(DMCreateGlobalVector(s.space.dm, &s.u));
  PetscCall(Solve(s.space, s.problem, s.sys, s.u, s.result));
  PetscCall(ReconstructP1(s.space, s.problem, s.sys, s.u, s.r));
  PetscFunctionReturn(0);
}

// v over all ranks of comm, combined by op (MPI_MAX, MPI_SUM).
static PetscReal Reduce(MPI_Comm comm, PetscReal v, MPI_Op op) { return MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPIU_REAL, op, comm), v; }
static PetscReal Max(MPI_Comm comm, PetscReal v) { return Reduce(comm, v, MPI_MAX); }
static PetscReal Sum(MPI_Comm comm, PetscReal v) { return Reduce(comm, v, MPI_SUM); }

static bool In(const std::vector<PetscInt> &parts, PetscInt p) { return std::find(parts.begin(), parts.end(), p) != parts.end(); }

// The errors, cell by cell with a quadrature of degree 8: F^2 = sum_T int_T |kappa grad u_h - sigma|^2 / kappa
// with sigma = sum_j flux_j (x - X_j) / (d |T|); E^2 = sum_T int_T kappa |grad u - grad u_h|^2 (exactGrad
// may be null: E = 0); osc^2 = sum_T (h_T / pi)^2 / kappa ||f - Pi_0 f||^2, Pi_0 f the mean by the cell rule.
struct Norms {
  PetscReal F = 0, E = 0, osc = 0;
};
template <class Grad>
static PetscErrorCode ComputeNorms(const Solved &s, const Grad *exactGrad, Norms &n)
{
  const Space       &sp = s.space;
  const PetscInt     dim = sp.dim, nb = sp.Nb();
  const Quadrature   rule = SimplexQuadrature(dim, 8);
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  PetscReal          F2 = 0, E2 = 0, osc2 = 0, x[3], gu[3], ge[3];
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(sp.dm, &loc));
  PetscCall(DMGlobalToLocal(sp.dm, s.u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  for (PetscInt c = 0; c < sp.NumCells(); ++c) {
    CellGeometry        g;
    const Space::Coords X = sp.X(c);
    ComputeCellGeometry(dim, X, g);
    sp.Grad(c, a, g, gu);
    const PetscReal kap = s.sys.Kappa(c);
    PetscReal       mean = 0, h = 0;
    for (PetscInt q = 0; q < s.sys.cellRule.Size(); ++q) {
      SimplexPoint(dim, X, s.sys.cellRule.Point(q), x);
      mean += s.sys.cellRule.weights[q] * s.problem.f->Scalar(x, dim, error);
    }
    for (PetscInt i = 0; i < nb; ++i)
      for (PetscInt j = 0; j < nb; ++j) {
        PetscReal l2 = 0;
        for (PetscInt d = 0; d < dim; ++d) l2 += (X[i * dim + d] - X[j * dim + d]) * (X[i * dim + d] - X[j * dim + d]);
        h = std::max(h, std::sqrt(l2));
      }
    PetscReal fdev = 0;
    for (PetscInt q = 0; q < rule.Size(); ++q) {
      const PetscReal w = rule.weights[q] * g.volume;
      SimplexPoint(dim, X, rule.Point(q), x);
      PetscReal sigma[3] = {0, 0, 0};
      for (PetscInt j = 0; j < nb; ++j)
        for (PetscInt d = 0; d < dim; ++d) sigma[d] += s.r.flux[c * nb + j] * (x[d] - X[j * dim + d]) / (dim * g.volume);
      PetscReal df = 0, de = 0;
      if (exactGrad) (*exactGrad)(x, ge);
      for (PetscInt d = 0; d < dim; ++d) {
        df += (kap * gu[d] - sigma[d]) * (kap * gu[d] - sigma[d]);
        if (exactGrad) de += (ge[d] - gu[d]) * (ge[d] - gu[d]);
      }
      F2 += w * df / kap;
      E2 += w * kap * de;
      const PetscReal dev = s.problem.f->Scalar(x, dim, error) - mean;
      fdev += w * dev * dev;
    }
    osc2 += (h / M_PI) * (h / M_PI) / kap * fdev;
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(sp.dm, &loc));
  MPI_Comm comm = PetscObjectComm((PetscObject)sp.dm);
  n.F           = std::sqrt(Sum(comm, F2));
  n.E           = std::sqrt(Sum(comm, E2));
  n.osc         = std::sqrt(Sum(comm, osc2));
  PetscFunctionReturn(0);
}

using NoGrad = void (*)(const PetscReal *, PetscReal *);

static PetscErrorCode CheckInvariants(unit::Checker &ck, const std::string &tag, const Solved &s, const Scene &sc)
{
  const Space   &sp   = s.space;
  MPI_Comm       comm = PetscObjectComm((PetscObject)sp.dm);
  const PetscInt dim = sp.dim, nb = sp.Nb(), nc = sp.NumCells();
  const auto    &flux = s.r.flux;
  std::string    error;
  PetscReal      x[3], lambda[4];
  PetscFunctionBeginUser;
  PetscReal scale = 0;
  for (PetscReal v : flux) scale = std::max(scale, std::fabs(v));
  scale = Max(comm, scale);
  ck.Check((PetscInt)flux.size() == nc * nb && scale > 0, tag + " one flux per cell face, not all zero");

  // 1. Per cell: sum of the outward fluxes = -int_T f by the assembly's rule.
  PetscReal worstCell = 0;
  for (PetscInt c = 0; c < nc; ++c) {
    CellGeometry        g;
    const Space::Coords X = sp.X(c);
    ComputeCellGeometry(dim, X, g);
    PetscReal intf = 0, sum = 0, big = 0;
    for (PetscInt q = 0; q < s.sys.cellRule.Size(); ++q) {
      SimplexPoint(dim, X, s.sys.cellRule.Point(q), x);
      intf += s.sys.cellRule.weights[q] * g.volume * s.problem.f->Scalar(x, dim, error);
    }
    for (PetscInt j = 0; j < nb; ++j) sum += flux[c * nb + j], big = std::max(big, std::fabs(flux[c * nb + j]));
    worstCell = std::max(worstCell, std::fabs(sum + intf) / std::max({std::fabs(intf), big, 1e-300}));
  }
  worstCell = Max(comm, worstCell);
  ck.Check(worstCell <= 1e-10, tag + " every cell: sum of outward fluxes = -int_T f (cell rule)", "worst relative error %.3g", (double)worstCell);

  // 2. Opposite fluxes on interior faces, on one rank and across ranks.
  PetscReal worstFace = 0;
  for (const InteriorFace &f : sp.interiorFaces) worstFace = std::max(worstFace, std::fabs(flux[f.cell[0] * nb + f.local[0]] + flux[f.cell[1] * nb + f.local[1]]));
  const PetscInt         ns = (PetscInt)sp.sharedFaces.size();
  std::vector<PetscReal> mine(ns), theirs(ns, NAN);
  for (PetscInt i = 0; i < ns; ++i) mine[i] = flux[sp.sharedFaces[i].cell * nb + sp.sharedFaces[i].local];
  PetscCall(PetscSFBcastBegin(sp.sharedFaceSF, MPIU_REAL, mine.data(), theirs.data(), MPI_REPLACE));
  PetscCall(PetscSFBcastEnd(sp.sharedFaceSF, MPIU_REAL, mine.data(), theirs.data(), MPI_REPLACE));
  PetscReal worstShared = 0;
  PetscInt  nShared     = 0;
  for (PetscInt i = 0; i < ns; ++i)
    if (!sp.sharedFaces[i].owned) worstShared = std::max(worstShared, std::fabs(mine[i] + theirs[i])), ++nShared;
  worstFace = Max(comm, worstFace) / scale, worstShared = Max(comm, std::isnan(worstShared) ? 1.0 : worstShared) / scale;
  ck.Check(worstFace <= 1e-12, tag + " interior faces: the two sides' fluxes are opposite", "worst |sum| / max flux %.3g", (double)worstFace);
  ck.Check(worstShared <= 1e-12, tag + " faces between ranks: the two sides' fluxes are opposite", "worst |sum| / max flux %.3g", (double)worstShared);

  // 3. Boundary faces: Neumann int_F g, contact >= 0, unnamed box faces 0.
  std::vector<char> named(nc * nb, 0), inner(nc * nb, 0);
  for (const InteriorFace &f : sp.interiorFaces) inner[f.cell[0] * nb + f.local[0]] = inner[f.cell[1] * nb + f.local[1]] = 1;
  for (const SharedFace &f : sp.sharedFaces) inner[f.cell * nb + f.local] = 1;
  PetscReal worstNeumann = 0, minContact = 0, contactSum = 0;
  PetscInt  nNeumann = 0, nContact = 0;
  for (const BoundaryFace &bf : sp.boundary) {
    named[bf.cell * nb + bf.opposite] = 1;
    const PetscReal phi = flux[bf.cell * nb + bf.opposite];
    if (In(s.problem.neumann, bf.part)) {
      PetscReal intg = 0;
      for (PetscInt q = 0; q < s.sys.faceRule.Size(); ++q) {
        sp.FaceToCell(bf, s.sys.faceRule.Point(q), lambda);
        sp.Point(bf.cell, lambda, x);
        intg += s.sys.faceRule.weights[q] * sp.FaceMeasure(bf) * s.problem.g->Scalar(x, dim, error);
      }
      worstNeumann = std::max(worstNeumann, std::fabs(phi - intg));
      ++nNeumann;
    } else if (In(s.problem.contact, bf.part)) {
      minContact = std::min(minContact, phi);
      contactSum += phi;
      ++nContact;
    }
  }
  PetscReal worstNatural = 0;
  for (PetscInt i = 0; i < nc * nb; ++i)
    if (!named[i] && !inner[i]) worstNatural = std::max(worstNatural, std::fabs(flux[i]));
  worstNatural = Max(comm, worstNatural) / scale;
  ck.Check(worstNatural <= 1e-12, tag + " boundary faces without a condition carry no flux", "worst |flux| / max flux %.3g", (double)worstNatural);
  if (!sc.neumann.empty()) {
    worstNeumann = Max(comm, worstNeumann) / scale;
    ck.Check(Sum(comm, nNeumann) > 0 && worstNeumann <= 1e-12, tag + " Neumann faces carry int_F g (face rule)", "worst error / max flux %.3g", (double)worstNeumann);
  }
  if (sc.active >= 0) {
    // The discrete reactions A u - b summed over the owned contact DOFs: the total contact force.
    Vec                res;
    const PetscScalar *ra;
    PetscReal          reaction = 0;
    PetscCall(VecDuplicate(s.u, &res));
    PetscCall(MatMult(s.sys.A, s.u, res));
    PetscCall(VecAXPY(res, -1.0, s.sys.b));
    PetscCall(VecGetArrayRead(res, &ra));
    for (PetscInt i : sp.contactOwned) reaction += PetscRealPart(ra[i]);
    PetscCall(VecRestoreArrayRead(res, &ra));
    PetscCall(VecDestroy(&res));
    reaction   = Sum(comm, reaction);
    contactSum = Sum(comm, contactSum);
    minContact = -Max(comm, -minContact);
    ck.Check(Sum(comm, nContact) > 0 && minContact >= -1e-12 * scale, tag + " contact faces carry fluxes >= 0", "min flux %.3g (max flux %.3g)", (double)minContact, (double)scale);
    ck.Check(std::fabs(contactSum - reaction) <= 1e-10 * scale, tag + " the contact fluxes sum to the discrete contact force sum (A u - b) over Gamma_C", "fluxes %.15g, reactions %.15g", (double)contactSum, (double)reaction);
    if (sc.active == 1) ck.Check(s.result.active > 0 && contactSum > 1e-3 * scale, tag + " contact is active and carries a force", "%d active, force %.3g", (int)s.result.active, (double)contactSum);
    else ck.Check(s.result.active == 0 && std::fabs(contactSum) <= 1e-12 * scale, tag + " no active contact, no contact force", "%d active, force %.3g", (int)s.result.active, (double)contactSum);
  }
  ck.Check(Sum(comm, error.empty() ? 0 : 1) == 0, tag + " data evaluated", "%s", error.c_str());
  PetscFunctionReturn(0);
}

// On more than one rank: the same scene on PETSC_COMM_SELF gives the same F.
static PetscErrorCode CheckSameAsOneRank(unit::Checker &ck, const std::string &tag, const Scene &sc, PetscReal F)
{
  PetscMPIInt size;
  Solved      serial;
  Norms       n;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(PETSC_COMM_WORLD, &size));
  if (size == 1) PetscFunctionReturn(0);
  PetscCall(SolveScene(PETSC_COMM_SELF, sc, serial));
  PetscCall(ComputeNorms<NoGrad>(serial, nullptr, n));
  ck.Close(F, n.F, 1e-10, tag + " F on all ranks = F of the same scene on one rank", 0.0);
  PetscCall(serial.Destroy());
  PetscFunctionReturn(0);
}

// The default patch solve (2D: along the cycle or path of cells around the vertex; 3D and stretched 2D
// cells: faces matched through small vertex numbers) against the general one (faces matched by hashing).
static PetscErrorCode CheckSameAsGeneric(unit::Checker &ck, const std::string &tag, const Solved &s)
{
  Reconstruction generic;
  PetscReal      diff = 0, size = 0;
  PetscFunctionBeginUser;
  PetscCall(ReconstructP1(s.space, s.problem, s.sys, s.u, generic, true));
  for (size_t i = 0; i < s.r.flux.size(); ++i) diff = std::max(diff, std::fabs(s.r.flux[i] - generic.flux[i])), size = std::max(size, std::fabs(generic.flux[i]));
  diff = Max(PETSC_COMM_WORLD, diff), size = Max(PETSC_COMM_WORLD, size);
  ck.Check(generic.flux.size() == s.r.flux.size() && diff <= 1e-12 * size, tag + ": the patch fluxes of the default solve = those of the general sparse elimination", "max difference %.3g, max flux %.3g", (double)diff, (double)size);
  PetscFunctionReturn(0);
}

static MeshOptions Box(PetscInt dim, PetscInt n)
{
  MeshOptions m;
  m.dim = dim;
  for (PetscInt d = 0; d < 3; ++d) m.faces[d] = n;
  return m;
}

static PetscErrorCode TestInvariants(unit::Checker &ck)
{
  PetscFunctionBeginUser;
  std::vector<Scene> scenes;
  for (PetscInt dim : {2, 3}) {
    // Box sides: 2D 1 bottom, 2 right (x = 1), 3 top, 4 left; 3D 1 bottom (z = 0), 2 top, 5 right (x = 1),
    // 6 left. Gamma_D meets Gamma_C on the left: a Dirichlet vertex's patch has contact faces too.
    const PetscInt top = dim == 2 ? 3 : 2, right = dim == 2 ? 2 : 5, left = dim == 2 ? 4 : 6;
    const char    *g   = dim == 2 ? "0.5 * y" : "0.5 * z";
    for (int active : {1, 0}) {
      Scene s;
      s.name = Format("%dD contact (%s)", (int)dim, active ? "active" : "inactive");
      s.mesh = Box(dim, dim == 2 ? 8 : 3);
      s.data.dirichlet = {top, left}, s.data.contact = {1}, s.data.f = "-6 - 4 * x", s.data.g = g;
      s.data.psi = active ? "-0.05 + 0.02 * x" : "-10", s.data.kappa = "1 + x";
      s.neumann = {right}, s.active = active;
      scenes.push_back(s);
    }
    // Cells of aspect ratio 1000 (the box's height 1e-3): the patches minimise in the full RT0 mass
    // matrices (SolveCoupled), contact forcing and gathered patches (2 ranks) included.
    Scene t = scenes[scenes.size() - 2];
    t.name  = Format("%dD contact, stretched", (int)dim);
    t.mesh.upper[dim - 1] = 1e-3;
    t.data.psi            = "-0.0005 + 0.001 * x"; // above u_D = 0 on the top 1e-3 away: active for x > 0.5
    scenes.push_back(t);
    Scene p;
    p.name = Format("%dD Dirichlet-Neumann", (int)dim);
    p.mesh = Box(dim, dim == 2 ? 8 : 3);
    p.data.dirichlet = {1}, p.data.f = "1 + x * y", p.data.g = "1 - x", p.data.kappa = "2 + y";
    p.neumann = {top};
    scenes.push_back(p);
  }
  for (const Scene &sc : scenes) {
    Solved s;
    Norms  n;
    PetscCall(SolveScene(PETSC_COMM_WORLD, sc, s));
    PetscCall(CheckInvariants(ck, sc.name, s, sc));
    PetscCall(ComputeNorms<NoGrad>(s, nullptr, n));
    PetscCall(CheckSameAsOneRank(ck, sc.name, sc, n.F));
    PetscCall(CheckSameAsGeneric(ck, sc.name, s));
    PetscCall(s.Destroy());
  }
  PetscFunctionReturn(0);
}

// u affine: u_h = u, and sigma must be kappa grad u exactly (F = 0 to round-off).
static PetscErrorCode TestAffine(unit::Checker &ck)
{
  PetscFunctionBeginUser;
  for (PetscInt dim : {2, 3}) {
    Scene sc;
    sc.name = Format("%dD affine u", (int)dim);
    sc.mesh = Box(dim, dim == 2 ? 6 : 3);
    sc.mesh.diagonal = Diagonal::Backslash;
    sc.data.f = "0", sc.data.kappa = "3", sc.data.uD = dim == 2 ? "1 + x + 2 * y" : "1 + x + 2 * y - z";
    sc.data.g = "3"; // kappa du/dn on x = 1
    sc.data.dirichlet = dim == 2 ? std::vector<PetscInt>{1, 3, 4} : std::vector<PetscInt>{1, 2, 3, 4, 6};
    sc.neumann = {dim == 2 ? 2 : 5};
    Solved s;
    Norms  n;
    PetscCall(SolveScene(PETSC_COMM_WORLD, sc, s));
    PetscCall(CheckInvariants(ck, sc.name, s, sc));
    const auto grad = [dim](const PetscReal *, PetscReal *g) { g[0] = 1, g[1] = 2, g[2] = -1; (void)dim; };
    PetscCall(ComputeNorms(s, &grad, n));
    ck.Check(n.F <= 1e-10 && n.E <= 1e-10, sc.name + ": sigma = kappa grad u_h = kappa grad u", "F %.3g, E %.3g", (double)n.F, (double)n.E);
    PetscCall(s.Destroy());
  }
  PetscFunctionReturn(0);
}

// Prager-Synge on u = prod_i sin(pi x_i), -Laplace u = d pi^2 u, u = 0 on the boundary.
static PetscErrorCode TestBound(unit::Checker &ck)
{
  PetscFunctionBeginUser;
  for (PetscInt dim : {2, 3}) {
    const auto grad = [dim](const PetscReal *x, PetscReal *g) {
      for (PetscInt d = 0; d < dim; ++d) {
        g[d] = M_PI * std::cos(M_PI * x[d]);
        for (PetscInt e = 0; e < dim; ++e)
          if (e != d) g[d] *= std::sin(M_PI * x[e]);
      }
    };
    for (PetscInt n : {dim == 2 ? 4 : 2, dim == 2 ? 8 : 4, dim == 2 ? 16 : 8}) {
      Scene sc;
      sc.name = Format("%dD sine %d^%d", (int)dim, (int)n, (int)dim);
      sc.mesh = Box(dim, n);
      sc.data.f = dim == 2 ? "2 * pi^2 * sin(pi * x) * sin(pi * y)" : "3 * pi^2 * sin(pi * x) * sin(pi * y) * sin(pi * z)";
      sc.data.dirichlet = dim == 2 ? std::vector<PetscInt>{1, 2, 3, 4} : std::vector<PetscInt>{1, 2, 3, 4, 5, 6};
      Solved s;
      Norms  nm;
      PetscCall(SolveScene(PETSC_COMM_WORLD, sc, s));
      PetscCall(ComputeNorms(s, &grad, nm));
      const PetscReal eta = nm.F + nm.osc;
      PetscCall(PetscPrintf(PETSC_COMM_WORLD, "  %s: error %.4e, F %.4e, osc %.4e, index (F + osc) / error %.3f\n", sc.name.c_str(), (double)nm.E, (double)nm.F, (double)nm.osc, (double)(eta / nm.E)));
      ck.Check(eta >= nm.E, sc.name + ": F + osc >= the energy error (Prager-Synge)", "F %.6g + osc %.6g < error %.6g", (double)nm.F, (double)nm.osc, (double)nm.E);
      PetscCall(s.Destroy());
    }
  }
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscErrorCode ierr = PetscInitialize(&argc, &argv, NULL, NULL);
  if (ierr) return ierr;
  unit::Checker ck;
  // Solve to round-off: the flux is equilibrated up to the solver's residual.
  ierr = PetscOptionsSetValue(NULL, "-ksp_rtol", "1e-14");
  if (!ierr) ierr = PetscOptionsSetValue(NULL, "-snes_rtol", "1e-14");
  if (!ierr) ierr = StagesRegister();
  if (!ierr && (ierr = TestInvariants(ck))) ck.PetscFailure(ierr, "invariants (PETSc error)");
  if ((ierr = TestAffine(ck))) ck.PetscFailure(ierr, "affine (PETSc error)");
  if ((ierr = TestBound(ck))) ck.PetscFailure(ierr, "Prager-Synge (PETSc error)");
  const int rc = ck.Finish();
  ierr         = PetscFinalize();
  return rc ? rc : ierr;
}

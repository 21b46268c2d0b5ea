// The estimate from a reconstruction (estimate.h): the flux, nonconformity, contact and oscillation terms
// cell by cell, their global sums, the bound eta and the cell indicators.
#include "signorini/estimate.h"
#include "signorini/datalift.h"
#include "signorini/options.h"
#include "signorini/stages.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace signorini {

PetscErrorCode EstimateOptionsFromCommandLine(MPI_Comm comm, EstimateOptions &o)
{
  PetscInt which = o.enabled ? 0 : 1;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "A posteriori error estimate", "signorini");
  PetscCall(OptionEList(PetscOptionsObject, "-estimate", "Estimate of the energy error: equilibrated (flux and conforming companion, a guaranteed bound) or none", {"equilibrated", "none"}, which));
  PetscOptionsEnd();
  o.enabled = which == 0;
  PetscFunctionReturn(0);
}

namespace {
bool InParts(const std::vector<PetscInt> &parts, PetscInt part) { return std::find(parts.begin(), parts.end(), part) != parts.end(); }

// The face of bf as dim vertex indices (v - vStart), the cell's geometry, and the reach of the cell from
// the vertex opposite the face (its longest edge there: no point of the cell is farther from that vertex).
struct FaceOf {
  PetscInt      vert[3];
  Space::Coords X;
  CellGeometry  g;
  PetscReal    area, poincare, reach = 0;
  FaceOf(const Space &space, const BoundaryFace &bf)
  {
    PetscInt n = 0;
    for (PetscInt k = 0; k <= space.dim; ++k)
      if (k != bf.opposite) vert[n++] = space.cellVert[bf.cell * space.Nb() + k];
    X = space.X(bf.cell);
    ComputeCellGeometry(space.dim, X, g);
    area     = space.FaceMeasure(bf);
    poincare = PoincareConstant(space.dim, X);
    for (PetscInt k = 0; k <= space.dim; ++k) {
      PetscReal l2 = 0;
      for (PetscInt d = 0; d < space.dim; ++d) l2 += (X[k * space.dim + d] - X[bf.opposite * space.dim + d]) * (X[k * space.dim + d] - X[bf.opposite * space.dim + d]);
      reach = std::max(reach, std::sqrt(l2));
    }
  }
};

// The affine part of values v_q at the points of a rule on a simplex of n vertices (a cell, or a face of
// it), given by their barycentric coordinates in the cell (lambdas, nb a point; skip: the cell's vertex off
// the face, or -1): l = Pi_1 v - Pi_0 v at the vertices (the mass matrix (1 + delta_jk) / (n (n + 1)) of
// the normalised rule inverted, less the mean; 0 at skip), and the rule's means of (v - Pi_0 v)^2 and
// (v - Pi_1 v)^2.
struct AffinePart {
  PetscReal l[4] = {0, 0, 0, 0}, dev2 = 0, rest2 = 0;
};
AffinePart ProjectAffine(PetscInt n, PetscInt nb, PetscInt skip, const Quadrature &rule, const PetscReal *values, const PetscReal *lambdas)
{
  AffinePart a;
  PetscReal  mean = 0, mu[4] = {0, 0, 0, 0}; // mu_k: the mean of v lambda_k
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    mean += rule.weights[q] * values[q];
    for (PetscInt k = 0; k < nb; ++k) mu[k] += rule.weights[q] * values[q] * lambdas[q * nb + k];
  }
  for (PetscInt k = 0; k < nb; ++k)
    if (k != skip) a.l[k] = n * (n + 1) * mu[k] - (n + 1) * mean;
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    PetscReal p1 = mean;
    for (PetscInt k = 0; k < nb; ++k) p1 += a.l[k] * lambdas[q * nb + k];
    a.dev2 += rule.weights[q] * (values[q] - mean) * (values[q] - mean);
    a.rest2 += rule.weights[q] * (values[q] - p1) * (values[q] - p1);
  }
  return a;
}

// One Neumann face's data: l = Pi_1 g - Pi_0 g at the cell's vertices (FaceLift), and the bounds: trace
// (of g - Pi_0 g), rest (the trace bound of g - Pi_1 g) and lifted (||kappa^{-1/2} tau|| + rest).
struct NeumannFace {
  FaceLift  lift;
  PetscReal trace, rest, lifted;
};

NeumannFace NeumannFaceData(const Space &space, const Problem &problem, const System &sys, const BoundaryFace &bf, std::vector<PetscReal> &values, std::vector<PetscReal> &lambdas, std::string &error)
{
  const PetscInt    dim = space.dim, nb = space.Nb();
  const Quadrature &rule = sys.oscFaceRule;
  const FaceOf      face(space, bf);
  PetscReal         x[3];
  values.resize(rule.Size()), lambdas.resize(rule.Size() * nb);
  problem.g->SetCellSet(space.CellSet(bf.cell));
  for (PetscInt q = 0; q < rule.Size(); ++q) {
    PetscReal *lambda = &lambdas[q * nb];
    space.FaceToCell(bf, rule.Point(q), lambda);
    space.Point(bf.cell, lambda, x);
    values[q] = problem.g->Scalar(x, dim, error);
  }
  const AffinePart a = ProjectAffine(dim, nb, bf.opposite, rule, values.data(), lambdas.data());
  NeumannFace      nf;
  nf.lift.opposite = bf.opposite;
  std::copy(a.l, a.l + 4, nf.lift.l);
  const PetscReal CP = face.poincare, C2 = face.area * CP / face.g.volume * (CP + 2 * face.reach / dim), kappa = sys.Kappa(bf.cell);
  nf.trace  = std::sqrt(C2 * a.dev2 * face.area / kappa);
  nf.rest   = std::sqrt(C2 * a.rest2 * face.area / kappa);
  nf.lifted = (NeumannLiftNorm(dim, face.X, face.g, bf.opposite, nf.lift.l) + std::sqrt(C2 * a.rest2 * face.area)) / std::sqrt(kappa);
  return nf;
}

// Adds the Neumann oscillation of each face of Gamma_N to its cell's, the smaller of two bounds of
// sup_e (g - Pi_0 g, e)_F / |||e|||_T (Pi_0 g the mean of g by the oscillation's face rule, assembly.h):
//  - trace: (g - Pi_0 g, e)_F = (g - Pi_0 g, e - e_T)_F <= ||g - Pi_0 g||_F C_F ||grad e||_T with
//      C_F^2 = |F| C_T / |T| (C_T + 2 l_F / d),
//    from int_F w = |F|/(d|T|) int_T (d w + (x - a_F) . grad w) (a_F the vertex opposite F) with
//    w = (e - e_T)^2, Poincare's ||e - e_T||_T <= C_T ||grad e||_T (PoincareConstant, at most h_T / pi), and
//    |x - a_F| <= l_F on T, l_F the longest edge at a_F (<= h_T);
//  - lifting: with Pi_1 g the L2 projection onto the affine functions on F, l = Pi_1 g - Pi_0 g (mean zero,
//    l_j at F's vertices X_j) is the normal trace on F of tau = sum_j l_j lambda_j (X_j - a_F) / h_F
//    (h_F = d |T| / |F| the height; on the other faces X_j - a_F is tangent or lambda_j = 0), affine with
//    div tau = sum_j l_j / h_F = 0, so (l, e)_F = int_T tau . grad e <= ||kappa^{-1/2} tau||_T |||e|||_T,
//    and the rest (g - Pi_1 g, e - e_T)_F by the trace bound. On faces where g is about affine the lifting
//    is 0.53 to 0.71 of the trace bound (Kuhn tetrahedra).
void AddNeumannOscillation(const Space &space, const Problem &problem, const System &sys, std::vector<PetscReal> &osc, std::string &error)
{
  if (!problem.HasNeumann() || problem.g->IsConstant()) return;
  std::vector<PetscReal> values, lambdas;
  for (const BoundaryFace &bf : space.boundary) {
    if (!InParts(problem.neumann, bf.part)) continue;
    const NeumannFace nf = NeumannFaceData(space, problem, sys, bf, values, lambdas, error);
    osc[bf.cell] += std::min(nf.trace, nf.lifted);
  }
}

// gamma = int_{Gamma_C} sigma.n (v - psi): sigma.n is Phi_F / |F| on face F (RT0) and v is affine there,
// so each face gives Phi_F (mean of v at its vertices - mean of psi by the face rule). Returns the local
// sum and adds each face's share, twice, to its cell's indicator (see EstimateFromReconstruction).
PetscReal ContactTerm(const Space &space, const Problem &problem, const System &sys, const Reconstruction &r, const PetscScalar *a, std::vector<PetscReal> &cellEta2, std::string &error)
{
  if (!problem.HasContact()) return 0;
  const PetscInt    dim  = space.dim, nb = space.Nb();
  const Quadrature &rule = sys.faceRule;
  PetscReal         sum = 0, lambda[4], x[3];
  for (const BoundaryFace &bf : space.boundary) {
    if (!InParts(problem.contact, bf.part)) continue;
    PetscReal vmean = 0, psimean = 0;
    for (PetscInt k = 0; k < nb; ++k) {
      if (k == bf.opposite) continue;
      const PetscInt v = space.cellVert[bf.cell * nb + k];
      vmean += (r.companion.empty() ? PetscRealPart(a[space.Dofs(bf.cell)[k]]) : r.companion[v]) / dim;
      if (problem.psi->IsConstant()) psimean = problem.psi->Scalar(&space.vertX[v * dim], dim, error);
    }
    if (!problem.psi->IsConstant())
      for (PetscInt q = 0; q < rule.Size(); ++q) {
        space.FaceToCell(bf, rule.Point(q), lambda);
        space.Point(bf.cell, lambda, x);
        psimean += rule.weights[q] * problem.psi->Scalar(x, dim, error);
      }
    const PetscReal gamma = r.flux[bf.cell * nb + bf.opposite] * (vmean - psimean);
    sum += gamma;
    cellEta2[bf.cell] += 2 * std::max(gamma, (PetscReal)0);
  }
  return sum;
}

// The f part of the oscillation per cell, for a reconstruction that did not read it.
PetscErrorCode CellOscillation(const Space &space, const Problem &problem, const System &sys, std::vector<PetscReal> &osc, std::string &error)
{
  std::vector<PetscReal> work;
  PetscFunctionBeginUser;
  osc.resize(space.NumCells());
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.X(c);
    CellGeometry        g;
    CellLoad            load;
    ComputeCellGeometry(space.dim, X, g);
    GetCellLoad(space, problem, sys, c, X, g, work, load, error);
    osc[c] = load.oscillation;
  }
  PetscFunctionReturn(0);
}

// The sums over the cells that the bounds need.
enum Sum { kF2, kN2, kOsc2, kGamma, kFOsc2, kFhOsc2, kFh2, kNumSums };

// The share of eta that the oscillation must make for it to be lifted into the flux (EstimateFromReconstruction).
// The second pass costs up to 7 times the first (CR in 3D; P1 about twice): taken where it can lower eta by
// more than this share (manufactured-3d -box_faces 32, CR: it would lower eta by 1.8 % for 0.22 to 0.27 s
// against 0.033 s; on 6 tetrahedra by 41 %).
constexpr PetscReal kLiftGain = 0.05;

// CellTerms for P1 (v = u_h) from the reconstruction's F_T^2: N_T = 0 and Fh_T = F_T (the same values, so
// the same sums, as the general loop's).
void CellTermsP1(const Space &space, const Reconstruction &r, std::vector<PetscReal> &cellEta2, PetscReal *sums)
{
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const PetscReal f2 = r.fluxTerm[c], o2 = r.oscillation[c] * r.oscillation[c], fo = std::sqrt(f2) + r.oscillation[c];
    cellEta2[c] += f2 + o2;
    sums[kF2] += f2, sums[kOsc2] += o2, sums[kFOsc2] += fo * fo, sums[kFhOsc2] += fo * fo, sums[kFh2] += f2;
  }
}

// The gradients of u_h and of the companion v (u_h itself for P1) on cell c.
template <PetscInt dim>
void CellGradients(const Space &space, const Reconstruction &r, const PetscScalar *a, PetscInt c, const CellGeometry &g, PetscReal *gu, PetscReal *gv)
{
  space.GradD<dim>(c, a, g, gu);
  for (PetscInt d = 0; d < dim; ++d) gv[d] = 0;
  for (PetscInt k = 0; k <= dim; ++k) {
    const PetscReal vk = r.companion.empty() ? PetscRealPart(a[space.Dofs(c)[k]]) : r.companion[space.cellVert[c * (dim + 1) + k]];
    for (PetscInt d = 0; d < dim; ++d) gv[d] += vk * g.gradLambda[k][d];
  }
}

// The cell terms F_T^2, N_T^2 and osc_T^2 into the indicators and the local sums: F^2, N^2, osc^2,
// sum_T (F_T + osc_T)^2, sum_T (Fh_T + osc_T)^2 and Fh^2 with Fh_T = ||kappa^{-1/2}(kappa grad u_h - sigma)||_T.
// With vertexSums (CR), also the per-vertex sums ImproveCompanion starts from.
// (The dimension a template parameter, as in the other cell loops: their short loops unroll.)
template <PetscInt dim>
void CellTermsD(const Space &space, const System &sys, const Reconstruction &r, const PetscScalar *a, std::vector<PetscReal> &cellEta2, PetscReal *sums, std::vector<PetscReal> *vertexSums)
{
  constexpr PetscInt nb = dim + 1;
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.XD<dim>(c);
    CellGeometry        g;
    PetscReal           gu[3], gv[3], w[3], wh[3], n2 = 0;
    ComputeCellGeometryD<dim>(X, g);
    CellGradients<dim>(space, r, a, c, g, gu, gv);
    const PetscReal kappa = sys.Kappa(c);
    for (PetscInt d = 0; d < dim; ++d) {
      w[d]  = kappa * gv[d];
      wh[d] = kappa * gu[d];
      n2 += (gu[d] - gv[d]) * (gu[d] - gv[d]);
    }
    n2 *= kappa * g.volume;
    for (PetscInt k = 0; vertexSums && k < nb; ++k) {
      PetscReal dot = 0, l2 = 0, *vs = &(*vertexSums)[2 * space.cellVert[c * nb + k]];
      for (PetscInt d = 0; d < dim; ++d) dot += (gu[d] - gv[d]) * g.gradLambda[k][d], l2 += g.gradLambda[k][d] * g.gradLambda[k][d];
      vs[0] += kappa * g.volume * dot, vs[1] += kappa * g.volume * l2;
    }
    const CellFlux  sigma(dim, X, g, &r.flux[c * nb], kappa);
    const PetscReal f2 = sigma.Term(dim, w), o2 = r.oscillation[c] * r.oscillation[c];
    cellEta2[c] += f2 + n2 + o2;
    const PetscReal fh2 = sigma.Term(dim, wh);
    const PetscReal fo = std::sqrt(f2) + r.oscillation[c], fho = std::sqrt(fh2) + r.oscillation[c];
    sums[kF2] += f2, sums[kN2] += n2, sums[kOsc2] += o2, sums[kFOsc2] += fo * fo, sums[kFhOsc2] += fho * fho, sums[kFh2] += fh2;
  }
}
void CellTerms(const Space &space, const System &sys, const Reconstruction &r, const PetscScalar *a, std::vector<PetscReal> &cellEta2, PetscReal *sums, std::vector<PetscReal> *vertexSums)
{
  if (!r.fluxTerm.empty()) CellTermsP1(space, r, cellEta2, sums);
  else WithDim(space.dim, [&](auto D) { CellTermsD<D>(space, sys, r, a, cellEta2, sums, vertexSums); });
}

// The Neumann faces of each local cell with their data (NeumannFaceData): faces[start[c] .. start[c + 1]).
struct NeumannFaces {
  std::vector<PetscInt>    start;
  std::vector<NeumannFace> faces;
};

void CollectNeumannFaces(const Space &space, const Problem &problem, const System &sys, NeumannFaces &nf, std::string &error)
{
  nf.start.assign(space.NumCells() + 1, 0);
  nf.faces.clear();
  if (!problem.HasNeumann() || problem.g->IsConstant()) return;
  std::vector<PetscReal> values, lambdas;
  std::vector<NeumannFace> found;
  std::vector<PetscInt>    cellOf;
  for (const BoundaryFace &bf : space.boundary)
    if (InParts(problem.neumann, bf.part)) {
      found.push_back(NeumannFaceData(space, problem, sys, bf, values, lambdas, error));
      cellOf.push_back(bf.cell);
      ++nf.start[bf.cell + 1];
    }
  std::partial_sum(nf.start.begin(), nf.start.end(), nf.start.begin());
  nf.faces.resize(found.size());
  std::vector<PetscInt> fill(nf.start.begin(), nf.start.end() - 1);
  for (size_t i = 0; i < found.size(); ++i) nf.faces[fill[cellOf[i]]++] = found[i];
}

// The cell terms with the data's affine parts lifted into the flux (datalift.h): sigma = sigma0 + tau on
// every cell, div sigma = -Pi_1 f, sigma.n = Pi_1 g on Gamma_N, and the oscillation that of f - Pi_1 f
// (Poincare, Pi_1 f keeps the mean) and g - Pi_1 g (the trace bound). Pi_1 f and ||f - Pi_1 f|| by the
// oscillation's rule. The same sums as CellTermsD.
template <PetscInt dim>
void LiftedCellTermsD(const Space &space, const Problem &problem, const System &sys, const Reconstruction &r, const PetscScalar *a, const NeumannFaces &nf, std::vector<PetscReal> &cellEta2, PetscReal *sums, std::string &error)
{
  constexpr PetscInt     nb   = dim + 1;
  const Quadrature      &rule = sys.oscCellRule;
  const bool             fvar = !problem.f->IsConstant(), fromLoads = !sys.cellLoads.empty() && sys.cellRule.degree >= System::kOscillationDegree;
  std::vector<PetscReal> x(rule.Size() * dim), fx(rule.Size()), work;
  FaceLift               lifts[4];
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    const Space::Coords X = space.XD<dim>(c);
    CellGeometry        g;
    PetscReal           gu[3], gv[3], n2 = 0;
    ComputeCellGeometryD<dim>(X, g);
    CellGradients<dim>(space, r, a, c, g, gu, gv);
    const PetscReal kappa = sys.Kappa(c);
    for (PetscInt d = 0; d < dim; ++d) n2 += (gu[d] - gv[d]) * (gu[d] - gv[d]);
    n2 *= kappa * g.volume;
    const PetscReal *phi = &r.flux[c * nb];
    // w - sigma0 and wh - sigma0 at the vertices: sigma0(X_m) = sum_k Phi_k (X_m - X_k) / (d |T|).
    PetscReal        D[nb * dim], Dh[nb * dim];
    for (PetscInt m = 0; m < nb; ++m)
      for (PetscInt d = 0; d < dim; ++d) {
        PetscReal s0 = 0;
        for (PetscInt k = 0; k < nb; ++k) s0 += phi[k] * (X[m * dim + d] - X[k * dim + d]);
        s0 /= dim * g.volume;
        D[m * dim + d] = kappa * gv[d] - s0, Dh[m * dim + d] = kappa * gu[d] - s0;
      }
    // The load's affine part l (mean zero) and ||f - Pi_1 f||^2 by the oscillation's rule: from the kept
    // load where it is that rule (moments int f lambda_k, and ||f - Pi_0 f||^2 through the first pass's
    // oscillation; Pythagoras holds for the rule's inner product, which integrates affine products
    // exactly), else from f evaluated again.
    PetscReal       lf[nb] = {}, rest2 = 0;
    const PetscReal C = fvar ? PoincareConstant(dim, X.x) : 0;
    if (fvar && fromLoads) {
      CellLoad  load;
      PetscReal mean = 0, mu[nb];
      GetCellLoad(space, problem, sys, c, X, g, work, load, error);
      for (PetscInt k = 0; k < nb; ++k) mu[k] = load.moment[k] / g.volume, mean += mu[k];
      for (PetscInt k = 0; k < nb; ++k) lf[k] = nb * (nb + 1) * mu[k] - (nb + 1) * mean;
      if (load.oscillation > 0) {
        const PetscReal dev2 = load.oscillation * load.oscillation * kappa / (C * C * g.volume);
        PetscReal       l2   = 0; // ||Pi_1 f - Pi_0 f||^2 / |T| = sum_k l_k^2 / ((d + 1)(d + 2)), as sum_k l_k = 0
        for (PetscInt k = 0; k < nb; ++k) l2 += lf[k] * lf[k];
        rest2 = dev2 - l2 / (nb * (nb + 1));
        // Where f is affine on T the difference is round-off, of the size of eps (mean^2 + dev2), and its
        // square root would make an oscillation of 1e-8 of the cell's, different in every vertex order (so
        // on other rank counts: the estimate of an adapted 3D mesh differed by 1e-9 between 1 and 2 ranks).
        if (rest2 <= 64 * PETSC_MACHINE_EPSILON * (mean * mean + dev2)) rest2 = 0;
      }
    } else if (fvar) {
      for (PetscInt q = 0; q < rule.Size(); ++q) SimplexPoint(dim, X.x, rule.Point(q), &x[q * dim]);
      problem.f->SetCellSet(space.CellSet(c));
      problem.f->EvalBatch(rule.Size(), x.data(), dim, nullptr, fx.data(), error);
      const AffinePart f = ProjectAffine(nb, nb, -1, rule, fx.data(), rule.Point(0));
      std::copy(f.l, f.l + nb, lf);
      rest2 = f.rest2;
    }
    const PetscReal oscf = rest2 > 0 ? C * std::sqrt(rest2 * g.volume / kappa) : 0;
    PetscInt  nfaces = 0;
    PetscReal oscg   = 0;
    for (PetscInt i = nf.start[c]; i < nf.start[c + 1]; ++i) lifts[nfaces++] = nf.faces[i].lift, oscg += nf.faces[i].rest;
    PetscReal r2, rh2;
    LiftCell(dim, X.x, g, lf, nfaces, lifts, D, Dh, &r2, &rh2);
    const PetscReal f2 = r2 / kappa, fh2 = rh2 / kappa, osc = oscf + oscg, o2 = osc * osc;
    cellEta2[c] += f2 + n2 + o2;
    const PetscReal fo = std::sqrt(f2) + osc, fho = std::sqrt(fh2) + osc;
    sums[kF2] += f2, sums[kN2] += n2, sums[kOsc2] += o2, sums[kFOsc2] += fo * fo, sums[kFhOsc2] += fho * fho, sums[kFh2] += fh2;
  }
}

// The terms the bounds are made of (global): N = |||u_h - v|||, F = ||kappa^{-1/2}(kappa grad v - sigma)||,
// Fh = ||kappa^{-1/2}(kappa grad_h u_h - sigma)||, osc = (sum_T osc_T^2)^{1/2}, b and bh (cell by cell, see
// Bound), gamma the contact term.
struct BoundTerms {
  PetscReal N, F, Fh, osc, b, bh, gamma;
};

// Bound 3 (see Bound): the largest min(E + N, S + Fh) over the (E, S) >= 0 with E <= Emax and
// (E - osc)^2 + S^2 <= G2 + osc^2 (G2 = F^2 + 2 gamma). On that disc's edge S + Fh = c(E) = sqrt(G2 + 2 osc E -
// E^2) + Fh is concave in E with its top at E = osc, and E + N rises: if c <= E + N at the top, the top is the
// answer; otherwise the answer is E + N where the two meet to the right of the top (the larger root of
// (E + N - Fh)^2 = G2 + 2 osc E - E^2 with E + N - Fh >= 0), or at Emax if they do not meet before it.
// (Checked against a brute-force maximisation on random terms while writing it.)
PetscReal FluxErrorBound(const BoundTerms &t, PetscReal gamma, PetscReal Emax)
{
  const PetscReal G2 = t.F * t.F + 2 * gamma, o = t.osc;
  Emax                   = std::min(Emax, o + std::sqrt(o * o + G2)); // beyond it, no S >= 0 is left
  const PetscReal top    = std::min(o, Emax);
  const PetscReal cTop   = std::sqrt(std::max(G2 + 2 * o * top - top * top, (PetscReal)0)) + t.Fh;
  if (cTop <= top + t.N) return cTop;
  const PetscReal p = t.N - t.Fh, disc = (p - o) * (p - o) - 2 * (p * p - G2);
  const PetscReal E = disc < 0 ? Emax : std::min(Emax, std::max({top, -p, (o - p + std::sqrt(disc)) / 2}));
  return E + t.N;
}

// The smallest of three guaranteed bounds of |||u - u_h|||, all from the variational inequality tested with
// v (see estimate.h for the assumptions), N = |||u_h - v|||, gamma the contact term:
//  1. estimate.h's: E = |||u - v||| <= (b + sqrt(b^2 + 4 gamma)) / 2 with b = F + osc, and |||u - u_h||| <= N + E.
//  2. With e = u - u_h: |||e|||^2 = (kappa grad_h e, grad(u - v)) + (kappa grad_h e, grad_h(v - u_h)); the second
//     term is <= |||e||| N, and the first, as in 1. but with kappa grad_h u_h in place of kappa grad v, is
//     <= bh |||u - v||| + gamma <= bh (|||e||| + N) + gamma with bh = Fh + osc. So |||e|||^2 <= a |||e||| + c,
//     a = N + bh, c = bh N + gamma: |||e||| <= (a + sqrt(a^2 + 4 c)) / 2. sigma is close to kappa grad_h u_h
//     (for CR it differs by the load term only), so bh is of the size of osc, and 2. is about N + 2 bh where
//     1. is about 2 N (F and N both measure how far v is from u_h). For P1 (N = 0) both are the same.
//  3. The primal-dual split (Prager-Synge for the inequality): with S = ||kappa^{-1/2}(kappa grad u - sigma)||
//     (the flux's own error), kappa^{-1/2}(kappa grad v - sigma) = kappa^{1/2} grad(v - u) + kappa^{-1/2}(kappa
//     grad u - sigma), so F^2 = E^2 + S^2 + 2 X, X = (grad(v - u), kappa grad u - sigma). The inequality
//     tested with v in K gives (kappa grad u, grad(v - u)) >= (f, v - u) + (g, v - u)_N, and Green's formula
//     with div sigma = -Pi_0 f, sigma.n = Pi_0 g on Gamma_N and v - u = 0 on Gamma_D gives (sigma, grad(v - u))
//     = (Pi_0 f, v - u) + (Pi_0 g, v - u)_N + (sigma.n, v - u)_C. So X >= (f - Pi_0 f, v - u) + (g - Pi_0 g,
//     v - u)_N - (sigma.n, v - psi)_C + (sigma.n, u - psi)_C >= -osc E - gamma (sigma.n >= 0, u >= psi on
//     Gamma_C; the oscillation as in estimate.h), i.e. E^2 + S^2 <= F^2 + 2 gamma + 2 osc E. The broken
//     gradient of the error is kappa^{-1/2}(kappa grad u - sigma) + kappa^{-1/2}(sigma - kappa grad_h u_h),
//     so |||e||| <= S + Fh, and |||e||| <= E + N as in 1.: |||e||| <= max min(E + N, S + Fh) over the (E, S)
//     allowed (FluxErrorBound), E <= the E of 1. too. Where v is close to u_h (F about N, Fh small), E and S
//     cannot both be large: the bound is about max(N, F) instead of the 2 N of 1. and the N + 2 bh of 2.
//     For P1 (Fh = F, N = 0) it is never below 1.
// b and bh combine flux and oscillation cell by cell (sum_T (F_T + osc_T) |||w|||_T <= b |||w|||), which is
// at most F + osc. gamma < 0 only where psi is not affine on a face (v >= psi at the vertices only): the
// bound then holds up to that data approximation, and gamma counts as 0.
PetscReal Bound(const BoundTerms &t)
{
  const PetscReal gamma = std::max(t.gamma, (PetscReal)0), a = t.N + t.bh, c = t.bh * t.N + gamma;
  const PetscReal E     = (t.b + std::sqrt(t.b * t.b + 4 * gamma)) / 2;
  return std::min({t.N + E, (a + std::sqrt(a * a + 4 * c)) / 2, FluxErrorBound(t, gamma, E)});
}

// From the quadratic inequality E^2 <= b E + gamma (estimate.h), E^2 <= b^2 + 2 gamma, so the cell
// indicators carry their contact faces' shares of gamma twice: then eta^2 <= 2 N^2 + 2 E^2
// <= 2 N^2 + 4 (F^2 + osc^2) + 4 gamma <= 4 sum_T eta_T^2, i.e. the indicators' root sum is at least eta/2
// and their sizes weigh the contact gap as the bound does for small gamma.
PetscErrorCode EstimateFromReconstruction(const Space &space, const Problem &problem, const System &sys, Vec u, Reconstruction &r, Estimate &e)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)space.dm);
  Vec                loc;
  const PetscScalar *a;
  std::string        error;
  PetscReal          sums[kNumSums] = {0};
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  if (r.oscillation.empty()) PetscCall(CellOscillation(space, problem, sys, r.oscillation, error));
  AddNeumannOscillation(space, problem, sys, r.oscillation, error);
  PetscCall(CheckAll(comm, error.empty(), error));
  // The cell and contact terms of the current companion into the indicators and the global sums.
  const auto Terms = [&](std::vector<PetscReal> &cellEta2, PetscReal *s, std::vector<PetscReal> *vs) -> PetscErrorCode {
    PetscFunctionBeginUser;
    cellEta2.assign(space.NumCells(), 0.0);
    std::fill(s, s + kNumSums, 0.0);
    s[kGamma] = ContactTerm(space, problem, sys, r, a, cellEta2, error);
    CellTerms(space, sys, r, a, cellEta2, s, vs);
    PetscCall(CheckAll(comm, error.empty(), error));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, s, kNumSums, MPIU_REAL, MPI_SUM, comm));
    PetscFunctionReturn(0);
  };
  // The terms of the companion r holds, moved by ImproveCompanion where that pays (CR; decided by the
  // element, the same on every rank: ImproveCompanion is collective, and a rank without cells has an empty
  // companion), then again where it moved.
  const auto TermsImproved = [&](std::vector<PetscReal> &cellEta2, PetscReal *s) -> PetscErrorCode {
    bool                   improve = space.element == Element::CR;
    std::vector<PetscReal> vertexSums(improve ? 2 * r.companion.size() : 0, 0.0);
    PetscFunctionBeginUser;
    for (bool again = true; again; improve = false) {
      PetscCall(Terms(cellEta2, s, improve ? &vertexSums : nullptr));
      again = false;
      if (improve) PetscCall(ImproveCompanion(space, sys, vertexSums, s[kN2], r, again));
    }
    PetscFunctionReturn(0);
  };
  const auto BoundOf = [](const PetscReal *s, PetscReal gamma) {
    return Bound({std::sqrt(s[kN2]), std::sqrt(s[kF2]), std::sqrt(s[kFh2]), std::sqrt(s[kOsc2]), std::sqrt(s[kFOsc2]), std::sqrt(s[kFhOsc2]), gamma});
  };
  const std::vector<PetscReal> average(r.anyPinned ? r.companion : std::vector<PetscReal>());
  PetscCall(TermsImproved(e.cellEta2, sums));
  e.eta = BoundOf(sums, sums[kGamma]);
  // gamma grows with the contact pressure where v lies above psi on an active face, as the average of u_h
  // does at its vertices by about the nonconformity, while the error does not (psi raised by a constant c
  // over a fully active Gamma_C, an affine part of u the space holds: eta grew like c^(1/2), from 0.32 at
  // c = 0 to 5.5e3 at c = 1e10, paper-5.1 -box_faces 8). v held at psi there (and moved elsewhere as
  // before, those vertices held) makes gamma vanish for a larger N (which on coarse meshes of smaller
  // pressures outweighs the gain: paper-5.1 -box_faces 8 0.318 -> 0.333): both are valid companions and
  // eta is the smaller, the second computed only where gamma weighs more than kLiftGain in eta.
  if (r.anyPinned && e.eta - BoundOf(sums, 0) > kLiftGain * e.eta) {
    std::vector<PetscReal> first(r.companion), cellEta2;
    std::vector<char>      movable(r.movable);
    PetscReal              held[kNumSums];
    r.companion = average;
    for (size_t v = 0; v < r.pinned.size(); ++v)
      if (r.pinned[v]) r.companion[v] = r.lower[v], r.movable[v] = 0;
    PetscCall(TermsImproved(cellEta2, held));
    r.movable = std::move(movable);
    const PetscReal eta = BoundOf(held, held[kGamma]);
    if (eta < e.eta) e.eta = eta, e.cellEta2 = std::move(cellEta2), std::copy(held, held + kNumSums, sums);
    else r.companion = std::move(first);
  }
  e.flux          = std::sqrt(sums[kF2]);
  e.nonconformity = std::sqrt(sums[kN2]);
  e.oscillation   = std::sqrt(sums[kOsc2]);
  e.contact       = sums[kGamma];
  // Where the oscillation weighs in eta (coarse meshes, rough data), the data's affine parts lifted into
  // the flux (datalift.h) give a second guaranteed bound, about the bound without oscillation (the
  // linear term gone, the lifted fields in F^2 instead); eta is the smaller of the two. Where the bound
  // without oscillation is within kLiftGain of eta, the second pass is left out.
  const PetscReal withoutOsc = Bound({e.nonconformity, e.flux, std::sqrt(sums[kFh2]), 0, e.flux, std::sqrt(sums[kFh2]), e.contact});
  if (e.eta - withoutOsc > kLiftGain * e.eta) {
    NeumannFaces           nf;
    std::vector<PetscReal> cellEta2(space.NumCells(), 0.0);
    PetscReal              lifted[kNumSums] = {0};
    CollectNeumannFaces(space, problem, sys, nf, error);
    lifted[kGamma] = ContactTerm(space, problem, sys, r, a, cellEta2, error);
    WithDim(space.dim, [&](auto D) { LiftedCellTermsD<D>(space, problem, sys, r, a, nf, cellEta2, lifted, error); });
    PetscCall(CheckAll(comm, error.empty(), error));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, lifted, kNumSums, MPIU_REAL, MPI_SUM, comm));
    const PetscReal eta = Bound({std::sqrt(lifted[kN2]), std::sqrt(lifted[kF2]), std::sqrt(lifted[kFh2]), std::sqrt(lifted[kOsc2]), std::sqrt(lifted[kFOsc2]), std::sqrt(lifted[kFhOsc2]), lifted[kGamma]});
    if (eta < e.eta) {
      e.eta         = eta;
      e.flux        = std::sqrt(lifted[kF2]);
      e.oscillation = std::sqrt(lifted[kOsc2]);
      e.cellEta2    = std::move(cellEta2);
    }
  }
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscFunctionReturn(0);
}
} // namespace

PetscReal NeumannLiftNorm(PetscInt dim, const PetscReal *X, const CellGeometry &g, PetscInt opposite, const PetscReal *l)
{
  // ||tau||^2 = sum_jk l_j l_k (X_j - X_o) . (X_k - X_o) int_T lambda_j lambda_k / h^2, with
  // int_T lambda_j lambda_k = |T| (1 + delta_jk) / ((d + 1)(d + 2)) and h = d |T| / |F|.
  const PetscReal *a   = &X[opposite * dim];
  PetscReal        gl2 = 0; // |grad lambda_o|^2 = 1 / h^2
  for (PetscInt d = 0; d < dim; ++d) gl2 += g.gradLambda[opposite][d] * g.gradLambda[opposite][d];
  PetscReal sum = 0;
  for (PetscInt j = 0; j <= dim; ++j)
    for (PetscInt k = 0; k <= dim; ++k) {
      if (j == opposite || k == opposite) continue;
      PetscReal dot = 0;
      for (PetscInt d = 0; d < dim; ++d) dot += (X[j * dim + d] - a[d]) * (X[k * dim + d] - a[d]);
      sum += l[j] * l[k] * dot * (j == k ? 2 : 1);
    }
  return std::sqrt(std::max(sum, (PetscReal)0) * g.volume * gl2 / ((dim + 1) * (dim + 2)));
}

PetscErrorCode EstimateError(const Space &space, const Problem &problem, const System &sys, Vec u, Estimate &e)
{
  PetscLogDouble t0;
  Reconstruction r;
  PetscFunctionBeginUser;
  e = Estimate();
  static PetscLogEvent events[2] = {0, 0}; // -log_view lists them under the Estimate stage
  if (!events[0]) PetscCall(PetscLogEventRegister("Reconstruct", DM_CLASSID, &events[0]));
  if (!events[1]) PetscCall(PetscLogEventRegister("EstimateCells", DM_CLASSID, &events[1]));
  PetscCall(PetscTime(&t0));
  PetscCall(StagePush(Stage::Estimate));
  PetscCall(PetscLogEventBegin(events[0], 0, 0, 0, 0));
  if (space.element == Element::CR) PetscCall(ReconstructCR(space, problem, sys, u, r));
  else PetscCall(ReconstructP1(space, problem, sys, u, r));
  PetscCall(PetscLogEventEnd(events[0], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(events[1], 0, 0, 0, 0));
  PetscCall(EstimateFromReconstruction(space, problem, sys, u, r, e));
  PetscCall(PetscLogEventEnd(events[1], 0, 0, 0, 0));
  PetscCall(StagePop(Stage::Estimate));
  PetscCall(SecondsSince(PetscObjectComm((PetscObject)space.dm), t0, &e.seconds));
  e.computed = true;
  PetscFunctionReturn(0);
}

} // namespace signorini

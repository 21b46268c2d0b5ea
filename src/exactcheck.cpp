// The check of a scene's exact solution against the scene (exactcheck.h).
#include "signorini/exactcheck.h"

#include "signorini/mesh.h"

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace signorini {

namespace {

enum Condition { kGradient, kEquation, kDirichlet, kNeumann, kAbove, kPressure, kComplementarity, kConditions };

// The worst miss of one condition on this rank: its ratio to the condition's tolerance, where, and the two
// values the warning shows.
struct Miss {
  PetscReal ratio = 0, x[3] = {0, 0, 0}, a[3] = {0, 0, 0}, b[3] = {0, 0, 0};
  void      Record(PetscReal miss, PetscReal tol, PetscInt dim, const PetscReal *at, const PetscReal *va, const PetscReal *vb, PetscInt n)
  {
    if (!(miss > tol)) return;
    const PetscReal r = tol > 0 ? miss / tol : PETSC_MAX_REAL;
    if (r <= ratio) return;
    ratio = r;
    std::copy(at, at + dim, x);
    std::copy(va, va + n, a);
    std::copy(vb, vb + n, b);
  }
};

// A point where the conditions are checked, with the step of its difference quotients and its cell's set.
struct Sample {
  PetscReal x[3] = {0, 0, 0}, n[3] = {0, 0, 0}; // n: the outward unit normal at a boundary point
  PetscReal h    = 0;
  PetscInt  set  = -1;
  char      kind = 0; // 0: inside a cell; else the boundary part's kind (exactcheck.h)
};

// Fourth-order central difference quotients along each direction: offsets -2, -1, 1, 2 steps.
const PetscReal kOffset[4] = {-2, -1, 1, 2}, kWeight[4] = {1.0 / 12, -8.0 / 12, 8.0 / 12, -1.0 / 12};

// What the samples give: at each, u, grad u (dim), kappa, and inside cells the difference quotients of u
// (dim) and div(kappa grad u); f, u_D, g, psi where they apply. Expressions are evaluated in blocks.
struct Values {
  std::vector<PetscReal> u, grad, kappa, fdGrad, div, f, uD, g, psi;
};

PetscErrorCode Evaluate(const Problem &p, PetscInt dim, const std::vector<Sample> &s, Values &v)
{
  const PetscInt         n = (PetscInt)s.size(), per = 1 + 4 * dim; // the point, then its stencil
  std::vector<PetscReal> x(n * per * dim), u(n * per), grad(n * per * dim), kappa(n * per);
  std::vector<PetscInt>  sets(n * per);
  std::string            error; // a non-finite value: reported where the run evaluates it (not here)
  PetscFunctionBeginUser;
  for (PetscInt i = 0; i < n; ++i)
    for (PetscInt k = 0; k < per; ++k) {
      PetscReal *y = &x[(i * per + k) * dim];
      std::copy(s[i].x, s[i].x + dim, y);
      if (k > 0) y[(k - 1) / 4] += kOffset[(k - 1) % 4] * s[i].h;
      sets[i * per + k] = s[i].set;
    }
  (void)p.exact->EvalBatch(n * per, x.data(), dim, sets.data(), u.data(), error);
  (void)p.exactGrad->EvalBatch(n * per, x.data(), dim, sets.data(), grad.data(), error);
  (void)p.kappa->EvalBatch(n * per, x.data(), dim, sets.data(), kappa.data(), error);
  v.u.resize(n), v.grad.resize(n * dim), v.kappa.resize(n), v.fdGrad.assign(n * dim, 0), v.div.assign(n, 0);
  for (PetscInt i = 0; i < n; ++i) {
    v.u[i]     = u[i * per];
    v.kappa[i] = kappa[i * per];
    for (PetscInt d = 0; d < dim; ++d) {
      v.grad[i * dim + d] = grad[i * per * dim + d];
      for (PetscInt k = 0; k < 4; ++k) {
        const PetscInt j = i * per + 1 + 4 * d + k;
        v.fdGrad[i * dim + d] += kWeight[k] * u[j] / s[i].h;
        v.div[i] += kWeight[k] * kappa[j] * grad[j * dim + d] / s[i].h;
      }
    }
  }
  std::vector<PetscReal> base(n * dim);
  for (PetscInt i = 0; i < n; ++i) std::copy(s[i].x, s[i].x + dim, &base[i * dim]);
  std::vector<PetscInt> baseSets(n);
  for (PetscInt i = 0; i < n; ++i) baseSets[i] = s[i].set;
  v.f.resize(n), v.uD.resize(n), v.g.resize(n), v.psi.resize(n);
  (void)p.f->EvalBatch(n, base.data(), dim, baseSets.data(), v.f.data(), error);
  (void)p.uD->EvalBatch(n, base.data(), dim, nullptr, v.uD.data(), error);
  (void)p.g->EvalBatch(n, base.data(), dim, baseSets.data(), v.g.data(), error);
  (void)p.psi->EvalBatch(n, base.data(), dim, nullptr, v.psi.data(), error);
  PetscFunctionReturn(0);
}

// The scales the tolerances are relative to, over all samples of all ranks: max |u|, max |grad u|, max
// kappa, and the size of the domain (its bounding box's diagonal).
struct Scales {
  PetscReal U = 0, G = 0, K = 0, L = 0;
};

void Judge(PetscInt dim, const std::vector<Sample> &s, const Values &v, const Scales &sc, Miss miss[kConditions])
{
  const PetscReal eps = DBL_EPSILON, reach = sc.U + sc.G * sc.L; // reach: the size of u's values
  for (size_t i = 0; i < s.size(); ++i) {
    const PetscReal *x = s[i].x, *grad = &v.grad[i * dim], kappa = v.kappa[i];
    PetscReal        dn = 0;
    for (PetscInt d = 0; d < dim; ++d) dn += grad[d] * s[i].n[d];
    const PetscReal flux = kappa * dn; // kappa du/dn
    if (s[i].kind == 0) {
      PetscReal diff = 0;
      for (PetscInt d = 0; d < dim; ++d) diff += PetscSqr(v.fdGrad[i * dim + d] - grad[d]);
      miss[kGradient].Record(std::sqrt(diff), 1e-3 * sc.G + 100 * eps * sc.U / s[i].h, dim, x, grad, &v.fdGrad[i * dim], dim);
      const PetscReal lhs = -v.div[i], scale = std::max({std::fabs(v.f[i]), std::fabs(lhs), kappa * sc.G / sc.L});
      miss[kEquation].Record(std::fabs(lhs - v.f[i]), 1e-3 * scale + 100 * eps * kappa * sc.G / s[i].h, dim, x, &lhs, &v.f[i], 1);
      continue;
    }
    if (s[i].kind == 1) miss[kDirichlet].Record(std::fabs(v.u[i] - v.uD[i]), 1e-6 * reach, dim, x, &v.u[i], &v.uD[i], 1);
    if (s[i].kind == 4) miss[kNeumann].Record(std::fabs(flux - v.g[i]), 1e-3 * std::max(std::fabs(v.g[i]), kappa * sc.G), dim, x, &flux, &v.g[i], 1);
    if (s[i].kind != 2) continue;
    const PetscReal gap = v.u[i] - v.psi[i];
    miss[kAbove].Record(-gap, 1e-6 * reach, dim, x, &v.u[i], &v.psi[i], 1);
    miss[kPressure].Record(-flux, 1e-3 * kappa * sc.G, dim, x, &flux, &flux, 1);
    // both clearly positive: the smaller of the two against its tolerance
    const PetscReal tolGap = 1e-3 * reach, tolFlux = 1e-3 * kappa * sc.G;
    if (gap > tolGap && flux > tolFlux) miss[kComplementarity].Record(std::min(gap / tolGap, flux / tolFlux), 1, dim, x, &gap, &flux, 1);
  }
}

} // namespace

PetscErrorCode CheckExactSolution(DM dm, const Problem &p, const std::vector<char> &kind, PetscInt *failed)
{
  MPI_Comm               comm = PetscObjectComm((PetscObject)dm);
  PetscInt               dim, pStart, cStart, cEnd, fStart, fEnd, cells;
  DMLabel                cellSets;
  std::vector<PetscReal> X;
  std::vector<Sample>    samples;
  PetscFunctionBeginUser;
  *failed = -1;
  if (!p.exact) PetscFunctionReturn(0);
  *failed = 0;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(DMPlexGetChart(dm, &pStart, NULL));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));
  PetscCall(DMGetLabel(dm, "Cell Sets", &cellSets));
  PetscCall(VertexCoordinates(dm, X));
  PetscInt vStart;
  PetscCall(DMPlexGetDepthStratum(dm, 0, &vStart, NULL));
  // Points inside every cell: its centroid and the midpoints towards its vertices (the centroid alone on
  // coarse meshes of over 10^4 cells); the same points on any number of ranks.
  PetscInt local = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(&local, &cells, 1, MPIU_INT, MPI_SUM, comm));
  const bool few = cells <= 10000;
  PetscReal lo[3] = {PETSC_MAX_REAL, PETSC_MAX_REAL, PETSC_MAX_REAL}, hi[3] = {-PETSC_MAX_REAL, -PETSC_MAX_REAL, -PETSC_MAX_REAL};
  for (size_t i = 0; i < X.size(); ++i) lo[i % dim] = std::min(lo[i % dim], X[i]), hi[i % dim] = std::max(hi[i % dim], X[i]);
  const auto centroidOf = [&](const PetscInt *verts, PetscInt nv, PetscReal *c) {
    for (PetscInt d = 0; d < dim; ++d) {
      c[d] = 0;
      for (PetscInt k = 0; k < nv; ++k) c[d] += X[(verts[k] - vStart) * dim + d] / nv;
    }
  };
  const auto diameterOf = [&](const PetscInt *verts, PetscInt nv) {
    PetscReal h2 = 0;
    for (PetscInt a = 0; a < nv; ++a)
      for (PetscInt b = a + 1; b < nv; ++b) {
        PetscReal e2 = 0;
        for (PetscInt d = 0; d < dim; ++d) e2 += PetscSqr(X[(verts[a] - vStart) * dim + d] - X[(verts[b] - vStart) * dim + d]);
        h2 = std::max(h2, e2);
      }
    return std::sqrt(h2);
  };
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscInt verts[4];
    PetscCall(SimplexVertices(dm, c, dim, verts));
    Sample s;
    centroidOf(verts, dim + 1, s.x);
    s.h = 1e-3 * diameterOf(verts, dim + 1);
    if (cellSets) PetscCall(DMLabelGetValue(cellSets, c, &s.set));
    samples.push_back(s);
    for (PetscInt k = 0; k <= dim && few; ++k) {
      Sample m = s;
      for (PetscInt d = 0; d < dim; ++d) m.x[d] = 0.5 * (s.x[d] + X[(verts[k] - vStart) * dim + d]);
      samples.push_back(m);
    }
  }
  // Points on every face of a named part: its centroid and the midpoints towards its vertices.
  for (PetscInt f = fStart; f < fEnd; ++f) {
    const PetscInt *supp;
    PetscInt        nsupp, verts[4], cverts[4];
    if (!kind[f - pStart]) continue;
    PetscCall(DMPlexGetSupportSize(dm, f, &nsupp));
    PetscCall(DMPlexGetSupport(dm, f, &supp));
    if (nsupp != 1) continue;
    PetscCall(SimplexVertices(dm, f, dim - 1, verts));
    PetscCall(SimplexVertices(dm, supp[0], dim, cverts));
    Sample    s;
    PetscReal cc[3], normal[3], area, n2 = 0, side = 0;
    centroidOf(verts, dim, s.x);
    centroidOf(cverts, dim + 1, cc);
    PetscCall(DMPlexComputeCellGeometryFVM(dm, f, &area, NULL, normal));
    for (PetscInt d = 0; d < dim; ++d) n2 += PetscSqr(normal[d]), side += normal[d] * (s.x[d] - cc[d]);
    for (PetscInt d = 0; d < dim; ++d) s.n[d] = (side < 0 ? -1 : 1) * normal[d] / std::sqrt(n2);
    if (cellSets) PetscCall(DMLabelGetValue(cellSets, supp[0], &s.set));
    s.kind = kind[f - pStart];
    s.h    = 1e-3 * diameterOf(cverts, dim + 1);
    samples.push_back(s);
    for (PetscInt k = 0; k < dim; ++k) {
      Sample m = s;
      for (PetscInt d = 0; d < dim; ++d) m.x[d] = 0.5 * (s.x[d] + X[(verts[k] - vStart) * dim + d]);
      samples.push_back(m);
    }
  }
  // Values in blocks (the stencils of a block at once), then the scales over all ranks, then the misses.
  const size_t        kBlock = 1024;
  std::vector<Values> blocks;
  Scales              sc;
  for (size_t b = 0; b < samples.size(); b += kBlock) {
    const std::vector<Sample> part(samples.begin() + b, samples.begin() + std::min(samples.size(), b + kBlock));
    blocks.emplace_back();
    PetscCall(Evaluate(p, dim, part, blocks.back()));
    const Values &w = blocks.back();
    for (size_t i = 0; i < part.size(); ++i) {
      PetscReal g2 = 0;
      for (PetscInt d = 0; d < dim; ++d) g2 += PetscSqr(w.grad[i * dim + d]);
      if (std::isfinite(w.u[i])) sc.U = std::max(sc.U, std::fabs(w.u[i]));
      if (std::isfinite(g2)) sc.G = std::max(sc.G, std::sqrt(g2));
      if (std::isfinite(w.kappa[i])) sc.K = std::max(sc.K, w.kappa[i]);
    }
  }
  PetscReal ext[3 + 6];
  ext[0] = sc.U, ext[1] = sc.G, ext[2] = sc.K;
  for (PetscInt d = 0; d < 3; ++d) ext[3 + d] = d < dim ? -lo[d] : 0, ext[6 + d] = d < dim ? hi[d] : 0;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, ext, 9, MPIU_REAL, MPI_MAX, comm));
  sc.U = ext[0], sc.G = ext[1], sc.K = ext[2];
  for (PetscInt d = 0; d < dim; ++d) sc.L += PetscSqr(ext[6 + d] + ext[3 + d]);
  sc.L = std::sqrt(sc.L);
  Miss miss[kConditions];
  for (size_t b = 0; b < blocks.size(); ++b) {
    const std::vector<Sample> part(samples.begin() + b * kBlock, samples.begin() + std::min(samples.size(), (b + 1) * kBlock));
    Judge(dim, part, blocks[b], sc, miss);
  }
  // Each condition's worst point over the ranks, and a warning where it failed.
  for (int k = 0; k < kConditions; ++k) {
    struct {
      double ratio;
      int    rank;
    } mine = {(double)miss[k].ratio, 0}, worst;
    PetscMPIInt rank;
    PetscCallMPI(MPI_Comm_rank(comm, &rank));
    mine.rank = rank;
    PetscCallMPI(MPI_Allreduce(&mine, &worst, 1, MPI_DOUBLE_INT, MPI_MAXLOC, comm));
    if (!(worst.ratio > 1)) continue;
    PetscReal buf[9];
    std::copy(miss[k].x, miss[k].x + 3, buf), std::copy(miss[k].a, miss[k].a + 3, buf + 3), std::copy(miss[k].b, miss[k].b + 3, buf + 6);
    PetscCallMPI(MPI_Bcast(buf, 9, MPIU_REAL, worst.rank, comm));
    const std::string at = CoordinatesText(dim, buf), a = Format("%.6g", (double)buf[3]), b = Format("%.6g", (double)buf[6]);
    std::string       text;
    switch (k) {
    case kGradient:
      text = Format("-exact_grad is not the gradient of -exact_u: at (%s) it is (%s), the difference quotients of -exact_u give (%s)", at.c_str(), CoordinatesText(dim, buf + 3).c_str(), CoordinatesText(dim, buf + 6).c_str());
      break;
    case kEquation:
      text = Format("-exact_u does not solve -div(kappa grad u) = f: at (%s) -div(kappa grad u) is %s (difference quotients of kappa times -exact_grad), -f gives %s", at.c_str(), a.c_str(), b.c_str());
      break;
    case kDirichlet: text = Format("-exact_u does not meet u = u_D on Gamma_D: at (%s) it is %s, -u_D gives %s", at.c_str(), a.c_str(), b.c_str()); break;
    case kNeumann: text = Format("-exact_grad does not meet kappa du/dn = g on Gamma_N: at (%s) kappa du/dn is %s, -g gives %s", at.c_str(), a.c_str(), b.c_str()); break;
    case kAbove: text = Format("-exact_u lies below the obstacle on Gamma_C: at (%s) it is %s, -psi gives %s", at.c_str(), a.c_str(), b.c_str()); break;
    case kPressure: text = Format("-exact_grad gives a negative contact pressure on Gamma_C: at (%s) kappa du/dn is %s", at.c_str(), a.c_str()); break;
    default: text = Format("-exact_u is off the obstacle and pressed onto it at once on Gamma_C: at (%s) u - psi is %s and kappa du/dn %s", at.c_str(), a.c_str(), b.c_str()); break;
    }
    PetscCall(PetscPrintf(comm, "signorini: warning: %s; the errors are measured against the functions as given\n", text.c_str()));
    ++*failed;
  }
  PetscFunctionReturn(0);
}

} // namespace signorini

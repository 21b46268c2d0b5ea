// The equilibrated flux of a conforming P1 solution (estimate.h): sigma = sum over vertices a of sigma_a,
// each sigma_a in RT0 on the patch omega_a of a (the cells containing a), found by a small constrained
// least-squares problem on the patch.
//
// Signs. The problem is -div(kappa grad u) = f with kappa du/dn = g on Gamma_N and the contact pressure
// kappa du/dn >= 0 on Gamma_C, so sigma approximates kappa grad u_h and div sigma = -Pi_0 f. With
// G_T = kappa_T grad u_h on T and the discrete residual r_a = sum_T (G_T . grad psi_a |T| - int_T f psi_a)
// - int_{Gamma_N} g psi_a (loads by the assembly's rules; r_a = (A u - b)_a: 0 at a free vertex, >= 0 at
// a contact vertex), sigma_a satisfies
//   - on every cell T of omega_a: int_T div sigma_a = G_T . grad psi_a |T| - int_T f psi_a (summed over
//     the vertices of T this is -int_T f, as psi_a sum to 1 and grad psi_a to 0);
//   - normal flux 0 on the faces of omega_a not containing a, int_F g psi_a on Neumann faces, free on
//     Dirichlet faces (of a Dirichlet vertex), >= 0 on contact faces (of a contact vertex; 0 for a
//     Dirichlet vertex, so that Gamma_C carries exactly the discrete contact pressure), 0 on the other
//     faces of the domain's boundary (natural condition, g = 0);
//   - it is closest to the cellwise RT0 interpolant of psi_a G (face fluxes G_T . n_F |F| / d on the
//     faces containing a): the sum of these interpolants over a is G itself, so sigma = kappa grad u_h
//     wherever the data allow it (u_h exact, e.g. u affine), and the estimate vanishes there.
// "Closest" is measured face by face, in the diagonal of the RT0 mass matrix weighted by 1/kappa_T
// (sum over the patch's cells T and faces F of T containing a of int_T |phi_F|^2 / kappa_T times the
// squared flux difference; phi_F the RT0 basis function of unit flux), which is equivalent to
// ||kappa^{-1/2} .|| on shape-regular cells. Any feasible sigma_a gives a guaranteed bound; this choice
// makes the patch problem a weighted graph Laplacian on the patch's cells (faces = edges), solved by a
// sparse elimination of the size of the cell count: in 3D (about 23 cells and 70 faces per patch)
// several times cheaper than the saddle point system of the full mass matrix, with the same efficiency
// indices on the sine problems of tests/unit_equilibrate (equal to three digits). On stretched cells the
// equivalence constant grows like the aspect ratio squared, and so did the index (86 on
// stiff-stretched-3d): a patch with a stretched cell (Stretched, a cheap shape measure per cell) is
// solved with the full mass matrices (SolveCoupled; index 1.61 there), the others as before.
// The cell constraints of a patch without Dirichlet or contact faces sum to r_a = 0: the equations are
// compatible exactly when u_h solves the discrete problem. A solver's residual r_a is spread over the
// patch's cells in proportion to their volume, so the flux is equilibrated up to it. At a contact vertex
// the cell constraints sum to r_a = the sum of the contact faces' fluxes; a contact flux that comes out
// negative is fixed at 0 and the patch solved again (it ends with every contact flux >= 0, and their sum
// still r_a > 0; at an inactive contact vertex, r_a = 0, all of them end at 0).
//
// Parallel: the mesh has no overlap, so a patch may span ranks. The cells of a patch are gathered on the
// owner of its vertex through a star forest whose leaves are the (cell, corner) pairs of shared vertices
// and whose roots are the owned vertices; patches entirely on one rank are solved where they are. Each
// (cell, corner) record carries everything its patch needs (global vertex numbers to match faces, the
// cell's face weights, the interpolant's fluxes, the loads), so the patch problem, and its result, do
// not depend on the partition beyond the order of the cells in it (round-off).
#include "signorini/estimate.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>

namespace signorini {

namespace {

enum FaceKind : char { kFaceOther = 0, kFaceDirichlet = 1, kFaceNeumann = 2, kFaceContact = 3 };

// Per local cell, what the patches of its vertices read, in one record a cell (80 B): a patch
// reads its cells' records where they are (the patch's corner of the cell beside them, CornerView), so
// nothing is copied per corner. No initialisers: ComputeCellData writes every record once. What the
// estimate has elsewhere stays there (the loads in System::cellLoads; kappa_T grad u_h is computed again
// for the flux terms): the array is new memory at every adaptive step, the largest of the estimate, and
// fresh memory costs more than the arithmetic saved by keeping it.
struct CellRecord {
  char      kind[4];   // FaceKind of the cell's face j (opposite vertex j)
  PetscInt  extra;     // index into CellData::extra, -1 for none
  PetscReal weight[4]; // int_T |phi_j|^2 / kappa_T, phi_j the RT0 function of unit flux on face j
  PetscReal target[4]; // fluxes of the RT0 interpolant of G_T: G_T . n_j |F_j| / d (psi_a G: all but face `corner`)
  PetscReal volume;
};
// What few cells need beyond their record: those with Neumann faces, and the coupled ones.
struct CellExtra {
  PetscReal neumann[16]; // [j * 4 + k] = int_{F_j} g psi_k (0 off Neumann faces)
  PetscReal mass[6];     // coupled cells: the RT0 mass matrix's entries off the diagonal / kappa_T (MassPair)
  bool      coupled = false; // whether the patches use the cell's full RT0 mass matrix (mass), see Stretched
};
struct CellData {
  std::unique_ptr<CellRecord[]> cell; // default-initialised: a zeroing pass over the records saved
  std::vector<CellExtra>        extra;
  const PetscReal              *load = nullptr; // int_T f psi_k at load[c * loadStride + k]
  PetscInt                      loadStride = 0;
  std::vector<PetscReal>        ownLoad; // the loads where the assembly did not keep them (System::cellLoads)
  bool                          anyCoupled = false; // on any rank: else no patch looks for coupled cells
};
// The place of entry (i, j), i != j, of a cell's mass matrix in CellExtra::mass: pairs (0,1) (0,2) (0,3)
// (1,2) (1,3) (2,3) (a triangle uses the first, second and fourth).
inline PetscInt MassPair(PetscInt i, PetscInt j)
{
  static constexpr PetscInt kPair[4][4] = {{-1, 0, 1, 2}, {0, -1, 3, 4}, {1, 3, -1, 5}, {2, 4, 5, -1}};
  return kPair[i][j];
}

// One cell as seen from one of its vertices (the patch's centre), as gathered from another rank.
struct Corner {
  CellRecord cell;
  PetscInt   gid[4];      // global vertex numbers of the cell's vertices
  PetscInt   corner;      // which vertex of the cell is the centre a
  PetscInt   coupled;     // CellExtra::coupled (the reals start 8-byte aligned)
  PetscReal  neumann[4];  // int_{F_j} g psi_a on Neumann faces, 0 elsewhere
  PetscReal  mass[6];     // CellExtra::mass of a coupled cell
  PetscReal  load[4];     // int_T f psi_k
};

// What a patch reads of one of its cells: the cell's record and its corner at the centre a.
struct CornerView {
  const CellRecord *rec;
  const PetscInt   *vert; // the cell's vertices, by numbers unique within the patch (local or global)
  const PetscReal  *nm;   // int_{F_j} g psi_a at nm[j * stride]
  PetscInt          corner, stride;
  const PetscReal  *mass; // CellExtra::mass of a coupled cell, null for the others
  const PetscReal  *load; // int_T f psi_k at load[k]
  PetscReal         Load() const { return load[corner]; }
  PetscReal         Neumann(PetscInt j) const { return nm[j * stride]; }
  // int_T phi_i . phi_j / kappa_T for faces i, j of the cell; 0 for i != j in an uncoupled cell, which a
  // coupled patch (one with a stretched cell among shape-regular ones) weighs by its diagonal as the others do
  PetscReal         Mass(PetscInt i, PetscInt j) const { return i == j ? rec->weight[i] : mass ? mass[MassPair(i, j)] : 0.0; }
};
const PetscReal kNoNeumann[1] = {0};
// A local patch matches faces by the local vertex numbers, a gathered one by the global ones.
CornerView ViewOf(const CellData &cd, const Space &space, PetscInt c, PetscInt k)
{
  const CellRecord &rec  = cd.cell[c];
  const PetscInt   *vert = &space.cellVert[c * space.Nb()];
  const PetscReal  *load = &cd.load[c * cd.loadStride];
  if (rec.extra < 0) return {&rec, vert, kNoNeumann, k, 0, nullptr, load};
  const CellExtra &x = cd.extra[rec.extra];
  return {&rec, vert, &x.neumann[k], k, 4, x.coupled ? x.mass : nullptr, load};
}
CornerView ViewOf(const Corner &g) { return {&g.cell, g.gid, g.neumann, g.corner, 1, g.coupled ? g.mass : nullptr, g.load}; }

// int_T |phi_j|^2 with phi_j = (x - X_j) / (d |T|), the diagonal of the RT0 mass matrix: exact, from
// int_T lambda_i lambda_m = |T| (1 + delta_im) / ((d+1)(d+2)).
// (dim a template parameter: the cell loops run once a cell over millions of cells, and with the
// dimension known the compiler unrolls their short loops and keeps the sums in registers.)
template <PetscInt dim>
void RT0MassDiagonal(const PetscReal *X, PetscReal volume, PetscReal *M)
{
  const PetscInt  nb    = dim + 1;
  const PetscReal scale = 1.0 / (dim * dim * volume * (dim + 1) * (dim + 2));
  for (PetscInt j = 0; j < nb; ++j) {
    PetscReal s = 0;
    for (PetscInt d = 0; d < dim; ++d) {
      PetscReal P = 0; // sum_i (X_i - X_j)
      for (PetscInt i = 0; i < nb; ++i) {
        const PetscReal e = X[i * dim + d] - X[j * dim + d];
        P += e;
        s += e * e;
      }
      s += P * P;
    }
    M[j] = s * scale;
  }
}

// The entries of the RT0 mass matrix off its diagonal (MassPair's places):
//   int_T phi_i . phi_j = ((x_T - X_i) . (x_T - X_j) + sum_k |X_k - x_T|^2 / ((d+1)(d+2))) / (d^2 |T|)
// (int_T (x - X_i) . (x - X_j) with x - X_i = (x - x_T) + (x_T - X_i), the cross terms of mean zero).
template <PetscInt dim>
void RT0MassOffDiagonal(const PetscReal *X, PetscReal volume, PetscReal *M)
{
  constexpr PetscInt nb = dim + 1;
  PetscReal          r[nb][dim], m2 = 0;
  for (PetscInt i = 0; i < nb; ++i)
    for (PetscInt d = 0; d < dim; ++d) {
      PetscReal xc = 0;
      for (PetscInt k = 0; k < nb; ++k) xc += X[k * dim + d];
      r[i][d] = xc / nb - X[i * dim + d];
      m2 += r[i][d] * r[i][d];
    }
  const PetscReal scale = 1.0 / (dim * dim * volume);
  for (PetscInt i = 0; i < nb; ++i)
    for (PetscInt j = i + 1; j < nb; ++j) {
      PetscReal dot = m2 / ((dim + 1) * (dim + 2));
      for (PetscInt d = 0; d < dim; ++d) dot += r[i][d] * r[j][d];
      M[MassPair(i, j)] = dot * scale;
    }
}

// Whether the patches weigh a cell's fluxes by its full RT0 mass matrix rather than by its diagonal.
// The diagonal is equivalent to the full matrix with constants that depend on the cell's shape only, and
// m = (trace of the mass matrix)^d |T|^(d-2), scale-free, measures that shape for the price of a product
// or two: 0.69 for a right isosceles triangle and 1.33 for the six tetrahedra of a cube (0.52 and 0.58
// for the equilateral ones), growing like s^2 for cells stretched by s (0.46 s^2 for the tetrahedra of a
// box of aspect ratio s, 0.42 s^2 for right triangles), where the smallest eigenvalue of the diagonally
// scaled matrix falls like 1 / s^2 (1.2e-6 at s = 1000): the diagonal then puts a flux that crosses the
// cell's large faces at up to s^2 times its cost, and the patch minimisers go around it (P1 index 86 on
// stiff-stretched-3d, 1.4 with the full matrix).
template <PetscInt dim>
bool Stretched(const PetscReal *M, PetscReal volume)
{
  constexpr PetscReal kStretched = 25; // a box's tetrahedra of aspect ratio about 7, right triangles of 12
  PetscReal t = 0;
  for (PetscInt j = 0; j <= dim; ++j) t += M[j];
  return (dim == 2 ? t * t : t * t * t * volume) > kStretched;
}

// A stretched cell's entry in the side table, with its mass matrix off the diagonal (out of line: the cell
// loop over shape-regular meshes stays as it was).
template <PetscInt dim>
__attribute__((noinline)) void CoupleCell(const PetscReal *X, PetscReal volume, PetscReal kappa, CellRecord &rec, std::vector<CellExtra> &extra)
{
  rec.extra = (PetscInt)extra.size();
  extra.push_back({});
  extra.back().coupled = true;
  PetscReal *M = extra.back().mass;
  RT0MassOffDiagonal<dim>(X, volume, M);
  for (PetscInt p = 0; p < 6; ++p) M[p] /= kappa;
}

// The cell loops read each cell's vertex coordinates (and values) where the vertex numbering,
// unlike the cells', is scattered over memory (a mesh refined in levels numbers them by other rules): they
// ask for the vertices of the cell kCellsAhead ahead, whose reads then no longer wait for memory.
constexpr PetscInt kCellsAhead = 16;
inline void PrefetchVertices(const Space &space, PetscInt c, const PetscScalar *u = nullptr)
{
  if (c >= space.NumCells()) return;
  for (PetscInt k = 0; k <= space.dim; ++k) {
    const PetscInt v = space.cellVert[c * (space.dim + 1) + k];
    __builtin_prefetch(&space.vertX[v * space.dim]);
    if (u) __builtin_prefetch(&u[v]);
  }
}

// The cell of a (cell, corner) index c * nb + corner: a shift or a division by the constant 3, where a
// division by the variable nb cost tens of cycles, and the patches make one per corner.
inline PetscInt CellOf(PetscInt i, PetscInt nb) { return nb == 4 ? i >> 2 : i / 3; }

bool Contains(const std::vector<PetscInt> &parts, PetscInt p) { return std::find(parts.begin(), parts.end(), p) != parts.end(); }

// The record of cell c.
template <PetscInt dim>
void CellDataOf(const Space &space, const System &sys, const PetscScalar *u, PetscInt c, CellRecord &rec, std::vector<CellExtra> &extra)
{
  constexpr PetscInt  nb = dim + 1;
  CellGeometry        g;
  const Space::Coords X = space.XD<dim>(c);
  ComputeCellGeometryD<dim>(X, g);
  for (PetscInt j = 0; j < 4; ++j) rec.kind[j] = kFaceOther, rec.weight[j] = rec.target[j] = 0;
  rec.extra           = -1;
  rec.volume          = g.volume;
  const PetscReal kap = sys.Kappa(c);
  PetscReal       G[3];
  space.GradD<dim>(c, u, g, G);
  RT0MassDiagonal<dim>(X, g.volume, rec.weight);
  if (Stretched<dim>(rec.weight, g.volume)) CoupleCell<dim>(X, g.volume, kap, rec, extra);
  for (PetscInt j = 0; j < nb; ++j) rec.weight[j] /= kap;
  for (PetscInt j = 0; j < nb; ++j) {
    PetscReal dot = 0; // |F_j| n_j = -d |T| grad lambda_j
    for (PetscInt d = 0; d < dim; ++d) dot += kap * G[d] * g.gradLambda[j][d];
    rec.target[j] = -g.volume * dot;
  }
}

// The records of all cells.
template <PetscInt dim>
void CellRecords(const Space &space, const System &sys, const PetscScalar *u, CellRecord *cell, std::vector<CellExtra> &extra)
{
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    PrefetchVertices(space, c + kCellsAhead, u);
    CellDataOf<dim>(space, sys, u, c, cell[c], extra);
  }
}

// The loads by the assembly's rules (AssembleCells, AssembleNeumann), per vertex of each cell, and the
// cells' oscillations that come with them: where the assembly kept them, or evaluated again.
void CellLoads(const Space &space, const Problem &problem, const System &sys, CellData &cd, std::vector<PetscReal> &oscillation, std::string &error)
{
  const PetscInt n = space.dim + 2, nc = space.NumCells(); // dim + 1 moments, then the oscillation
  if (sys.cellLoads.empty()) {
    std::vector<PetscReal> work;
    cd.ownLoad.resize(nc * n);
    for (PetscInt c = 0; c < nc; ++c) {
      const Space::Coords X = space.X(c);
      CellGeometry        g;
      CellLoad            load;
      ComputeCellGeometry(space.dim, X, g);
      EvaluateCellLoad(space, problem, sys, c, X, g, work, load, error);
      std::copy(load.moment, load.moment + n - 1, &cd.ownLoad[c * n]);
      cd.ownLoad[c * n + n - 1] = load.oscillation;
    }
  }
  cd.load       = sys.cellLoads.empty() ? cd.ownLoad.data() : sys.cellLoads.data();
  cd.loadStride = n;
  oscillation.resize(nc);
  for (PetscInt c = 0; c < nc; ++c) oscillation[c] = cd.load[c * n + n - 1];
}

PetscErrorCode ComputeCellData(const Space &space, const Problem &problem, const System &sys, const PetscScalar *u, CellData &cd, std::vector<PetscReal> &oscillation)
{
  const PetscInt nb = space.Nb(), dim = space.dim, nc = space.NumCells();
  std::string    error;
  PetscReal      x[3], lambda[4];
  PetscFunctionBeginUser;
  CellLoads(space, problem, sys, cd, oscillation, error);
  cd.cell.reset(new CellRecord[nc]);
  cd.extra.clear();
  WithDim(dim, [&](auto D) { CellRecords<D>(space, sys, u, cd.cell.get(), cd.extra); });
  PetscInt coupled = (PetscInt)cd.extra.size(); // so far only the coupled cells have an entry
  for (const BoundaryFace &bf : space.boundary) {
    CellRecord &rec  = cd.cell[bf.cell];
    char       &kind = rec.kind[bf.opposite];
    if (Contains(problem.dirichlet, bf.part)) kind = kFaceDirichlet;
    else if (Contains(problem.contact, bf.part)) kind = kFaceContact;
    else if (Contains(problem.neumann, bf.part)) {
      kind = kFaceNeumann;
      if (!problem.HasNeumann()) continue;
      std::array<PetscReal, 4> share{0, 0, 0, 0};
      const PetscReal          area = space.FaceMeasure(bf);
      problem.g->SetCellSet(space.CellSet(bf.cell));
      for (PetscInt q = 0; q < sys.faceRule.Size(); ++q) {
        space.FaceToCell(bf, sys.faceRule.Point(q), lambda);
        space.Point(bf.cell, lambda, x);
        const PetscReal gq = problem.g->Scalar(x, dim, error) * sys.faceRule.weights[q] * area;
        for (PetscInt k = 0; k < nb; ++k) share[k] += gq * lambda[k];
      }
      if (rec.extra < 0) rec.extra = (PetscInt)cd.extra.size(), cd.extra.push_back({});
      for (PetscInt k = 0; k < nb; ++k) cd.extra[rec.extra].neumann[bf.opposite * 4 + k] = share[k];
    }
  }
  PetscCall(CheckAll(PetscObjectComm((PetscObject)space.dm), error.empty(), error));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &coupled, 1, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)space.dm)));
  cd.anyCoupled = coupled > 0;
  PetscFunctionReturn(0);
}

void FillCorner(const CellData &cd, const Space &space, const PetscInt *gidx, PetscInt c, PetscInt k, Corner &r)
{
  const PetscInt   nb = space.Nb();
  const CornerView v  = ViewOf(cd, space, c, k);
  r.cell              = cd.cell[c];
  r.corner            = k;
  r.coupled           = v.mass != nullptr;
  for (PetscInt j = 0; j < 4; ++j) r.gid[j] = j < nb ? gidx[v.vert[j]] : 0, r.neumann[j] = j < nb ? v.Neumann(j) : 0.0, r.load[j] = j < nb ? v.load[j] : 0.0;
  for (PetscInt p = 0; p < 6; ++p) r.mass[p] = v.mass ? v.mass[p] : 0.0;
}

// Solves L z = b in place (z in b) for L symmetric positive definite, row-major N x N, by Cholesky's
// factorisation (lower triangle overwritten). Returns false if L is not positive definite. The patch
// matrices are sparse graph Laplacians (at most 4 entries a row) and much of their factor stays zero:
// the rows of each column's nonzeros below the diagonal are listed (column k: nz[start[k] .. start[k+1]),
// ascending; start: N + 1 entries, nz: N (N - 1) / 2), and the factorisation and both triangular solves
// touch only those. Every entry sees the dense algorithm's operations in its order, less the updates by
// a zero (which change nothing), so the result is the dense one's. FactorSPD factorises, SolveFactored
// solves with the factor (as many right-hand sides as wanted).
bool FactorSPD(PetscInt N, PetscReal *L, PetscInt *start, PetscInt *nz)
{
  start[0] = 0;
  for (PetscInt k = 0; k < N; ++k) {
    const PetscReal d = L[k * N + k];
    if (!(d > 0)) return false;
    const PetscReal r = std::sqrt(d), inv = 1.0 / r;
    L[k * N + k]      = r;
    PetscInt *col     = &nz[start[k]], n = 0;
    for (PetscInt i = k + 1; i < N; ++i)
      if ((L[i * N + k] *= inv) != 0) col[n++] = i;
    start[k + 1] = start[k] + n;
    for (PetscInt a = 0; a < n; ++a) {
      const PetscInt  i   = col[a];
      const PetscReal lik = L[i * N + k];
      PetscReal      *Li  = &L[i * N];
      for (PetscInt c = 0; c <= a; ++c) Li[col[c]] -= lik * L[col[c] * N + k];
    }
  }
  return true;
}
void SolveFactored(PetscInt N, const PetscReal *L, PetscReal *b, const PetscInt *start, const PetscInt *nz)
{
  for (PetscInt j = 0; j < N; ++j) { // L y = b, by columns
    b[j] /= L[j * N + j];
    if (b[j] == 0) continue;
    for (PetscInt p = start[j]; p < start[j + 1]; ++p) b[nz[p]] -= L[nz[p] * N + j] * b[j];
  }
  for (PetscInt j = N - 1; j >= 0; --j) { // L^T z = y: z_j from the z_i, i > j, of column j's nonzeros
    for (PetscInt p = start[j + 1] - 1; p >= start[j]; --p) b[j] -= L[nz[p] * N + j] * b[nz[p]];
    b[j] /= L[j * N + j];
  }
}
bool SolveSPD(PetscInt N, PetscReal *L, PetscReal *b, PetscInt *start, PetscInt *nz)
{
  if (!FactorSPD(N, L, start, nz)) return false;
  SolveFactored(N, L, b, start, nz);
  return true;
}

// Solves L z = b in place (z in b) for L symmetric positive definite and N <= 64, row-major N x N, by
// symmetric Gaussian elimination (L = U^T D U) in a minimum degree order: adj[i] has bit j set where
// L_ij != 0 (i != j). The patch matrices are graph Laplacians of the patch's cells (degree <= 4), whose
// factor in the cells' given order fills in; eliminating a cell with the fewest remaining neighbours first
// keeps each step's neighbour set (its fill) small: on paper-5.1-3d 66 multipliers and 234 updates per
// patch of 22 rows. The elimination graph lives in bit masks and the cells in buckets by their degree,
// so choosing the order costs a few bit operations a step. Returns false if a pivot is not positive. L is
// overwritten (the multipliers in the eliminated columns), adj too (adj[p]: the set p was eliminated with);
// order, deg and d are work arrays of N entries.
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("popcnt"))) // every x86-64 processor of the last 15 years has the instruction
#endif
bool SolveSPDMinDegree(PetscInt N, PetscReal *L, PetscReal *b, uint64_t *adj, PetscInt *order, PetscInt *deg, PetscReal *dinv)
{
  // bucket[k]: the cells not yet eliminated with k neighbours left; the lowest such cell of the lowest
  // non-empty bucket is the next pivot.
  uint64_t bucket[65] = {0};
  for (PetscInt i = 0; i < N; ++i) deg[i] = __builtin_popcountll(adj[i]), bucket[deg[i]] |= 1ull << i;
  for (PetscInt t = 0; t < N; ++t) {
    PetscInt k = 0;
    while (!bucket[k]) ++k;
    const PetscInt  p = __builtin_ctzll(bucket[k]);
    const uint64_t  S = adj[p], bp = 1ull << p;
    const PetscReal dp = L[p * N + p], *Lp = &L[p * N];
    if (!(dp > 0)) return false;
    const PetscReal inv = 1 / dp;
    dinv[p] = inv, order[t] = p, bucket[k] &= ~bp;
    PetscInt  idx[64], ns = 0; // S as a list, and row p on it
    PetscReal lp[64];
    for (uint64_t m = S; m; m &= m - 1) idx[ns] = __builtin_ctzll(m), lp[ns] = Lp[idx[ns]], ++ns;
    for (PetscInt a = 0; a < ns; ++a) {
      const PetscInt  i  = idx[a];
      PetscReal      *Li = &L[i * N];
      const PetscReal l  = Li[p] * inv;
      Li[p]              = l; // the multiplier, where L's entry is read no more
      for (PetscInt c = 0; c < ns; ++c) Li[idx[c]] -= l * lp[c];
      b[i] -= l * b[p];
      bucket[deg[i]] &= ~(1ull << i);
      adj[i] = (adj[i] | S) & ~(1ull << i) & ~bp;
      deg[i] = __builtin_popcountll(adj[i]);
      bucket[deg[i]] |= 1ull << i;
    }
  }
  for (PetscInt t = N - 1; t >= 0; --t) { // U z = D^{-1} y: z_p from the z_i of the later pivots i in its set
    const PetscInt p = order[t];
    PetscReal      z = b[p] * dinv[p];
    for (uint64_t m = adj[p]; m; m &= m - 1) z -= L[__builtin_ctzll(m) * N + p] * b[__builtin_ctzll(m)];
    b[p] = z;
  }
  return true;
}

// The patch problem of one vertex. Unknowns: the fluxes of the faces containing a that are free (interior
// to the patch: one unknown for the two sides; Dirichlet; contact not yet fixed at 0). Writes the fluxes
// of every face of every patch cell (nb per corner record, outward, 0 on the face opposite a).
class Patch {
public:
  // mayCouple: whether any cell is coupled (CellData::anyCoupled)
  Patch(PetscInt dim, bool mayCouple) : mayCouple_(mayCouple), nb_(dim + 1) {}

  // The patch of a vertex of kind vertexKind whose cells are the n corner records. Returns false for a
  // singular system. One object serves all patches, so its work arrays are allocated once.
  bool Solve(char vertexKind, const CornerView *corners, PetscInt n, PetscReal *flux, bool generic = false)
  {
    vertexKind_ = vertexKind;
    corners_    = corners;
    n_          = n;
    coupled_    = false;
    for (PetscInt e = 0; e < n && mayCouple_; ++e) coupled_ |= corners[e].mass != nullptr;
    if (nb_ == 3 && !generic && !coupled_ && Chain()) return SolveChain(flux);
    MatchFaces(generic);
    d_.resize(n);
    for (;;) {
      Unknowns();
      if (!(coupled_ ? SolveCoupled(flux) : SolveOnce(flux))) return false;
      bool changed = false; // contact fluxes must be >= 0: fix the negative ones at 0 and solve again
      for (const Unknown &u : unknowns_)
        if (u.contact && u.x < 0) forced_[u.first] = 1, changed = true;
      if (!changed) return true;
    }
  }

private:
  // 2D: the patch's cells in the order in which they turn around a, each cell's faces containing a as
  // the one towards the previous cell (left) and the one towards the next (right). Around an interior
  // vertex the cells close a cycle, at a boundary vertex they form a path from one boundary face to the
  // other. Returns false for anything else (a vertex where the mesh pinches: two paths), which the
  // general solve handles.
  bool Chain()
  {
    // Per cell, its two faces containing a and their other vertices (face j = {a, gid[3 - corner - j]}).
    ends_.resize(n_);
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView  &c  = corners_[e];
      const PetscInt j1 = c.corner == 0 ? 1 : 0, j2 = c.corner == 2 ? 1 : 2;
      ends_[e]          = {{j1, j2}, {c.vert[3 - c.corner - j1], c.vert[3 - c.corner - j2]}, {-1, -1}, {-1, -1}};
    }
    // The cell and side across each face (-1: none): a few comparisons of small integers per pair of cells.
    for (PetscInt e = 0; e < n_; ++e)
      for (PetscInt s = 0; s < 2; ++s) {
        if (ends_[e].next[s] >= 0) continue;
        for (PetscInt g = e + 1; g < n_; ++g)
          for (PetscInt t = 0; t < 2; ++t)
            if (ends_[g].other[t] == ends_[e].other[s]) {
              if (ends_[g].next[t] >= 0) return false; // a third cell on one face: not a simplex mesh
              ends_[e].next[s] = g, ends_[e].nextSide[s] = t, ends_[g].next[t] = e, ends_[g].nextSide[t] = s;
            }
      }
    chain_.resize(n_);
    PetscInt start = 0, side = 0; // the side of the start cell towards the previous cell
    cycle_ = true;
    for (PetscInt e = 0; e < n_ && cycle_; ++e) // a path starts at a cell with a boundary face
      for (PetscInt s = 0; s < 2 && cycle_; ++s)
        if (ends_[e].next[s] < 0) start = e, side = s, cycle_ = false;
    PetscInt e = start;
    for (PetscInt i = 0; i < n_; ++i) {
      const End &E = ends_[e];
      chain_[i]    = {e, E.face[side], E.face[1 - side]};
      const PetscInt next = E.next[1 - side];
      if (i == n_ - 1) return cycle_ ? next == start && E.nextSide[1 - side] == 0 : next < 0;
      if (next < 0 || next == start) return false;
      side = E.nextSide[1 - side], e = next;
    }
    return false;
  }
  struct End {
    PetscInt face[2], other[2], next[2], nextSide[2];
  };
  std::vector<End> ends_;

  // The patch problem on the chain (the same problem as SolveOnce's): edge i lies between chain cells i - 1
  // and i (edge 0 of a cycle between the last cell and the first; of a path, the first cell's boundary
  // face, and edge n the last cell's). The fluxes follow from the cells' constraints along the chain up to
  // one parameter (SolveChainOnce): no matching of faces by hashing, no factorisation of a matrix.
  bool SolveChain(PetscReal *flux)
  {
    const PetscInt n = n_, ne = cycle_ ? n : n + 1;
    edges_.resize(ne);
    for (PetscInt i = 0; i < ne; ++i) {
      ChainEdge &E = edges_[i];
      E.leftCell = i > 0 ? i - 1 : (cycle_ ? n - 1 : -1);
      E.rightCell = i < n ? i : -1;
      E.free = true, E.contact = false, E.value = 0;
      if (E.leftCell >= 0 && E.rightCell >= 0) continue;
      const Link    &L    = chain_[E.leftCell >= 0 ? E.leftCell : E.rightCell];
      const CornerView  &c    = corners_[L.entry];
      const PetscInt face = E.leftCell >= 0 ? L.right : L.left, kind = c.rec->kind[face];
      E.contact = kind == kFaceContact;
      E.free    = kind == kFaceDirichlet || (kind == kFaceContact && vertexKind_ != kDirichlet);
      if (!E.free) E.value = kind == kFaceNeumann ? c.Neumann(face) : 0.0;
    }
    for (;;) {
      if (!SolveChainOnce()) return false;
      bool changed = false; // contact fluxes must be >= 0: fix the negative ones at 0 and solve again
      for (ChainEdge &E : edges_)
        if (E.free && E.contact && E.x < 0) E.free = false, E.value = 0, changed = true;
      if (!changed) break;
    }
    for (PetscInt i = 0; i < n; ++i) {
      PetscReal *y = &flux[chain_[i].entry * 3];
      y[0] = y[1] = y[2] = 0;
    }
    for (const ChainEdge &E : edges_) {
      const PetscReal v = E.free ? E.x : E.value;
      if (E.leftCell >= 0) flux[chain_[E.leftCell].entry * 3 + chain_[E.leftCell].right] = v;
      if (E.rightCell >= 0) flux[chain_[E.rightCell].entry * 3 + chain_[E.rightCell].left] = E.leftCell >= 0 ? -v : v;
    }
    return true;
  }

  // SolveChain's problem in its primal form. With z_k the flux across edge k from chain cell k - 1 to cell
  // k (edge 0 of a path: into the first cell; edge n: out of the last), cell i's constraint reads
  // z_{i+1} - z_i = rhs_i over its free edges (the fixed fluxes are in rhs_i), so z_k = z_0 + S_k with
  // S_k = rhs_0 + ... + rhs_{k-1}: one parameter z_0, set by the constraint of a fixed boundary edge, or
  // else (a cycle, a path with both boundary edges free) the minimiser of sum_k (h_k z_k^2 / 2 - c_k z_k)
  // over the free edges, z_0 = sum_k (c_k - h_k S_k) / sum_k h_k. The multipliers' tridiagonal system
  // solves the same problem in two sweeps with three divisions a row, one waiting for the other.
  bool SolveChainOnce()
  {
    const PetscInt n = n_, ne = (PetscInt)edges_.size();
    // resid = t - fixed on a cell's faces containing a; the constraint's right-hand side per cell.
    rhs_.resize(n);
    PetscReal volume = 0, mismatch = 0;
    const bool freeFirst = edges_[0].free, freeLast = edges_[ne - 1].free;
    const bool grounded = !cycle_ && (freeFirst || freeLast);
    const auto resid    = [&](PetscInt cell, bool rightFace) {
      const Link      &L    = chain_[cell];
      const PetscInt   face = rightFace ? L.right : L.left;
      const ChainEdge &E    = edges_[rightFace ? (cell + 1) % ne : cell];
      return corners_[L.entry].rec->target[face] - (E.free ? 0.0 : E.value);
    };
    for (PetscInt i = 0; i < n; ++i) {
      const CornerView &c = corners_[chain_[i].entry];
      rhs_[i]             = -c.Load() + resid(i, false) + resid(i, true);
      volume += c.rec->volume, mismatch += rhs_[i];
    }
    // Without a free boundary face the constraints sum to r_a: make them compatible.
    if (!grounded)
      for (PetscInt i = 0; i < n; ++i) rhs_[i] -= mismatch * corners_[chain_[i].entry].rec->volume / volume;
    // Per free edge: h = the sum of its sides' weights, c = sum of sign * weight * resid (sign +1 on the
    // left cell's side, -1 on the right's; for z, whose edge 0 points into the path's first cell, -c there).
    PetscReal S = 0, H = 0, C = 0;
    for (PetscInt k = 0; k < ne; ++k) {
      ChainEdge &E = edges_[k];
      if (k > 0) S += rhs_[k - 1];
      E.x = S; // S_k, until z_0 is known
      if (!E.free) continue;
      E.h = E.c = 0;
      if (E.leftCell >= 0) {
        const PetscReal w = corners_[chain_[E.leftCell].entry].rec->weight[chain_[E.leftCell].right];
        E.h += w, E.c += w * resid(E.leftCell, true);
      }
      if (E.rightCell >= 0) {
        const PetscReal w = corners_[chain_[E.rightCell].entry].rec->weight[chain_[E.rightCell].left];
        E.h += w, E.c -= w * resid(E.rightCell, false); // for a path's edge 0 too: -c of x = -z
      }
      H += E.h, C += E.c - E.h * S;
    }
    PetscReal z0 = 0; // a path whose edge 0 is fixed: z_1 = rhs_0 (its z_0 counts in rhs_0)
    if (cycle_ || (freeFirst && freeLast)) {
      if (!(H > 0)) return false;
      z0 = C / H;
    } else if (freeFirst) z0 = -S; // edge n fixed: 0 - z_{n-1} = rhs_{n-1}, i.e. z_0 = -S_n
    for (PetscInt k = 0; k < ne; ++k) {
      ChainEdge &E = edges_[k];
      E.x          = !cycle_ && k == 0 ? -z0 : z0 + E.x; // x: outward from the left cell, or from the only one
    }
    return true;
  }

  struct Link {
    PetscInt entry, left, right; // the corner record, its faces containing a towards the previous and next cell
  };
  struct ChainEdge {
    PetscInt  leftCell, rightCell; // chain positions (-1: none, a boundary face)
    bool      free, contact;
    PetscReal value, h, c, x;      // value: fixed flux; x: the free flux, outward from the left cell
  };
  std::vector<Link>      chain_;
  std::vector<ChainEdge> edges_;
  bool                   cycle_ = false;

  // Per face containing a, seen from one cell: slot e * nb + j is face j of corner record e.
  // An unknown flux: of an interior face of the patch (two slots: outward from the first, inward to the
  // second) or of a free boundary face (one slot). hinv: 1 / the sum of its slots' weights; c: the sum of
  // sign * weight * (interpolant's flux - fixed flux); x: the flux, outward from the first slot's cell.
  struct Unknown {
    PetscInt  first, second; // slots; second -1 for a boundary face
    PetscInt  e1, e2;        // their corner records (e2 -1 for a boundary face)
    bool      contact;
    PetscReal hinv, c, x;
  };

  // The faces containing a, matched between the patch's cells: partner_[slot] is the other cell's slot of
  // the face, -1 for a boundary face (and for the face opposite a). A face containing a is known by its
  // other vertices (one in 2D, two in 3D). These get small numbers first (a patch has some 14 of them in
  // 3D, each in about 5 cells), and a face is then a place in a table of kSmall x kSmall, which pairs
  // its two slots without a search: the open-addressing search over the faces' vertex pairs that this
  // replaces was the patch problem's largest part in 3D, most of it the branch between a face met for the
  // first and for the second time, which no predictor can foresee. A patch with more than kSmall other
  // vertices falls back to that search (MatchFacesHashed), and so does every patch with generic.
  void MatchFaces(bool generic)
  {
    const PetscInt nslots = n_ * nb_;
    partner_.resize(nslots + 1); // the last place takes the writes of a face met the first time
    forced_.assign(nslots, 0);
    if (vertexTable_.empty() || stamp_ == INT32_MAX) NewTables();
    ++stamp_; // entries of earlier patches (an older stamp) count as empty: no clearing per patch
    if (generic || !MatchFacesSmall()) MatchFacesHashed();
  }
  static constexpr PetscInt kSmall = 32, kVertexBuckets = 128;
  struct VertexBucket {
    PetscInt id, stamp, small;
  };
  struct FaceEntry {
    PetscInt slot, stamp;
  };
  void NewTables()
  {
    table_.assign(table_.size(), Bucket{0, -1, 0});
    vertexTable_.assign(kVertexBuckets, VertexBucket{0, -1, 0});
    faceTable_.assign(kSmall * kSmall, FaceEntry{-1, -1});
    stamp_ = 0;
  }
  // The small number of vertex id in this patch, given at its first sight; -1 once there are kSmall.
  PetscInt SmallNumber(PetscInt id, PetscInt &count)
  {
    uint32_t      h = ((uint32_t)id * 2654435761u) >> 25; // 7 bits: kVertexBuckets
    VertexBucket *b = &vertexTable_[h];
    while (b->stamp == stamp_ && b->id != id) h = (h + 1) & (kVertexBuckets - 1), b = &vertexTable_[h];
    if (b->stamp != stamp_) {
      if (count == kSmall) return -1;
      *b = {id, stamp_, count++};
    }
    return b->small;
  }
  bool MatchFacesSmall()
  {
    PetscInt count = 0;
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView &c = corners_[e];
      PetscInt          k[4]; // the small numbers of the cell's vertices (the centre's unused)
      for (PetscInt j = 0; j < nb_; ++j)
        if (j != c.corner && (k[j] = SmallNumber(c.vert[j], count)) < 0) return false;
      for (PetscInt j = 0; j < nb_; ++j) {
        const PetscInt slot = e * nb_ + j;
        if (j == c.corner) {
          partner_[slot] = -1;
          continue;
        }
        const PetscInt *o = FaceOthers(c.corner, j), p = k[o[0]], q = nb_ == 3 ? 0 : k[o[1]];
        const PetscInt  place = nb_ == 3 ? p : p < q ? p * kSmall + q : q * kSmall + p;
        FaceEntry     &f    = faceTable_[place];
        const bool     met  = f.stamp == stamp_;
        const PetscInt prev = met ? f.slot : -1;
        partner_[slot]                  = prev;
        partner_[met ? prev : n_ * nb_] = slot; // the spare place when met the first time
        f                               = {slot, stamp_};
      }
    }
    return true;
  }
  // The same by the faces' other vertices' numbers (smaller first, packed in one integer) through a
  // small open-addressing hash table.
  void MatchFacesHashed()
  {
    const PetscInt nslots = n_ * nb_;
    size_t         size   = std::max<size_t>(table_.size(), 16);
    while (size < (size_t)(2 * nslots)) size *= 2;
    if (size > table_.size()) table_.assign(size, Bucket{0, -1, 0});
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView &c = corners_[e];
      for (PetscInt j = 0; j < nb_; ++j) {
        const PetscInt slot = e * nb_ + j;
        partner_[slot]      = -1;
        if (j == c.corner) continue;
        const PetscInt *o = FaceOthers(c.corner, j);
        const uint32_t  p = (uint32_t)c.vert[o[0]], q = nb_ == 3 ? 0 : (uint32_t)c.vert[o[1]];
        const uint64_t  key = nb_ == 3 ? p : p < q ? (uint64_t)p << 32 | q : (uint64_t)q << 32 | p;
        size_t  h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 40) & (size - 1);
        Bucket *b = &table_[h];
        while (b->stamp == stamp_ && b->key != key) h = (h + 1) & (size - 1), b = &table_[h];
        if (b->stamp != stamp_) *b = {key, slot, stamp_};
        else partner_[b->slot] = slot, partner_[slot] = b->slot;
      }
    }
  }
  // The cell's vertices on face j (opposite vertex j) other than the centre at corner: one in 2D (the first
  // entry), two in 3D.
  const PetscInt *FaceOthers(PetscInt corner, PetscInt j) const { return nb_ == 3 ? kOtherTri[corner][j] : kOther[corner][j]; }
  // kOtherTri[k][j]: the triangle's vertex other than k and j.
  static constexpr PetscInt kOtherTri[3][3][1] = {
    {{0}, {2}, {1}},
    {{2}, {0}, {0}},
    {{1}, {0}, {0}}
  };
  // kOther[k][j]: the two cell vertices (of a tetrahedron) other than k and j.
  static constexpr PetscInt kOther[4][4][2] = {
    {{0, 0}, {2, 3}, {1, 3}, {1, 2}},
    {{2, 3}, {0, 0}, {0, 3}, {0, 2}},
    {{1, 3}, {0, 3}, {0, 0}, {0, 1}},
    {{1, 2}, {0, 2}, {0, 1}, {0, 0}}
  };

  // The unknowns, in the order of their first slot, and the fixed fluxes of the other slots (0 on the
  // face opposite a and on slots of unknowns): Neumann faces their load, Dirichlet faces of a Dirichlet
  // vertex... (see the top of the file), and contact faces forced to 0 by an earlier solve.
  void Unknowns()
  {
    unknowns_.clear();
    fixed_.assign(n_ * nb_, 0.0);
    boundaryUnknown_ = false;
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView &c = corners_[e];
      for (PetscInt j = 0; j < nb_; ++j) {
        const PetscInt slot = e * nb_ + j, other = partner_[slot];
        if (j == c.corner || (other >= 0 && other < slot)) continue; // the pair is listed at its first slot
        if (other >= 0) {
          unknowns_.push_back({slot, other, e, Entry(other), false, 0, 0, 0});
          continue;
        }
        const PetscInt kind = c.rec->kind[j];
        const bool     free = !forced_[slot] && (kind == kFaceDirichlet || (kind == kFaceContact && vertexKind_ != kDirichlet));
        if (free) unknowns_.push_back({slot, -1, e, -1, kind == kFaceContact, 0, 0, 0}), boundaryUnknown_ = true;
        else fixed_[slot] = kind == kFaceNeumann ? c.Neumann(j) : 0.0;
      }
    }
  }

  // y_e = fluxes of entry e; objective 1/2 sum_e (y_e - t_e)^T W_e (y_e - t_e) with t_e the interpolant's
  // fluxes without the face opposite a (W_e the cell's mass matrix over kappa, or its diagonal); constraint
  // sum_j y_e[j] = sum_j t_e[j] - load_e. Fills resid_ = t - fixed and rhs_, and returns the number of
  // constraints kept.
  PetscInt Constraints()
  {
    resid_.resize(n_ * nb_);
    rhs_.resize(n_);
    PetscReal volume = 0, mismatch = 0;
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView &c = corners_[e];
      rhs_[e]         = -c.Load();
      PetscReal *r = &resid_[e * nb_];
      for (PetscInt j = 0; j < nb_; ++j) r[j] = c.rec->target[j] - fixed_[e * nb_ + j];
      r[c.corner] = 0; // the face opposite a: no target, flux 0
      for (PetscInt j = 0; j < nb_; ++j) rhs_[e] += r[j];
      volume += c.rec->volume;
      mismatch += rhs_[e];
    }
    // Without a free boundary face the constraints sum to r_a: make them compatible, drop the last one.
    const PetscInt rows = boundaryUnknown_ ? n_ : n_ - 1;
    if (!boundaryUnknown_) {
      const PetscReal share = mismatch / volume;
      for (PetscInt e = 0; e < n_; ++e) rhs_[e] -= share * corners_[e].rec->volume;
    }
    return rows;
  }

  bool SolveOnce(PetscReal *flux)
  {
    const PetscInt rows = Constraints();
    // Minimise 1/2 x^T H x - c^T x subject to B x = rhs (B: +-1 per slot, in the row of its entry), H the
    // diagonal weights: x = H^{-1} (c - B^T mu) with (B H^{-1} B^T) mu = B H^{-1} c - rhs, a graph
    // Laplacian on the cells (grounded by the free boundary faces, or by the dropped row).
    L_.assign(rows * rows, 0.0);
    mu_.resize(rows);
    adj_.assign(rows, 0);
    for (PetscInt e = 0; e < rows; ++e) mu_[e] = -rhs_[e];
    for (Unknown &u : unknowns_) {
      const PetscInt  e1 = u.e1, e2 = u.e2;
      const PetscReal w1 = corners_[e1].rec->weight[u.first - e1 * nb_];
      PetscReal       h  = w1;
      u.c                = w1 * resid_[u.first];
      if (u.second >= 0) {
        const PetscReal w2 = corners_[e2].rec->weight[u.second - e2 * nb_];
        h += w2, u.c -= w2 * resid_[u.second];
      }
      const PetscReal inv = 1 / h, q = u.c * inv;
      u.hinv              = inv;
      if (e1 < rows) L_[e1 * rows + e1] += inv, mu_[e1] += q;
      if (u.second < 0 || e2 >= rows) continue;
      L_[e2 * rows + e2] += inv, mu_[e2] -= q;
      if (e1 >= rows) continue;
      L_[e1 * rows + e2] -= inv, L_[e2 * rows + e1] -= inv;
      if (rows <= 64) adj_[e1] |= 1ull << e2, adj_[e2] |= 1ull << e1;
    }
    start_.resize(rows + 1);
    nz_.resize(rows * (rows - 1) / 2 + 1);
    if (rows <= 64) {
      if (!SolveSPDMinDegree(rows, L_.data(), mu_.data(), adj_.data(), start_.data(), nz_.data(), d_.data())) return false;
    } else if (!SolveSPD(rows, L_.data(), mu_.data(), start_.data(), nz_.data())) return false;
    for (PetscInt i = 0; i < n_ * nb_; ++i) flux[i] = fixed_[i];
    for (Unknown &u : unknowns_) {
      const PetscInt e1 = u.e1, e2 = u.e2;
      u.x                = u.c;
      if (e1 < rows) u.x -= mu_[e1];
      if (u.second >= 0 && e2 < rows) u.x -= -mu_[e2];
      u.x *= u.hinv;
      flux[u.first] = u.x;
      if (u.second >= 0) flux[u.second] = -u.x;
    }
    return true;
  }
  PetscInt Entry(PetscInt slot) const { return CellOf(slot, nb_); } // the slot's corner record

  // SolveOnce's problem with the full mass matrices of the cells (some of them stretched): the Hessian K
  // couples the unknowns of a cell's faces, so x = K^{-1} (c - B^T mu) with (B K^{-1} B^T) mu = B K^{-1} c
  // - rhs by two Cholesky factorisations (K: the unknowns, about 40 in 3D; then the cells').
  bool SolveCoupled(PetscReal *flux)
  {
    const PetscInt rows = Constraints(), nu = (PetscInt)unknowns_.size(), nr = rows + 1;
    slotUnknown_.assign(n_ * nb_, -1); // 2 k for the first slot of unknown k, 2 k + 1 for its second
    for (PetscInt k = 0; k < nu; ++k) {
      slotUnknown_[unknowns_[k].first] = 2 * k;
      if (unknowns_[k].second >= 0) slotUnknown_[unknowns_[k].second] = 2 * k + 1;
    }
    K_.assign(nu * nu, 0.0);
    Z_.assign(nu * nr, 0.0); // column-major: column 0 c, column 1 + i row i of B
    for (PetscInt e = 0; e < n_; ++e) {
      const CornerView &c = corners_[e];
      const PetscReal  *r = &resid_[e * nb_];
      for (PetscInt i = 0; i < nb_; ++i) {
        const PetscInt ki = slotUnknown_[e * nb_ + i];
        if (i == c.corner || ki < 0) continue;
        const PetscReal si = ki & 1 ? -1.0 : 1.0;
        for (PetscInt j = 0; j < nb_; ++j) {
          if (j == c.corner) continue;
          const PetscReal w  = c.Mass(i, j);
          const PetscInt  kj = slotUnknown_[e * nb_ + j];
          Z_[ki / 2] += si * w * r[j];
          if (kj >= 0) K_[(kj / 2) * nu + ki / 2] += si * (kj & 1 ? -w : w);
        }
      }
    }
    for (PetscInt k = 0; k < nu; ++k) {
      const Unknown &u = unknowns_[k];
      if (u.e1 < rows) Z_[(1 + u.e1) * nu + k] += 1;
      if (u.second >= 0 && u.e2 < rows) Z_[(1 + u.e2) * nu + k] -= 1;
    }
    start_.resize(std::max(nu, rows) + 1);
    nz_.resize(std::max(nu, rows) * (std::max(nu, rows) - 1) / 2 + 1);
    if (nu > 0) {
      if (!FactorSPD(nu, K_.data(), start_.data(), nz_.data())) return false;
      for (PetscInt r = 0; r < nr; ++r) SolveFactored(nu, K_.data(), &Z_[r * nu], start_.data(), nz_.data());
    }
    if (rows > 0) { // S mu = g with S = B Z_B, g = B Z_c - rhs
      S_.assign(rows * rows, 0.0);
      mu_.resize(rows);
      for (PetscInt i = 0; i < rows; ++i) mu_[i] = -rhs_[i];
      for (PetscInt k = 0; k < nu; ++k) {
        const Unknown &u = unknowns_[k];
        for (PetscInt side = 0; side < 2; ++side) {
          const PetscInt e = side ? (u.second >= 0 ? u.e2 : rows) : u.e1;
          if (e >= rows) continue;
          const PetscReal b = side ? -1.0 : 1.0;
          mu_[e] += b * Z_[k];
          for (PetscInt j = 0; j < rows; ++j) S_[j * rows + e] += b * Z_[(1 + j) * nu + k];
        }
      }
      if (!SolveSPD(rows, S_.data(), mu_.data(), start_.data(), nz_.data())) return false;
    }
    for (PetscInt i = 0; i < n_ * nb_; ++i) flux[i] = fixed_[i];
    for (PetscInt k = 0; k < nu; ++k) {
      Unknown &u = unknowns_[k];
      u.x        = Z_[k];
      for (PetscInt i = 0; i < rows; ++i) u.x -= Z_[(1 + i) * nu + k] * mu_[i];
      flux[u.first] = u.x;
      if (u.second >= 0) flux[u.second] = -u.x;
    }
    return true;
  }
  bool                   mayCouple_, coupled_ = false;
  std::vector<PetscInt>  slotUnknown_;
  std::vector<PetscReal> K_, Z_, S_;

  PetscInt               nb_;
  char                   vertexKind_ = kFree;
  const CornerView      *corners_ = nullptr;
  PetscInt               n_       = 0;
  std::vector<Unknown>   unknowns_;
  bool                   boundaryUnknown_ = false;
  struct Bucket {
    uint64_t key;
    PetscInt slot, stamp;
  };
  std::vector<Bucket>       table_;
  std::vector<VertexBucket> vertexTable_;
  std::vector<FaceEntry>    faceTable_;
  PetscInt                  stamp_ = 0;
  std::vector<uint64_t>  adj_;
  std::vector<char>      forced_;
  std::vector<PetscInt>  partner_, start_, nz_;
  std::vector<PetscReal> L_, mu_, fixed_, rhs_, resid_, d_;
};

// F_T^2 = ||kappa^{-1/2}(kappa grad u_h - sigma)||_T^2 of every cell (see CellFlux), from the flux and
// kappa_T grad u_h (computed again: see CellRecord). The dimension is a constant here, so that the short
// loops of CellFlux, inlined, unroll: with the dimension a variable they did not, and the loop was slow.
template <PetscInt dim>
void FluxTermsD(const Space &space, const System &sys, const PetscScalar *u, Reconstruction &r)
{
  constexpr PetscInt nb = dim + 1;
  CellGeometry       g;
  PetscReal          G[3], kg[3];
  r.fluxTerm.resize(space.NumCells());
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    PrefetchVertices(space, c + kCellsAhead, u);
    const Space::Coords X = space.XD<dim>(c);
    ComputeCellGeometryD<dim>(X, g);
    space.GradD<dim>(c, u, g, G);
    const PetscReal kap = sys.Kappa(c);
    for (PetscInt d = 0; d < dim; ++d) kg[d] = kap * G[d];
    r.fluxTerm[c] = CellFlux(dim, X, g, &r.flux[c * nb], kap).Term(dim, kg);
  }
}
void FluxTerms(const Space &space, const System &sys, const PetscScalar *u, Reconstruction &r)
{
  WithDim(space.dim, [&](auto D) { FluxTermsD<D>(space, sys, u, r); });
}

} // namespace

PetscErrorCode ReconstructP1(const Space &space, const Problem &problem, const System &sys, Vec u, Reconstruction &r, bool generic)
{
  MPI_Comm             comm = PetscObjectComm((PetscObject)space.dm);
  static PetscLogEvent event = 0, cellEvent = 0, patchEvent = 0, termEvent = 0; // -log_view: the whole, its cell loop, its local patches, its flux terms
  PetscFunctionBeginUser;
  PetscCheck(space.element == Element::P1, comm, PETSC_ERR_ARG_WRONG, "ReconstructP1 needs the P1 space");
  if (!event) PetscCall(PetscLogEventRegister("ReconstructP1", DM_CLASSID, &event));
  if (!cellEvent) PetscCall(PetscLogEventRegister("P1CellData", DM_CLASSID, &cellEvent));
  if (!patchEvent) PetscCall(PetscLogEventRegister("P1LocalPatches", DM_CLASSID, &patchEvent));
  if (!termEvent) PetscCall(PetscLogEventRegister("P1FluxTerms", DM_CLASSID, &termEvent));
  PetscCall(PetscLogEventBegin(event, 0, 0, 0, 0));
  const PetscInt nb = space.Nb(), nc = space.NumCells(), nv = space.numLocal;

  Vec                loc;
  const PetscScalar *ua;
  CellData           cd;
  const PetscInt    *gidx;
  PetscCall(ISLocalToGlobalMappingGetIndices(space.ltog, &gidx));
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &ua));
  PetscCall(PetscLogEventBegin(cellEvent, 0, 0, 0, 0));
  PetscCall(ComputeCellData(space, problem, sys, ua, cd, r.oscillation));
  PetscCall(PetscLogEventEnd(cellEvent, 0, 0, 0, 0));

  // The vertices in the order in which the cells first reach them (pos: a vertex's place in it), which is
  // the order of the patches below: the cells of consecutive patches then lie close in memory, where the
  // vertex order may scatter them (a mesh refined in levels numbers cells and vertices by different
  // rules), which made the patches' reads of the cell data and writes of the fluxes wait for memory. The
  // local cells of each vertex (CSR, by that order: the patches read it front to back).
  std::vector<PetscInt> order, pos(nv, -1), start(nv + 1, 0), list(nc * nb);
  order.reserve(nv);
  for (PetscInt i = 0; i < nc * nb; ++i)
    if (pos[space.cellVert[i]] < 0) pos[space.cellVert[i]] = (PetscInt)order.size(), order.push_back(space.cellVert[i]);
  for (PetscInt v = 0; v < nv; ++v)
    if (pos[v] < 0) pos[v] = (PetscInt)order.size(), order.push_back(v); // in no local cell (none expected)
  for (PetscInt i = 0; i < nc * nb; ++i) ++start[pos[space.cellVert[i]] + 1];
  for (PetscInt o = 0; o < nv; ++o) start[o + 1] += start[o];
  {
    std::vector<PetscInt> next(start.begin(), start.end() - 1);
    for (PetscInt i = 0; i < nc * nb; ++i) list[next[pos[space.cellVert[i]]]++] = i; // i = c * nb + corner
  }
  // Which vertices have cells on other ranks too (their count summed over ranks is larger): none on one rank.
  std::vector<char> shared(nv, 0);
  bool              anyShared = false; // on this rank: else it has no corners to send
  PetscMPIInt       size;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  if (size > 1) {
    Vec                total, count;
    PetscScalar       *la;
    const PetscScalar *ca;
    PetscCall(DMGetGlobalVector(space.dm, &total));
    PetscCall(DMGetLocalVector(space.dm, &count));
    PetscCall(VecGetArray(count, &la));
    for (PetscInt v = 0; v < nv; ++v) la[v] = start[pos[v] + 1] - start[pos[v]];
    PetscCall(VecRestoreArray(count, &la));
    PetscCall(VecSet(total, 0));
    PetscCall(DMLocalToGlobal(space.dm, count, ADD_VALUES, total));
    PetscCall(DMGlobalToLocal(space.dm, total, INSERT_VALUES, count));
    PetscCall(DMRestoreGlobalVector(space.dm, &total));
    PetscCall(VecGetArrayRead(count, &ca));
    for (PetscInt v = 0; v < nv; ++v) shared[v] = PetscRealPart(ca[v]) > start[pos[v] + 1] - start[pos[v]] + 0.5, anyShared = anyShared || shared[v];
    PetscCall(VecRestoreArrayRead(count, &ca));
    PetscCall(DMRestoreLocalVector(space.dm, &count));
  }

  std::vector<PetscInt> ranges;
  PetscMPIInt           rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCall(OwnershipRanges(comm, space.numOwned, ranges));
  const auto owned = [&](PetscInt v) { return gidx[v] >= ranges[rank] && gidx[v] < ranges[rank + 1]; };

  r.flux.assign(nc * nb, 0.0);
  r.companion.clear();
  bool                   ok = true;
  std::vector<CornerView> corners;
  std::vector<PetscInt>  cells;
  std::vector<PetscReal> out;
  Patch                  patch(space.dim, cd.anyCoupled);
  PetscInt               failed = -1; // the vertex of a singular patch problem
  // Patches on this rank alone, in the order of `order`.
  PetscCall(PetscLogEventBegin(patchEvent, 0, 0, 0, 0));
  const PetscInt kAhead = 4;
  for (PetscInt o = 0; o < nv && ok; ++o) {
    const PetscInt v = order[o];
    if (o + kAhead < nv) { // the cell records of a patch a few ahead: their reads missed the cache
      const PetscInt w = o + kAhead;
      for (PetscInt i = start[w]; i < start[w + 1]; ++i) {
        const PetscInt c   = CellOf(list[i], nb);
        const char    *rec = (const char *)&cd.cell[c];
        for (size_t b = 0; b < sizeof(CellRecord); b += 64) __builtin_prefetch(rec + b);
        __builtin_prefetch(&r.flux[c * nb], 1); // and the fluxes it adds to
        __builtin_prefetch(&space.cellVert[c * nb]); // and the vertices it matches faces by
        __builtin_prefetch(&cd.load[c * cd.loadStride]); // and its loads
      }
    }
    const PetscInt n = start[o + 1] - start[o], *at = &list[start[o]]; // at[e] = c * nb + corner
    if (shared[v] || n == 0) continue;
    corners.resize(n);
    cells.resize(n);
    out.resize(n * nb);
    for (PetscInt e = 0; e < n; ++e) {
      cells[e] = CellOf(at[e], nb);
      corners[e] = ViewOf(cd, space, cells[e], at[e] - cells[e] * nb);
    }
    ok = patch.Solve(space.kindLocal[v], corners.data(), n, out.data(), generic);
    if (!ok) failed = v;
    for (PetscInt e = 0; e < n && ok; ++e)
      for (PetscInt j = 0; j < nb; ++j) r.flux[cells[e] * nb + j] += out[e * nb + j];
  }
  PetscCall(PetscLogEventEnd(patchEvent, 0, 0, 0, 0));

  // Patches across ranks: gather their corners on the vertex's owner, solve there, scatter back.
  std::vector<PetscInt>    leafAt;
  std::vector<PetscSFNode> remote;
  for (PetscInt i = 0; i < nc * nb && anyShared; ++i) {
    const PetscInt v = space.cellVert[i];
    if (!shared[v]) continue;
    const PetscMPIInt owner = OwnerOf(ranges, gidx[v]);
    leafAt.push_back(i);
    remote.push_back({owner, gidx[v] - ranges[owner]});
  }
  PetscSF sf;
  PetscCall(PetscSFCreate(comm, &sf));
  PetscCall(PetscSFSetGraph(sf, space.numOwned, (PetscInt)leafAt.size(), NULL, PETSC_COPY_VALUES, remote.data(), PETSC_COPY_VALUES));
  const PetscInt *degree;
  PetscCall(PetscSFComputeDegreeBegin(sf, &degree));
  PetscCall(PetscSFComputeDegreeEnd(sf, &degree));
  PetscInt nmulti = 0;
  for (PetscInt i = 0; i < space.numOwned; ++i) nmulti += degree[i];
  std::vector<char> rootKind(nmulti > 0 ? space.numOwned : 0, kFree); // of the roots that get corners
  for (PetscInt v = 0; v < nv && nmulti > 0; ++v)
    if (owned(v)) rootKind[gidx[v] - ranges[rank]] = space.kindLocal[v];
  std::vector<Corner> leafCorners(leafAt.size()), rootCorners(nmulti);
  for (size_t l = 0; l < leafAt.size(); ++l) FillCorner(cd, space, gidx, leafAt[l] / nb, leafAt[l] % nb, leafCorners[l]);
  MPI_Datatype cornerType, fluxType;
  PetscCallMPI(MPI_Type_contiguous((int)sizeof(Corner), MPI_BYTE, &cornerType));
  PetscCallMPI(MPI_Type_commit(&cornerType));
  PetscCallMPI(MPI_Type_contiguous((int)nb, MPIU_REAL, &fluxType));
  PetscCallMPI(MPI_Type_commit(&fluxType));
  PetscCall(PetscSFGatherBegin(sf, cornerType, leafCorners.data(), rootCorners.data()));
  PetscCall(PetscSFGatherEnd(sf, cornerType, leafCorners.data(), rootCorners.data()));
  std::vector<PetscReal> rootFlux(nmulti * nb, 0.0), leafFlux(leafAt.size() * nb, 0.0);
  for (PetscInt i = 0, off = 0; i < space.numOwned && ok; off += degree[i++]) {
    if (degree[i] == 0) continue;
    corners.resize(degree[i]);
    for (PetscInt e = 0; e < degree[i]; ++e) corners[e] = ViewOf(rootCorners[off + e]);
    ok = patch.Solve(rootKind[i], corners.data(), degree[i], &rootFlux[off * nb], generic);
    for (PetscInt v = 0; v < nv && !ok; ++v)
      if (owned(v) && gidx[v] - ranges[rank] == i) failed = v;
  }
  PetscCall(ISLocalToGlobalMappingRestoreIndices(space.ltog, &gidx));
  PetscCall(PetscSFScatterBegin(sf, fluxType, rootFlux.data(), leafFlux.data()));
  PetscCall(PetscSFScatterEnd(sf, fluxType, rootFlux.data(), leafFlux.data()));
  for (size_t l = 0; l < leafAt.size(); ++l)
    for (PetscInt j = 0; j < nb; ++j) r.flux[(leafAt[l] / nb) * nb + j] += leafFlux[l * nb + j];
  PetscCallMPI(MPI_Type_free(&cornerType));
  PetscCallMPI(MPI_Type_free(&fluxType));
  PetscCall(PetscSFDestroy(&sf));
  // A patch problem is singular only where the patch's cells are not joined through faces containing its
  // vertex: a mesh pinched there (two bodies, or two parts of one, touching at that vertex or along an
  // edge through it). P1 functions are continuous at such a vertex and H^1 functions need not be, so the
  // residual does not balance on each part of the patch and no flux equilibrates it.
  PetscCall(CheckAll(comm, ok,
                     Format("estimate: the cells around the vertex at (%s) are not joined through faces (the mesh is pinched there: its parts touch only at that vertex or along an edge), where P1 functions are continuous and H^1 functions need not be, so no equilibrated P1 flux exists on that vertex patch; use -space cr, or -estimate none to solve without an estimate",
                            failed >= 0 ? CoordinatesText(space.dim, &space.vertX[failed * space.dim]).c_str() : "?")));
  std::vector<PetscInt>().swap(list); // their memory for fluxTerm: the estimate's peak stays where it was
  cd.cell.reset();
  PetscCall(PetscLogEventBegin(termEvent, 0, 0, 0, 0));
  FluxTerms(space, sys, ua, r);
  PetscCall(VecRestoreArrayRead(loc, &ua));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscCall(PetscLogEventEnd(termEvent, 0, 0, 0, 0));
  PetscCall(PetscLogEventEnd(event, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

} // namespace signorini

#include "signorini/space.h"
#include "signorini/options.h"
#include "signorini/layout.h"
#include "signorini/mesh.h"

#include <petsc/private/dmlabelimpl.h> // the strata of a label: sorted index sets or hash sets, see ReadCellSets

#include <algorithm>
#include <cmath>
#include <map>

namespace signorini {

const char *ElementName(Element e) { return e == Element::P1 ? "p1" : "cr"; }

PetscErrorCode ElementFromCommandLine(MPI_Comm comm, Element &e)
{
  PetscInt which = (PetscInt)e;
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Discrete space", "signorini");
  PetscCall(OptionEList(PetscOptionsObject, "-space", "Finite element: p1 (conforming, vertex DOFs) or cr (Crouzeix-Raviart, face DOFs)", {"p1", "cr"}, which));
  PetscOptionsEnd();
  e = (Element)which;
  PetscFunctionReturn(0);
}

bool ComputeCellGeometry(PetscInt dim, const PetscReal *X, CellGeometry &g)
{
  return WithDim(dim, [&](auto D) { return ComputeCellGeometryD<D>(X, g); });
}

bool SimplexIsValid(PetscInt dim, const PetscReal *X)
{
  PetscReal J[3][3], det;
  return WithDim(dim, [&](auto D) { return SimplexJacobian<D>(X, J, det); });
}

void Space::Point(PetscInt c, const PetscReal *lambda, PetscReal *x) const { SimplexPoint(dim, X(c), lambda, x); }

void Space::DofPoint(PetscInt c, PetscInt i, PetscReal *x) const
{
  PetscReal lambda[4];
  DofLambda(element, dim, i, lambda);
  Point(c, lambda, x);
}

std::vector<PetscReal> DofPoints(const Space &s)
{
  std::vector<PetscReal> x(s.numLocal * s.dim);
  for (PetscInt c = 0; c < s.NumCells(); ++c)
    for (PetscInt i = 0; i < s.Nb(); ++i) s.DofPoint(c, i, &x[s.Dofs(c)[i] * s.dim]);
  return x;
}

PetscReal Space::FaceMeasure(const BoundaryFace &bf) const
{
  const Coords Xc = X(bf.cell);
  PetscInt     v[3], n = 0;
  for (PetscInt k = 0; k <= dim; ++k)
    if (k != bf.opposite) v[n++] = k;
  PetscReal e[2][3] = {{0}};
  for (PetscInt j = 1; j < dim; ++j)
    for (PetscInt d = 0; d < dim; ++d) e[j - 1][d] = Xc[v[j] * dim + d] - Xc[v[0] * dim + d];
  if (dim == 2) return std::hypot(e[0][0], e[0][1]);
  const PetscReal cx = e[0][1] * e[1][2] - e[0][2] * e[1][1], cy = e[0][2] * e[1][0] - e[0][0] * e[1][2], cz = e[0][0] * e[1][1] - e[0][1] * e[1][0];
  return 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
}

void Space::FaceToCell(const BoundaryFace &bf, const PetscReal *mu, PetscReal *lambda) const
{
  PetscInt n = 0;
  for (PetscInt k = 0; k <= dim; ++k) lambda[k] = k == bf.opposite ? 0.0 : mu[n++];
}

// The section of a space's DOFs: one on each point of [start, end), the vertices (P1) or the faces (CR).
// The chart covers the points that carry DOFs only, not the whole mesh: the local and the global section
// keep two integers per point of their chart (2D P1: six mesh points per vertex).
static PetscErrorCode DofSection(MPI_Comm comm, PetscInt start, PetscInt end, PetscSection *section)
{
  PetscFunctionBeginUser;
  PetscCall(PetscSectionCreate(comm, section));
  PetscCall(PetscSectionSetChart(*section, start, end));
  for (PetscInt p = start; p < end; ++p) PetscCall(PetscSectionSetDof(*section, p, 1));
  PetscCall(PetscSectionSetUp(*section));
  PetscFunctionReturn(0);
}

// The points carrying the DOFs of element e on mesh.
static PetscErrorCode DofPoints(DM mesh, Element e, PetscInt *start, PetscInt *end)
{
  PetscFunctionBeginUser;
  if (e == Element::P1) PetscCall(DMPlexGetDepthStratum(mesh, 0, start, end));
  else PetscCall(DMPlexGetHeightStratum(mesh, 1, start, end));
  PetscFunctionReturn(0);
}

// The layout of the DOFs (Space::dm), their numbers and their global indices (Space::ltog), from the local
// section and the global one PETSc makes from it and the mesh's point SF, as a DMPlex carrying the section
// would (DMGetGlobalSection, DMGetLocalToGlobalMapping), without the DM: a clone of the mesh copies all its
// labels, which the adaptive meshes keep as hash sets (half of a small step's set-up).
static PetscErrorCode CreateLayout(Space &s, PetscInt start, PetscInt end)
{
  MPI_Comm     comm = PetscObjectComm((PetscObject)s.mesh);
  PetscSection local, global;
  PetscSF      pointSF;
  PetscInt    *indices;
  PetscFunctionBeginUser;
  PetscCall(DofSection(comm, start, end, &local));
  PetscCall(PetscSectionGetStorageSize(local, &s.numLocal));
  // The cell tables and, for P1, Dofs() and ForEachBoundaryDof rely on DOF = p - start.
  PetscCall(LayoutCheckPointOrder(local, start, end));
  PetscCall(DMGetPointSF(s.mesh, &pointSF));
  PetscCall(PetscSectionCreateGlobalSection(local, pointSF, PETSC_FALSE, PETSC_FALSE, &global));
  PetscCall(PetscSectionGetConstrainedStorageSize(global, &s.numOwned));
  PetscCallMPI(MPI_Allreduce(&s.numOwned, &s.numGlobal, 1, MPIU_INT, MPI_SUM, comm));
  PetscCall(LayoutCreate(comm, local, global, &s.dm));
  // A DOF another rank owns has the offset -(its global index + 1).
  PetscCall(PetscMalloc1(s.numLocal, &indices));
  for (PetscInt p = start; p < end; ++p) {
    PetscInt off;
    PetscCall(PetscSectionGetOffset(global, p, &off));
    indices[p - start] = off >= 0 ? off : -(off + 1);
  }
  PetscCall(ISLocalToGlobalMappingCreate(comm, 1, s.numLocal, indices, PETSC_OWN_POINTER, &s.ltog));
  PetscCall(PetscSectionDestroy(&global));
  PetscCall(PetscSectionDestroy(&local));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceSectionDM(const Space &s, DM *dm)
{
  PetscSection section;
  PetscInt     start, end;
  PetscFunctionBeginUser;
  PetscCheck(s.mesh, PETSC_COMM_SELF, PETSC_ERR_ORDER, "the space's mesh was released");
  PetscCall(DMClone(s.mesh, dm));
  PetscCall(DofPoints(*dm, s.element, &start, &end));
  PetscCall(DofSection(PetscObjectComm((PetscObject)*dm), start, end, &section));
  PetscCall(DMSetLocalSection(*dm, section));
  PetscCall(PetscSectionDestroy(&section));
  PetscCall(DMSetMatType(*dm, MATAIJ));
  PetscFunctionReturn(0);
}

// The "Cell Sets" value of each cell cStart .. cEnd - 1. Where the label's strata are sorted index sets (as
// the mesh reader, both refinements and the distribution leave them) each stratum's cells are copied in one
// pass, instead of DMLabelGetValue's binary search through every stratum per cell; a stratum still held as
// a hash set (points added one by one) would have to be sorted first, and there a lookup per cell is cheaper.
static PetscErrorCode ReadCellSets(DMLabel label, PetscInt cStart, PetscInt cEnd, std::vector<PetscInt> &cellSet)
{
  PetscFunctionBeginUser;
  cellSet.assign(cEnd - cStart, label->defaultValue);
  bool sorted = true;
  for (PetscInt v = 0; v < label->numStrata; ++v) sorted = sorted && label->validIS[v];
  if (!sorted) {
    for (PetscInt c = cStart; c < cEnd; ++c) PetscCall(DMLabelGetValue(label, c, &cellSet[c - cStart]));
    PetscFunctionReturn(0);
  }
  for (PetscInt v = 0; v < label->numStrata; ++v) {
    const PetscInt *points;
    PetscInt        n;
    PetscCall(ISGetLocalSize(label->points[v], &n));
    PetscCall(ISGetIndices(label->points[v], &points));
    for (const PetscInt *p = std::lower_bound(points, points + n, cStart); p < points + n && *p < cEnd; ++p) cellSet[*p - cStart] = label->stratumValues[v];
    PetscCall(ISRestoreIndices(label->points[v], &points));
  }
  PetscFunctionReturn(0);
}

// Cell tables: vertices, DOFs and Cell Sets values of each cell, and the vertex coordinates.
static PetscErrorCode BuildCellTables(Space &s, PetscInt fStart)
{
  DMLabel          cellSets;
  std::string      problem;
  CellVertexReader reader;
  PetscFunctionBeginUser;
  const PetscInt nb = s.dim + 1, nc = s.NumCells(), dim = s.dim;
  PetscCall(DMGetLabel(s.mesh, "Cell Sets", &cellSets));
  PetscCall(VertexCoordinates(s.mesh, s.vertX));
  PetscCall(reader.Init(s.mesh));
  if (s.element == Element::CR) s.cellDof.resize(nc * nb);
  s.cellVert.resize(nc * nb);
  for (PetscInt c = 0; c < nc; ++c) {
    const PetscInt cell = s.cStart + c;
    PetscInt      *verts = &s.cellVert[c * nb];
    reader.PrefetchAhead(cell, s.cEnd);
    reader.Vertices(cell, verts);
    if (s.element == Element::CR) {
      const PetscInt *cone;
      PetscCall(DMPlexGetCone(s.mesh, cell, &cone));
      for (PetscInt i = 0; i < nb; ++i) s.cellDof[c * nb + i] = cone[i] - fStart; // DOF = p - start, see CreateLayout
    }
    for (PetscInt i = 0; i < nb; ++i) verts[i] -= s.vStart;
    const Space::Coords X = s.X(c);
    if (!SimplexIsValid(dim, X) && problem.empty()) problem = Format("mesh: cell %d (near (%g, %g)) is degenerate", (int)cell, (double)X[0], (double)X[1]);
  }
  if (cellSets) PetscCall(ReadCellSets(cellSets, s.cStart, s.cEnd, s.cellSet));
  PetscCall(CheckAll(PetscObjectComm((PetscObject)s.mesh), problem.empty(), problem));
  PetscFunctionReturn(0);
}

// "x, y[, z]" of the centroid of mesh point p, for messages.
static std::string PointText(const Space &s, PetscInt p)
{
  PetscReal measure, x[3] = {0, 0, 0}, n[3];
  if (DMPlexComputeCellGeometryFVM(s.mesh, p, &measure, x, n)) return "?";
  return CoordinatesText(s.dim, x);
}

// Collects the faces of every named part, checking that each part exists and lies on the boundary.
static PetscErrorCode CollectBoundary(Space &s, const Problem &problem)
{
  MPI_Comm comm = PetscObjectComm((PetscObject)s.mesh);
  DMLabel  faceSets;
  PetscFunctionBeginUser;
  PetscCall(DMGetLabel(s.mesh, "Face Sets", &faceSets));
  const std::pair<const char *, const std::vector<PetscInt> *> parts[] = {{"-bc_dirichlet", &problem.dirichlet}, {"-bc_neumann", &problem.neumann}, {"-bc_contact", &problem.contact}};
  // Each face carries at most one condition: a face in two named parts (a Gmsh line in two physical
  // groups, say) would get its Neumann integral twice, or be both Dirichlet and contact.
  std::map<PetscInt, std::pair<const char *, PetscInt>> named;
  std::string                                            interior, overlap;
  std::vector<PetscInt>                                  faces;
  for (const auto &part : parts) {
    for (PetscInt value : *part.second) {
      PetscCall(LabelFaces(s.mesh, faceSets, value, faces));
      for (const PetscInt f : faces) {
        PetscInt        nsupp;
        const PetscInt *supp, *cone;
        // A boundary face has one cell, as DMPlexMarkBoundaryFaces decides it, without marking them all.
        PetscCall(DMPlexGetSupportSize(s.mesh, f, &nsupp));
        if (nsupp != 1) {
          if (interior.empty()) interior = Format("option %s: boundary part %d contains interior faces", part.first, (int)value);
          continue;
        }
        const auto first = named.emplace(f, std::make_pair(part.first, value));
        if (!first.second) {
          if (overlap.empty()) overlap = Format("option%s %s%s%s: boundary parts %d and %d overlap (they share the face near (%s)); each face may carry one condition", first.first->second.first == part.first ? "" : "s", first.first->second.first, first.first->second.first == part.first ? "" : " and ", first.first->second.first == part.first ? "" : part.first, (int)first.first->second.second, (int)value, PointText(s, f).c_str());
          continue;
        }
        PetscCall(DMPlexGetSupport(s.mesh, f, &supp));
        PetscCall(DMPlexGetCone(s.mesh, supp[0], &cone));
        BoundaryFace bf{supp[0] - s.cStart, -1, value, -1, f};
        for (PetscInt k = 0; k <= s.dim; ++k)
          if (cone[k] == f) {
            bf.opposite = k;
            if (s.element == Element::CR) bf.dof = s.cellDof[bf.cell * s.Nb() + k];
          }
        s.boundary.push_back(bf);
      }
      PetscInt local = (PetscInt)faces.size(), global;
      PetscCallMPI(MPI_Allreduce(&local, &global, 1, MPIU_INT, MPI_SUM, comm));
      if (global == 0) SIGNORINI_INPUT_ERROR(comm, "%s", MissingPartMessage(part.first, value).c_str());
    }
  }
  PetscCall(CheckAll(comm, interior.empty(), interior));
  PetscCall(CheckAll(comm, overlap.empty(), overlap));
  PetscFunctionReturn(0);
}

// Marks Dirichlet and contact DOFs. A P1 vertex where Gamma_D meets Gamma_C is Dirichlet. Flags are summed
// over ranks so that a vertex shared by two ranks gets the same kind on both: each face of a part adds
// kDirichletFlag or kContactFlag to its DOFs, and a sum tells both flags apart exactly (fewer than
// kDirichletFlag faces meet at a DOF), so one local and one global vector do for both kinds.
static PetscErrorCode ClassifyDofs(Space &s, const Problem &problem)
{
  const PetscReal kDirichletFlag = 4096, kContactFlag = 1;
  Vec          lflag, gflag;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMCreateLocalVector(s.dm, &lflag));
  PetscCall(DMCreateGlobalVector(s.dm, &gflag));
  PetscCall(VecSet(lflag, 0));
  PetscCall(VecSet(gflag, 0));
  PetscCall(VecGetArray(lflag, &a));
  for (const BoundaryFace &bf : s.boundary) {
    const bool dirichlet = std::find(problem.dirichlet.begin(), problem.dirichlet.end(), bf.part) != problem.dirichlet.end();
    const bool contact   = std::find(problem.contact.begin(), problem.contact.end(), bf.part) != problem.contact.end();
    if (!dirichlet && !contact) continue;
    const PetscReal flag = dirichlet ? kDirichletFlag : kContactFlag;
    if (s.element == Element::CR) a[bf.dof] += flag;
    else
      for (PetscInt i = 0; i < s.Nb(); ++i)
        if (i != bf.opposite) a[s.Dofs(bf.cell)[i]] += flag;
  }
  PetscCall(VecRestoreArray(lflag, &a));
  PetscCall(DMLocalToGlobal(s.dm, lflag, ADD_VALUES, gflag));
  PetscCall(DMGlobalToLocal(s.dm, gflag, INSERT_VALUES, lflag));
  const auto kind = [&](PetscScalar v) { return PetscRealPart(v) >= kDirichletFlag ? kDirichlet : (PetscRealPart(v) > 0 ? kContact : kFree); };
  const PetscScalar *l, *g;
  PetscCall(VecGetArrayRead(lflag, &l));
  s.kindLocal.resize(s.numLocal);
  for (PetscInt i = 0; i < s.numLocal; ++i) s.kindLocal[i] = kind(l[i]);
  PetscCall(VecRestoreArrayRead(lflag, &l));
  PetscCall(VecGetArrayRead(gflag, &g));
  for (PetscInt i = 0; i < s.numOwned; ++i) {
    const char k = kind(g[i]);
    if (k == kDirichlet) s.dirichletOwned.push_back(i);
    else if (k == kContact) s.contactOwned.push_back(i);
  }
  PetscCall(VecRestoreArrayRead(gflag, &g));
  PetscCall(VecDestroy(&lflag));
  PetscCall(VecDestroy(&gflag));
  PetscInt counts[2] = {(PetscInt)s.dirichletOwned.size(), (PetscInt)s.contactOwned.size()}, sums[2];
  PetscCallMPI(MPI_Allreduce(counts, sums, 2, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)s.mesh)));
  s.numDirichletGlobal = sums[0];
  s.numContactGlobal   = sums[1];
  PetscFunctionReturn(0);
}

// The obstacle must not lie above the Dirichlet data where Gamma_D and Gamma_C meet: the trace of u is
// continuous there, so u = u_D and u >= psi cannot both hold. The discrete set K_h would not notice (it
// constrains only contact DOFs), so the check is made at the vertices the two parts share. A vertex can be
// on a Dirichlet face of one rank and a contact face of another: the flags are or-ed onto the owner
// through the point SF.
static PetscErrorCode CheckObstacleMeetsDirichlet(const Space &s, const Problem &problem)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)s.mesh);
  PetscSF            sf;
  PetscInt           pStart, pEnd, nroots, nleaves, vStart, vEnd;
  const PetscInt    *leaves;
  Vec                coords;
  PetscSection       csec;
  const PetscScalar *xa;
  PetscInt           verts[4];
  std::string        problemText, error;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(s.mesh, &pStart, &pEnd));
  PetscCall(DMPlexGetDepthStratum(s.mesh, 0, &vStart, &vEnd));
  std::vector<PetscInt> flags(pEnd - pStart, 0);
  for (const BoundaryFace &bf : s.boundary) {
    const bool dirichlet = std::count(problem.dirichlet.begin(), problem.dirichlet.end(), bf.part) > 0;
    const bool contact   = std::count(problem.contact.begin(), problem.contact.end(), bf.part) > 0;
    if (!dirichlet && !contact) continue;
    PetscCall(SimplexVertices(s.mesh, bf.face, s.dim - 1, verts));
    for (PetscInt i = 0; i < s.dim; ++i) flags[verts[i] - pStart] |= dirichlet ? 1 : 2;
  }
  std::vector<PetscInt> owned(flags);
  std::vector<char>     isLeaf(pEnd - pStart, 0);
  PetscCall(DMGetPointSF(s.mesh, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &leaves, NULL));
  if (nroots >= 0) {
    PetscCall(PetscSFReduceBegin(sf, MPIU_INT, flags.data(), owned.data(), MPI_BOR));
    PetscCall(PetscSFReduceEnd(sf, MPIU_INT, flags.data(), owned.data(), MPI_BOR));
    for (PetscInt i = 0; i < nleaves; ++i) isLeaf[(leaves ? leaves[i] : i) - pStart] = 1;
  }
  PetscCall(DMGetCoordinatesLocal(s.mesh, &coords));
  PetscCall(DMGetCoordinateSection(s.mesh, &csec));
  PetscCall(VecGetArrayRead(coords, &xa));
  for (PetscInt v = vStart; v < vEnd && problemText.empty(); ++v) {
    if (owned[v - pStart] != 3 || isLeaf[v - pStart]) continue;
    PetscInt  off;
    PetscReal x[3] = {0, 0, 0};
    PetscCall(PetscSectionGetOffset(csec, v, &off));
    for (PetscInt d = 0; d < s.dim; ++d) x[d] = PetscRealPart(xa[off + d]);
    const PetscReal psi = problem.psi->Scalar(x, s.dim, error), uD = problem.uD->Scalar(x, s.dim, error);
    if (!error.empty()) problemText = error;
    else if (psi - uD > 1e-8 * std::max({(PetscReal)1.0, std::fabs(psi), std::fabs(uD)}))
      problemText = Format("options -psi and -u_D: the obstacle psi = %g lies above the Dirichlet value u_D = %g at (%g, %g, %g), where Gamma_D and Gamma_C meet; no solution satisfies both (infeasible)", (double)psi, (double)uD, (double)x[0], (double)x[1], (double)x[2]);
  }
  PetscCall(VecRestoreArrayRead(coords, &xa));
  PetscCall(CheckAll(comm, problemText.empty(), problemText));
  PetscFunctionReturn(0);
}

// Index of face f in the cone of cell c (the cell vertex opposite it).
static PetscErrorCode ConeIndex(DM dm, PetscInt c, PetscInt f, PetscInt nb, PetscInt *k)
{
  const PetscInt *cone;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetCone(dm, c, &cone));
  for (*k = 0; *k < nb && cone[*k] != f; ++*k) {}
  PetscCheck(*k < nb, PETSC_COMM_SELF, PETSC_ERR_PLIB, "face %d is not in the cone of its support cell %d", (int)f, (int)c);
  PetscFunctionReturn(0);
}

// The face tables (see InteriorFace): a face with two local cells is interior; one with one local cell is
// shared with another rank if the point SF holds it (a leaf here, or a root that some rank points at),
// and on the boundary of the domain otherwise.
static PetscErrorCode BuildFaceTables(Space &s, PetscInt fStart, PetscInt fEnd)
{
  PetscSF            pointSF;
  PetscInt           pStart, pEnd, nroots, nleaves;
  const PetscInt    *leaves, *degree = nullptr;
  const PetscSFNode *remotes;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(s.mesh, &pStart, &pEnd));
  PetscCall(DMGetPointSF(s.mesh, &pointSF));
  PetscCall(PetscSFGetGraph(pointSF, &nroots, &nleaves, &leaves, &remotes));
  std::vector<PetscInt> leafOf(pEnd - pStart, -1); // position in the point SF's leaves
  if (nroots >= 0) {
    for (PetscInt i = 0; i < nleaves; ++i) leafOf[(leaves ? leaves[i] : i) - pStart] = i;
    PetscCall(PetscSFComputeDegreeBegin(pointSF, &degree));
    PetscCall(PetscSFComputeDegreeEnd(pointSF, &degree));
  }
  std::vector<PetscInt> entry(pEnd - pStart, -1); // owned shared face -> its index in sharedFaces
  for (PetscInt f = fStart; f < fEnd; ++f) {
    const PetscInt *supp;
    PetscInt        nsupp;
    PetscCall(DMPlexGetSupportSize(s.mesh, f, &nsupp));
    PetscCall(DMPlexGetSupport(s.mesh, f, &supp));
    if (nsupp == 2) {
      InteriorFace face;
      for (PetscInt j = 0; j < 2; ++j) {
        face.cell[j] = supp[j] - s.cStart;
        PetscCall(ConeIndex(s.mesh, supp[j], f, s.Nb(), &face.local[j]));
      }
      s.interiorFaces.push_back(face);
      continue;
    }
    const bool leaf = leafOf[f - pStart] >= 0, root = degree && degree[f - pStart] > 0;
    if (nsupp != 1 || (!leaf && !root)) continue;
    SharedFace face{supp[0] - s.cStart, 0, !leaf};
    PetscCall(ConeIndex(s.mesh, supp[0], f, s.Nb(), &face.local));
    if (face.owned) entry[f - pStart] = (PetscInt)s.sharedFaces.size();
    s.sharedFaces.push_back(face);
  }
  // Each leaf learns the index of its face in the owner's sharedFaces.
  std::vector<PetscInt> remoteEntry(entry);
  if (nroots >= 0) {
    PetscCall(PetscSFBcastBegin(pointSF, MPIU_INT, entry.data(), remoteEntry.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(pointSF, MPIU_INT, entry.data(), remoteEntry.data(), MPI_REPLACE));
  }
  std::vector<PetscInt>    local;
  std::vector<PetscSFNode> remote;
  PetscInt                 i = 0;
  for (PetscInt f = fStart; f < fEnd; ++f) {
    if (leafOf[f - pStart] < 0 || i >= (PetscInt)s.sharedFaces.size()) continue;
    PetscInt nsupp;
    PetscCall(DMPlexGetSupportSize(s.mesh, f, &nsupp));
    if (nsupp != 1) continue;
    // sharedFaces lists the faces in point order, so the entry of f is the next non-owned one
    while (s.sharedFaces[i].owned) ++i;
    local.push_back(i++);
    remote.push_back({remotes[leafOf[f - pStart]].rank, remoteEntry[f - pStart]});
  }
  PetscCall(PetscSFCreate(PetscObjectComm((PetscObject)s.mesh), &s.sharedFaceSF));
  PetscCall(PetscSFSetGraph(s.sharedFaceSF, (PetscInt)s.sharedFaces.size(), (PetscInt)local.size(), local.data(), PETSC_COPY_VALUES, remote.data(), PETSC_COPY_VALUES));
  PetscFunctionReturn(0);
}

// The vertex exchange (Space::vertexSF) from the mesh's point SF: each leaf vertex learns its index among
// the owner's vertices.
static PetscErrorCode BuildVertexSF(Space &s, PetscInt vEnd)
{
  PetscSF            pointSF;
  PetscInt           pStart, pEnd, nroots, nleaves;
  const PetscInt    *leaves;
  const PetscSFNode *remotes;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(s.mesh, &pStart, &pEnd));
  PetscCall(DMGetPointSF(s.mesh, &pointSF));
  PetscCall(PetscSFGetGraph(pointSF, &nroots, &nleaves, &leaves, &remotes));
  std::vector<PetscInt>    local;
  std::vector<PetscSFNode> remote;
  if (nroots >= 0) {
    std::vector<PetscInt> index(pEnd - pStart, -1), remoteIndex(pEnd - pStart, -1);
    for (PetscInt v = s.vStart; v < vEnd; ++v) index[v - pStart] = v - s.vStart;
    PetscCall(PetscSFBcastBegin(pointSF, MPIU_INT, index.data(), remoteIndex.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(pointSF, MPIU_INT, index.data(), remoteIndex.data(), MPI_REPLACE));
    for (PetscInt i = 0; i < nleaves; ++i) {
      const PetscInt p = leaves ? leaves[i] : i;
      if (p < s.vStart || p >= vEnd) continue;
      local.push_back(p - s.vStart);
      remote.push_back({remotes[i].rank, remoteIndex[p - pStart]});
    }
  }
  PetscCall(PetscSFCreate(PetscObjectComm((PetscObject)s.mesh), &s.vertexSF));
  PetscCall(PetscSFSetGraph(s.vertexSF, vEnd - s.vStart, (PetscInt)local.size(), local.data(), PETSC_COPY_VALUES, remote.data(), PETSC_COPY_VALUES));
  PetscFunctionReturn(0);
}

// -log_view lists the steps of SpaceCreate under the Setup stage.
static PetscErrorCode SpaceEvents(PetscLogEvent ev[4])
{
  static PetscLogEvent events[4] = {0, 0, 0, 0};
  static const char   *names[4]  = {"SpaceSection", "SpaceCellTables", "SpaceBoundary", "SpaceClassify"};
  PetscFunctionBeginUser;
  for (int i = 0; i < 4; ++i) {
    if (!events[i]) PetscCall(PetscLogEventRegister(names[i], DM_CLASSID, &events[i]));
    ev[i] = events[i];
  }
  PetscFunctionReturn(0);
}

// The mesh, its strata and the section of the DOFs with their layout: the start of both ways to create a space.
static PetscErrorCode SpaceCreateLayout(DM mesh, Element element, Space &s, PetscInt &vEnd, PetscInt &fStart, PetscInt &fEnd)
{
  PetscInt vStart;
  PetscFunctionBeginUser;
  // The mesh itself, not a clone: the space reads its topology only, and its section lives in the layout.
  PetscCall(PetscObjectReference((PetscObject)mesh));
  s.mesh = mesh;
  s.element = element;
  PetscCall(DMGetDimension(s.mesh, &s.dim));
  PetscCheck(s.dim == 2 || s.dim == 3, PetscObjectComm((PetscObject)mesh), PETSC_ERR_SUP, "only 2D and 3D simplex meshes are supported");
  PetscCall(DMPlexGetDepthStratum(s.mesh, 0, &vStart, &vEnd));
  PetscCall(DMPlexGetHeightStratum(s.mesh, 1, &fStart, &fEnd));
  PetscCall(DMPlexGetHeightStratum(s.mesh, 0, &s.cStart, &s.cEnd));
  s.vStart = vStart;
  PetscCall(CreateLayout(s, element == Element::P1 ? vStart : fStart, element == Element::P1 ? vEnd : fEnd));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceCreate(DM mesh, Element element, const Problem &problem, Space &s, bool interiorFaces, bool vertexExchange)
{
  PetscInt      vEnd, fStart, fEnd;
  PetscLogEvent ev[4];
  PetscFunctionBeginUser;
  PetscCall(SpaceEvents(ev));
  PetscCall(PetscLogEventBegin(ev[0], 0, 0, 0, 0));
  PetscCall(SpaceCreateLayout(mesh, element, s, vEnd, fStart, fEnd));
  PetscCall(PetscLogEventEnd(ev[0], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[1], 0, 0, 0, 0));
  PetscCall(BuildCellTables(s, fStart));
  PetscCall(PetscLogEventEnd(ev[1], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[2], 0, 0, 0, 0));
  PetscCall(CollectBoundary(s, problem));
  if (interiorFaces) PetscCall(BuildFaceTables(s, fStart, fEnd));
  if (vertexExchange) PetscCall(BuildVertexSF(s, vEnd));
  PetscCall(PetscLogEventEnd(ev[2], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[3], 0, 0, 0, 0));
  PetscCall(ClassifyDofs(s, problem));
  if (problem.HasContact() && !problem.dirichlet.empty()) PetscCall(CheckObstacleMeetsDirichlet(s, problem));
  PetscCall(PetscLogEventEnd(ev[3], 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceCreateP1Of(DM mesh, const Space &cr, const Problem &problem, Space &s)
{
  PetscInt      vEnd, fStart, fEnd;
  PetscLogEvent ev[4];
  PetscFunctionBeginUser;
  PetscCall(SpaceEvents(ev));
  PetscCall(PetscLogEventBegin(ev[0], 0, 0, 0, 0));
  PetscCall(SpaceCreateLayout(mesh, Element::P1, s, vEnd, fStart, fEnd));
  PetscCall(PetscLogEventEnd(ev[0], 0, 0, 0, 0));
  PetscCheck(cr.dim == s.dim && cr.cStart == s.cStart && cr.cEnd == s.cEnd && cr.vStart == s.vStart && (PetscInt)cr.vertX.size() == (vEnd - s.vStart) * s.dim, PETSC_COMM_SELF, PETSC_ERR_ARG_INCOMP, "the space given is not one of this mesh");
  // The tables depend on the mesh only, the checks on them were made for cr.
  PetscCall(PetscLogEventBegin(ev[1], 0, 0, 0, 0));
  s.cellVert = cr.cellVert;
  s.vertX    = cr.vertX;
  s.cellSet  = cr.cellSet;
  PetscCall(PetscLogEventEnd(ev[1], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[2], 0, 0, 0, 0));
  s.boundary = cr.boundary;
  for (BoundaryFace &bf : s.boundary) bf.dof = -1;
  PetscCall(PetscLogEventEnd(ev[2], 0, 0, 0, 0));
  PetscCall(PetscLogEventBegin(ev[3], 0, 0, 0, 0));
  PetscCall(ClassifyDofs(s, problem));
  PetscCall(PetscLogEventEnd(ev[3], 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceReleaseWorkVectors(const Space &s)
{
  PetscFunctionBeginUser;
  PetscCall(DMClearLocalVectors(s.dm));
  PetscCall(DMClearGlobalVectors(s.dm));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceShareOwners(const Space &s, std::vector<PetscInt> &values)
{
  Vec          loc, glob;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(s.dm, &loc));
  PetscCall(DMGetGlobalVector(s.dm, &glob));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < s.numLocal; ++i) a[i] = (PetscScalar)values[i];
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(s.dm, loc, INSERT_VALUES, glob)); // the owners' entries
  PetscCall(DMGlobalToLocal(s.dm, glob, INSERT_VALUES, loc));
  PetscCall(VecGetArray(loc, &a));
  for (PetscInt i = 0; i < s.numLocal; ++i) values[i] = (PetscInt)PetscRealPart(a[i]);
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMRestoreGlobalVector(s.dm, &glob));
  PetscCall(DMRestoreLocalVector(s.dm, &loc));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceReleaseMesh(Space &s)
{
  PetscFunctionBeginUser;
  PetscCall(DMDestroy(&s.mesh));
  PetscFunctionReturn(0);
}

PetscErrorCode SpaceDestroy(Space &s)
{
  PetscFunctionBeginUser;
  PetscCall(DMDestroy(&s.mesh));
  PetscCall(DMDestroy(&s.dm));
  PetscCall(ISLocalToGlobalMappingDestroy(&s.ltog));
  PetscCall(PetscSFDestroy(&s.sharedFaceSF));
  PetscCall(PetscSFDestroy(&s.vertexSF));
  s = Space();
  PetscFunctionReturn(0);
}

} // namespace signorini

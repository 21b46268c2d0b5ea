#include "signorini/problem.h"

#include "signorini/components.h"
#include "signorini/exactcheck.h"
#include "signorini/gmsh.h"
#include "signorini/mesh.h"
#include "signorini/options.h"

#include <algorithm>
#include <cstdlib>
#include <map>
#include <tuple>

namespace signorini {

// Without a Dirichlet or a contact part, u is determined only up to a constant.
static PetscErrorCode CheckDetermined(MPI_Comm comm, const Problem &p)
{
  PetscFunctionBeginUser;
  if (p.dirichlet.empty() && p.contact.empty())
    SIGNORINI_INPUT_ERROR(comm, "options -bc_dirichlet/-bc_contact: the scene has neither a Dirichlet nor a contact part, so u is not determined (singular problem)");
  PetscFunctionReturn(0);
}

// The names the boundary parts may be given by, besides their numbers: the box's sides, or the physical
// names of dimension 1 and 2 in the mesh file (read on rank 0, up to its $Nodes; a name given to several
// physical groups names them all). `known` lists them for the message on an unknown name.
static PetscErrorCode PartNames(MPI_Comm comm, std::map<std::string, std::vector<PetscInt>> &names, std::string &known)
{
  char        file[PETSC_MAX_PATH_LEN] = "", dimText[64] = "2";
  PetscBool   hasFile;
  PetscMPIInt rank;
  PetscFunctionBeginUser;
  PetscCall(PetscOptionsGetString(NULL, NULL, "-mesh_file", file, sizeof file, &hasFile));
  if (!hasFile || !file[0]) {
    // (-dim read as text: its own reader refuses a bad value with the option's message)
    PetscCall(PetscOptionsGetString(NULL, NULL, "-dim", dimText, sizeof dimText, NULL));
    static const char *sides2[] = {"bottom", "right", "top", "left"}, *sides3[] = {"bottom", "top", "front", "back", "right", "left"};
    const bool         three    = Trim(dimText) == "3";
    known                       = three ? "the box's sides: bottom 1 (z = 0), top 2, front 3 (y = 0), back 4, right 5 (x = 1), left 6" : "the box's sides: bottom 1, right 2, top 3, left 4";
    for (int k = 0; k < (three ? 6 : 4); ++k) names[three ? sides3[k] : sides2[k]] = {k + 1};
    PetscFunctionReturn(0);
  }
  std::string text; // "tag name" lines; "?" where the file cannot be opened (its reader says why, later)
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) {
    std::vector<GmshPhysicalName> physical;
    if (!GmshPhysicalNames(file, physical)) text = "?";
    for (const GmshPhysicalName &n : physical)
      if (n.dim == 1 || n.dim == 2) text += Format("%ld %s\n", n.tag, n.name.c_str());
  }
  int length = (int)text.size();
  PetscCallMPI(MPI_Bcast(&length, 1, MPI_INT, 0, comm));
  text.resize(length);
  PetscCallMPI(MPI_Bcast(text.data(), length, MPI_CHAR, 0, comm));
  if (text == "?") {
    known = Format("the mesh file '%s' cannot be opened", file);
    PetscFunctionReturn(0);
  }
  std::string list;
  for (size_t pos = 0; pos < text.size();) {
    const size_t      end  = text.find('\n', pos), space = text.find(' ', pos);
    const PetscInt    tag  = (PetscInt)std::atol(text.substr(pos, space - pos).c_str());
    const std::string name = text.substr(space + 1, end - space - 1);
    std::vector<PetscInt> &tags = names[name];
    if (std::find(tags.begin(), tags.end(), tag) == tags.end()) tags.push_back(tag);
    list += Format("%s'%s' %d", list.empty() ? "" : ", ", name.c_str(), (int)tag);
    pos = end + 1;
  }
  known = list.empty() ? Format("'%s' has no physical names", file) : Format("the physical names of '%s': %s", file, list.c_str());
  PetscFunctionReturn(0);
}

PetscErrorCode ProblemFromCommandLine(MPI_Comm comm, Problem &p)
{
  std::string f = "0", g = "0", uD = "0", psi = "0", kappa = "1", ex, exg;
  bool        hasExact = false, hasGrad = false;
  std::map<std::string, std::vector<PetscInt>> names;
  std::string                                  known;
  PetscFunctionBeginUser;
  PetscCall(PartNames(comm, names, known));
  PetscOptionsBegin(comm, "", "Scene: boundary parts and data (expressions in x, y, z, cell_set; constant pi)", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-scene", "Name of the scene, reported in the summary", p.scene));
  PetscCall(OptionNamedIntList(PetscOptionsObject, "-bc_dirichlet", "Face Sets values of Gamma_D, comma separated, or their names (the box's sides bottom, right, top, left, in 3D bottom, top, front, back, right, left; a Gmsh file's physical names)", p.dirichlet, names, known));
  PetscCall(OptionNamedIntList(PetscOptionsObject, "-bc_neumann", "Face Sets values (or names) of Gamma_N", p.neumann, names, known));
  PetscCall(OptionNamedIntList(PetscOptionsObject, "-bc_contact", "Face Sets values (or names) of Gamma_C (u >= psi there)", p.contact, names, known));
  PetscCall(OptionString(PetscOptionsObject, "-f", "Source f in -div(kappa grad u) = f; cell_set is the Cell Sets value of the cell integrated over", f));
  PetscCall(OptionString(PetscOptionsObject, "-g", "Neumann flux g = kappa du/dn on Gamma_N; cell_set is that of the one cell next to the Neumann face", g));
  PetscCall(OptionString(PetscOptionsObject, "-u_D", "Dirichlet value on Gamma_D (a value at boundary points, which may touch cells of several sets: no cell_set)", uD));
  PetscCall(OptionString(PetscOptionsObject, "-psi", "Obstacle on Gamma_C (a value at boundary points, which may touch cells of several sets: no cell_set)", psi));
  PetscCall(OptionString(PetscOptionsObject, "-kappa", "Coefficient kappa > 0, taken constant per cell (value at the centroid); cell_set is the cell's Cell Sets value", kappa));
  PetscCall(OptionString(PetscOptionsObject, "-exact_u", "Exact solution, if known (cell_set: that of the cell of the error integral)", ex, &hasExact));
  PetscCall(OptionString(PetscOptionsObject, "-exact_grad", "Gradient of the exact solution, dim comma-separated components (cell_set as in -exact_u)", exg, &hasGrad));
  PetscOptionsEnd();

  const std::pair<const char *, std::vector<PetscInt> *> parts[] = {{"-bc_dirichlet", &p.dirichlet}, {"-bc_neumann", &p.neumann}, {"-bc_contact", &p.contact}};
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      for (PetscInt v : *parts[a].second)
        if (std::count(parts[b].second->begin(), parts[b].second->end(), v))
          SIGNORINI_INPUT_ERROR(comm, "options %s and %s: boundary part %" PetscInt_FMT " is named in both", parts[a].first, parts[b].first, v);
  PetscCall(CheckDetermined(comm, p));

  PetscCall(Expression::Create(comm, "-f", f, 1, p.f));
  PetscCall(Expression::Create(comm, "-g", g, 1, p.g));
  PetscCall(Expression::Create(comm, "-u_D", uD, 1, p.uD, Expression::At::Point));
  PetscCall(Expression::Create(comm, "-psi", psi, 1, p.psi, Expression::At::Point));
  PetscCall(Expression::Create(comm, "-kappa", kappa, 1, p.kappa));
  if (hasExact != hasGrad) SIGNORINI_INPUT_ERROR(comm, "options -exact_u and -exact_grad: give both or neither");
  if (hasExact) PetscCall(Expression::Create(comm, "-exact_u", ex, 1, p.exact));
  p.exactGradText = exg;
  PetscFunctionReturn(0);
}

PetscErrorCode ProblemSetUp(MPI_Comm comm, PetscInt dim, Problem &p)
{
  PetscFunctionBeginUser;
  PetscCall(CheckDetermined(comm, p));
  if (p.exact) PetscCall(Expression::Create(comm, "-exact_grad", p.exactGradText, (int)dim, p.exactGrad));
  PetscFunctionReturn(0);
}

std::string MissingPartMessage(const char *option, PetscInt value)
{
  return Format("option %s: boundary part %d does not exist on the mesh (no face carries that \"Face Sets\" value)", option, (int)value);
}

// Collective: the centroid x of mesh point `point` (-1: none on this rank) of the lowest rank that has one
// (x untouched where no rank has one), for a message that names one place.
static PetscErrorCode PointOfLowestRank(DM dm, PetscInt point, PetscReal x[3])
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)dm);
  PetscMPIInt rank, from;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  from = point >= 0 ? rank : PETSC_MPI_INT_MAX;
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &from, 1, MPI_INT, MPI_MIN, comm));
  if (from == PETSC_MPI_INT_MAX) PetscFunctionReturn(0);
  if (rank == from) PetscCall(DMPlexComputeCellGeometryFVM(dm, point, NULL, x, NULL));
  PetscCallMPI(MPI_Bcast(x, 3, MPIU_REAL, from, comm));
  PetscFunctionReturn(0);
}

// The faces of the domain's boundary in no named part, where kappa du/dn = 0 holds (the natural
// condition): right where it is meant (a symmetry plane), a silent wrong answer where a part was forgotten
// or mistyped, so the run says so. A face with one cell on this rank lies on the domain's boundary unless
// another rank holds its other cell, i.e. unless it is in the point SF (the mesh has no overlap).
static PetscErrorCode CountUnnamedBoundary(DM dm, const std::vector<char> &named, CoarseFindings &b)
{
  MPI_Comm           comm = PetscObjectComm((PetscObject)dm);
  PetscSF            sf;
  PetscInt           pStart, pEnd, fStart, fEnd, nroots, nleaves;
  const PetscInt    *leaves, *degree = nullptr;
  const PetscSFNode *remotes;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(dm, &pStart, &pEnd));
  PetscCall(DMPlexGetHeightStratum(dm, 1, &fStart, &fEnd));
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &leaves, &remotes));
  std::vector<char> shared(pEnd - pStart, 0);
  if (nroots >= 0) {
    for (PetscInt i = 0; i < nleaves; ++i) shared[(leaves ? leaves[i] : i) - pStart] = 1;
    PetscCall(PetscSFComputeDegreeBegin(sf, &degree));
    PetscCall(PetscSFComputeDegreeEnd(sf, &degree));
    for (PetscInt q = pStart; q < pEnd; ++q)
      if (degree[q - pStart] > 0) shared[q - pStart] = 1;
  }
  PetscInt counts[2] = {0, 0}, first = -1; // boundary faces, unnamed ones; the first unnamed face
  for (PetscInt f = fStart; f < fEnd; ++f) {
    PetscInt nsupp;
    PetscCall(DMPlexGetSupportSize(dm, f, &nsupp));
    if (nsupp != 1 || shared[f - pStart]) continue;
    ++counts[0];
    if (named[f - pStart]) continue;
    ++counts[1];
    if (first < 0) first = f;
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPIU_INT, MPI_SUM, comm));
  b.faces = counts[0], b.unnamed = counts[1];
  PetscCall(PointOfLowestRank(dm, first, b.example));
  PetscFunctionReturn(0);
}

// An expression of cell_set reads -1 in a cell of no "Cell Sets" value, and on a mesh without the label
// (a built-in box, a Gmsh file without physical surfaces or volumes) in every cell: kappa "cell_set == 1 ?
// 1 : 100" was 100 everywhere there, without a word. Refused where a cell of the coarse mesh has no value
// (refinement hands every cell's value to its children).
static PetscErrorCode CheckCellSets(DM dm, PetscInt dim, const Problem &p)
{
  MPI_Comm comm = PetscObjectComm((PetscObject)dm);
  DMLabel  cellSets;
  PetscInt cStart, cEnd;
  PetscFunctionBeginUser;
  const Expression *uses = nullptr;
  for (const Expression *e : {p.kappa.get(), p.f.get(), p.g.get(), p.exact.get(), p.exactGrad.get()})
    if (e && e->UsesCellSet() && !uses) uses = e;
  if (!uses) PetscFunctionReturn(0);
  PetscCall(DMGetLabel(dm, "Cell Sets", &cellSets));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscInt counts[2] = {cEnd - cStart, 0}, first = -1; // cells, those without a value
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscInt value = -1;
    if (cellSets) PetscCall(DMLabelGetValue(cellSets, c, &value));
    if (value != -1) continue;
    if (first < 0) first = c;
    ++counts[1];
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPIU_INT, MPI_SUM, comm));
  if (counts[1] == 0) PetscFunctionReturn(0);
  if (counts[1] == counts[0])
    SIGNORINI_INPUT_ERROR(comm, "option %s: '%s' uses cell_set, but no cell of the mesh is in a \"Cell Sets\" (a built-in box, or a Gmsh file without physical %s): cell_set would read -1 everywhere", uses->Option().c_str(), uses->Text().c_str(), dim == 2 ? "surfaces" : "volumes");
  PetscReal x[3] = {0, 0, 0};
  PetscCall(PointOfLowestRank(dm, first, x));
  SIGNORINI_INPUT_ERROR(comm, "option %s: '%s' uses cell_set, but %d of the %d cells of the coarse mesh %s in no \"Cell Sets\" (one near (%s)): cell_set would read -1 there", uses->Option().c_str(), uses->Text().c_str(), (int)counts[1], (int)counts[0], counts[1] == 1 ? "is" : "are", CoordinatesText(dim, x).c_str());
}

// The scene's parts determine u piece by piece: a domain in several pieces (cells joined through faces;
// pieces that touch at a vertex or an edge are apart, since such a point carries no trace in H^1) needs a
// Dirichlet or a contact face on each. A piece with neither was solved as a singular system and ended in
// a linear solver's failure that named neither. Pieces with contact but no Dirichlet face are counted for
// the assembly's check of their loads (CheckLoadTowardsObstacle).
static PetscErrorCode CheckPieces(DM dm, PetscInt dim, const std::vector<char> &kind, CoarseFindings &b)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)dm);
  PetscInt              pStart, pEnd, cStart, cEnd, count;
  PetscSF               sf;
  std::vector<PetscInt> component;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(dm, &pStart, &pEnd));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMGetPointSF(dm, &sf));
  ItemGraph graph; // items: the mesh points (faces in the lists); cells: the cones
  graph.numItems  = pEnd - pStart;
  graph.numCells  = cEnd - cStart;
  graph.per       = dim + 1;
  std::vector<PetscInt> cones((cEnd - cStart) * (dim + 1));
  for (PetscInt c = cStart; c < cEnd; ++c) {
    const PetscInt *cone;
    PetscCall(DMPlexGetCone(dm, c, &cone));
    for (PetscInt k = 0; k <= dim; ++k) cones[(c - cStart) * (dim + 1) + k] = cone[k] - pStart;
  }
  graph.cellItems   = [&](PetscInt c) { return &cones[c * (dim + 1)]; };
  graph.shareOwners = [&](std::vector<PetscInt> &v) {
    PetscInt nroots;
    PetscFunctionBeginUser;
    PetscCall(PetscSFGetGraph(sf, &nroots, NULL, NULL, NULL));
    if (nroots < 0) PetscFunctionReturn(0); // one rank: no shared points
    const std::vector<PetscInt> roots(v);
    PetscCall(PetscSFBcastBegin(sf, MPIU_INT, roots.data(), v.data(), MPI_REPLACE));
    PetscCall(PetscSFBcastEnd(sf, MPIU_INT, roots.data(), v.data(), MPI_REPLACE));
    PetscFunctionReturn(0);
  };
  PetscCall(ConnectedComponents(comm, graph, component, &count));
  b.pieces = count, b.contactOnly = 0;
  if (count <= 1) PetscFunctionReturn(0);
  // Per piece: whether it has Dirichlet (bit 1), contact (bit 2) and Neumann (bit 4) faces.
  std::vector<PetscInt> has(count, 0), cellPiece(cEnd - cStart);
  for (PetscInt q = 0; q < pEnd - pStart; ++q)
    if (component[q] >= 0 && kind[q]) has[component[q]] |= kind[q];
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, has.data(), (PetscMPIInt)count, MPIU_INT, MPI_BOR, comm));
  for (PetscInt c = 0; c < cEnd - cStart; ++c) cellPiece[c] = component[cones[c * (dim + 1)]];
  std::vector<std::array<PetscReal, 3>> lowest;
  std::vector<std::array<PetscReal, 3>> centroid(cEnd - cStart);
  for (PetscInt c = cStart; c < cEnd; ++c) PetscCall(DMPlexComputeCellGeometryFVM(dm, c, NULL, centroid[c - cStart].data(), NULL));
  PetscCall(LowestPoints(comm, dim, cEnd - cStart, cellPiece, count, [&](PetscInt c, PetscReal *x) { std::copy(centroid[c].begin(), centroid[c].end(), x); }, lowest));
  PetscInt floating = 0, first = -1;
  for (PetscInt k = 0; k < count; ++k) {
    if ((has[k] & 3) == 2) ++b.contactOnly;
    if ((has[k] & 3) != 0) continue;
    ++floating;
    if (first < 0 || lowest[k] < lowest[first]) first = k;
  }
  if (floating)
    SIGNORINI_INPUT_ERROR(comm, "options -bc_dirichlet/-bc_contact: the mesh is in %d pieces (cells joined through faces), and %d of them (one near (%s)) %s neither a Dirichlet nor a contact face, so u is not determined there (singular problem)", (int)count, (int)floating,
                          CoordinatesText(dim, lowest[first].data()).c_str(), floating == 1 ? "has" : "have");
  PetscFunctionReturn(0);
}

PetscErrorCode ProblemCheckMesh(DM dm, Problem &p)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)dm);
  PetscInt              dim, pStart, pEnd;
  DMLabel               faceSets;
  std::vector<PetscInt> faces;
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &dim));
  PetscCall(ProblemSetUp(comm, dim, p));
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  PetscCall(DMPlexGetChart(dm, &pStart, &pEnd));
  std::vector<char> named(pEnd - pStart, 0), kind(pEnd - pStart, 0); // kind: 1 Dirichlet, 2 contact, 4 Neumann
  const std::tuple<const char *, const std::vector<PetscInt> *, char> parts[] = {{"-bc_dirichlet", &p.dirichlet, 1}, {"-bc_neumann", &p.neumann, 4}, {"-bc_contact", &p.contact, 2}};
  for (const auto &[option, values, k] : parts)
    for (PetscInt value : *values) {
      PetscCall(LabelFaces(dm, faceSets, value, faces));
      for (PetscInt f : faces) named[f - pStart] = 1, kind[f - pStart] = k;
      PetscInt local = (PetscInt)faces.size(), global;
      PetscCallMPI(MPI_Allreduce(&local, &global, 1, MPIU_INT, MPI_SUM, comm));
      if (global == 0) SIGNORINI_INPUT_ERROR(comm, "%s", MissingPartMessage(option, value).c_str());
    }
  PetscCall(CheckCellSets(dm, dim, p));
  PetscCall(CheckPieces(dm, dim, kind, p.coverage));
  PetscCall(CheckExactSolution(dm, p, kind, &p.coverage.exactFailed));
  PetscCall(CountUnnamedBoundary(dm, named, p.coverage));
  const CoarseFindings &b = p.coverage;
  if (b.unnamed > 0)
    PetscCall(PetscPrintf(comm, "note: %d of the %d boundary faces of the coarse mesh %s in no part of -bc_dirichlet, -bc_neumann, -bc_contact (one near (%s)): kappa du/dn = 0 there\n", (int)b.unnamed, (int)b.faces, b.unnamed == 1 ? "is" : "are",
                          CoordinatesText(dim, b.example).c_str()));
  PetscFunctionReturn(0);
}

} // namespace signorini

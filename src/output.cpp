#include "signorini/output.h"
#include "signorini/contact.h"
#include "signorini/options.h"
#include "signorini/layout.h"
#include "signorini/mesh.h"
#include "signorini/stages.h"

#include <petscviewerhdf5.h>

#include <algorithm>
#include <sstream>

namespace signorini {

PetscErrorCode OutputOptionsFromCommandLine(MPI_Comm comm, Element element, const Problem &problem, OutputOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Output", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-output", "Write mesh and solution to FILE.h5 (HDF5) and XDMF 3 files for ParaView and meshio: FILE.xmf (the mesh), FILE-contact.xmf (Gamma_C: u, psi, pressure, active set), FILE-dofs.xmf (CR DOFs)", o.file));
  PetscOptionsEnd();
  o.contact = problem.HasContact();
  o.cr      = element == Element::CR;
  if (o.file.empty()) PetscFunctionReturn(0);
  if (o.file.size() < 4 || o.file.substr(o.file.size() - 3) != ".h5") SIGNORINI_INPUT_ERROR(comm, "option -output: '%s' must end in .h5", o.file.c_str());
  // XDMF names a dataset as FILE:PATH, and readers (meshio) split at the colon
  if (o.file.substr(o.file.find_last_of('/') + 1).find(':') != std::string::npos) SIGNORINI_INPUT_ERROR(comm, "option -output: '%s' has a ':' in its name, which XDMF readers take for the end of the file name", o.file.c_str());
  PetscCall(OutputClaim(comm, "-output", o));
  PetscFunctionReturn(0);
}

std::vector<std::string> OutputFiles(const OutputOptions &o)
{
  const std::string        stem = o.file.substr(0, o.file.size() - 3);
  std::vector<std::string> files{o.file, stem + ".xmf"};
  if (o.contact) files.push_back(stem + "-contact.xmf");
  if (o.cr) files.push_back(stem + "-dofs.xmf");
  return files;
}

PetscErrorCode OutputClaim(MPI_Comm comm, const std::string &option, const OutputOptions &o)
{
  PetscFunctionBeginUser;
  for (const std::string &f : OutputFiles(o)) PetscCall(FileClaim(comm, option, f));
  PetscFunctionReturn(0);
}

// A clone of the mesh with one DOF per cell (cells = true) or per vertex.
static PetscErrorCode PointFieldDM(DM mesh, bool cells, DM *dm)
{
  PetscSection s;
  PetscInt     pStart, pEnd, a, b;
  PetscFunctionBeginUser;
  PetscCall(DMClone(mesh, dm));
  PetscCall(PetscSectionCreate(PetscObjectComm((PetscObject)mesh), &s));
  PetscCall(PetscSectionSetNumFields(s, 1));
  PetscCall(PetscSectionSetFieldName(s, 0, "value"));
  PetscCall(DMPlexGetChart(*dm, &pStart, &pEnd));
  PetscCall(PetscSectionSetChart(s, pStart, pEnd));
  if (cells) PetscCall(DMPlexGetHeightStratum(*dm, 0, &a, &b));
  else PetscCall(DMPlexGetDepthStratum(*dm, 0, &a, &b));
  for (PetscInt p = a; p < b; ++p) {
    PetscCall(PetscSectionSetDof(s, p, 1));
    PetscCall(PetscSectionSetFieldDof(s, p, 0, 1));
  }
  PetscCall(PetscSectionSetUp(s));
  PetscCall(DMSetLocalSection(*dm, s));
  PetscCall(PetscSectionDestroy(&s));
  PetscFunctionReturn(0);
}

// Cell means and vertex averages of the cellwise linear function u_h (for P1 the vertex average is u_h),
// into vectors of the cell and vertex layouts, whose local entry of cell c and vertex v are c and v - vStart
// (checked by OutputBegin).
static PetscErrorCode DerivedFields(const Space &space, Vec u, DM cellDM, DM vertDM, Vec cellMean, Vec vertexAvg)
{
  Vec                uloc, vsum, vcnt, vsumG, vcntG, cloc;
  const PetscScalar *ua;
  PetscScalar       *cm, *vs, *vc;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &uloc));
  PetscCall(DMGlobalToLocal(space.dm, u, INSERT_VALUES, uloc));
  PetscCall(DMGetLocalVector(vertDM, &vsum));
  PetscCall(DMGetLocalVector(vertDM, &vcnt));
  PetscCall(VecSet(vsum, 0));
  PetscCall(VecSet(vcnt, 0));
  PetscCall(VecGetArrayRead(uloc, &ua));
  PetscCall(DMGetLocalVector(cellDM, &cloc));
  PetscCall(VecGetArray(cloc, &cm));
  PetscCall(VecGetArray(vsum, &vs));
  PetscCall(VecGetArray(vcnt, &vc));
  const PetscInt nb = space.Nb();
  for (PetscInt c = 0; c < space.NumCells(); ++c) {
    PetscReal centroid[4];
    for (PetscInt k = 0; k < nb; ++k) centroid[k] = 1.0 / nb;
    cm[c] = space.Value(c, ua, centroid);
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal lambda[4] = {0, 0, 0, 0};
      lambda[k]           = 1;
      const PetscInt off  = space.Vertex(c, k) - space.vStart;
      vs[off] += space.Value(c, ua, lambda);
      vc[off] += 1;
    }
  }
  PetscCall(VecRestoreArrayRead(uloc, &ua));
  PetscCall(VecRestoreArray(cloc, &cm));
  PetscCall(DMLocalToGlobal(cellDM, cloc, INSERT_VALUES, cellMean));
  PetscCall(DMRestoreLocalVector(cellDM, &cloc));
  PetscCall(VecRestoreArray(vsum, &vs));
  PetscCall(VecRestoreArray(vcnt, &vc));
  PetscCall(DMGetGlobalVector(vertDM, &vsumG));
  PetscCall(DMGetGlobalVector(vertDM, &vcntG));
  PetscCall(VecSet(vsumG, 0));
  PetscCall(VecSet(vcntG, 0));
  PetscCall(DMLocalToGlobal(vertDM, vsum, ADD_VALUES, vsumG));
  PetscCall(DMLocalToGlobal(vertDM, vcnt, ADD_VALUES, vcntG));
  PetscCall(VecPointwiseDivide(vertexAvg, vsumG, vcntG));
  PetscCall(DMRestoreGlobalVector(vertDM, &vsumG));
  PetscCall(DMRestoreGlobalVector(vertDM, &vcntG));
  PetscCall(DMRestoreLocalVector(space.dm, &uloc));
  PetscCall(DMRestoreLocalVector(vertDM, &vsum));
  PetscCall(DMRestoreLocalVector(vertDM, &vcnt));
  PetscFunctionReturn(0);
}

static std::string BaseName(const std::string &path)
{
  size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

static std::string XmlEscaped(const std::string &s)
{
  std::string e;
  for (char c : s) e += c == '&' ? "&amp;" : c == '<' ? "&lt;" : c == '>' ? "&gt;" : std::string(1, c);
  return e;
}

// One XDMF 3 file with one grid, its data in the HDF5 file `h5` (a name relative to the XDMF file).
class XdmfGrid {
public:
  XdmfGrid(const std::string &h5, const char *name) : h5_(h5) { x_ << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n  <Grid Name=\"" << name << "\" GridType=\"Uniform\">\n"; }
  // `type` is an XDMF topology type; the dataset holds `elements` x `corners` vertex numbers.
  void Topology(const char *type, PetscInt elements, PetscInt corners, const char *path)
  {
    x_ << "   <Topology TopologyType=\"" << type << "\" NumberOfElements=\"" << elements << "\" NodesPerElement=\"" << corners << "\">\n";
    Item(Format("%d %d", (int)elements, (int)corners), "Int", sizeof(PetscInt), path);
    x_ << "   </Topology>\n";
  }
  void Geometry(PetscInt points, PetscInt dim, const char *path)
  {
    x_ << "   <Geometry GeometryType=\"" << (dim == 2 ? "XY" : "XYZ") << "\">\n";
    Item(Format("%d %d", (int)points, (int)dim), "Float", 8, path);
    x_ << "   </Geometry>\n";
  }
  // A scalar per point (node) or per element (cell), a dataset of `n` values.
  void Attribute(const char *name, bool node, PetscInt n, const std::string &path)
  {
    x_ << "   <Attribute Name=\"" << name << "\" AttributeType=\"Scalar\" Center=\"" << (node ? "Node" : "Cell") << "\">\n";
    Item(Format("%d", (int)n), "Float", 8, path);
    x_ << "   </Attribute>\n";
  }
  std::string Text() const { return x_.str() + "  </Grid>\n </Domain>\n</Xdmf>\n"; }

private:
  void Item(const std::string &dims, const char *type, size_t precision, const std::string &path)
  {
    x_ << "    <DataItem Dimensions=\"" << dims << "\" DataType=\"" << type << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << XmlEscaped(h5_) << ":" << path << "</DataItem>\n";
  }
  std::string        h5_;
  std::ostringstream x_;
};

Output::~Output()
{
  DMDestroy(&cellLayout);
  DMDestroy(&vertLayout);
}

// The layout of a point field whose points [start, end) are contiguous and carry one DOF each: the local
// entry of point p is p - start, which DerivedFields relies on.
static PetscErrorCode PointFieldLayout(DM field, bool cells, DM *layout, PetscInt *global)
{
  PetscSection s;
  PetscInt     start, end, owned;
  PetscFunctionBeginUser;
  if (cells) PetscCall(DMPlexGetHeightStratum(field, 0, &start, &end));
  else PetscCall(DMPlexGetDepthStratum(field, 0, &start, &end));
  PetscCall(DMGetLocalSection(field, &s));
  PetscCall(LayoutCheckPointOrder(s, start, end));
  PetscCall(LayoutCreateFromDM(field, layout));
  PetscCall(DMGetGlobalSection(field, &s));
  PetscCall(PetscSectionGetConstrainedStorageSize(s, &owned));
  PetscCallMPI(MPI_Allreduce(&owned, global, 1, MPIU_INT, MPI_SUM, PetscObjectComm((PetscObject)field)));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputBegin(const Space &space, const OutputOptions &o, Output &out)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)space.dm);
  DM          cellDM, vertDM;
  PetscViewer viewer;
  PetscFunctionBeginUser;
  PetscCheck(space.mesh, comm, PETSC_ERR_ORDER, "the output needs the space's mesh, which was released");
  PetscCall(StagePush(Stage::Output));
  out.opts = o;
  out.dim  = space.dim;
  PetscCall(out.files.Add(comm, o.file, out.h5)); // removed by the FileSet unless OutputEnd commits it
  PetscCall(PointFieldDM(space.mesh, true, &cellDM));
  PetscCall(PointFieldDM(space.mesh, false, &vertDM));
  PetscCall(PetscViewerHDF5Open(comm, out.h5.c_str(), FILE_MODE_WRITE, &viewer));
  PetscCall(PetscViewerPushFormat(viewer, PETSC_VIEWER_HDF5_XDMF));
  PetscCall(DMView(vertDM, viewer)); // /geometry/vertices and /viz/topology/cells
  PetscCall(PetscViewerPopFormat(viewer));
  PetscCall(PetscViewerDestroy(&viewer));
  PetscCall(PointFieldLayout(cellDM, true, &out.cellLayout, &out.nc));
  PetscCall(PointFieldLayout(vertDM, false, &out.vertLayout, &out.nv));
  PetscCall(DMDestroy(&cellDM));
  PetscCall(DMDestroy(&vertDM));
  PetscCall(StagePop(Stage::Output));
  PetscFunctionReturn(0);
}

// Writes vector v into `group` of the open file, as a dataset named like v.
static PetscErrorCode ViewInGroup(PetscViewer viewer, const char *group, Vec v)
{
  PetscFunctionBeginUser;
  PetscCall(PetscViewerHDF5PushGroup(viewer, group));
  PetscCall(VecView(v, viewer));
  PetscCall(PetscViewerHDF5PopGroup(viewer));
  PetscFunctionReturn(0);
}

// Writes `values` (n per rank, in blocks of bs) into group/name: a dataset of (global n / bs) x bs reals,
// or of global n reals when bs = 1. Returns the global number of blocks.
static PetscErrorCode WriteReals(PetscViewer viewer, const char *group, const char *name, const std::vector<PetscReal> &values, PetscInt bs, PetscInt *blocks)
{
  MPI_Comm     comm = PetscObjectComm((PetscObject)viewer);
  Vec          v;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(VecCreate(comm, &v));
  PetscCall(VecSetSizes(v, (PetscInt)values.size(), PETSC_DECIDE));
  PetscCall(VecSetBlockSize(v, bs));
  PetscCall(VecSetType(v, VECSTANDARD));
  PetscCall(PetscObjectSetName((PetscObject)v, name));
  PetscCall(VecGetArray(v, &a));
  for (size_t i = 0; i < values.size(); ++i) a[i] = values[i];
  PetscCall(VecRestoreArray(v, &a));
  PetscCall(ViewInGroup(viewer, group, v));
  PetscCall(VecGetSize(v, blocks));
  *blocks /= bs;
  PetscCall(VecDestroy(&v));
  PetscFunctionReturn(0);
}

// Writes the topology of `n` local elements of `corners` points each whose points are numbered in order
// (element k of this rank has the points corners * (first + k) + j, first the elements of the lower ranks)
// into group/cells, as the integers an XDMF topology needs.
static PetscErrorCode WriteOwnPoints(PetscViewer viewer, const char *group, PetscInt n, PetscInt corners)
{
  MPI_Comm              comm = PetscObjectComm((PetscObject)viewer);
  PetscInt              first = 0, count = n * corners;
  IS                    is;
  std::vector<PetscInt> idx(count);
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Exscan(&count, &first, 1, MPIU_INT, MPI_SUM, comm));
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  if (rank == 0) first = 0; // MPI_Exscan leaves rank 0's result undefined
  for (PetscInt i = 0; i < count; ++i) idx[i] = first + i;
  PetscCall(ISCreateGeneral(comm, count, idx.data(), PETSC_COPY_VALUES, &is));
  PetscCall(ISSetBlockSize(is, corners));
  PetscCall(PetscObjectSetName((PetscObject)is, "cells"));
  PetscCall(PetscViewerHDF5PushGroup(viewer, group));
  PetscCall(ISView(is, viewer));
  PetscCall(PetscViewerHDF5PopGroup(viewer));
  PetscCall(ISDestroy(&is));
  PetscFunctionReturn(0);
}

// The local values of global vector g at the local DOFs.
static PetscErrorCode LocalValues(const Space &space, Vec g, std::vector<PetscReal> &values)
{
  Vec                loc;
  const PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(space.dm, &loc));
  PetscCall(DMGlobalToLocal(space.dm, g, INSERT_VALUES, loc));
  PetscCall(VecGetArrayRead(loc, &a));
  values.resize(space.numLocal);
  for (PetscInt i = 0; i < space.numLocal; ++i) values[i] = PetscRealPart(a[i]);
  PetscCall(VecRestoreArrayRead(loc, &a));
  PetscCall(DMRestoreLocalVector(space.dm, &loc));
  PetscFunctionReturn(0);
}

static const char *const kContactFields[] = {"u", "psi", "pressure", "active"};

// Gamma_C as a grid of its own: every contact face (on the rank of its cell) with its own copies of its
// vertices, into /contact: vertices, cells, and u, psi, pressure, active at the contact DOFs (per face
// vertex for P1, per face for CR). Returns the global numbers of faces and of points.
static PetscErrorCode WriteContactGrid(const Space &space, const Problem &problem, const System &sys, Vec u, PetscViewer viewer, PetscInt *faces, PetscInt *points)
{
  Vec                    g[4];
  std::vector<PetscReal> local[4], X, values[4];
  PetscInt               n = 0, dummy;
  PetscFunctionBeginUser;
  g[0] = u;
  for (int k = 1; k < 4; ++k) PetscCall(VecDuplicate(u, &g[k]));
  PetscCall(ContactFields(space, problem, sys, u, g[1], g[2], g[3]));
  for (int k = 0; k < 4; ++k) PetscCall(LocalValues(space, g[k], local[k]));
  for (int k = 1; k < 4; ++k) PetscCall(VecDestroy(&g[k]));
  for (const BoundaryFace &bf : space.boundary) {
    if (std::find(problem.contact.begin(), problem.contact.end(), bf.part) == problem.contact.end()) continue;
    ++n;
    for (PetscInt i = 0; i < space.Nb(); ++i) {
      if (i == bf.opposite) continue;
      const PetscInt v = space.cellVert[bf.cell * space.Nb() + i];
      for (PetscInt d = 0; d < space.dim; ++d) X.push_back(space.vertX[v * space.dim + d]);
      if (space.element == Element::P1)
        for (int k = 0; k < 4; ++k) values[k].push_back(local[k][space.Dofs(bf.cell)[i]]);
    }
    if (space.element == Element::CR)
      for (int k = 0; k < 4; ++k) values[k].push_back(local[k][bf.dof]);
  }
  PetscCall(WriteReals(viewer, "/contact", "vertices", X, space.dim, points));
  PetscCall(WriteOwnPoints(viewer, "/contact", n, space.dim));
  for (int k = 0; k < 4; ++k) PetscCall(WriteReals(viewer, "/contact", kContactFields[k], values[k], 1, &dummy));
  *faces = *points / space.dim;
  PetscFunctionReturn(0);
}

// The CR DOFs as points (face midpoints), into /dofs: points, cells; their values are /fields/u.
static PetscErrorCode WriteDofGrid(const Space &space, Vec u, PetscViewer viewer, PetscInt *n)
{
  Vec                    xg;
  std::vector<PetscReal> X(space.numOwned * space.dim), component;
  PetscFunctionBeginUser;
  const std::vector<PetscReal> points = DofPoints(space);
  PetscCall(VecDuplicate(u, &xg));
  for (PetscInt d = 0; d < space.dim; ++d) { // owned entries of a global vector: the DOFs in their global order
    Vec          loc;
    PetscScalar *a;
    PetscCall(DMGetLocalVector(space.dm, &loc));
    PetscCall(VecGetArray(loc, &a));
    for (PetscInt i = 0; i < space.numLocal; ++i) a[i] = points[i * space.dim + d];
    PetscCall(VecRestoreArray(loc, &a));
    PetscCall(DMLocalToGlobal(space.dm, loc, INSERT_VALUES, xg));
    PetscCall(DMRestoreLocalVector(space.dm, &loc));
    PetscCall(VecGetArray(xg, &a));
    for (PetscInt i = 0; i < space.numOwned; ++i) X[i * space.dim + d] = PetscRealPart(a[i]);
    PetscCall(VecRestoreArray(xg, &a));
  }
  PetscCall(VecDestroy(&xg));
  PetscCall(WriteReals(viewer, "/dofs", "points", X, space.dim, n));
  PetscCall(WriteOwnPoints(viewer, "/dofs", space.numOwned, 1));
  PetscFunctionReturn(0);
}

// The XDMF files of OutputFiles, after FILE.h5, as text.
static std::vector<std::string> XdmfFiles(const Output &out, PetscInt contactFaces, PetscInt contactPoints, PetscInt dofs, bool p1, bool eta)
{
  const std::string        h5 = BaseName(out.opts.file);
  std::vector<std::string> text;
  XdmfGrid                 mesh(h5, "mesh");
  mesh.Topology(out.dim == 2 ? "Triangle" : "Tetrahedron", out.nc, out.dim + 1, "/viz/topology/cells");
  mesh.Geometry(out.nv, out.dim, "/geometry/vertices");
  mesh.Attribute("u_h (vertex)", true, out.nv, "/vertex_fields/u_vertex_value");
  mesh.Attribute("u_h (cell mean)", false, out.nc, "/cell_fields/u_cell_value");
  if (eta) mesh.Attribute("eta", false, out.nc, "/cell_fields/eta");
  text.push_back(mesh.Text());
  if (out.opts.contact) {
    XdmfGrid contact(h5, "Gamma_C");
    contact.Topology(out.dim == 2 ? "Polyline" : "Triangle", contactFaces, out.dim, "/contact/cells");
    contact.Geometry(contactPoints, out.dim, "/contact/vertices");
    const char *names[] = {"u_h", "psi", "pressure", "active"};
    for (int k = 0; k < 4; ++k) contact.Attribute(names[k], p1, p1 ? contactPoints : contactFaces, std::string("/contact/") + kContactFields[k]);
    text.push_back(contact.Text());
  }
  if (out.opts.cr) {
    XdmfGrid grid(h5, "CR DOFs");
    grid.Topology("Polyvertex", dofs, 1, "/dofs/cells");
    grid.Geometry(dofs, out.dim, "/dofs/points");
    grid.Attribute("u_h", true, dofs, "/fields/u");
    text.push_back(grid.Text());
  }
  return text;
}

// The indicators eta_T = sqrt(cellEta2) as a vector of the cell layout (local entry of cell c: c).
static PetscErrorCode IndicatorField(const std::vector<PetscReal> &cellEta2, DM cellLayout, Vec eta)
{
  Vec          loc;
  PetscScalar *a;
  PetscFunctionBeginUser;
  PetscCall(DMGetLocalVector(cellLayout, &loc));
  PetscCall(VecGetArray(loc, &a));
  for (size_t c = 0; c < cellEta2.size(); ++c) a[c] = std::sqrt(cellEta2[c]);
  PetscCall(VecRestoreArray(loc, &a));
  PetscCall(DMLocalToGlobal(cellLayout, loc, INSERT_VALUES, eta));
  PetscCall(DMRestoreLocalVector(cellLayout, &loc));
  PetscFunctionReturn(0);
}

PetscErrorCode OutputEnd(const Space &space, const Problem &problem, const System &sys, Vec u, Output &out, const std::vector<PetscReal> &cellEta2)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)space.dm);
  Vec         cellMean, vertexAvg;
  PetscViewer viewer;
  PetscInt    contactFaces = 0, contactPoints = 0, dofs = 0;
  PetscFunctionBeginUser;
  PetscCheck(!out.h5.empty(), comm, PETSC_ERR_ORDER, "OutputEnd without OutputBegin");
  PetscCall(StagePush(Stage::Output));
  PetscCall(DMCreateGlobalVector(out.cellLayout, &cellMean));
  PetscCall(DMCreateGlobalVector(out.vertLayout, &vertexAvg));
  PetscCall(PetscObjectSetName((PetscObject)cellMean, "u_cell_value")); // the names the XDMF file refers to
  PetscCall(PetscObjectSetName((PetscObject)vertexAvg, "u_vertex_value"));
  PetscCall(DerivedFields(space, u, out.cellLayout, out.vertLayout, cellMean, vertexAvg));
  PetscCall(PetscViewerHDF5Open(comm, out.h5.c_str(), FILE_MODE_APPEND, &viewer));
  PetscCall(ViewInGroup(viewer, "/vertex_fields", vertexAvg));
  PetscCall(ViewInGroup(viewer, "/cell_fields", cellMean));
  const bool eta = !cellEta2.empty() || space.NumCells() == 0; // a rank without cells has an estimate too
  PetscBool  anyEta, etaAll = eta ? PETSC_TRUE : PETSC_FALSE;
  PetscCallMPI(MPI_Allreduce(&etaAll, &anyEta, 1, MPIU_BOOL, MPI_LAND, comm));
  if (anyEta) {
    Vec field;
    PetscCall(DMCreateGlobalVector(out.cellLayout, &field));
    PetscCall(PetscObjectSetName((PetscObject)field, "eta"));
    PetscCall(IndicatorField(cellEta2, out.cellLayout, field));
    PetscCall(ViewInGroup(viewer, "/cell_fields", field));
    PetscCall(VecDestroy(&field));
  }
  PetscCall(ViewInGroup(viewer, "/fields", u)); // the raw DOF vector (faces for CR, vertices for P1)
  if (out.opts.contact) PetscCall(WriteContactGrid(space, problem, sys, u, viewer, &contactFaces, &contactPoints));
  if (out.opts.cr) PetscCall(WriteDofGrid(space, u, viewer, &dofs));
  PetscCall(PetscViewerDestroy(&viewer));
  PetscCall(VecDestroy(&cellMean));
  PetscCall(VecDestroy(&vertexAvg));

  const std::vector<std::string> names = OutputFiles(out.opts), text = XdmfFiles(out, contactFaces, contactPoints, dofs, space.element == Element::P1, anyEta);
  for (size_t i = 0; i < text.size(); ++i) PetscCall(out.files.AddText(comm, names[i + 1], text[i]));
  PetscCall(out.files.Commit(comm)); // FILE.h5 and its XDMF files together
  out.h5.clear();
  PetscCall(StagePop(Stage::Output));
  PetscFunctionReturn(0);
}

PetscErrorCode WriteSolution(const Space &space, const Problem &problem, const System &sys, Vec u, const OutputOptions &o)
{
  Output out;
  PetscFunctionBeginUser;
  PetscCall(OutputBegin(space, o, out));
  PetscCall(OutputEnd(space, problem, sys, u, out));
  PetscFunctionReturn(0);
}

} // namespace signorini

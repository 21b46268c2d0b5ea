#include "signorini/output.h"
#include "signorini/options.h"
#include "signorini/layout.h"
#include "signorini/mesh.h"
#include "signorini/report.h"
#include "signorini/stages.h"

#include <petscviewerhdf5.h>

#include <cstdio>
#include <sstream>

namespace signorini {

PetscErrorCode OutputOptionsFromCommandLine(MPI_Comm comm, OutputOptions &o)
{
  PetscFunctionBeginUser;
  PetscOptionsBegin(comm, "", "Output", "signorini");
  PetscCall(OptionString(PetscOptionsObject, "-output", "Write mesh and solution to FILE.h5 (HDF5) and FILE.xmf (XDMF for ParaView)", o.file));
  PetscOptionsEnd();
  if (!o.file.empty() && (o.file.size() < 4 || o.file.substr(o.file.size() - 3) != ".h5")) SIGNORINI_INPUT_ERROR(comm, "option -output: '%s' must end in .h5", o.file.c_str());
  if (!o.file.empty()) PetscCall(CheckWritable(comm, "-output", o.file));
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
    PetscReal centroid[4], mean = 0;
    for (PetscInt k = 0; k < nb; ++k) centroid[k] = 1.0 / nb;
    for (PetscInt i = 0; i < nb; ++i) mean += PetscRealPart(ua[space.Dofs(c)[i]]) * space.BasisValue(c, i, centroid);
    cm[c] = mean;
    for (PetscInt k = 0; k < nb; ++k) {
      PetscReal lambda[4] = {0, 0, 0, 0}, val = 0;
      lambda[k]           = 1;
      for (PetscInt i = 0; i < nb; ++i) val += PetscRealPart(ua[space.Dofs(c)[i]]) * space.BasisValue(c, i, lambda);
      const PetscInt off = space.Vertex(c, k) - space.vStart;
      vs[off] += val;
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

static std::string Xdmf(const std::string &h5, PetscInt dim, PetscInt nv, PetscInt nc, const char *vertexName, const char *cellName)
{
  std::ostringstream x;
  x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"2.0\">\n <Domain>\n  <Grid Name=\"signorini\" GridType=\"Uniform\">\n";
  x << "   <Topology TopologyType=\"" << (dim == 2 ? "Triangle" : "Tetrahedron") << "\" NumberOfElements=\"" << nc << "\">\n";
  x << "    <DataItem Dimensions=\"" << nc << " " << dim + 1 << "\" NumberType=\"Int\" Format=\"HDF\">" << h5 << ":/viz/topology/cells</DataItem>\n   </Topology>\n";
  x << "   <Geometry GeometryType=\"" << (dim == 2 ? "XY" : "XYZ") << "\">\n";
  x << "    <DataItem Dimensions=\"" << nv << " " << dim << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/geometry/vertices</DataItem>\n   </Geometry>\n";
  x << "   <Attribute Name=\"u_h (vertex)\" AttributeType=\"Scalar\" Center=\"Node\">\n";
  x << "    <DataItem Dimensions=\"" << nv << " 1\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/vertex_fields/" << vertexName << "</DataItem>\n   </Attribute>\n";
  x << "   <Attribute Name=\"u_h (cell mean)\" AttributeType=\"Scalar\" Center=\"Cell\">\n";
  x << "    <DataItem Dimensions=\"" << nc << " 1\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/cell_fields/" << cellName << "</DataItem>\n   </Attribute>\n";
  x << "  </Grid>\n </Domain>\n</Xdmf>\n";
  return x.str();
}

Output::~Output()
{
  // A run that ended between OutputBegin and OutputEnd leaves no half-written file behind.
  if (pending && rank == 0) std::remove((opts.file + ".tmp").c_str());
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
  PetscCallMPI(MPI_Comm_rank(comm, &out.rank));
  out.opts    = o;
  out.dim     = space.dim;
  out.pending = true; // from here on the destructor removes FILE.h5.tmp unless OutputEnd renamed it
  PetscCall(PointFieldDM(space.mesh, true, &cellDM));
  PetscCall(PointFieldDM(space.mesh, false, &vertDM));
  PetscCall(PetscViewerHDF5Open(comm, (o.file + ".tmp").c_str(), FILE_MODE_WRITE, &viewer));
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

PetscErrorCode OutputEnd(const Space &space, Vec u, Output &out)
{
  MPI_Comm    comm = PetscObjectComm((PetscObject)space.dm);
  Vec         cellMean, vertexAvg;
  PetscViewer viewer;
  std::string problem;
  PetscFunctionBeginUser;
  PetscCheck(out.pending, comm, PETSC_ERR_ORDER, "OutputEnd without OutputBegin");
  PetscCall(StagePush(Stage::Output));
  PetscCall(DMCreateGlobalVector(out.cellLayout, &cellMean));
  PetscCall(DMCreateGlobalVector(out.vertLayout, &vertexAvg));
  PetscCall(PetscObjectSetName((PetscObject)cellMean, "u_cell_value")); // the names the XDMF file refers to
  PetscCall(PetscObjectSetName((PetscObject)vertexAvg, "u_vertex_value"));
  PetscCall(DerivedFields(space, u, out.cellLayout, out.vertLayout, cellMean, vertexAvg));
  const std::string tmp = out.opts.file + ".tmp";
  PetscCall(PetscViewerHDF5Open(comm, tmp.c_str(), FILE_MODE_APPEND, &viewer));
  PetscCall(ViewInGroup(viewer, "/vertex_fields", vertexAvg));
  PetscCall(ViewInGroup(viewer, "/cell_fields", cellMean));
  PetscCall(ViewInGroup(viewer, "/fields", u)); // the raw DOF vector (faces for CR, vertices for P1)
  PetscCall(PetscViewerDestroy(&viewer));
  PetscCall(VecDestroy(&cellMean));
  PetscCall(VecDestroy(&vertexAvg));

  if (out.rank == 0 && std::rename(tmp.c_str(), out.opts.file.c_str()) != 0) problem = Format("option -output: renaming '%s' failed", tmp.c_str());
  PetscCall(CheckAll(comm, problem.empty(), problem));
  out.pending         = false;
  const std::string h5 = out.opts.file, xmf = h5.substr(0, h5.size() - 3) + ".xmf";
  PetscCall(WriteFileAtomically(comm, xmf, Xdmf(BaseName(h5), out.dim, out.nv, out.nc, "u_vertex_value", "u_cell_value")));
  PetscCall(StagePop(Stage::Output));
  PetscFunctionReturn(0);
}

PetscErrorCode WriteSolution(const Space &space, Vec u, const OutputOptions &o)
{
  Output out;
  PetscFunctionBeginUser;
  PetscCall(OutputBegin(space, o, out));
  PetscCall(OutputEnd(space, u, out));
  PetscFunctionReturn(0);
}

} // namespace signorini

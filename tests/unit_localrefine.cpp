// Unit tests of the refinement of marked triangles (RefineMarkedSBR), three adaptive steps driven by a
// synthetic indicator (cell area over the squared distance to a point) and Doerfler marking, on the
// distributed mesh and, as the independent computation, on the same mesh held whole by each rank
// (PETSC_COMM_SELF). At every step the distributed mesh must
//   - pass PETSc's consistency checks (symmetry, skeleton, faces, geometry, point star forest, interface cones);
//   - be the serial mesh: the same number of cells, area, cell centroids and areas, boundary length per
//     "Face Sets" value and area per "Cell Sets" value;
//   - keep the invariants of a refinement: the coarse mesh's area, boundary lengths and Cell Sets areas;
//   - give a parent map under which every fine cell lies inside its parent, every marked cell has at
//     least two children and some cell only one (the refinement is local).
// Runs on 1 and 2 ranks (ctest).
#include "signorini/localrefine.h"
#include "signorini/mark.h"
#include "signorini/mesh.h"
#include "unit_check.h"

#include <algorithm>

using namespace signorini;

constexpr PetscInt kValues = 16; // label values looked at: 0 .. kValues - 1

struct Figures {
  PetscInt                          cells = 0;
  double                            area  = 0;
  std::vector<double>               faceLength, cellSetArea; // per label value
  std::vector<std::array<double, 3>> centroids;              // all ranks', sorted, rounded to 1e-12
};

static PetscErrorCode IsLeaf(DM dm, std::vector<char> &leaf)
{
  PetscSF         sf;
  PetscInt        pStart, pEnd, nroots, nleaves;
  const PetscInt *ilocal;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetChart(dm, &pStart, &pEnd));
  leaf.assign(pEnd, 0);
  PetscCall(DMGetPointSF(dm, &sf));
  PetscCall(PetscSFGetGraph(sf, &nroots, &nleaves, &ilocal, NULL));
  for (PetscInt l = 0; nroots >= 0 && l < nleaves; ++l) leaf[ilocal ? ilocal[l] : l] = 1;
  PetscFunctionReturn(0);
}

static PetscErrorCode ComputeFigures(DM dm, Figures &f)
{
  MPI_Comm          comm = PetscObjectComm((PetscObject)dm);
  PetscInt          cStart, cEnd;
  DMLabel           faceSets, cellSets;
  std::vector<char> leaf;
  PetscFunctionBeginUser;
  PetscCall(IsLeaf(dm, leaf));
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  PetscCall(DMGetLabel(dm, "Face Sets", &faceSets));
  PetscCall(DMGetLabel(dm, "Cell Sets", &cellSets));
  f.faceLength.assign(kValues, 0);
  f.cellSetArea.assign(kValues, 0);
  std::vector<double> mine; // x, y, area per cell
  double              area = 0;
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscReal vol, x[3];
    PetscInt  v = -1;
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, x, NULL));
    const auto r = [](PetscReal a) { return std::round(a * 1e12) / 1e12; };
    mine.insert(mine.end(), {r(x[0]), r(x[1]), r(vol)});
    area += vol;
    if (cellSets) PetscCall(DMLabelGetValue(cellSets, c, &v));
    if (v >= 0 && v < kValues) f.cellSetArea[v] += vol;
  }
  for (PetscInt v = 0; v < kValues; ++v) {
    std::vector<PetscInt> faces;
    PetscCall(LabelFaces(dm, faceSets, v, faces));
    for (PetscInt face : faces) {
      PetscReal len;
      PetscCall(DMPlexComputeCellGeometryFVM(dm, face, &len, NULL, NULL));
      if (!leaf[face]) f.faceLength[v] += len; // each shared face once, by its owner
    }
  }
  PetscInt n = cEnd - cStart;
  PetscCallMPI(MPI_Allreduce(&n, &f.cells, 1, MPIU_INT, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(&area, &f.area, 1, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, f.faceLength.data(), kValues, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, f.cellSetArea.data(), kValues, MPI_DOUBLE, MPI_SUM, comm));
  // The test gathers the cell list (the code under test never does).
  PetscMPIInt size, count = (PetscMPIInt)mine.size();
  PetscCallMPI(MPI_Comm_size(comm, &size));
  std::vector<PetscMPIInt> counts(size), displs(size, 0);
  PetscCallMPI(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (PetscMPIInt p = 1; p < size; ++p) displs[p] = displs[p - 1] + counts[p - 1];
  std::vector<double> all(displs[size - 1] + counts[size - 1]);
  PetscCallMPI(MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, comm));
  f.centroids.clear();
  for (size_t i = 0; i < all.size(); i += 3) f.centroids.push_back({all[i], all[i + 1], all[i + 2]});
  std::sort(f.centroids.begin(), f.centroids.end());
  PetscFunctionReturn(0);
}

static double MaxDiff(const std::vector<double> &a, const std::vector<double> &b)
{
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

// Synthetic squared indicators: cell area over the squared distance of its centroid to x0 (a point
// singularity), then Doerfler marking.
static PetscErrorCode Mark(DM dm, const double x0[2], std::vector<char> &marked)
{
  PetscInt cStart, cEnd;
  PetscFunctionBeginUser;
  PetscCall(DMPlexGetHeightStratum(dm, 0, &cStart, &cEnd));
  std::vector<PetscReal> eta2;
  for (PetscInt c = cStart; c < cEnd; ++c) {
    PetscReal vol, x[3];
    PetscCall(DMPlexComputeCellGeometryFVM(dm, c, &vol, x, NULL));
    eta2.push_back(vol / ((x[0] - x0[0]) * (x[0] - x0[0]) + (x[1] - x0[1]) * (x[1] - x0[1])));
  }
  PetscCall(MarkDoerfler(PetscObjectComm((PetscObject)dm), eta2, 0.5, marked));
  PetscFunctionReturn(0);
}

static PetscErrorCode TestCase(unit::Checker &ck, const std::string &name, const MeshOptions &o, const double x0[2])
{
  DM      par, ser;
  MeshInfo info;
  Figures  coarse, fp, fs;
  PetscFunctionBeginUser;
  PetscCall(MeshCreate(PETSC_COMM_WORLD, o, &par, info));
  PetscCall(MeshCreate(PETSC_COMM_SELF, o, &ser, info));
  PetscCall(ComputeFigures(par, coarse));
  for (PetscInt step = 1; step <= 3; ++step) {
    const std::string     tag = name + Format(" step %d", (int)step);
    std::vector<char>     mp, ms;
    std::vector<PetscInt> parent, parentSer;
    DM                    fine, fineSer;
    PetscCall(Mark(par, x0, mp));
    PetscCall(Mark(ser, x0, ms));
    PetscCall(RefineMarkedSBR(par, mp, &fine, &parent));
    PetscCall(RefineMarkedSBR(ser, ms, &fineSer, &parentSer));

    PetscCall(unit::CheckPlex(fine));
    ck.Check(true, tag + " passes DMPlexCheckSymmetry/Skeleton/Faces/Geometry/PointSF/InterfaceCones");

    double outside;
    PetscCall(unit::ParentOutside(par, fine, parent, &outside));
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &outside, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD));
    ck.Check(outside < 1e-12, tag + " every fine cell's centroid lies in its parent", "barycentric coordinate %g", -outside);
    std::vector<PetscInt> children(mp.size(), 0);
    for (PetscInt p : parent) ++children[p];
    PetscInt counts[3] = {0, 0, 0}; // marked cells with fewer than two children, cells with one child, marked cells
    for (size_t c = 0; c < mp.size(); ++c) counts[0] += mp[c] && children[c] < 2, counts[1] += children[c] == 1, counts[2] += mp[c];
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 3, MPIU_INT, MPI_SUM, PETSC_COMM_WORLD));
    ck.Check(counts[2] > 0 && counts[0] == 0 && counts[1] > 0, tag + " marked cells are refined, others stay", "%d marked, %d of them unrefined, %d cells with one child", (int)counts[2], (int)counts[0], (int)counts[1]);

    PetscCall(ComputeFigures(fine, fp));
    PetscCall(ComputeFigures(fineSer, fs));
    double centroidDiff = fp.centroids.size() == fs.centroids.size() ? 0 : 1e300;
    for (size_t i = 0; centroidDiff < 1e300 && i < fp.centroids.size(); ++i)
      for (int d = 0; d < 3; ++d) centroidDiff = std::max(centroidDiff, std::fabs(fp.centroids[i][d] - fs.centroids[i][d]));
    ck.Check(fp.cells == fs.cells && centroidDiff < 1e-11, tag + Format(" the same mesh as on one rank (%d cells, centroids and areas)", (int)fs.cells), "%d cells, %d on one rank, centroid difference %g", (int)fp.cells, (int)fs.cells, centroidDiff);
    ck.Check(std::fabs(fp.area - fs.area) < 1e-12 && MaxDiff(fp.faceLength, fs.faceLength) < 1e-12 && MaxDiff(fp.cellSetArea, fs.cellSetArea) < 1e-12, tag + " area, Face Sets lengths, Cell Sets areas as on one rank");
    ck.Check(std::fabs(fp.area - coarse.area) < 1e-12 && MaxDiff(fp.faceLength, coarse.faceLength) < 1e-12 && MaxDiff(fp.cellSetArea, coarse.cellSetArea) < 1e-12, tag + " labels kept: area, Face Sets lengths, Cell Sets areas of the coarse mesh", "area %g vs %g, lengths differ by %g, Cell Sets areas by %g", fp.area, coarse.area, MaxDiff(fp.faceLength, coarse.faceLength), MaxDiff(fp.cellSetArea, coarse.cellSetArea));
    PetscCall(DMDestroy(&par));
    PetscCall(DMDestroy(&ser));
    par = fine, ser = fineSer;
  }
  PetscCall(DMDestroy(&par));
  PetscCall(DMDestroy(&ser));
  PetscFunctionReturn(0);
}

int main(int argc, char **argv)
{
  PetscCall(PetscInitialize(&argc, &argv, NULL, NULL));
  unit::Checker ck;
  {
    MeshOptions o;
    o.faces[0] = 8, o.faces[1] = 6, o.diagonal = Diagonal::Crossed;
    const double x0[2] = {0.3, 0.0};
    PetscErrorCode ierr = TestCase(ck, "box 8x6 crossed", o, x0);
    if (ierr) ck.PetscFailure(ierr, "box");
  }
  {
    MeshOptions o;
    o.file             = std::string(SIGNORINI_TEST_DATA) + "/square.msh";
    const double x0[2] = {0.5, 0.5};
    PetscErrorCode ierr = TestCase(ck, "gmsh square with Cell Sets", o, x0);
    if (ierr) ck.PetscFailure(ierr, "gmsh");
  }
  const int status = ck.Finish();
  PetscCall(PetscFinalize());
  return status;
}

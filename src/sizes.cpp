#include "signorini/sizes.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace signorini {

namespace {

// The memory model: peak resident bytes of one rank = kFixedBytes + bytes per DOF x its DOFs (+ for a
// study, which keeps every mesh level alive, kMeshBytesPerPoint x the points of its levels). Calibrated
// on the 2-core development VM (1 rank, peak RSS from /usr/bin/time -v and run/bench):
// - kFixedBytes: a run with 208 DOFs (paper-5.1 -box_faces 8) peaks at 47.7 MB: MPI, PETSc, hypre.
// - bytes per DOF: README's run/bench table at the largest sizes (peak RSS / DOFs, nested iteration on):
//   2D P1 763 / 737 (1.05 M / 4.2 M DOFs), 2D CR 581 / 570 (3.1 M / 12.6 M), 3D P1 1958 (0.91 M),
//   3D CR 600 / 582 (1.3 M / 10.7 M); rounded up. Checked against (peak - kFixedBytes) / DOFs of runs of
//   this build: 2D CR 787 456 DOFs 547, 2D P1 263 169 DOFs 707, 3D P1 117 649 DOFs 1808, 3D CR 169 344
//   DOFs 549 B per DOF.
// - kMeshBytesPerPoint: the DMPlex of a refined level (cones, supports, orientations, their sections,
//   coordinates, labels). A study keeps its meshes: paper-5.1-3d CR -box_faces 16 -study_levels 1
//   -reference_refine 1 (CR reference) peaked 62 MB above the single run on the same finest mesh
//   (-box_faces 32, 284 MB), with 0.96 M points in its two levels: 64 B per point; rounded up.
// - 64-bit PetscInt makes every index twice as wide: 2D CR 787 456 DOFs 659 instead of 547 B per DOF,
//   3D CR 399 360 DOFs 309.6 instead of 284.4 MB (build64, issue 16): a factor 1.2.
constexpr double kFixedBytes        = 50e6;
constexpr double kMeshBytesPerPoint = 80;
constexpr double kIndexWidthFactor  = sizeof(PetscInt) == 8 ? 1.2 : 1.0;
double           BytesPerDof(PetscInt dim, Element e)
{
  const double bytes = dim == 2 ? (e == Element::P1 ? 780 : 600) : (e == Element::P1 ? 2000 : 610);
  return kIndexWidthFactor * bytes;
}

// Physical memory of this node, or less where a control group limits this process; -memory_limit instead
// where given.
double NodeMemory(double limitGB)
{
  if (limitGB > 0) return limitGB * 1e9;
  double bytes = (double)sysconf(_SC_PHYS_PAGES) * (double)sysconf(_SC_PAGE_SIZE);
  for (const char *file : {"/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"}) {
    if (FILE *fp = std::fopen(file, "r")) {
      double limit;
      if (std::fscanf(fp, "%lf", &limit) == 1 && limit > 0) bytes = std::min(bytes, limit); // "max": no limit
      std::fclose(fp);
    }
  }
  return bytes;
}

std::string GB(double bytes) { return Format("%.3g GB", bytes / 1e9); }

// The options that set the size, as the user gave them.
std::string Asked(const MeshOptions &o, const StudyOptions &study)
{
  std::string s = (o.file.empty() ? BoxName(o) : "mesh file '" + o.file + "'") + Format(" with -refine %d", (int)(o.refine - o.coarsened));
  if (study.levels > 0) s += Format(" -study_levels %d", (int)study.levels);
  if (study.levels > 0 && study.referenceRefine > 0) s += Format(" -reference_refine %d", (int)study.referenceRefine);
  return s;
}

} // namespace

MeshCounts BoxCounts(const MeshOptions &o)
{
  MeshCounts     m;
  const double   N = o.faces[0], M = o.faces[1], L = o.dim == 3 ? o.faces[2] : 0;
  m.dim          = o.dim;
  if (o.dim == 2) {
    const double squares = N * M, grid = N * (M + 1) + (N + 1) * M; // vertices and edges of the grid
    const bool   crossed = o.diagonal == Diagonal::Crossed;
    m.v                  = (N + 1) * (M + 1) + (crossed ? squares : 0);
    m.e                  = grid + (crossed ? 4 : 1) * squares;
    m.c                  = (crossed ? 4 : 2) * squares;
  } else {
    const double cubes = N * M * L;
    m.v                = (N + 1) * (M + 1) * (L + 1);
    // grid edges, one diagonal per square of the grid, one per cube
    m.e = N * (M + 1) * (L + 1) + (N + 1) * M * (L + 1) + (N + 1) * (M + 1) * L + N * M * (L + 1) + N * (M + 1) * L + (N + 1) * M * L + cubes;
    m.c = 6 * cubes;
    m.f = 1 - m.v + m.e + m.c; // Euler: V - E + F - C = 1 for a ball
  }
  return m;
}

PetscErrorCode CountMesh(DM dm, MeshCounts &m)
{
  PetscInt depth, range[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
  double   local[4] = {0, 0, 0, 0}, global[4];
  PetscFunctionBeginUser;
  PetscCall(DMGetDimension(dm, &m.dim));
  PetscCall(DMPlexGetDepth(dm, &depth));
  for (PetscInt d = 0; d <= std::min<PetscInt>(depth, 3); ++d) {
    PetscCall(DMPlexGetDepthStratum(dm, d, &range[d][0], &range[d][1]));
    local[d] = (double)(range[d][1] - range[d][0]);
  }
  PetscCallMPI(MPI_Allreduce(local, global, 4, MPI_DOUBLE, MPI_SUM, PetscObjectComm((PetscObject)dm)));
  m.v = global[0], m.e = global[1];
  if (m.dim == 2) m.c = global[2];
  else m.f = global[2], m.c = global[3];
  PetscFunctionReturn(0);
}

MeshCounts Refined(MeshCounts m, PetscInt times)
{
  // Past 1e200 points nothing fits anywhere: stop before the doubles overflow (and before a refinement
  // count of 2^31 takes seconds to count).
  for (PetscInt k = 0; k < times && m.c < 1e200; ++k) {
    const MeshCounts r = m;
    m.v                = r.v + r.e;
    if (m.dim == 2) {
      m.e = 2 * r.e + 3 * r.c;
      m.c = 4 * r.c;
    } else {
      m.e = 2 * r.e + 3 * r.f + r.c;
      m.f = 4 * r.f + 8 * r.c;
      m.c = 8 * r.c;
    }
  }
  return m;
}

double Dofs(const MeshCounts &m, Element e) { return e == Element::P1 ? m.v : m.dim == 2 ? m.e : m.f; }

double Nonzeros(const MeshCounts &m, Element e)
{
  // P1: a row per vertex, a column per neighbour across each edge. CR: a row per face, a column per face
  // of each cell beside it (every pair of faces of a cell couples: 3 pairs of a triangle, 6 of a
  // tetrahedron, each counted in both rows).
  if (e == Element::P1) return m.v + 2 * m.e;
  return m.dim == 2 ? m.e + 6 * m.c : m.f + 12 * m.c;
}

PetscErrorCode CheckSizes(MPI_Comm comm, const MeshOptions &o, const MeshCounts &coarse, Element element, const StudyOptions &study)
{
  PetscMPIInt size;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // The study refines its base mesh (this run's -refine) levels - 1 + reference_refine times more.
  const PetscInt       extra  = study.levels > 0 ? study.levels - 1 + study.referenceRefine : 0;
  const MeshCounts     finest = Refined(coarse, o.refine + extra);
  std::vector<Element> solved = {element};
  if (study.levels > 0) solved = study.referenceRefine > 0 ? std::vector<Element>{study.referenceElement} : study.elements;
  double dofs = 0, nonzeros = 0, variable = 0;
  for (Element e : solved) {
    dofs     = std::max(dofs, Dofs(finest, e));
    nonzeros = std::max(nonzeros, Nonzeros(finest, e));
    variable = std::max(variable, SolveBytes(finest.dim, e, Dofs(finest, e)));
  }
  if (study.levels > 0) // every level's mesh stays alive during the study
    for (PetscInt l = 0; l <= extra; ++l) variable += kIndexWidthFactor * kMeshBytesPerPoint * Refined(coarse, o.refine + l).Points();

  // 32-bit PetscInt indexes each rank's mesh points and cone arrays (the coarse mesh is on rank 0 before
  // it is distributed), the global DOFs, and each rank's matrix nonzeros.
  const double limit = (double)PETSC_MAX_INT;
  const double rankPoints = std::max(coarse.Points(), finest.Points() / size), rankCones = std::max(coarse.ConeEntries(), finest.ConeEntries() / size);
  const bool   indices    = sizeof(PetscInt) < 8 && (rankPoints > limit || rankCones > limit || dofs > limit || nonzeros / size > limit);

  bool        fits = true;
  std::string need;
  if (o.memoryCheck) PetscCall(MemoryFits(comm, variable, o.memoryLimit, fits, need));
  const bool memory = !fits;
  need += "; use fewer refinements or more nodes, or -memory_check 0 to run anyway";

  const std::string mesh = Format("%s gives a finest mesh of %.3g cells with %.3g DOFs", Asked(o, study).c_str(), finest.c, dofs);
  if (indices)
    SIGNORINI_INPUT_ERROR(comm, "sizes: %s, %.3g mesh points (%.3g cone entries) and %.3g matrix nonzeros per rank on %d rank(s), beyond the 32-bit indices of this PETSc build (at most %" PetscInt_FMT "); use fewer refinements, or the 64-bit PETSc build (Debian libpetsc64-real3.18-dev, cmake -DSIGNORINI_PETSC64=ON)%s", mesh.c_str(), rankPoints, rankCones, nonzeros / size, (int)size, PETSC_MAX_INT,
                          memory ? ("; also, " + need).c_str() : "");
  if (memory) SIGNORINI_INPUT_ERROR(comm, "sizes: %s; %s", mesh.c_str(), need.c_str());
  PetscFunctionReturn(0);
}

double SolveBytes(PetscInt dim, Element e, double dofs) { return BytesPerDof(dim, e) * dofs; }
double FixedBytes() { return kFixedBytes; }

PetscErrorCode MemoryFits(MPI_Comm comm, double variable, double limitGB, bool &fits, std::string &need)
{
  PetscMPIInt size, nodeSize;
  MPI_Comm    node;
  PetscFunctionBeginUser;
  PetscCallMPI(MPI_Comm_size(comm, &size));
  // Each rank gets an equal share of its node; the job, the memory of all its nodes.
  PetscCallMPI(MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node));
  PetscCallMPI(MPI_Comm_size(node, &nodeSize));
  PetscCallMPI(MPI_Comm_free(&node));
  const double share = NodeMemory(limitGB) / nodeSize, perRank = kFixedBytes + variable / size;
  double       total, minShare;
  PetscCallMPI(MPI_Allreduce(&share, &total, 1, MPI_DOUBLE, MPI_SUM, comm));
  PetscCallMPI(MPI_Allreduce(&share, &minShare, 1, MPI_DOUBLE, MPI_MIN, comm));
  fits = !(perRank > minShare || size * kFixedBytes + variable > total);
  need = Format("it needs about %s of memory (%s per rank), more than the %s of the nodes of this run (%s per rank, %d rank(s) on a node)", GB(size * kFixedBytes + variable).c_str(), GB(perRank).c_str(), GB(total).c_str(), GB(minShare).c_str(), (int)nodeSize);
  PetscFunctionReturn(0);
}

} // namespace signorini

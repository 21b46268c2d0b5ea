// The mesh: a coarse simplex mesh built on one rank (a box cut into triangles or tetrahedra, or a Gmsh
// file), partitioned with METIS, distributed, then refined uniformly in parallel so that the fine mesh is
// never held by one rank.
//
// Boundary parts are the values of the DMLabel "Face Sets" on faces (height-1 points). Box meshes number
// their sides like PETSc's box mesh: 2D 1 = bottom (y = lo), 2 = right, 3 = top, 4 = left; 3D 1 = bottom
// (z = lo), 2 = top, 3 = front (y = lo), 4 = back, 5 = right (x = hi), 6 = left. Gmsh physical curves
// (2D) or surfaces (3D) become "Face Sets" values, physical surfaces (2D) or volumes (3D) "Cell Sets".
#pragma once

#include "signorini/common.h"

#include <petscdmplex.h>

#include <functional>

namespace signorini {

enum class Diagonal { Slash, Backslash, Crossed };
// How a uniform refinement is made: Direct builds the fine DMPlex from the coarse one (see refine.h),
// Transform uses PETSc's DMPlexTransform. Both give the same mesh.
enum class Refinement { Direct, Transform };

struct MeshOptions {
  std::string file;                 // Gmsh .msh file; empty: built-in box
  PetscInt    dim        = 2;       // box dimension
  bool        dimSet     = false;   // -dim given: with -mesh_file, the file's mesh must have it
  PetscInt    faces[3]   = {8, 8, 8};
  PetscReal   lower[3]   = {0, 0, 0};
  PetscReal   upper[3]   = {1, 1, 1};
  Diagonal    diagonal   = Diagonal::Slash;
  PetscInt    refine     = 0;       // uniform parallel refinements after distribution (coarsened included)
  bool        coarsen    = true;    // -box_coarsen: build the box through a coarser box (see CoarsenBox)
  PetscInt    coarsened  = 0;       // how many of the refinements make the box asked for from `faces`
  bool        memoryCheck = true;   // -memory_check: refuse a run predicted not to fit (see sizes.h)
  double      memoryLimit = 0;      // -memory_limit: GB per node the check assumes (0: the machine's)
  std::string partitioner = "metis"; // "metis" or any PetscPartitioner type (ptscotch, simple, ...)
  Refinement  refinement = Refinement::Direct;
};

// What the report needs to know about how the mesh was made.
struct MeshInfo {
  PetscInt              coarseCells = 0;
  PetscInt              cells       = 0; // global, fine mesh
  PetscInt              edgeCut     = -1; // METIS edge cut of the coarse partition (-1: not METIS)
  std::vector<PetscInt> cellsPerRank;    // fine cells owned by each rank
  std::string           description;     // e.g. "box 64x64 backslash" or the file name
};

struct MeshCounts; // sizes.h

// Reads the options and applies CoarsenBox for the ranks of `comm`.
PetscErrorCode MeshOptionsFromCommandLine(MPI_Comm comm, MeshOptions &opts);
// The fast path of -box_faces: a box (slash, backslash or 3D Kuhn cells) with N = n 2^k cells in every
// direction is the box n refined k times (tests/unit_fastpath.cpp), and refining in parallel is far
// cheaper than building the box on rank 0, and gives nested iteration its levels. Replaces `faces` by the
// coarsest such n that still gives each of `ranks` ranks kMinCoarseCellsPerRank cells, adds k to `refine`
// and sets `coarsened` = k. Crossed squares are not the refinement of coarser crossed squares: that box is
// built as asked, as is every box with `coarsen` false.
void CoarsenBox(MeshOptions &opts, PetscMPIInt ranks);
// The box as asked, e.g. "box 512x512" (`faces` refined `coarsened` times).
std::string BoxName(const MeshOptions &opts);
// The d + 1 vertices of a simplex mesh point p of depth d (1: edge, 2: triangle, 3: tetrahedron), found by
// descending cones: the vertices of the first cone point, then the one vertex of the second that is not
// among them. Every table that lists a cell's vertices uses this order. Much cheaper than a transitive
// closure (the cell tables need d + 2 of these per cell).
PetscErrorCode SimplexVertices(DM dm, PetscInt p, PetscInt depth, PetscInt verts[4]);
// The dim + 1 vertices of cell p ordered so that vertex k is the one not on face k of its cone (the order
// of the cell tables of a discrete space).
PetscErrorCode CellVertices(DM dm, PetscInt p, PetscInt dim, PetscInt verts[4]);
// CellVertices for loops over every cell: reads the cones straight from the DMPlex's arrays. Ten cone
// lookups per tetrahedron through DMPlexGetCone (each through the cone section's offsets, a second
// scattered read), and the searches among them, were most of the time of the adaptive transfer's
// evaluation on the fine cells. Valid while the mesh's topology does not change.
class CellVertexReader {
public:
  // dm: an interpolated simplex DMPlex. strides: look for the strides of the cones (a pass over the
  // points, worth it for a loop over many cells, see Kind).
  PetscErrorCode Init(DM dm, bool strides = true);
  PetscInt       Dim() const { return dim_; }
  // As CellVertices(dm, p, dim, verts).
  void Vertices(PetscInt p, PetscInt verts[4]) const { WithDim(dim_, [&](auto D) { Vertices<D>(p, verts); }); }
  // Starts loading what Vertices(p) will read, for a loop over the cells in order: the cones of p's
  // faces (round 0) and, some cells later, once those are in cache, the cones of their edges (round 1,
  // tetrahedra only). The faces and edges of consecutive cells are not close to each other in memory.
  void Prefetch(PetscInt p, int round) const { WithDim(dim_, [&](auto D) { Prefetch<D>(p, round); }); }
  // Both rounds at their distances ahead of cell p, for a loop over the cells [.., end) in order.
  void PrefetchAhead(PetscInt p, PetscInt end) const
  {
    if (p + 16 < end) Prefetch(p + 16, 0);
    if (p + 8 < end) Prefetch(p + 8, 1);
  }

private:
  template <int D>
  void Vertices(PetscInt p, PetscInt verts[4]) const;
  template <int D>
  void Prefetch(PetscInt p, int round) const;
  // The points of one kind (cells, faces, edges) and where their cones lie: in a DMPlex built stratum by
  // stratum the cones of a stratum follow each other with the same size (checked by Init), so the cone of
  // p is found without reading the cone section's offsets; otherwise (stride 0) through them.
  struct Kind {
    PetscInt start = 0, base = 0, stride = 0;
  };
  const PetscInt *Cone(const Kind &k, PetscInt p) const { return cones_ + (k.stride ? k.base + (p - k.start) * k.stride : offsets_[p - pStart_]); }
  PetscErrorCode  InitKind(PetscInt start, PetscInt end, PetscInt size, Kind &k) const;
  PetscInt        dim_ = 0, pStart_ = 0;
  const PetscInt *offsets_ = nullptr, *cones_ = nullptr;
  Kind            cell_, face_, edge_;
};
// The coordinates of the local vertices of a DMPlex, dim per vertex (v - vStart).
PetscErrorCode VertexCoordinates(DM dm, std::vector<PetscReal> &x);
// The local faces (height-1 points) that carry `value` in `label` (which may be null: no faces). Refined
// labels also hold vertices and edges; those are left out.
PetscErrorCode LabelFaces(DM dm, DMLabel label, PetscInt value, std::vector<PetscInt> &faces);
// Longest edge of the mesh (max over ranks).
PetscErrorCode MeshSize(DM dm, PetscReal *hmax);
// One uniform (regular) refinement, local to each rank. If `parent` is given, parent[c] is the cell of
// `coarse` (as c - cStart) that fine cell cStart + c came from: the nested-mesh map used to evaluate a
// coarse function on the fine mesh.
PetscErrorCode MeshRefine(DM coarse, DM *fine, std::vector<PetscInt> *parent, Refinement how = Refinement::Direct);
// The nested meshes of the refinement, for nested iteration: dm[0] is the distributed coarse mesh (or the
// coarsest kept level), dm.back() the fine mesh MeshCreate returns (one more reference to it), and
// parent[l] (l >= 1) maps the cells of level l to their parent cells in level l - 1 (as in MeshRefine).
struct MeshLevels {
  std::vector<DM>                    dm;
  std::vector<std::vector<PetscInt>> parent;
  PetscInt                           Count() const { return (PetscInt)dm.size(); }
};
PetscErrorCode MeshLevelsDestroy(MeshLevels &levels);

// Collective: builds, partitions, distributes and refines; pushes the Mesh, Distribute and Refine stages.
// With `levels`, also keeps the coarser levels (at most `keep` below the fine mesh; -1: all of them) and
// their parent maps instead of dropping them. `checkCoarse`, if given, is called with the distributed
// coarse mesh before the refinement: input errors found there cost seconds, not the refinement's minutes.
// `checkSizes`, if given, is called with the counts of the coarse mesh as soon as they are known (a box:
// before it is built; a file: once read, before it is distributed), see CheckSizes in sizes.h.
PetscErrorCode MeshCreate(MPI_Comm comm, const MeshOptions &opts, DM *dm, MeshInfo &info, MeshLevels *levels = nullptr, PetscInt keep = -1, const std::function<PetscErrorCode(DM)> &checkCoarse = nullptr,
                          const std::function<PetscErrorCode(const MeshCounts &)> &checkSizes = nullptr);

} // namespace signorini

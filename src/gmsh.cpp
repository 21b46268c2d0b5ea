#include "signorini/gmsh.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <unistd.h>
#include <unordered_map>

namespace signorini {

namespace {

struct ElementKind {
  int         type, dim, order;
  const char *name;
};

// The Gmsh element types the scan knows (Gmsh's numbering). Linear quadrangles, hexahedra, prisms and
// pyramids are read by PETSc and refused afterwards by the cell-type check; types not listed are left to
// PETSc, which names them.
const ElementKind kElementKinds[] = {
  {15, 0, 1, "point"},
  {1, 1, 1, "line"},
  {2, 2, 1, "triangle"},
  {3, 2, 1, "quadrangle"},
  {4, 3, 1, "tetrahedron"},
  {5, 3, 1, "hexahedron"},
  {6, 3, 1, "prism"},
  {7, 3, 1, "pyramid"},
  {8, 1, 2, "3-node line"},
  {9, 2, 2, "6-node triangle"},
  {10, 2, 2, "9-node quadrangle"},
  {11, 3, 2, "10-node tetrahedron"},
  {12, 3, 2, "27-node hexahedron"},
  {13, 3, 2, "18-node prism"},
  {14, 3, 2, "14-node pyramid"},
  {16, 2, 2, "8-node quadrangle"},
  {17, 3, 2, "20-node hexahedron"},
  {18, 3, 2, "15-node prism"},
  {19, 3, 2, "13-node pyramid"},
  {20, 2, 3, "9-node triangle"},
  {21, 2, 3, "10-node triangle"},
  {22, 2, 4, "12-node triangle"},
  {23, 2, 4, "15-node triangle"},
  {24, 2, 5, "15-node triangle"},
  {25, 2, 5, "21-node triangle"},
  {26, 1, 3, "4-node line"},
  {27, 1, 4, "5-node line"},
  {28, 1, 5, "6-node line"},
  {29, 3, 3, "20-node tetrahedron"},
  {30, 3, 4, "35-node tetrahedron"},
  {31, 3, 5, "56-node tetrahedron"},
};

const ElementKind *FindKind(int type)
{
  for (const ElementKind &k : kElementKinds)
    if (k.type == type) return &k;
  return nullptr;
}

struct Element {
  long              tag;
  const ElementKind *kind;
  std::vector<long> nodes;
};

// Line-by-line reader of the ASCII sections. Any text it does not understand makes the scan give up
// (ok = false): PETSc then reads the file and reports what is wrong with it.
struct Reader {
  FILE *fp;
  char  line[4096] = "";
  bool  ok         = true;
  explicit Reader(FILE *f) : fp(f) {}

  bool Next()
  {
    if (!ok || !std::fgets(line, sizeof line, fp)) return ok = false;
    if (!std::strchr(line, '\n') && !std::feof(fp)) return ok = false; // a line longer than the buffer
    return true;
  }
  bool Is(const char *section) const { return std::strncmp(line, section, std::strlen(section)) == 0; }
  // Skips to the line that starts with `section`.
  bool SkipTo(const char *section)
  {
    while (Next())
      if (Is(section)) return true;
    return false;
  }
  // The integers of the current line.
  std::vector<long> Integers()
  {
    std::vector<long> v;
    char             *p = line, *end;
    for (long x = std::strtol(p, &end, 10); end != p; x = std::strtol(p, &end, 10)) v.push_back(x), p = end;
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n') ++p;
    if (*p) ok = false;
    return v;
  }
  bool Coordinates(double x[3])
  {
    if (std::sscanf(line, "%lf %lf %lf", &x[0], &x[1], &x[2]) != 3) ok = false;
    return ok;
  }
};

struct Scan {
  std::vector<long>   nodeTag;
  std::vector<double> xyz;
  std::vector<Element> elements;
};

// msh 2.2: "$Nodes", count, "tag x y z" lines; "$Elements", count, "tag type ntags tags... nodes..." lines.
bool ReadV22(Reader &r, Scan &s)
{
  if (!r.SkipTo("$Nodes") || !r.Next()) return false;
  const long n = std::atol(r.line);
  for (long i = 0; i < n && r.Next(); ++i) {
    long   tag;
    double x[3];
    if (std::sscanf(r.line, "%ld %lf %lf %lf", &tag, &x[0], &x[1], &x[2]) != 4) return false;
    s.nodeTag.push_back(tag);
    s.xyz.insert(s.xyz.end(), x, x + 3);
  }
  if (!r.SkipTo("$Elements") || !r.Next()) return false;
  const long m = std::atol(r.line);
  for (long i = 0; i < m && r.Next(); ++i) {
    std::vector<long> v = r.Integers();
    if (!r.ok || v.size() < 3 || (long)v.size() < 3 + v[2]) return false;
    s.elements.push_back({v[0], FindKind((int)v[1]), std::vector<long>(v.begin() + 3 + v[2], v.end())});
  }
  return r.ok;
}

// msh 4.1: blocks of nodes ("dim entity parametric count", then the tags, then the coordinates) and blocks
// of elements ("dim entity type count", then "tag nodes..." lines).
bool ReadV41(Reader &r, Scan &s)
{
  if (!r.SkipTo("$Nodes") || !r.Next()) return false;
  std::vector<long> head = r.Integers();
  if (!r.ok || head.size() != 4) return false;
  for (long b = 0; b < head[0]; ++b) {
    if (!r.Next()) return false;
    std::vector<long> block = r.Integers();
    if (!r.ok || block.size() != 4) return false;
    for (long i = 0; i < block[3]; ++i) {
      if (!r.Next()) return false;
      s.nodeTag.push_back(std::atol(r.line));
    }
    for (long i = 0; i < block[3]; ++i) {
      double x[3];
      if (!r.Next() || !r.Coordinates(x)) return false;
      s.xyz.insert(s.xyz.end(), x, x + 3);
    }
  }
  if (!r.SkipTo("$Elements") || !r.Next()) return false;
  head = r.Integers();
  if (!r.ok || head.size() != 4) return false;
  for (long b = 0; b < head[0]; ++b) {
    if (!r.Next()) return false;
    std::vector<long> block = r.Integers();
    if (!r.ok || block.size() != 4) return false;
    const ElementKind *kind = FindKind((int)block[2]);
    for (long i = 0; i < block[3]; ++i) {
      if (!r.Next()) return false;
      std::vector<long> v = r.Integers();
      if (!r.ok || v.size() < 2) return false;
      s.elements.push_back({v[0], kind, std::vector<long>(v.begin() + 1, v.end())});
    }
  }
  return r.ok;
}

// The cells are the elements of the highest dimension; PETSc takes the elements one dimension below as
// labels of cell faces and fails ("Could not determine Plex facet") on one that is no face: what a file
// that mixes 2D and 3D cells gives.
std::string CheckFacets(const Scan &s, const std::string &name, const std::unordered_map<long, long> &index)
{
  int dim = 0;
  for (const Element &e : s.elements) dim = std::max(dim, e.kind->dim);
  const int   simplexType = dim == 2 ? 2 : 4;
  const char *cellName    = dim == 2 ? "triangle" : "tetrahedron";
  if (dim < 2) return "";
  // cells of each node (compressed rows), for the linear simplices only: other cell types are refused later
  std::vector<long> start(s.nodeTag.size() + 1, 0), cells;
  std::vector<const Element *> simplices;
  for (const Element &e : s.elements)
    if (e.kind->dim == dim) {
      if (e.kind->type != simplexType) return "";
      simplices.push_back(&e);
      for (long n : e.nodes) start[index.at(n) + 1]++;
    }
  for (size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  cells.resize(start.back());
  std::vector<long> fill(start.begin(), start.end() - 1);
  for (size_t c = 0; c < simplices.size(); ++c)
    for (long n : simplices[c]->nodes) cells[fill[index.at(n)]++] = (long)c;
  for (const Element &e : s.elements) {
    if (e.kind->dim != dim - 1) continue;
    const long first = index.at(e.nodes[0]);
    bool       found = false;
    for (long k = start[first]; k < start[first + 1] && !found; ++k) {
      const std::vector<long> &cn = simplices[cells[k]]->nodes;
      found = std::all_of(e.nodes.begin(), e.nodes.end(), [&](long n) { return std::find(cn.begin(), cn.end(), n) != cn.end(); });
    }
    if (!found) return Format("%s: element %ld, a %s, is not a face of any %s (the mesh is %dD: its lower-dimensional elements may only mark faces of its cells; does the file mix %dD and %dD cells?)", name.c_str(), e.tag, e.kind->name, cellName, dim, dim - 1, dim);
  }
  return "";
}

// The element checks: order, dangling and repeated node references, faces.
std::string CheckElements(const Scan &s, const std::string &name, GmshNodes &nodes)
{
  std::unordered_map<long, long> index; // node tag -> position in $Nodes
  index.reserve(s.nodeTag.size());
  for (size_t i = 0; i < s.nodeTag.size(); ++i) index.emplace(s.nodeTag[i], (long)i);
  std::vector<char> used(s.nodeTag.size(), 0);
  for (const Element &e : s.elements) {
    if (!e.kind) return ""; // a type PETSc names in its own message
    if (e.kind->order > 1) return Format("%s: element %ld is a %s (Gmsh type %d), an element of order %d; only first-order (straight-sided) triangles and tetrahedra are supported: mesh with gmsh -order 1", name.c_str(), e.tag, e.kind->name, e.kind->type, e.kind->order);
    for (size_t i = 0; i < e.nodes.size(); ++i) {
      auto it = index.find(e.nodes[i]);
      if (it == index.end()) return Format("%s: element %ld (a %s) refers to node %ld, which is not in $Nodes", name.c_str(), e.tag, e.kind->name, e.nodes[i]);
      if (std::find(e.nodes.begin(), e.nodes.begin() + i, e.nodes[i]) != e.nodes.begin() + i) return Format("%s: element %ld (a %s) lists node %ld twice", name.c_str(), e.tag, e.kind->name, e.nodes[i]);
      used[it->second] = 1;
    }
  }
  if (std::string facets = CheckFacets(s, name, index); !facets.empty()) return facets;
  for (size_t i = 0; i < s.nodeTag.size(); ++i)
    if (used[i]) {
      nodes.tag.push_back(s.nodeTag[i]);
      nodes.xyz.insert(nodes.xyz.end(), &s.xyz[3 * i], &s.xyz[3 * i] + 3);
    }
  return "";
}

} // namespace

std::string GmshCheckFile(const std::string &file, const std::string &name, GmshNodes &nodes)
{
  nodes = GmshNodes();
  FILE *fp = std::fopen(file.c_str(), "r");
  if (!fp) {
    const int error = errno;
    // A relative path is taken from the working directory, not from the options file that named it (the
    // scenes of petsc-options/ name their meshes from the repository's root): say which directory that was.
    char        cwd[4096];
    std::string from = !file.empty() && file[0] != '/' && getcwd(cwd, sizeof(cwd)) ? Format(" (a relative path, taken from the working directory %s)", cwd) : "";
    return Format("%s: cannot open it for reading (%s)%s", name.c_str(), std::strerror(error), from.c_str());
  }
  Reader r(fp);
  std::string problem;
  if (!r.Next()) problem = name + (std::ferror(fp) ? ": cannot be read (is it a directory?)" : ": the file is empty");
  else if (r.Is("$NOD") || r.Is("$NOE")) problem = name + ": a Gmsh file of version 1 (msh1), which PETSc does not read; save it again as msh 2.2 or 4.1 (gmsh option -format msh41)";
  else if (!r.Is("$MeshFormat")) problem = name + ": not a Gmsh mesh (no $MeshFormat header)";
  else if (r.Next()) {
    double version = 0;
    int    binary  = 1;
    Scan   s;
    // binary files and other versions go straight to PETSc
    if (std::sscanf(r.line, "%lf %d", &version, &binary) == 2 && binary == 0) {
      bool read = false;
      if (version == 2.2) read = ReadV22(r, s);
      else if (version == 4.1) read = ReadV41(r, s);
      if (read) problem = CheckElements(s, name, nodes);
    }
  }
  std::fclose(fp);
  return problem;
}

bool GmshPhysicalNames(const std::string &file, std::vector<GmshPhysicalName> &names)
{
  names.clear();
  FILE *fp = std::fopen(file.c_str(), "r");
  if (!fp) return false;
  Reader r(fp);
  while (r.Next() && !r.Is("$Nodes"))
    if (r.Is("$PhysicalNames")) {
      if (!r.Next()) break;
      const long n = std::atol(r.line);
      for (long i = 0; i < n && r.Next(); ++i) {
        int  dim, used = 0;
        long tag;
        if (std::sscanf(r.line, "%d %ld %n", &dim, &tag, &used) != 2) break;
        std::string name(r.line + used);
        while (!name.empty() && std::isspace((unsigned char)name.back())) name.pop_back();
        if (name.size() >= 2 && name.front() == '"' && name.back() == '"') name = name.substr(1, name.size() - 2);
        names.push_back({dim, tag, name});
      }
      break;
    }
  std::fclose(fp);
  return true;
}

std::string CheckCoincidentVertices(DM dm, const std::string &name, const GmshNodes &nodes)
{
  PetscInt           cdim, vStart, vEnd, eStart, eEnd;
  Vec                coords;
  PetscSection       csec;
  const PetscScalar *x;
  if (DMGetCoordinateDim(dm, &cdim) || DMPlexGetDepthStratum(dm, 0, &vStart, &vEnd) || DMPlexGetDepthStratum(dm, 1, &eStart, &eEnd) || DMGetCoordinatesLocal(dm, &coords) || DMGetCoordinateSection(dm, &csec) || VecGetArrayRead(coords, &x)) return name + ": cannot query the mesh vertices";
  const PetscInt         nv = vEnd - vStart;
  std::vector<PetscReal> X(nv * cdim), h(nv, PETSC_MAX_REAL), lo(cdim, PETSC_MAX_REAL), hi(cdim, PETSC_MIN_REAL);
  for (PetscInt v = 0; v < nv; ++v) {
    PetscInt off = 0;
    PetscSectionGetOffset(csec, vStart + v, &off);
    for (PetscInt d = 0; d < cdim; ++d) {
      X[v * cdim + d] = PetscRealPart(x[off + d]);
      lo[d]           = std::min(lo[d], X[v * cdim + d]);
      hi[d]           = std::max(hi[d], X[v * cdim + d]);
    }
  }
  VecRestoreArrayRead(coords, &x);
  auto dist = [&](PetscInt a, PetscInt b) {
    PetscReal s = 0;
    for (PetscInt d = 0; d < cdim; ++d) s += PetscSqr(X[a * cdim + d] - X[b * cdim + d]);
    return std::sqrt(s);
  };
  // h: the shortest edge at each vertex. The tolerance is relative to it, not to the whole mesh, so that a
  // strongly graded mesh is judged by its own local size.
  for (PetscInt e = eStart; e < eEnd; ++e) {
    const PetscInt *cone;
    if (DMPlexGetCone(dm, e, &cone)) return name + ": cannot query the mesh edges";
    const PetscInt  a = cone[0] - vStart, b = cone[1] - vStart;
    const PetscReal l = dist(a, b);
    h[a] = std::min(h[a], l), h[b] = std::min(h[b], l);
  }
  const PetscReal rel = 1e-10;
  PetscReal       diam = 0, bucket = 0;
  for (PetscInt d = 0; d < cdim; ++d) diam = std::max(diam, hi[d] - lo[d]);
  for (PetscInt v = 0; v < nv; ++v)
    if (h[v] < PETSC_MAX_REAL) bucket = std::max(bucket, rel * h[v]);
  // Two coincident vertices lie in the same or neighbouring buckets of this size; the lower bound keeps the
  // bucket numbers within 64 bits.
  bucket = std::max(bucket, std::max(diam, (PetscReal)1) * 1e-15);
  using Key  = std::array<long long, 3>;
  auto hash  = [](const Key &k) { return std::hash<unsigned long long>()((unsigned long long)k[0] * 73856093ULL ^ (unsigned long long)k[1] * 19349663ULL ^ (unsigned long long)k[2] * 83492791ULL); };
  std::unordered_map<Key, std::vector<PetscInt>, decltype(hash)> buckets(2 * nv + 1, hash);
  Key      key{0, 0, 0};
  long     pairs    = 0;
  PetscInt first[2] = {-1, -1};
  for (PetscInt v = 0; v < nv; ++v) {
    for (PetscInt d = 0; d < cdim; ++d) key[d] = (long long)std::floor((X[v * cdim + d] - lo[d]) / bucket);
    // visit the 3^cdim neighbouring buckets
    for (int k = 0; k < (cdim == 3 ? 27 : cdim == 2 ? 9 : 3); ++k) {
      Key nb = key;
      for (int d = 0, kk = k; d < cdim; ++d, kk /= 3) nb[d] += kk % 3 - 1;
      auto it = buckets.find(nb);
      if (it == buckets.end()) continue;
      for (PetscInt w : it->second) {
        const PetscReal tol = rel * std::min(h[v], h[w]);
        if (tol < PETSC_MAX_REAL * rel && dist(v, w) <= tol) {
          if (!pairs++) first[0] = w, first[1] = v;
        }
      }
    }
    buckets[key].push_back(v);
  }
  if (!pairs) return "";
  // vertex k is node k of those the elements use, in the order of the file (see gmsh.h), unless PETSc
  // changed the vertices (periodic files): then the coordinates tell
  bool named = (PetscInt)nodes.tag.size() == nv;
  for (PetscInt v = 0; v < nv && named; ++v)
    for (PetscInt d = 0; d < cdim && named; ++d) named = std::fabs(nodes.xyz[3 * v + d] - X[v * cdim + d]) <= 1e-12 * std::max(diam, (PetscReal)1);
  const PetscInt a = first[0], b = first[1];
  std::string    where;
  for (PetscInt d = 0; d < cdim; ++d) where += Format(d ? ", %g" : "(%g", (double)X[a * cdim + d]);
  where += ")";
  const std::string which = named ? Format("nodes %ld and %ld", nodes.tag[a], nodes.tag[b]) : std::string("two vertices");
  const std::string more  = pairs > 1 ? Format(" (and %ld more such pairs)", pairs - 1) : std::string();
  return Format("%s: %s are at the same point %s%s; a duplicated node cuts the mesh (a crack): merge the duplicates (Gmsh: Coherence Mesh;)", name.c_str(), which.c_str(), where.c_str(), more.c_str());
}

} // namespace signorini

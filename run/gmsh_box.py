"""Writes the paper-5.1 mesh (unit square, N x N squares cut along (1,0)-(0,1), the same mesh as
`-box_faces N -box_diagonal backslash`) as an ASCII Gmsh 2.2 file, for runs on a fine mesh that has no
refinement hierarchy: signorini reads such a file as it is, on one level, unless -refine is given.

  python3 run/gmsh_box.py N FILE

Physical curves as in the built-in box: bottom (y = 0) 1, right (x = 1) 2, top (y = 1) 3, left (x = 0) 4;
one physical surface 1. Fine meshes are large (N = 1024: 2 M triangles, about 60 MB), so they are written at
benchmark or test time, not kept in the repository."""
import os
import sys


def write(N, path):
    """Writes the file through a temporary name (no half-written mesh is left)."""
    n1 = N + 1
    vid = lambda i, j: j * n1 + i + 1  # node (i, j) at (i/N, j/N), numbered from 1

    def lines():
        yield "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % (n1 * n1)
        for j in range(n1):
            y = repr(j / N)
            yield "".join("%d %r %s 0\n" % (vid(i, j), i / N, y) for i in range(n1))
        edges = [(1, [(vid(i, 0), vid(i + 1, 0)) for i in range(N)]),
                 (2, [(vid(N, j), vid(N, j + 1)) for j in range(N)]),
                 (3, [(vid(i + 1, N), vid(i, N)) for i in range(N)]),
                 (4, [(vid(0, j + 1), vid(0, j)) for j in range(N)])]
        yield "$EndNodes\n$Elements\n%d\n" % (4 * N + 2 * N * N)
        k = 0
        for tag, segs in edges:
            text = []
            for a, b in segs:
                k += 1
                text.append("%d 1 2 %d %d %d %d\n" % (k, tag, tag, a, b))
            yield "".join(text)
        for j in range(N):
            text = []
            for i in range(N):
                a, b, c, d = vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)
                # both triangles counter-clockwise, the diagonal from b = (1,0) to d = (0,1)
                text.append("%d 2 2 1 1 %d %d %d\n%d 2 2 1 1 %d %d %d\n" % (k + 1, a, b, d, k + 2, b, c, d))
                k += 2
            yield "".join(text)
        yield "$EndElements\n"

    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        for chunk in lines():
            f.write(chunk)
    os.replace(tmp, path)


def main(argv):
    if len(argv) != 3 or not argv[1].isdigit() or int(argv[1]) < 1:
        sys.stderr.write("usage: gmsh_box.py N FILE (N >= 1 squares per side)\n")
        return 2
    write(int(argv[1]), argv[2])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

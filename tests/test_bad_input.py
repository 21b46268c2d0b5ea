"""Bad input: every case exits with status 1 (not 2, not a hang), prints exactly one line
"signorini: error: ..." on stderr that names the offending option or file, and leaves neither a summary
nor any output file (.h5, .xmf, *.tmp) behind. Mesh-file, boundary-label and kappa cases, whose failure
can be found on one rank only, also run on 2 ranks, and so do the options files and the solver options, which
PETSc reads on rank 0 or on all ranks at once."""
import os
import subprocess
import tempfile

import harness
from harness import ROOT, Checker, scene



def write_gmsh(path, nodes, elements, version="2.2"):
    """Gmsh ASCII file: nodes {id: (x, y, z)}, elements [(gmsh type, physical tag, node ids)]. Version 4.1
    puts the elements of each (dimension, physical tag) in an entity of that tag, and all nodes in one block."""
    with open(path, "w") as f:
        f.write("$MeshFormat\n%s 0 8\n$EndMeshFormat\n" % version)
        if version == "2.2":
            f.write("$Nodes\n%d\n" % len(nodes))
            for k, p in nodes.items():
                f.write("%d %r %r %r\n" % ((k,) + tuple(p)))
            f.write("$EndNodes\n$Elements\n%d\n" % len(elements))
            for i, (kind, tag, ids) in enumerate(elements):
                f.write("%d %d 2 %d %d %s\n" % (i + 1, kind, tag, tag, " ".join(map(str, ids))))
            f.write("$EndElements\n")
            return
        dims = {15: 0, 1: 1, 2: 2, 4: 3, 8: 1, 9: 2}
        blocks = {}
        for kind, tag, ids in elements:
            blocks.setdefault((dims[kind], tag, kind), []).append(ids)
        entities = [sorted({(d, t) for d, t, _ in blocks if d == dim}) for dim in range(4)]
        f.write("$Entities\n%s\n" % " ".join(str(len(e)) for e in entities))
        for dim, es in enumerate(entities):
            for _, t in es:
                f.write("%d %s 1 %d%s\n" % (t, " ".join(["0"] * (3 if dim == 0 else 6)), t, "" if dim == 0 else " 0"))
        f.write("$EndEntities\n$Nodes\n1 %d %d %d\n2 10 0 %d\n" % (len(nodes), min(nodes), max(nodes), len(nodes)))
        f.write("".join("%d\n" % k for k in nodes) + "".join("%r %r %r\n" % tuple(p) for p in nodes.values()))
        f.write("$EndNodes\n$Elements\n%d %d 1 %d\n" % (len(blocks), len(elements), len(elements)))
        number = 0
        for (dim, tag, kind), members in blocks.items():
            f.write("%d %d %d %d\n" % (dim, tag, kind, len(members)))
            for ids in members:
                number += 1
                f.write("%d %s\n" % (number, " ".join(map(str, ids))))
        f.write("$EndElements\n")


def unit_square(path, center=(0.5, 0.5, 0.0), z=lambda x, y: 0.0, extra_lines=(), triangles=True, edit=None, extra_nodes=None, extra_elements=(), version="2.2"):
    """The unit square as a 3x3 grid of nodes (node 5 at `center`), 8 triangles (physical surface 10),
    sides labelled 1 bottom, 2 right, 3 top, 4 left, plus (tag, (a, b)) extra labelled lines. `edit` changes
    the list of triangles (node triples); extra nodes {id: (x, y, z)} and elements (gmsh type, tag, ids)
    are added as given."""
    nodes = {1 + i + 3 * j: (0.5 * i, 0.5 * j, z(0.5 * i, 0.5 * j)) for j in range(3) for i in range(3)}
    nodes[5] = center
    nodes.update(extra_nodes or {})
    lines = {1: [(1, 2), (2, 3)], 2: [(3, 6), (6, 9)], 3: [(9, 8), (8, 7)], 4: [(7, 4), (4, 1)]}
    elements = [(1, tag, l) for tag, ls in lines.items() for l in ls] + [(1, tag, l) for tag, l in extra_lines]
    if triangles:
        tris = []
        for j in range(2):
            for i in range(2):
                a = 1 + i + 3 * j
                tris += [(a, a + 1, a + 4), (a, a + 4, a + 3)]
        elements += [(2, 10, t) for t in (edit(tris) if edit else tris)]
    write_gmsh(path, nodes, elements + list(extra_elements), version)
    return nodes, elements


def second_order(path):
    """The square of unit_square with 3-node lines and 6-node triangles (Gmsh types 8 and 9): a node in the
    middle of every edge, numbered 100 + 10 a + b for the edge (a, b), a < b."""
    corners, first = unit_square(path)
    nodes, elements = dict(corners), []
    for kind, tag, ids in first:
        edges = list(zip(ids, ids[1:] + ids[:1])) if kind == 2 else [tuple(ids)]
        middle = [100 + 10 * min(a, b) + max(a, b) for a, b in edges]
        for (a, b), m in zip(edges, middle):
            nodes[m] = tuple((p + q) / 2 for p, q in zip(corners[a], corners[b]))
        elements.append((9 if kind == 2 else 8, tag, tuple(ids) + tuple(middle)))
    write_gmsh(path, nodes, elements)


def msh1(path):
    """The unit square in Gmsh's format version 1 ($NOD / $ELM sections), which PETSc does not read."""
    with open(path, "w") as f:
        f.write("$NOD\n4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n$ENDNOD\n")
        f.write("$ELM\n2\n1 2 10 10 3 1 2 3\n2 2 10 10 3 1 3 4\n$ENDELM\n")


c = Checker()
base = scene("paper-5.1") + ["-box_faces", "8"]
PREFIX = "signorini: error:"

with tempfile.TemporaryDirectory() as inputs:
    square = os.path.join(ROOT, "tests", "data", "square.msh")
    missing = os.path.join(inputs, "missing.msh")
    empty = os.path.join(inputs, "empty.msh")
    text = os.path.join(inputs, "notes.msh")
    truncated = os.path.join(inputs, "truncated.msh")
    open(empty, "w").close()
    with open(text, "w") as f:
        f.write("This is a text file, not a mesh.\nx y z\n1 2 3\n")
    with open(square) as f:
        msh = f.read()
    start, end = msh.index("$Elements\n"), msh.index("$EndElements")
    with open(truncated, "w") as f:
        f.write(msh[: start + (end - start) // 2])  # cut in the middle of $Elements (and of a line)
    nodir = os.path.join(inputs, "no-such-directory", "out.h5")
    never = os.path.join(inputs, "never.json")  # -study_output of a run that is no study
    folded, flat, lines, surface, quads, overlap = (os.path.join(inputs, n + ".msh") for n in ("folded", "flat", "lines", "surface", "quads", "overlap"))
    unit_square(folded, center=(1.2, 0.5, 0.0))  # node 5 moved across the right side: cells overlap
    unit_square(flat, center=(1.0, 0.25, 0.0))  # node 5 on the right side: a cell of zero area
    unit_square(lines, triangles=False)  # boundary lines only: no 2D cells
    unit_square(surface, z=lambda x, y: x * y)  # a curved surface in 3D, not a planar mesh
    write_gmsh(quads, {1: (0, 0, 0), 2: (1, 0, 0), 3: (1, 1, 0), 4: (0, 1, 0)}, [(1, 1, (1, 2)), (3, 10, (1, 2, 3, 4))])
    unit_square(overlap, extra_lines=[(5, (1, 2))])  # one bottom line also in physical group 5
    # Gmsh files that PETSc reads into a wrong mesh, or fails on with a misleading message
    duplicate, dangling, repeated, mixed, order2, version1 = (os.path.join(inputs, n + ".msh") for n in ("duplicate", "dangling", "repeated", "mixed", "order2", "version1"))
    # node 10 is node 5 again, used by the upper four triangles: read as it is, the mesh has a crack
    duplicate41 = os.path.join(inputs, "duplicate41.msh")  # the same in msh 4.1
    for path, version in (duplicate, "2.2"), (duplicate41, "4.1"):
        unit_square(path, version=version, extra_nodes={10: (0.5, 0.5, 0.0)}, edit=lambda ts: ts[:4] + [tuple(10 if v == 5 else v for v in t) for t in ts[4:]])
    unit_square(dangling, edit=lambda ts: [(1, 2, 42)] + ts[1:])  # there is no node 42
    unit_square(repeated, edit=lambda ts: [(1, 1, 5)] + ts[1:])
    unit_square(mixed, extra_nodes={10: (0.5, 0.5, 1.0)}, extra_elements=[(4, 20, (1, 2, 4, 10))])  # one tetrahedron
    second_order(order2)
    msh1(version1)
    missing_options = os.path.join(inputs, "no-such-options-file")
    isdir = os.path.join(inputs, "a-directory.h5")
    os.mkdir(isdir)
    notdir = os.path.join(square, "summary.json")  # a path below a regular file
    square_scene = ["-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4"]
    two_squares, corner_squares, cube = (os.path.join(ROOT, "tests", "data", n + ".msh") for n in ("two-squares", "corner-squares", "cube"))

    # (name, extra options, text the message must contain, also on 2 ranks)
    cases = [
        ("missing mesh file", ["-mesh_file", missing], missing, True),
        ("empty mesh file", ["-mesh_file", empty], empty, True),
        ("text file as mesh", ["-mesh_file", text], text, True),
        ("truncated mesh file", ["-mesh_file", truncated], truncated, True),
        ("unknown boundary label", ["-bc_contact", "7"], "-bc_contact", True),
        ("expression does not parse", ["-f", "2*sin("], "option -f:", False),
        ("unknown variable", ["-f", "w"], "option -f:", False),
        ("kappa <= 0 somewhere", ["-kappa", "x - 0.5"], "-kappa", True),
        ("kappa <= 0 on the right only", ["-kappa", "x > 0.5 ? -1 : 1"], "-kappa", True),
        ("kappa <= 0 on the left only", ["-kappa", "x < 0.5 ? 0 : 1"], "-kappa", True),
        ("kappa NaN", ["-kappa", "sqrt(-1)"], "-kappa", True),
        ("zero cell count", ["-box_faces", "0,4"], "-box_faces", False),
        ("negative refine", ["-refine", "-1"], "-refine", False),
        ("dim 4", ["-dim", "4"], "-dim", False),
        ("unknown space", ["-space", "q2"], "-space", True),
        ("output in a missing directory", ["-output", nodir], nodir, False),
        ("output path is a directory", ["-output", isdir], isdir, False),
        ("summary below a regular file", ["-summary", notdir], "-summary", False),
        ("inverted (folded) cells", ["-mesh_file", folded] + square_scene, "inverted cell", True),
        ("zero-area cells", ["-mesh_file", flat] + square_scene, "zero measure", True),
        ("no cells of dimension 2 or 3", ["-mesh_file", lines] + square_scene, "mesh dimension is 1", True),
        ("curved surface mesh", ["-mesh_file", surface] + square_scene, "not flat", True),
        ("quadrilateral cells", ["-mesh_file", quads, "-bc_dirichlet", "1", "-bc_contact", ""], "quadrilateral", True),
        ("a face in a Dirichlet and a contact part", ["-mesh_file", overlap, "-bc_dirichlet", "3,5"], "-bc_dirichlet and -bc_contact", True),
        ("a face in two Neumann parts", ["-mesh_file", overlap, "-bc_neumann", "2,4,5", "-g", "1"], "overlap", True),
        ("same part named twice", ["-bc_neumann", "1,2,4"], "-bc_neumann and -bc_contact", False),
        # an option of another kind of run would be ignored, and a file asked for never written
        ("study option without a study", ["-reference_refine", "1"], "option -reference_refine: applies to a convergence study only", False),
        ("study table file without a study", ["-study_output", never], "option -study_output: applies to a convergence study only", False),
        ("-output in a study", ["-study_levels", "2"], "option -output: a convergence study writes", False),
        ("a study's element named twice", ["-study_levels", "2", "-study_spaces", "p1, cr,P1"], "option -study_spaces: element p1 is named twice", False),
        ("a study of no element", ["-study_levels", "2", "-study_spaces", ""], "option -study_spaces: no element to study", False),
        ("no Dirichlet and no contact part (singular)", ["-bc_dirichlet", "", "-bc_contact", "", "-bc_neumann", "1,2,3,4"], "singular", False),
        # without a Dirichlet part a solution exists only for a load pushing u towards the obstacle (sum < 0)
        ("no Dirichlet part, load pushing u away from the obstacle", ["-bc_dirichlet", "", "-bc_neumann", "2,3,4", "-f", "1 + x"], "no solution exists", True),
        ("no Dirichlet part, load of sum zero", ["-bc_dirichlet", "", "-bc_neumann", "2,3,4"], "not unique", True),
        ("no Dirichlet part, Neumann flux pushing u away", ["-bc_dirichlet", "", "-bc_neumann", "2,3,4", "-f", "-1", "-g", "y > 0.999 ? 2 : 0"], "no solution exists", True),
        # the same piece by piece: tests/data/two-squares.msh is [0,1]^2 (bottom 1, sides 2, top 3) and [2,3] x [0,1]
        # (bottom 4, sides and top 5); corner-squares.msh has the second square at [1,2]^2, touching the first at (1, 1)
        ("a piece with neither a Dirichlet nor a contact face", ["-mesh_file", two_squares, "-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4,5"],
         "the mesh is in 2 pieces (cells joined through faces), and 1 of them (one near (2.33333, 0.666667)) has neither a Dirichlet nor a contact face", True),
        ("pieces touching at a vertex", ["-mesh_file", corner_squares, "-bc_dirichlet", "3", "-bc_contact", "1", "-bc_neumann", "2,4,5"],
         "1 of them (one near (1.33333, 1.66667)) has neither", True),
        ("a piece with contact only, load pushing it away", ["-mesh_file", two_squares, "-bc_dirichlet", "3", "-bc_contact", "1,4", "-bc_neumann", "2,5", "-f", "1"],
         "1 of them (one near (2.33333, 0.666667)) has contact but no Dirichlet faces, so the load must push each such piece towards the obstacle, but the total there (int f + int g over Gamma_N) is 1", True),
        ("a piece with contact only, load of sum zero", ["-mesh_file", two_squares, "-bc_dirichlet", "3", "-bc_contact", "1,4", "-bc_neumann", "2,5"], "so the solution is not unique", True),
        # P1 couples the two squares at (1, 1), where H^1 does not: no equilibrated flux on that vertex's patch
        ("P1 estimate on a pinched mesh", ["-mesh_file", corner_squares, "-bc_dirichlet", "3", "-bc_contact", "1,4", "-bc_neumann", "2,5", "-f", "-1", "-psi", "-1", "-space", "p1"],
         "estimate: the cells around the vertex at (1, 1) are not joined through faces", True),
        # a scene's -dim against another file's mesh
        ("-dim 2 with a 3D mesh file", ["-mesh_file", cube], "options -dim 2 and -mesh_file: the mesh of '%s' is 3D" % cube, True),
        # a part by a name the mesh does not have: the message lists the names it has
        ("unknown name of a box side", ["-bc_contact", "bottm"], "option -bc_contact: 'bottm' is neither a number nor the name of a part (the box's sides: bottom 1, right 2, top 3, left 4)", False),
        ("a name in a file without physical names", ["-mesh_file", two_squares, "-bc_dirichlet", "top"], "option -bc_dirichlet: 'top' is neither a number nor the name of a part ('%s' has no physical names)" % two_squares, False),
        ("obstacle above u_D where Gamma_D meets Gamma_C", ["-bc_dirichlet", "3,4", "-bc_neumann", "2", "-psi", "0.5 - x"], "infeasible", True),
        ("f NaN", ["-f", "sqrt(x - 0.5)"], "option -f:", True),
        ("f infinite", ["-f", "1 / (x - x)"], "option -f:", True),
        # expressions without variables are evaluated once; a non-finite constant must still be caught
        ("kappa an infinite constant", ["-kappa", "1 / 0"], "option -kappa:", True),
        ("psi a NaN constant", ["-psi", "sqrt(-1)"], "option -psi:", True),
        ("g NaN on Gamma_N", ["-g", "sqrt(y - 2)"], "option -g:", True),
        ("u_D NaN on Gamma_D", ["-u_D", "log(x - 0.5)"], "option -u_D:", True),
        ("psi NaN on Gamma_C", ["-psi", "sqrt(x - 0.5)"], "option -psi:", True),
        ("exact solution NaN", ["-exact_u", "sqrt(x - 0.5)", "-exact_grad", "0, 0"], "option -exact_u:", True),
        ("exact gradient infinite", ["-exact_u", "0", "-exact_grad", "0, 1 / (y - y)"], "option -exact_grad:", True),
        ("exact gradient with 3 components in 2D", ["-exact_u", "0", "-exact_grad", "0, 0, 0"], "option -exact_grad:", False),
        # option errors come before the mesh file is even read
        ("singular, and a missing mesh file", ["-bc_dirichlet", "", "-bc_contact", "", "-mesh_file", missing], "singular", False),
        ("bad expression, and a missing mesh file", ["-f", "2*sin(", "-mesh_file", missing], "option -f:", False),
        # the mesh is what the file says, or the real reason why not
        ("duplicated node", ["-mesh_file", duplicate] + square_scene, "nodes 5 and 10 are at the same point", True),
        ("duplicated node, msh 4.1", ["-mesh_file", duplicate41] + square_scene, "nodes 5 and 10 are at the same point", True),
        ("dangling node reference", ["-mesh_file", dangling] + square_scene, "refers to node 42, which is not in $Nodes", True),
        ("a triangle (a, a, b)", ["-mesh_file", repeated] + square_scene, "element 9 (a triangle) lists node 1 twice", True),
        ("triangles and a tetrahedron", ["-mesh_file", mixed] + square_scene, "is not a face of any tetrahedron", True),
        ("second-order elements", ["-mesh_file", order2] + square_scene, "of order 2", True),
        ("msh version 1", ["-mesh_file", version1] + square_scene, "version 1", True),
        # errors while PETSc or its objects read the options
        ("missing options file", ["-options_file", missing_options], "option -options_file: cannot open '%s'" % missing_options, True),
        ("unknown partitioner", ["-mesh_partitioner", "bogus"], "option -mesh_partitioner: 'bogus' is not an available partitioner", True),
        ("SNES type without bounds", ["-snes_type", "newtonls"], "vinewtonrsls", True),
        ("unknown KSP type", ["-ksp_type", "bogus"], "KSP type bogus", True),
        ("unknown PC type", ["-pc_type", "bogus"], "PC type bogus", True),
        ("unknown PC type for the inactive-set blocks", ["-vi_pc_type", "bogus"], "PC type bogus", True),
        # tolerances PETSc reads unchecked and refuses only inside the solve; a line search the solve cannot use
        ("KSP rtol of 1", ["-ksp_rtol", "1"], "option -ksp_rtol 1: must be at least 0 and below 1", True),
        ("negative SNES atol", ["-snes_atol", "-1e-3"], "option -snes_atol -0.001: must be at least 0", True),
        ("negative KSP max_it", ["-ksp_max_it", "-3"], "option -ksp_max_it -3: must be at least 0", False),
        ("KSP rtol of 2, no contact part", ["-ksp_rtol", "2", "-bc_contact", "", "-bc_neumann", "2,4,1"], "option -ksp_rtol 2: must be at least 0 and below 1", False),
        ("line search nleqerr", ["-snes_linesearch_type", "nleqerr"], "option -snes_linesearch_type nleqerr: the contact solve cannot use it", True),
    ]

    # Errors that need no fine mesh must stop the run before the refinement (which costs minutes at scale):
    # -dm_view prints the mesh only once it is refined, so these runs must print no "DM Object".
    before_refinement = {"missing mesh file", "empty mesh file", "text file as mesh", "truncated mesh file",
                         "unknown boundary label", "expression does not parse", "unknown variable", "zero cell count",
                         "negative refine", "dim 4", "unknown space", "same part named twice",
                         "study option without a study", "study table file without a study", "-output in a study",
                         "a study's element named twice", "a study of no element",
                         "no Dirichlet and no contact part (singular)", "a piece with neither a Dirichlet nor a contact face", "pieces touching at a vertex", "-dim 2 with a 3D mesh file", "unknown name of a box side",
                         "a name in a file without physical names", "exact gradient with 3 components in 2D",
                         "singular, and a missing mesh file", "bad expression, and a missing mesh file",
                         "quadrilateral cells", "no cells of dimension 2 or 3", "curved surface mesh",
                         "duplicated node", "duplicated node, msh 4.1", "dangling node reference", "a triangle (a, a, b)", "triangles and a tetrahedron",
                         "second-order elements", "msh version 1", "missing options file", "unknown partitioner",
                         "SNES type without bounds", "unknown KSP type", "unknown PC type", "KSP rtol of 1", "negative SNES atol",
                         "negative KSP max_it", "KSP rtol of 2, no contact part", "line search nleqerr"}
    c.check(before_refinement <= {case[0] for case in cases}, "every case named in before_refinement exists")
    for name, extra, names, parallel in cases:
        for ranks in [1, 2] if parallel else [1]:
            what = "%s, %d rank(s)" % (name, ranks)
            with tempfile.TemporaryDirectory() as out:
                args = base + ["-output", os.path.join(out, "out.h5"), "-refine", "1", "-dm_view"] + extra
                try:
                    rc, stdout, err, summary = harness.run(args, ranks=ranks, check=False)
                except subprocess.TimeoutExpired:
                    c.check(False, "%s: finished (it hung until the harness timeout)" % what)
                    continue
                left = sorted(os.listdir(out))
            lines = [l for l in err.splitlines() if l.strip()]
            ours = [l for l in lines if l.startswith(PREFIX)]
            msg = ours[0] if ours else (lines[0] if lines else "(nothing on stderr)")
            c.check(rc == 1, "%s: exit status %d" % (what, rc))
            # On 2 ranks mpirun adds its own notice about the non-zero exit status; ours must appear once.
            c.check(len(ours) == 1 and (ranks > 1 or len(lines) == 1),
                    "%s: one error line (%d of ours, %d lines in all): %s" % (what, len(ours), len(lines), msg))
            c.check(len(ours) == 1 and names in ours[0], "%s: the message names '%s'" % (what, names))
            c.check("MPI_ABORT" not in err, "%s: no MPI_Abort" % what)
            if name in before_refinement:
                c.check("DM Object" not in stdout, "%s: stopped before the refinement (no -dm_view output)" % what)
            c.check(summary is None and not left, "%s: no summary, nothing left in the output directory %s" % (what, left))
    c.check(not os.path.exists(os.path.dirname(nodir)), "the missing output directory was not created")
    c.check(not os.path.exists(never), "the study table of a run without a study was not written")
c.done()

"""The faces into a shell and a solid: ``BRep_Builder`` shell → ``ShapeFix_Shell`` → ``MakeSolid`` →
``ShapeFix_Solid`` → ``OrientClosedSolid``; a shell with free edges sewn as the last resort, and the healing a
solid may need after that."""

from __future__ import annotations

from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeSolid, BRepBuilderAPI_Sewing
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepLib import BRepLib
from OCP.ShapeFix import ShapeFix_Shell, ShapeFix_Solid
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID, TopAbs_WIRE
from OCP.TopExp import TopExp_Explorer
from OCP.TopTools import TopTools_IndexedMapOfShape
from OCP.TopoDS import TopoDS, TopoDS_Compound, TopoDS_Shell

from ._edges import fix_edges
from ._faces import PRECISION_SHARE, face_problems
from ._result import collapsed_face_count, count_shapes, free_edge_count, shape_validity


#: Sewing tolerances tried, as multiples of the tolerance, when the shell has free edges (the last resort): copies
#: of shared edges need almost none; beyond 10× sewing closed no more shells and merged small edges (bench/brep.md).
SEWING_FACTORS = (1.0, 10.0)


#: Small edges that make a sewn shell unorientable are dropped at these multiples of the tolerance, the least first.
SMALL_EDGE_FACTORS = (2.0, 4.0)


def assemble(faces, tolerance, open_mesh, warnings):
    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    for f in faces:
        builder.Add(shell, f)
    sewn_shell = False
    if free_edge_count(shell) > 0 and not open_mesh:
        # Faces that did not use the shared edges (copies, fillings, failures): sew as the last resort, at the
        # smallest tolerance that closes the shell (copies of shared edges need almost none; a wide sewing
        # merges the small edges of small faces). A mesh of several bodies sews into several shells: their
        # faces go back into one shell, which ShapeFix_Shell splits by connection below.
        best = None
        for factor in SEWING_FACTORS:
            sewn = _sewn(faces, factor * tolerance)
            if sewn is None:
                continue
            free = free_edge_count(sewn)
            if best is None or free < best[0]:
                best = (free, factor, sewn)
            if free == 0:
                break
        if best is not None:
            shell = best[2]
            sewn_shell = True
            warnings.append(f"shell had free edges; sewn at {best[1] * tolerance:g} ({best[1]:g}× the tolerance)")
            if best[0] == 0 and orientation_conflicts(shell):
                shell = _without_small_edges(shell, tolerance, warnings)
        else:
            warnings.append("shell had free edges; sewing returned no face")
    # A shell as built needs orientation only: every face was mended (and checked) on its own already, and
    # ShapeFix_Shell's own pass of ShapeFix_Face works at OCC's 1e-7 and re-merges what the faces share (it can
    # split a closed manifold shell into several with free edges). Sewing re-cuts edges: that pass mends what it
    # leaves.
    face_mode = -1 if sewn_shell else 0  # -1: its default
    fixed = _shell_fixed(shell, face_mode)
    if fixed is None and face_mode:  # mending the faces failed in OCC: orienting them may not
        warnings.append("mending the sewn faces failed (OpenCascade: command not done): the sewn faces only oriented")
        face_mode, fixed = 0, _shell_fixed(shell, 0)
    if fixed is None:  # the shell as built: the verdict judges what it holds
        warnings.append("orienting the shell's faces failed (OpenCascade: command not done): the shell as built")
        fixed = shell
    if face_mode:
        # ShapeFix_Face makes degenerate an edge whose vertex lies within its (sewing-widened) tolerance of a
        # narrow side of its surface: a shared edge lost splits the shell in two, a face bounded by it alone has no
        # area left (no STEP file holds it). The sewn faces only oriented are kept when they stay whole.
        oriented = _shell_fixed(shell, 0)
        if oriented is not None and _pieces(fixed) > _pieces(oriented):
            warnings.append("mending the sewn faces split the shell or left a face with no area: the sewn faces "
                            "only oriented")
            face_mode, fixed = 0, oriented
    shells = []
    exp = TopExp_Explorer(fixed, TopAbs_SHELL)
    while exp.More():
        shells.append(TopoDS.Shell_s(exp.Current()))
        exp.Next()
    if not shells:
        warnings.append("ShapeFix_Shell returned no shell: the result is the loose faces")
        comp = TopoDS_Compound()
        builder.MakeCompound(comp)
        for f in faces:
            builder.Add(comp, f)
        return comp
    if open_mesh:
        return shells[0] if len(shells) == 1 else fixed
    solids = []
    for sh in shells:
        if free_edge_count(sh) > 0:
            warnings.append(f"a shell with {free_edge_count(sh)} free edges is left as a shell")
            solids.append(sh)
            continue
        mk = BRepBuilderAPI_MakeSolid(sh)
        if not mk.IsDone():
            warnings.append("BRepBuilderAPI_MakeSolid failed: a closed shell is left as a shell")
            solids.append(sh)
            continue
        sf = ShapeFix_Solid(mk.Solid())
        sf.FixShellTool().FixFaceMode = face_mode  # (as for the shell above)
        sf.Perform()
        fixed_solid = sf.Solid()
        if fixed_solid.IsNull() or fixed_solid.ShapeType() != TopAbs_SOLID:
            warnings.append("ShapeFix_Solid returned no solid: a closed shell is left as a shell")
            solids.append(sh)
            continue
        solid = TopoDS.Solid_s(fixed_solid)
        try:
            oriented = BRepLib.OrientClosedSolid_s(solid)
        except Exception as err:  # noqa: BLE001  (OCC raises Standard_Failure subclasses on degenerate faces)
            warnings.append(f"BRepLib.OrientClosedSolid failed ({type(err).__name__}): a closed shell is left as a shell")
            solids.append(sh)
            continue
        if not oriented:
            warnings.append("BRepLib.OrientClosedSolid could not orient the solid")
        solids.append(solid)
    if len(solids) == 1:
        return solids[0]
    comp = TopoDS_Compound()
    builder.MakeCompound(comp)
    for s in solids:
        builder.Add(comp, s)
    warnings.append(f"{len(solids)} bodies: the result is a compound")
    return comp


def _shell_fixed(shell, face_mode: int):
    """``ShapeFix_Shell`` on ``shell`` (its faces oriented alike, split by connection), with ``FixFaceMode``
    ``face_mode``: -1 mends every face too (ShapeFix_Face), 0 orients only; None when OpenCascade fails."""
    fix = ShapeFix_Shell(shell)
    fix.FixFaceMode = face_mode
    try:
        fix.Perform()
    except Exception:  # noqa: BLE001  (OCC raises Standard_Failure subclasses: StdFail_NotDone on seed 149)
        return None
    return fix.Shape()


def _pieces(shape) -> int:
    """Shells and faces with no area in ``shape``: what a face mending must not add."""
    return count_shapes(shape, TopAbs_SHELL) + collapsed_face_count(shape)


def _sewn(faces, tolerance: float):
    """All ``faces`` sewn at ``tolerance``, back in one shell (``None`` if sewing returned no face)."""
    sew = BRepBuilderAPI_Sewing(tolerance)
    for f in faces:
        sew.Add(f)
    sew.Perform()
    builder = BRep_Builder()
    shell = TopoDS_Shell()
    builder.MakeShell(shell)
    n_faces = 0
    exp = TopExp_Explorer(sew.SewedShape(), TopAbs_FACE)
    while exp.More():
        builder.Add(shell, exp.Current())
        n_faces += 1
        exp.Next()
    return shell if n_faces else None


def orientation_conflicts(shell) -> int:
    """Edges that two faces of ``shell`` run in the same direction: where no orientation of the faces agrees.

    In a closed orientable shell every edge is used once forward and once reversed. Faces are built oriented by
    the mesh normals, so a conflict is not a face the wrong way round but an edge sewing joined wrongly: a short
    edge cut where the sewing tolerance spans more than it, along which ShapeFix_Shell splits the closed shell.
    """
    emap = TopTools_IndexedMapOfShape()
    uses: dict[int, list] = {}
    faces = TopExp_Explorer(shell, TopAbs_FACE)
    i = 0
    while faces.More():
        edges = TopExp_Explorer(faces.Current(), TopAbs_EDGE)  # orientations composed with the face's
        while edges.More():
            edge = edges.Current()
            if not BRep_Tool.Degenerated_s(TopoDS.Edge_s(edge)):
                uses.setdefault(emap.Add(edge), []).append((i, edge.Orientation()))
            edges.Next()
        faces.Next()
        i += 1
    return sum(len(u) == 2 and u[0][0] != u[1][0] and u[0][1] == u[1][1] for u in uses.values())


def _without_small_edges(shell, tolerance: float, warnings):
    """``shell`` with its small edges dropped (vertices merged, in every face that shares them) at the least of
    :data:`SMALL_EDGE_FACTORS` × ``tolerance`` that leaves no orientation conflict and every face; else ``shell``.
    """
    from OCP.ShapeFix import ShapeFix_Wireframe

    n_faces = count_shapes(shell, TopAbs_FACE)
    for factor in SMALL_EDGE_FACTORS:
        fix = ShapeFix_Wireframe(shell)
        fix.SetPrecision(factor * tolerance)
        fix.ModeDropSmallEdges = True
        if not fix.FixSmallEdges():
            continue
        out = fix.Shape()
        same_faces = out.ShapeType() == TopAbs_SHELL and count_shapes(out, TopAbs_FACE) == n_faces
        if same_faces and not orientation_conflicts(out):
            warnings.append(f"sewing left {orientation_conflicts(shell)} edges no orientation agrees on: edges under "
                            f"{factor:g}× the tolerance were dropped")
            return TopoDS.Shell_s(out)
    warnings.append(f"sewing left {orientation_conflicts(shell)} edges no orientation agrees on")
    return shell


def whole_fixed(shape, tolerance: float, warnings):
    """A closed solid BRepCheck refuses, after ShapeFix_Shape on the whole of it; ``shape`` if that is no better.

    The last resort, kept only when the result is one valid closed solid with every face: ShapeFix_Shape mends
    the faces and their shared edges together, where :func:`mend_faces` mends each face alone.
    """
    from OCP.ShapeFix import ShapeFix_Shape

    fix = ShapeFix_Shape(shape)
    fix.SetPrecision(PRECISION_SHARE * tolerance)
    fix.SetMaxTolerance(SEWING_FACTORS[-1] * tolerance)
    fix.Perform()
    out = fix.Shape()
    if (out.ShapeType() == TopAbs_SOLID and count_shapes(out, TopAbs_FACE) == count_shapes(shape, TopAbs_FACE)
            and shape_validity(out).ok):
        warnings.append("the solid was invalid after assembly: mended whole by ShapeFix_Shape")
        return TopoDS.Solid_s(out)
    return shape


def mend_faces(shape, tolerance: float, warnings) -> None:
    """Mend, in place, faces of the assembled ``shape`` that BRepCheck refuses: edges made same-parameter, then
    ShapeFix_Wire's self-intersection fix.

    Every face was valid when it was built; sewing at a tolerance above the edges' own re-cuts and re-tolerances
    them (a valid B-spline face can self-intersect after sewing at 10× the tolerance).
    """
    from OCP.ShapeFix import ShapeFix_Wire

    exp = TopExp_Explorer(shape, TopAbs_FACE)
    while exp.More():
        face = TopoDS.Face_s(exp.Current())
        exp.Next()
        if BRepCheck_Analyzer(face).IsValid():
            continue
        fix_edges(face)
        if not BRepCheck_Analyzer(face).IsValid():
            wires = TopExp_Explorer(face, TopAbs_WIRE)
            while wires.More():
                ShapeFix_Wire(TopoDS.Wire_s(wires.Current()), face, PRECISION_SHARE * tolerance).FixSelfIntersection()
                wires.Next()
        problems = face_problems(face)
        still = f"; still: {problems}" if problems else ""
        warnings.append(f"a face invalid after assembly was mended in place{still}")

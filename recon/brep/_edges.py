"""Edges and wires: the network's vertices and edges made once as OCC topology, shared by the faces on both sides.

Also the repairs that keep them shared: a face's ShapeFix may split or re-tolerance a shared edge, recorded in a
context the later faces read (:func:`shared_wire`, :func:`hand_on`), and undone when the face fails.
"""

from __future__ import annotations

import numpy as np
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve2d
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeVertex
from OCP.Geom import Geom_BSplineCurve, Geom_Circle
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.ShapeFix import ShapeFix_Edge
from OCP.TColgp import TColgp_Array1OfPnt
from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopTools import TopTools_IndexedMapOfShape
from OCP.TopoDS import TopoDS, TopoDS_Wire

from ..fit import BSplineCurve, CurveKind, EdgeCurve
from ..network import CurveNetwork, NetworkGeometry
from ..errors import BrepError

#: A vertex's tolerance never below OCC's own precision (``Precision::Confusion``), however small its gap.
MIN_VERTEX_TOLERANCE = 1e-7
#: A vertex tolerance raised to a measured gap goes 1% beyond it (scales with the gap): rounding never leaves it short.
VERTEX_SLACK = 1.01


def pnt(p) -> gp_Pnt:
    return gp_Pnt(float(p[0]), float(p[1]), float(p[2]))


def vec3(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()])


def bspline_curve(spline: BSplineCurve) -> Geom_BSplineCurve:
    """The OCC curve of ``spline``: its full knot vector as distinct knots with multiplicities."""
    ctrl = np.asarray(spline.control_points, float)
    knots = np.asarray(spline.knots, float)
    vals, mults = np.unique(np.round(knots, 14), return_counts=True)
    poles = TColgp_Array1OfPnt(1, len(ctrl))
    for i, c in enumerate(ctrl, start=1):
        poles.SetValue(i, pnt(c))
    kn = TColStd_Array1OfReal(1, len(vals))
    mu = TColStd_Array1OfInteger(1, len(vals))
    for i, (v, m) in enumerate(zip(vals, mults), start=1):
        kn.SetValue(i, float(v))
        mu.SetValue(i, int(m))
    return Geom_BSplineCurve(poles, kn, mu, int(spline.degree))


def geom_curve(curve: EdgeCurve) -> Geom_Circle | Geom_BSplineCurve | None:
    """The one conversion of an :class:`~recon.fit.EdgeCurve` to an OCC curve: a ``Geom_Circle`` or a
    ``Geom_BSplineCurve``; None for a line (an edge between its two vertices needs no curve object)."""
    if curve.kind is CurveKind.CIRCLE:
        c = curve.circle
        assert c is not None
        ax = gp_Ax2(pnt(c.center), gp_Dir(*map(float, c.normal)), gp_Dir(*map(float, c.x_dir)))
        return Geom_Circle(ax, float(c.radius))
    if curve.kind is CurveKind.BSPLINE:
        assert curve.spline is not None
        return bspline_curve(curve.spline)
    return None


def make_edge(curve: EdgeCurve, v1, v2, builder: BRep_Builder):
    """A TopoDS_Edge on ``curve`` between the shared vertices ``v1``, ``v2``."""
    try:
        geom = geom_curve(curve)
        if geom is None:
            mk = BRepBuilderAPI_MakeEdge(v1, v2)
        elif isinstance(geom, Geom_Circle):
            # The vertices lie on the fitted circle within the fit residual: let their tolerance cover it.
            for v, t in ((v1, curve.t0), (v2, curve.t1)):
                d = BRep_Tool.Pnt_s(v).Distance(geom.Value(float(t)))
                if d > BRep_Tool.Tolerance_s(v):
                    builder.UpdateVertex(v, VERTEX_SLACK * d)
            mk = BRepBuilderAPI_MakeEdge(geom, v1, v2, float(curve.t0), float(curve.t1))
        else:
            # Explicit parameters: on a closed curve both ends project to the first one otherwise.
            mk = BRepBuilderAPI_MakeEdge(geom, v1, v2, geom.FirstParameter(), geom.LastParameter())
        if not mk.IsDone():
            raise BrepError(f"BRepBuilderAPI_MakeEdge failed ({mk.Error()}) for a {curve.kind} edge")
        return mk.Edge()
    except BrepError:
        raise
    except Exception as err:
        raise BrepError(f"could not build a {curve.kind} edge: {err}") from err


def shared_wire(refs, edges, context=None):
    """A wire of the shared edges ``refs`` (signed ``±(edge + 1)``), as the context has them by now.

    An earlier face's ShapeFix may have replaced or split a shared edge (recorded in ``context``); this face
    must use the same replacement or the two faces stop sharing it. The edges go in as they are
    (``BRep_Builder``): ``BRepBuilderAPI_MakeWire`` joins vertices that lie within each other's tolerance by
    copying edges onto one of them, a change nobody records, so the neighbouring face keeps the old edge
    (free edges before sewing). Joining them is
    ShapeFix's job, recorded in its context.
    """
    builder = BRep_Builder()
    wire = TopoDS_Wire()
    builder.MakeWire(wire)
    n = 0
    for r in refs:
        e = edges[abs(r) - 1]
        if e is None:
            raise BrepError(f"shared edge {abs(r) - 1} could not be built")
        e = e if r > 0 else TopoDS.Edge_s(e.Reversed())
        pieces = [e]
        if context is not None:
            now = context.Apply(e)
            if now.IsNull():
                raise BrepError(f"shared edge {abs(r) - 1} was removed by an earlier repair")
            if now.ShapeType() == TopAbs_EDGE:
                pieces = [TopoDS.Edge_s(now)]
            else:
                pieces = []
                exp = TopExp_Explorer(now, TopAbs_EDGE)
                while exp.More():
                    pieces.append(TopoDS.Edge_s(exp.Current()))
                    exp.Next()
        for piece in pieces:
            builder.Add(wire, piece)
            n += 1
    if not n:
        raise BrepError("the boundary loop has no edges")
    return wire


def checked_edges(loop, edges, context) -> list:
    """The loop's current shared edges, each checked to have a 3D curve and two non-null vertices.

    ``BRepOffsetAPI_MakeFilling`` dereferences edge vertices without checks: a null one there has killed
    the whole process ("BRep_Tool:: TopoDS_Vertex hasn't gp_Pnt", then a segfault). Nothing unchecked
    goes in.
    """
    out = []
    wire = shared_wire(loop, edges, context)
    exp = TopExp_Explorer(wire, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        if edge.IsNull() or BRep_Tool.Degenerated_s(edge):
            raise BrepError("a boundary edge is null or degenerate")
        if not BRep_Tool.IsGeometric_s(edge):
            raise BrepError("a boundary edge has no 3D curve")
        for vtx in (TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)):
            if vtx.IsNull() or vtx.TShape() is None:
                raise BrepError("a boundary edge has a null vertex")
        out.append(edge)
        exp.Next()
    if not out:
        raise BrepError("the boundary loop has no edges")
    return out


def shape_tolerance(shape) -> float:
    if shape.ShapeType() == TopAbs_VERTEX:
        return BRep_Tool.Tolerance_s(TopoDS.Vertex_s(shape))
    return BRep_Tool.Tolerance_s(TopoDS.Edge_s(shape))


def set_tolerance(shape, tol: float) -> None:
    """Set the tolerance of one vertex or edge, down as well as up (BRep_Builder only raises it)."""
    from OCP.ShapeFix import ShapeFix_ShapeTolerance

    if shape_tolerance(shape) != tol:
        ShapeFix_ShapeTolerance().SetTolerance(shape, tol, shape.ShapeType())


def subshapes(wires) -> list:
    """The vertices, then the edges, of ``wires`` (each once)."""
    out = []
    for kind in (TopAbs_VERTEX, TopAbs_EDGE):
        found = TopTools_IndexedMapOfShape()
        for wire in wires:
            TopExp.MapShapes_s(wire, kind, found)
        out.extend(found.FindKey(i) for i in range(1, found.Extent() + 1))
    return out


def hand_on(local, shapes, context) -> None:
    """Record in the shared ``context`` what the face's own ``local`` context did to ``shapes``.

    ``shapes`` are the wires' vertices and edges as they were before ShapeFix: ShapeFix edits the wires
    themselves (their edges after it are its own), and a vertex it merged with a neighbour must reach the
    other edges that meet there, in faces not built yet, or the next face finds two vertices and merges
    them again into a third (free edges before sewing).
    """
    for s in shapes:
        now = local.Apply(s)
        if now.IsNull():
            context.Remove(s)
        elif not now.IsSame(s):
            context.Replace(s, now)


def fix_edges(face) -> None:
    """Make every edge of ``face`` same-parameter with a tolerance that covers its measured gap.

    The network's edges lie on a fitted surface only within the fit's residual, and the pieces of an edge
    that ShapeFix split at a seam lose their same-range flag; ``ShapeFix_Edge`` re-projects the p-curve,
    measures the 3D/2D deviation and raises the edge (and vertex) tolerance to it.
    """
    sfe = ShapeFix_Edge()
    surface = BRep_Tool.Surface_s(face)
    exp = TopExp_Explorer(face, TopAbs_EDGE)
    while exp.More():
        edge = TopoDS.Edge_s(exp.Current())
        sfe.FixSameParameter(edge, face)
        sfe.FixVertexTolerance(edge, face)
        _cover_pcurve_ends(edge, face, surface)
        exp.Next()


def _cover_pcurve_ends(edge, face, surface) -> None:
    """Raise each vertex's tolerance to reach the ends of the edge's p-curve mapped onto the surface.

    The vertex is the surfaces' least-squares meeting point, off a fitted surface by up to the fit residual;
    the p-curve ends lie on the surface. Without this the wire is open in the face's parameter space
    (BRepCheck NotClosed) although it is closed in 3D.
    """
    first, last = TopExp.FirstVertex_s(edge), TopExp.LastVertex_s(edge)
    if first.IsNull() or last.IsNull():
        return
    if not BRep_Tool.IsGeometric_s(edge) or BRep_Tool.CurveOnSurface_s(edge, face, 0.0, 0.0) is None:
        return
    c2d = BRepAdaptor_Curve2d(edge, face)
    t0, t1 = c2d.FirstParameter(), c2d.LastParameter()
    builder = BRep_Builder()
    for vtx, t in ((first, t0), (last, t1)):
        uv = c2d.Value(t)
        d = surface.Value(uv.X(), uv.Y()).Distance(BRep_Tool.Pnt_s(vtx))
        if d > BRep_Tool.Tolerance_s(vtx):
            # 5% beyond the measured p-curve gap (scales with the gap): covers the re-projection ShapeFix does later
            builder.UpdateVertex(vtx, 1.05 * d)


def shared_topology(network: CurveNetwork, geo: NetworkGeometry, warnings: list) -> list:
    """One ``TopoDS_Edge`` per network edge (None where it could not be built, named in ``warnings``), on one
    ``TopoDS_Vertex`` per network vertex whose tolerance covers its gap to the surfaces that meet there."""
    builder = BRep_Builder()
    vertices = []
    for p, gap in zip(geo.points, geo.vertex_gap):
        vtx = BRepBuilderAPI_MakeVertex(pnt(p)).Vertex()
        builder.UpdateVertex(vtx, max(MIN_VERTEX_TOLERANCE, VERTEX_SLACK * float(gap)))
        vertices.append(vtx)
    edges = []
    for e in range(network.n_edges):
        a, b = network.edge_vertices[e]
        try:
            edges.append(make_edge(geo.curves[e], vertices[a], vertices[b], builder))
        except BrepError as err:
            # The faces that use it fail (as records); the rest of the solid is still built.
            warnings.append(f"edge {e} between parts {network.edge_parts[e].tolist()}: {err}")
            edges.append(None)
    return edges

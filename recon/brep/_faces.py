"""A part's face on its own surface: bounded by the shared edges, by copies of them, or by its own p-curves.

Each face is its surface bounded by wires (``BRepBuilderAPI_MakeFace(surface, wire, Inside=False)`` +
``ShapeFix_Face`` for the p-curves, the recipe measured in shared/OCP-NOTES.md). The ways it is tried in turn,
and the fallbacks after them, are :mod:`recon.brep._strategies`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeVertex
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepLib import BRepLib
from OCP.ShapeBuild import ShapeBuild_ReShape
from OCP.ShapeFix import ShapeFix_Face
from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX, TopAbs_WIRE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopTools import TopTools_IndexedMapOfShape
from OCP.TopoDS import TopoDS, TopoDS_Face, TopoDS_Wire

from .._parallel import Failure, FailureKind, isolated
from ..network import CurveNetwork, NetworkGeometry
from .._tolerance import SMOOTH_TURN
from ..fit import CLOSED_KINDS
from ..errors import BrepError
from . import _serial  # noqa: F401  (faces cross the pipe from a child as BREP bytes)
from ._edges import (
    MIN_VERTEX_TOLERANCE,
    fix_edges,
    hand_on,
    make_edge,
    pnt,
    set_tolerance,
    shape_tolerance,
    shared_wire,
    subshapes,
)
from ._result import count_shapes, face_area
from ._surfaces import SurfaceModel

log = logging.getLogger(__name__)


#: Seconds a face on its own curves may take in its child: such faces take well under a tenth of it; one that
#: takes longer spins (the evidence: bench/brep.md, "OWN_CURVES_TIMEOUT").
OWN_CURVES_TIMEOUT = 5.0


#: ShapeFix_Face's precision as a share of the tolerance (OCC's default is 1e-7): p-curves approximated at the
#: full tolerance move a face's area by up to it; a tenth of it keeps them exact (bench/brep.md).
PRECISION_SHARE = 0.1


#: A fit out of tolerance still bounds its own face ("poor") before any filling is tried when its RMS deviation is
#: within this many tolerances: nearer, its face beats a filling; farther, the fit is of a wrong shape (bench/brep.md).
OWN_SURFACE_RMS = 4.0


def reach_margin(tolerance: float, diagonal: float) -> float:
    """How far a face may reach outside the mesh's bounding box: 2T (the fit's max) plus the chord sag of the
    longest chord the mesh can hold (its diagonal) across the largest smooth turn, :data:`recon._tolerance.SMOOTH_TURN` (≈ 0.1 × diagonal).
    A face beyond it is not the mesh's surface: a plane or B-spline left untrimmed, a filling gone wild."""
    return 2.0 * tolerance + 0.5 * float(np.tan(SMOOTH_TURN / 4.0)) * diagonal


#: A face whose optimal box passes the margin is triangulated to bound it closer only when that box lies within this
#: many diagonals of the mesh (scales with the part's size): a face farther out is wild anyway, and meshing a face
#: reaching 1e8 diagonals out took minutes and gigabytes (the deviation's BRepMesh, bench/brep.md "REACH").
REACH_MESHED = 10.0


@dataclass(frozen=True)
class Reach:
    """The box a part's face must stay within: the mesh's bounding box ``lo``..``hi`` grown by ``margin``."""

    lo: np.ndarray
    hi: np.ndarray
    margin: float
    #: Linear deflections a face must get triangles at (:meth:`unmeshable`): FreeCAD's for the mesh's box, first
    deflections: tuple[float, ...]

    @classmethod
    def of(cls, points, tolerance: float) -> Reach:
        """The reach for a mesh whose points (or a sample of them holding its extremes) are ``points (k, 3)``."""
        from ._tessellate import box_display_deflection

        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return cls(lo, hi, reach_margin(tolerance, float(np.linalg.norm(hi - lo))), (box_display_deflection(lo, hi),))

    def meshing_at(self, deflection: float) -> Reach:
        """This reach, its faces also required to mesh at ``deflection``: FreeCAD's for a built solid, whose box
        (OpenCascade's, B-spline poles and tolerances included) is not the mesh's, and a face can mesh at one
        deflection and not at another a few per cent away (bench/brep.md, stop 34)."""
        return replace(self, deflections=self.deflections + (float(deflection),))

    def outside(self, face) -> float:
        """How far ``face`` reaches outside the mesh's box (≤ 0 within it), from a box that holds it.

        OpenCascade's quick box of a face holds a B-spline's poles, its optimal box the surface over the face's whole
        UV rectangle (a band across a torus: the torus's far side): each is only an upper bound, so a face past the
        margin by one is bounded again, finer. Last, a face that is not wild (within :data:`REACH_MESHED` diagonals)
        is triangulated at a quarter of the margin, and its nodes grown by that deflection bound it.
        """
        far = self._beyond(face, optimal=False)
        if far > self.margin:
            far = self._beyond(face, optimal=True)
        if self.margin < far <= REACH_MESHED * self.diagonal:
            far = min(far, self._beyond_meshed(face))
        return far

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))

    def refusal(self, face) -> str:
        """Why ``face`` is refused for reaching too far outside the mesh, or "" when it stays within the margin."""
        far = self.outside(face)
        return "" if far <= self.margin else self.why(far)

    def why(self, far: float) -> str:
        """The reason a face reaching ``far`` outside the mesh's box (past the margin) is refused."""
        return (f"its face reaches {far:.4g} outside the mesh's bounding box (more than the margin {self.margin:.4g}: "
                "a surface left untrimmed or a filling gone wild); refused")

    def unmeshable(self, face) -> bool:
        """Whether OpenCascade's mesher leaves ``face`` without a triangle at FreeCAD's display settings for this mesh
        (a hole in every viewer and every STL export; issue 25), or at any other of :attr:`deflections`. Meshed on a
        copy, as :func:`recon.brep._tessellate.unmeshed_faces` meshes the result."""
        from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
        from OCP.BRepMesh import BRepMesh_IncrementalMesh

        from ._tessellate import DISPLAY_ANGLE, has_triangles

        for deflection in self.deflections:
            try:
                copy = TopoDS.Face_s(BRepBuilderAPI_Copy(face, True, False).Shape())
                BRepMesh_IncrementalMesh(copy, deflection, False, DISPLAY_ANGLE, True)
            except Exception:  # noqa: BLE001  (OCC raises Standard_Failure: then the face got no triangles)
                return True
            if not has_triangles(copy):
                return True
        return False

    def wild(self, far: float) -> bool:
        """Whether a face reaching ``far`` outside is wild: farther than :data:`REACH_MESHED` diagonals, where
        meshing it for the deviation took minutes and gigabytes; nearer, a refused face is still measurable."""
        return not far <= REACH_MESHED * self.diagonal

    def _box_beyond(self, x0, y0, z0, x1, y1, z1) -> float:
        return float(max(np.max(self.lo - np.array([x0, y0, z0])), np.max(np.array([x1, y1, z1]) - self.hi)))

    def _beyond(self, face, *, optimal: bool) -> float:
        box = Bnd_Box()
        try:
            if optimal:
                BRepBndLib.AddOptimal_s(face, box, False, False)
            else:
                BRepBndLib.Add_s(face, box, False)
        except Exception:  # noqa: BLE001  (OCC cannot bound the face: it reaches nowhere measurable)
            return float("inf")
        if box.IsVoid() or box.IsOpen():  # no box, or an infinite face
            return float("inf")
        return self._box_beyond(*box.Get())

    def _beyond_meshed(self, face) -> float:
        """The face's reach from its triangulation at a quarter of the margin (on a copy: the face keeps none)."""
        from OCP.BRepBuilderAPI import BRepBuilderAPI_Copy
        from OCP.BRepMesh import BRepMesh_IncrementalMesh
        from OCP.TopLoc import TopLoc_Location

        deflection = 0.25 * self.margin
        try:
            copy = TopoDS.Face_s(BRepBuilderAPI_Copy(face, True, False).Shape())
            BRepMesh_IncrementalMesh(copy, deflection, False, 0.5, False)
            loc = TopLoc_Location()
            tri = BRep_Tool.Triangulation_s(copy, loc)
        except Exception:  # noqa: BLE001  (OCC cannot mesh it: the boxes above stand)
            return float("inf")
        if tri is None or tri.NbNodes() == 0:
            return float("inf")
        trsf = loc.Transformation()
        nodes = np.array([[(p := tri.Node(i).Transformed(trsf)).X(), p.Y(), p.Z()]
                          for i in range(1, tri.NbNodes() + 1)])
        return self._box_beyond(*nodes.min(axis=0), *nodes.max(axis=0)) + deflection


def near_enough(fit, tolerance: float) -> bool:
    """Whether an out-of-tolerance fit is still close enough to bound its own face (:data:`OWN_SURFACE_RMS`)."""
    dev = getattr(fit, "deviation", None) or {}
    rms = dev.get("rms", np.nan)
    return bool(np.isfinite(rms) and rms <= OWN_SURFACE_RMS * tolerance)


def orientation_vote(model: SurfaceModel, points, normals) -> int:
    """+1 if the surface's own normal agrees with the mesh's outward normals on this part, else -1."""
    if len(points) == 0:
        return 1
    sn = model.signed_normals(points)
    return 1 if float(np.sum(np.einsum("ij,ij->i", sn, normals))) >= 0 else -1


def face_fixer(model: SurfaceModel, wires, precision: float):
    """``ShapeFix_Face`` (not yet performed) of the face on ``model``'s surface bounded by ``wires``."""
    mk = BRepBuilderAPI_MakeFace(model.geom, wires[0], False)
    if not mk.IsDone():
        raise BrepError(f"BRepBuilderAPI_MakeFace failed ({mk.Error()})")
    for w in wires[1:]:
        mk.Add(w)
    fix = ShapeFix_Face(mk.Face())
    # Near the model's tolerance, not at OCC's 1e-7: a p-curve end that misses its neighbour's by less than the
    # vertices' tolerance is not a gap to fill with a new edge (ShapeFix_Wire's FixLacking), an edge that the
    # neighbouring face never sees (see PRECISION_SHARE).
    fix.SetPrecision(PRECISION_SHARE * precision)
    fix.SetMaxTolerance(10.0 * precision)
    return fix


def face_of_whole_surface(model: SurfaceModel, vote: int, *, precision: float):
    """The face covering all of a sphere or torus, for a closed body one part covers (a part with no loop); its
    normal turned to the mesh's outward one (``vote``). ``(face, area)``."""
    if model.kind not in CLOSED_KINDS:
        raise BrepError(f"a closed body one {model.kind} part covers has no edge to bound its face (only a whole "
                        f"{' or '.join(CLOSED_KINDS)} closes on itself)")
    mk = BRepBuilderAPI_MakeFace(model.geom, precision)
    if not mk.IsDone():
        raise BrepError(f"BRepBuilderAPI_MakeFace failed on the whole {model.kind} ({mk.Error()})")
    face = mk.Face()
    if not BRepCheck_Analyzer(face).IsValid():
        raise BrepError(f"the whole {model.kind} face is not valid ({face_problems(face)})")
    return (TopoDS.Face_s(face.Reversed()) if vote < 0 else face), face_area(face)


def face_on_surface(model: SurfaceModel, loops: list[np.ndarray], edges, vote: int, context, *,
                     precision: float, both_sides: bool = True):
    """Face on the part's own surface; wires run counter-clockwise about the surface normal.

    With ``both_sides`` the face must pass BRepCheck in both orientations: a wire that BRepTools_WireExplorer
    walks one way but not the other (p-curves jumping by a period, edges ShapeFix added) is NotClosed as soon as
    ShapeFix_Shell turns the face over to agree with its neighbours, and the solid is invalid for that one face.
    """
    try:
        return _face_on_surface_occ(model, loops, edges, vote, context, precision, both_sides)
    except BrepError:
        raise
    except Exception as err:  # OCC raises Standard_Failure subclasses
        raise BrepError(f"OpenCascade failed on the face: {type(err).__name__}: {err}") from err


def _face_on_surface_occ(model: SurfaceModel, loops: list[np.ndarray], edges, vote: int, context, precision: float,
                         both_sides: bool):
    if vote < 0:
        loops = [-r[::-1] for r in loops]
    wires = [shared_wire(r, edges, context) for r in loops]
    fix = face_fixer(model, wires, precision)
    # ShapeFix may split a shared edge (a hole's circle at a cylinder's seam): the neighbouring faces must get
    # the same pieces. It records into a context of this face's own, handed on to the shared one only when
    # the face is accepted: a face that fails must not leave its neighbours with edges split for nothing.
    local = ShapeBuild_ReShape()
    fix.SetContext(local)
    # ShapeFix edits the wires in place: what they held before is what the shared context must map.
    before = subshapes(wires)
    tolerances = [shape_tolerance(s) for s in before]
    try:
        fix.Perform()
        # A wire that crosses itself on the surface is cut into loops and the face split into pieces
        # (ShapeFix_Face's FixLoopWire / FixSplitFace); fix.Face() is one of them, the others are lost with
        # their edges, which the neighbours still use (free edges in the shell). Such a face failed on its
        # surface: its fallbacks follow.
        pieces = count_shapes(fix.Result(), TopAbs_FACE)
        if pieces > 1:
            raise BrepError(f"face on its surface was split into {pieces} pieces (its boundary crosses itself)")
        face = TopoDS.Face_s(local.Apply(fix.Face()))
        area = face_area(face)
        if not area > 0:
            raise BrepError(f"face on its surface has area {area:.4g}")
        flipped = TopoDS.Face_s(face.Reversed())
        if not (BRepCheck_Analyzer(face).IsValid() and (not both_sides or BRepCheck_Analyzer(flipped).IsValid())):
            fix_edges(face)
            problems = face_problems(face) or (face_problems(flipped) if both_sides else "")
            if problems:
                raise BrepError(f"face on its surface is not valid ({problems})")
    except Exception:
        # ShapeFix and the edge repair raise the shared edges' and vertices' tolerances in place to fit this
        # face: one that fails must not leave them raised, or the fallback face bounded by them fails too
        for shape, tol in zip(before, tolerances):
            set_tolerance(shape, tol)
        raise
    hand_on(local, before, context)
    return (TopoDS.Face_s(face.Reversed()) if vote < 0 else face), area


def face_problems(face) -> str:
    """``BRepCheck_Analyzer``'s complaints about ``face`` and its wires, edges and vertices, counted; "" if valid."""
    analyzer = BRepCheck_Analyzer(face)
    if analyzer.IsValid():
        return ""
    counts: dict[str, int] = {}

    def note(result):
        if result is None:
            return
        try:
            items = [result.Status()]
            result.InitContextIterator()
            while result.MoreShapeInContext():
                items.append(result.StatusOnShape())
                result.NextShapeInContext()
        except Exception:  # noqa: BLE001  (the list wrapper differs between OCP builds)
            return
        for lst in items:
            for st in lst:
                name = str(st).rsplit(".", 1)[-1].replace("BRepCheck_", "")
                if name != "NoError":
                    counts[name] = counts.get(name, 0) + 1

    note(analyzer.Result(face))
    for kind in (TopAbs_WIRE, TopAbs_EDGE, TopAbs_VERTEX):
        exp = TopExp_Explorer(face, kind)
        while exp.More():
            note(analyzer.Result(exp.Current()))
            exp.Next()
    return "BRepCheck: " + (", ".join(f"{k} ×{v}" for k, v in sorted(counts.items())) or "invalid")


def face_on_copies(model: SurfaceModel, loops: list[np.ndarray], network: CurveNetwork, geo: NetworkGeometry,
                    vote: int, *, precision: float):
    """The part's face on fresh copies of its boundary edges, or ``(None, 0.0)``.

    A face that fails on the shared edges can succeed on the same curves built anew: an earlier neighbour's
    ShapeFix may have split, re-parametrised or re-toleranced a shared edge in a way this face's ShapeFix
    cannot follow (a face valid alone is NotClosed on the shared edges). The copies are the same curves between the same points, so sewing joins the face to its
    neighbours with no gap to bridge.
    """
    builder = BRep_Builder()
    used = {abs(int(r)) - 1 for loop in loops for r in loop}
    ends = {int(v) for e in used for v in network.edge_vertices[e]}
    vertices = {}
    for v in ends:
        vtx = BRepBuilderAPI_MakeVertex(pnt(geo.points[v])).Vertex()
        # 1% beyond the vertex's measured gap (scales with the gap): rounding never leaves it short
        builder.UpdateVertex(vtx, max(MIN_VERTEX_TOLERANCE, 1.01 * float(geo.vertex_gap[v])))
        vertices[v] = vtx
    copies = [None] * network.n_edges
    try:
        for e in used:
            a, b = network.edge_vertices[e]
            copies[e] = make_edge(geo.curves[e], vertices[int(a)], vertices[int(b)], builder)
        return face_on_surface(model, loops, copies, vote, ShapeBuild_ReShape(), precision=precision)
    except BrepError as err:
        log.info("%s face on copies of its edges failed too: %s", model.kind, err)
        return None, 0.0


def _uv_loop(analysis, loop, geo: NetworkGeometry, precision: float) -> list[np.ndarray]:
    """The UV points of each edge of ``loop`` on the surface, continuous along the loop.

    Consecutive edges share their meeting point's UV exactly, and in a periodic direction each point is taken
    a whole number of periods from where OCC puts it so that it lies nearest the point before (OCC keeps one
    period; the loop must not jump back across it). So the loop closes in the parameter plane, up to a period
    for a loop that goes round a periodic surface, which ShapeFix_Face gives a seam.
    """
    surface = analysis.Surface()
    periods = np.array([surface.UPeriod() if surface.IsUPeriodic() else 0.0,
                        surface.VPeriod() if surface.IsVPeriodic() else 0.0])
    out, last = [], None
    for r in loop:
        pts = geo.polyline(abs(int(r)) - 1)
        pts = pts if r > 0 else pts[::-1]
        uvs = [] if last is None else [last]
        for p in pts[len(uvs):]:
            uv = analysis.ValueOfUV(pnt(p), precision)
            uv = np.array([uv.X(), uv.Y()])
            if last is not None:
                step = np.where(periods > 0, periods * np.round((uv - last) / np.where(periods > 0, periods, 1.0)), 0.0)
                uv = uv - step
            last = uv
            uvs.append(uv)
        out.append(np.array(uvs))
    # The loop's first point, reached again: the same UV, or the same one a whole number of periods on.
    start, end = out[0][0], out[-1][-1]
    shift = np.where(periods > 0, periods * np.round((end - start) / np.where(periods > 0, periods, 1.0)), 0.0)
    out[-1][-1] = start + shift
    return out


def _boundary_edge_count(face) -> int:
    """Edges of ``face``, each once, not counting seams."""
    found = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(face, TopAbs_EDGE, found)
    return sum(not BRep_Tool.IsClosed_s(TopoDS.Edge_s(found.FindKey(i)), face) for i in range(1, found.Extent() + 1))


def _pcurve(uv: np.ndarray):
    """A degree-1 B-spline through the UV points ``uv (k, 2)`` (chord-length parameters on [0, 1])."""
    from OCP.Geom2d import Geom2d_BSplineCurve
    from OCP.TColgp import TColgp_Array1OfPnt2d
    from OCP.gp import gp_Pnt2d

    seg = np.linalg.norm(np.diff(uv, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-12])
    keep[-1] = True
    uv = uv[keep]
    if len(uv) < 2 or np.linalg.norm(uv[-1] - uv[0]) <= 1e-12 and len(uv) < 3:
        raise BrepError("an edge is a point in the surface's parameters")
    t = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))])
    t /= t[-1]
    poles = TColgp_Array1OfPnt2d(1, len(uv))
    for i, (u, v) in enumerate(uv, 1):
        poles.SetValue(i, gp_Pnt2d(float(u), float(v)))
    knots = TColStd_Array1OfReal(1, len(uv))
    mults = TColStd_Array1OfInteger(1, len(uv))
    for i, x in enumerate(t, 1):
        knots.SetValue(i, float(x))
        mults.SetValue(i, 2 if i in (1, len(uv)) else 1)
    return Geom2d_BSplineCurve(poles, knots, mults, 1)


def face_on_own_curves(model: SurfaceModel, loops: list[np.ndarray], geo: NetworkGeometry, vote: int, *,
                        precision: float):
    """The part's face bounded by its edge polylines projected onto its own surface, or ``(None, 0.0)``.

    The last resort before a filling: each edge is its polyline's image in the surface's parameters (a
    p-curve) with the 3D curve built from it, so the face's edges lie on its surface exactly and its wires
    close in the parameter plane by construction. The shared network edges lie on the surface only within
    the fit's residual, and where that residual is large (a poor fit, a CAD tessellation's long chords) the
    p-curves ShapeFix projects from them can miss each other (BRepCheck NotClosed) or cross
    (SelfIntersectingWire). The face has edges of its own, up to the edge gap from its neighbours': sewing
    joins them.
    """
    try:
        face = face_in_child(own_curves_face, (model, loops, geo, vote, precision), "ShapeFix_Face",
                              OWN_CURVES_TIMEOUT)
        return face, abs(face_area(face))
    except BrepError as err:
        log.info("%s face on its own curves failed: %s", model.kind, err)
        return None, 0.0


def own_curves_face(model: SurfaceModel, loops: list[np.ndarray], geo: NetworkGeometry, vote: int,
                     precision: float):
    """:func:`face_on_own_curves`' face, made in this process; raises :class:`BrepError`."""
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface

    try:
        analysis = ShapeAnalysis_Surface(model.geom)
        builder = BRep_Builder()
        wires = []
        for loop in (loops if vote > 0 else [-r[::-1] for r in loops]):
            # a thousandth of the face precision (scales with tolerance): the UV loop is finer than the fit
            uvs = _uv_loop(analysis, loop, geo, 1e-3 * precision)
            wire = TopoDS_Wire()
            builder.MakeWire(wire)
            first = vtx = None
            for k, uv in enumerate(uvs):
                c2d = _pcurve(uv)
                if vtx is None:
                    p = model.geom.Value(*map(float, uv[0]))
                    first = vtx = BRepBuilderAPI_MakeVertex(p).Vertex()
                closing = k == len(uvs) - 1
                end = first if closing else BRepBuilderAPI_MakeVertex(model.geom.Value(*map(float, uv[-1]))).Vertex()
                mk = BRepBuilderAPI_MakeEdge(c2d, model.geom, vtx, end, c2d.FirstParameter(), c2d.LastParameter())
                if not mk.IsDone():
                    raise BrepError(f"BRepBuilderAPI_MakeEdge on the surface failed ({mk.Error()})")
                edge = mk.Edge()
                # a thousandth of the face precision (scales with tolerance), as the UV loop above
                BRepLib.BuildCurves3d_s(edge, 1e-3 * precision)
                builder.Add(wire, edge)
                vtx = end
            wires.append(wire)
        fix = face_fixer(model, wires, precision)
        fix.Perform()
        face = fix.Face()
        # ShapeFix drops a wire it cannot mend (a face left with only its hole). It may split edges
        # and join a band's two wires with a seam, but every edge it was given is still there, in pieces.
        kept, given = _boundary_edge_count(face), sum(len(loop) for loop in loops)
        if kept < given:
            raise BrepError(f"face on its own curves kept {kept} of its {given} edges")
        area = face_area(face)
        if not area > 0:
            raise BrepError(f"face on its own curves has area {area:.4g}")
        flipped = TopoDS.Face_s(face.Reversed())
        problems = face_problems(face) or face_problems(flipped)
        if problems:
            raise BrepError(f"face on its own curves is not valid ({problems})")
        return flipped if vote < 0 else face
    except BrepError:
        raise
    except Exception as err:  # OCC raises Standard_Failure subclasses
        raise BrepError(f"{type(err).__name__}: {err}") from err


def face_on_own_edges(model: SurfaceModel, loops: list[np.ndarray], network: CurveNetwork, geo: NetworkGeometry,
                       vote: int, *, precision: float):
    """A face on edges of its own, for sewing: on copies of the shared curves, else on its own p-curves.

    Returns ``(face or None, area, how it was built)``.
    """
    face, area = face_on_copies(model, loops, network, geo, vote, precision=precision)
    if face is not None:
        return face, area, "built on copies of them"
    face, area = face_on_own_curves(model, loops, geo, vote, precision=precision)
    return face, area, "built on its own curves"


def face_in_child(build, args: tuple, what: str, timeout: float):
    """The face ``build(*args)`` returns, computed in a child process killed after ``timeout`` seconds
    (:func:`recon._parallel.isolated`).

    Some OCC calls can crash the whole process where no exception can be caught (a segmentation fault inside
    GeomPlate on noisy boundaries, inside ShapeFix_Face on a cone's own curves) or spin for minutes
    (``ProjLib_CompProjectedCurve`` inside ``GeomPlate_BuildPlateSurface``). In a child the crash or the hang costs one face, not the user's session: the face comes back
    pickled through the pipe as BREP bytes (:mod:`._serial`). ``build`` raises :class:`BrepError` for a face it
    cannot make.
    """
    got = isolated(build, *args, timeout=timeout, what=what)
    if isinstance(got, Failure):
        if got.kind is FailureKind.TIMED_OUT:
            raise BrepError(f"{what} did not finish within {timeout:g} s; the part has no face")
        if got.kind is FailureKind.CRASHED and got.signal is not None:
            raise BrepError(f"{what} crashed (signal {got.signal}); the part has no face")
        if got.error_type == "BrepError":
            raise BrepError(got.message)
        raise BrepError(f"{what} failed")
    if not isinstance(got, TopoDS_Face) or got.IsNull():
        raise BrepError(f"{what} returned no face")
    return got

"""What :func:`recon.brep.build_solid` returns: a record per face, the solid's validity, the result.

Also the checks a result is measured by (``BRepCheck_Analyzer``, free edges, volume) and the colours the paper
gives each kind of part.
"""

from __future__ import annotations

import enum
import functools
from dataclasses import dataclass, field

from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp
from OCP.GProp import GProp_GProps
from OCP.ShapeAnalysis import ShapeAnalysis_FreeBounds
from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID
from OCP.TopExp import TopExp_Explorer
from OCP.TopoDS import TopoDS_Shape

from ..network import NetworkGeometry

__all__ = ["BrepResult", "FaceRecord", "FaceStatus", "KIND_COLOURS", "Validity", "collapsed_face_count", "free_edge_count",
           "shape_validity"]


class FaceStatus(str, enum.Enum):
    """How a part's face was built (a ``str``: it compares equal to, and is written in reports as, its value)."""

    OK = "ok"  # on its own surface, bounded by the shared edges
    POOR = "poor"  # the same, although its fit is not within tolerance: nothing better could be built
    OK_SEWN = "ok-sewn"  # on its own surface, on edges of its own, joined to its neighbours by sewing
    POOR_SEWN = "poor-sewn"  # the same for a fit not within tolerance
    FILLED = "filled"  # a MakeFilling B-spline through its boundary and mesh points, trimmed by the shared edges
    FILLED_SEWN = "filled-sewn"  # MakeFilling's own face, joined by sewing
    FAILED = "failed"  # no face: the shell has a hole there

    def __str__(self) -> str:
        return self.value

    @property
    def own(self) -> bool:
        """Whether the face lies on the part's own fitted surface."""
        return self in (FaceStatus.OK, FaceStatus.OK_SEWN, FaceStatus.POOR, FaceStatus.POOR_SEWN)

    @staticmethod
    def on_own_surface(fit_ok: bool, *, sewn: bool) -> "FaceStatus":
        """The status of a face on the part's own surface."""
        if fit_ok:
            return FaceStatus.OK_SEWN if sewn else FaceStatus.OK
        return FaceStatus.POOR_SEWN if sewn else FaceStatus.POOR


#: Paper §4 / Figure 4: smooth patches grey, linear parts purple, junctions yellow (terminals green, §3).
KIND_COLOURS = {
    "patch": (0.75, 0.75, 0.75),
    "linear": (0.58, 0.29, 0.78),
    "junction": (0.95, 0.85, 0.15),
    "terminal": (0.30, 0.70, 0.30),
}


@dataclass(frozen=True)
class FaceRecord:
    """One B-rep face: its part, name, kind and surface type, how it was built (:class:`FaceStatus`) and its
    area; ``face`` is the ``TopoDS_Face`` in the final shape (None: the part has no face there)."""

    part: int
    name: str
    kind: str
    surface_type: str
    status: FaceStatus
    area: float
    face: object = field(repr=False, default=None)
    message: str = ""


@dataclass(frozen=True)
class Validity:
    """What OpenCascade says about the result: the checks a user cares about ("a valid closed solid")."""

    shape_type: str
    valid: bool
    closed: bool
    free_edges: int
    volume: float
    n_faces: int
    n_solids: int
    n_shells: int = 0

    @property
    def ok(self) -> bool:
        """One valid closed solid, or (a mesh of several bodies) a compound of them and nothing else."""
        solids = self.shape_type == "solid" or (
            self.shape_type == "compound" and self.n_solids > 0 and self.n_shells == self.n_solids)
        return self.valid and self.closed and solids and self.volume > 0


@dataclass(frozen=True)
class BrepResult:
    """The built B-rep.

    Attributes
    ----------
    occ : TopoDS_Shape
        The OCP shape: a solid, a shell, or a compound of them.
    shape : build123d Solid, Shell or Compound
        ``occ`` wrapped for the user, made on first use (importing build123d takes about 2 s, more than
        the whole B-rep stage of a 100k-triangle box; writing STEP, BREP or STL does not need it).
    faces : tuple of FaceRecord
        One per part that has a boundary, in ``network.parts`` order.
    validity : Validity
    geometry : NetworkGeometry
        Where the network's vertices and edges ended up, with their gaps to the surfaces.
    warnings : tuple of str
    """

    occ: TopoDS_Shape
    faces: tuple
    validity: Validity
    geometry: NetworkGeometry
    warnings: tuple

    @functools.cached_property
    def shape(self):
        from build123d import Compound, Shell, Solid

        return {TopAbs_SOLID: Solid, TopAbs_SHELL: Shell}.get(self.occ.ShapeType(), Compound)(self.occ)

    @property
    def ok(self) -> bool:
        """A valid closed solid in which every part got its own face (no failed face, none lost to fixing)."""
        return self.validity.ok and all(r.status != FaceStatus.FAILED and r.face is not None for r in self.faces)

    def face_names(self) -> list[str]:
        return [f.name for f in self.faces if f.face is not None]


def count_shapes(shape, kind) -> int:
    n = 0
    exp = TopExp_Explorer(shape, kind)
    while exp.More():
        n += 1
        exp.Next()
    return n


def collapsed_face_count(shape) -> int:
    """Faces of ``shape`` bounded by degenerate edges only: a face sewing shrank to a point or a line, with no area.

    OpenCascade's STEP writer skips such a face (an edge loop of degenerate edges is empty), and with it a shell and
    a solid made of nothing else: the file would hold no face.
    """
    from OCP.BRep import BRep_Tool
    from OCP.TopoDS import TopoDS

    n = 0
    faces = TopExp_Explorer(shape, TopAbs_FACE)
    while faces.More():
        edges = TopExp_Explorer(faces.Current(), TopAbs_EDGE)
        while edges.More() and BRep_Tool.Degenerated_s(TopoDS.Edge_s(edges.Current())):
            edges.Next()
        n += not edges.More()
        faces.Next()
    return n


def free_edge_count(shape) -> int:
    """Edges bounding only one face (``ShapeAnalysis_FreeBounds``, no sewing)."""
    fb = ShapeAnalysis_FreeBounds(shape, False, True, False)
    return count_shapes(fb.GetClosedWires(), TopAbs_EDGE) + count_shapes(fb.GetOpenWires(), TopAbs_EDGE)


def shape_validity(shape) -> Validity:
    """Type, validity (``BRepCheck_Analyzer``), closedness (free edges), volume of a shape."""
    occ = getattr(shape, "wrapped", shape)
    type_name = {TopAbs_SOLID: "solid", TopAbs_SHELL: "shell"}.get(occ.ShapeType(), "compound")
    n_solids = count_shapes(occ, TopAbs_SOLID)
    if type_name == "compound" and n_solids == 0:
        type_name = "compound"
    props = GProp_GProps()
    try:
        BRepGProp.VolumeProperties_s(occ, props)
        volume = float(props.Mass())
    except Exception:  # noqa: BLE001  (OCC raises Standard_ConstructionError on a broken shape: it has no volume)
        volume = float("nan")
    free = free_edge_count(occ)
    return Validity(
        shape_type=type_name,
        valid=bool(BRepCheck_Analyzer(occ).IsValid()),
        closed=free == 0,
        free_edges=free,
        volume=volume,
        n_faces=count_shapes(occ, TopAbs_FACE),
        n_solids=n_solids,
        n_shells=count_shapes(occ, TopAbs_SHELL),
    )


def face_area(face) -> float:
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(face, props)
    return float(props.Mass())
